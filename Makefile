# fuelid: the set-up path on Linux. `make demo` and `make test` create .venv when it is missing,
# install fuelid with its dev extras (once; again only when pyproject.toml changes) and run.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.fuelid-installed
DEMO_DIR ?= demo-output

.PHONY: help install demo plc-demo test test-slow soak dashboard-soak lint typecheck pytest \
	browser postgres bench dashboard-soak-page clean docs docs-serve docs-assets

help:
	@echo "make demo   - install if needed, run the reference-plant demo (writes $(DEMO_DIR)/)"
	@echo "make plc-demo - the virtual PLC over Modbus: record, export, identify (writes $(DEMO_DIR)/plc/)"
	@echo "make test   - install if needed, run ruff, mypy and the fast pytest suite (about 6 min)"
	@echo "make test-slow - the long fault runs and a 3 h soak (CI runs them after make test)"
	@echo "make soak   - the 24 h soak against the virtual PLC (on demand, about 30 min, prints its table)"
	@echo "make dashboard-soak - a loop page open 30 min on a virtual loop at 20x (on demand; heap table)"
	@echo "make dashboard-soak-page - the same, its table written to docs/benchmarks/dashboard_soak.md"
	@echo "make bench  - run the benchmarks (on demand; prints tables, writes docs/benchmarks/)"
	@echo "make docs   - build the documentation site into site/ (mkdocs build --strict)"
	@echo "make docs-serve - serve the documentation with live reload on http://127.0.0.1:8000"
	@echo "make docs-assets - write docs/assets/ (the report screenshot) and the benchmark index"
	@echo "make clean  - remove the virtual environment and generated files"

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --upgrade pip
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[dev,plc,dashboard,fleet]'
	@touch $(STAMP)

install: $(STAMP)

REFERENCE_PLANT := src/fuelid/data/reference_plant.toml

demo: $(STAMP)
	$(BIN)/fuelid plant info --u 1.25
	$(BIN)/python examples/demo.py --out $(DEMO_DIR)
	$(BIN)/fuelid simulate $(DEMO_DIR)/random_binary.parquet --profile random --levels 1.0,2.0 \
		--hold 5 --duration 600 --seed 7 --force --quiet
	@echo "--- the same chain from the command line: identify to JSON, tune from it ---"
	$(BIN)/fuelid identify $(DEMO_DIR)/step_sequence.csv --config $(REFERENCE_PLANT) \
		--json > $(DEMO_DIR)/ident.json
	$(BIN)/fuelid tune --model $(DEMO_DIR)/ident.json --config $(REFERENCE_PLANT) --rule simc \
		--control-period 1 --simulate --plot $(DEMO_DIR)/tune_closed_loop.png --force

# The PLC link end to end: the virtual PLC over Modbus TCP on 127.0.0.1, 15 s of recording at 20×
# real time (5 minutes of plant time), export, identify; see examples/plc_demo.py.
plc-demo: $(STAMP)
	$(BIN)/python examples/plc_demo.py --out $(DEMO_DIR)/plc

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks examples docs/hooks docs/scripts
	$(BIN)/ruff format --check src tests benchmarks examples docs/hooks docs/scripts
	$(BIN)/lint-imports

typecheck: $(STAMP)
	$(BIN)/mypy

# The browser test (tests/integration/htmlreport/test_report_browser.py) opens the HTML report in headless
# Chromium. As root (CI, a container) Chromium is installed from Debian when missing; otherwise
# the test skips and says why (under CI, with CI set, it fails instead).
browser:
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || \
	if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
		echo "installing chromium for the browser test (apt-get)"; \
		apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
			--no-install-recommends chromium fonts-liberation >/dev/null; \
	else \
		echo "chromium missing and not root (or no apt-get): the browser test will skip"; \
	fi

# The central-store tests (issue 26) start a temporary PostgreSQL cluster (initdb, pg_ctl) on
# 127.0.0.1. As root the server is installed from Debian when no initdb is found (on PATH or
# under /usr/lib/postgresql/*/bin, where Debian puts it); otherwise those tests skip and say why
# (under CI, with CI set, they fail instead).
postgres:
	@command -v initdb >/dev/null 2>&1 || ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1 || \
	if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
		echo "installing postgresql for the central-store tests (apt-get)"; \
		apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
			--no-install-recommends postgresql >/dev/null; \
	else \
		echo "postgresql missing and not root (or no apt-get): the central-store tests will skip"; \
	fi

# `make test` runs the short version of every test, on every core (pytest-xdist; the tests that
# run a PLC at speed share one worker under --dist loadgroup: tests/conftest.py); budget 6 min
# with lint and mypy on 2 cores (.ci/run). Every test has a deadline (pytest-timeout,
# pyproject.toml). The long fault runs and the soak are marked slow. The 20 slowest tests are
# printed at the end, so that the suite's growth stays visible.
PYTEST_WORKERS ?= auto
pytest: $(STAMP) browser postgres
	$(BIN)/python -m pytest -q -m "not slow" -n $(PYTEST_WORKERS) --dist loadgroup --durations=20

test: lint typecheck pytest

# The slow set runs in one process: the fault runs and the soak drive the virtual PLC at 20-50x
# real time, and a second worker on a 2-core machine would starve their recorders. The soak
# runs SLOW_SOAK_HOURS of plant time (3 h here: the CI budget, .ci/run; its bands are computed
# for the hours run) with its own deadline; every other slow test gets 15 min; the 20 slowest are
# printed, so the set's growth stays visible. -rfEP: they print
# their measurements, and a failure's one-line reason comes last (CI shows the output's tail).
SLOW_SOAK_HOURS ?= 3
test-slow: $(STAMP) postgres
	FUELID_SOAK_HOURS=$(SLOW_SOAK_HOURS) $(BIN)/python -m pytest -q -m slow -rfEP -p no:xdist \
		--timeout=900 --durations=20

# The 24 h soak (tests/system/test_online_soak.py) on demand: about 30 min at 50x, prints its
# table; SOAK_HOURS=… for another length (its bands are computed from the counts of the run).
SOAK_HOURS ?= 24
soak: $(STAMP)
	FUELID_SOAK_HOURS=$(SOAK_HOURS) $(BIN)/python -m pytest -q -m slow -s -p no:xdist \
		tests/system/test_online_soak.py

# The dashboard's soak (tests/system/test_dashboard_soak.py, issue 39) on demand: one loop page in
# headless Chromium open for DASHBOARD_SOAK_MINUTES of wall time on a virtual loop at 20x (30 min:
# 10 h of plant time); prints the tab's heap, minute by minute. Collected only with
# FUELID_DASHBOARD_SOAK_MINUTES set: neither make test nor the slow set runs it.
DASHBOARD_SOAK_MINUTES ?= 30
dashboard-soak: $(STAMP) browser
	FUELID_DASHBOARD_SOAK_MINUTES=$(DASHBOARD_SOAK_MINUTES) $(BIN)/python -m pytest -q -rP \
		-p no:xdist tests/system/test_dashboard_soak.py
# The same run writing its table into docs/benchmarks/dashboard_soak.md (make bench runs it too).
dashboard-soak-page: $(STAMP) browser
	$(BIN)/python benchmarks/bench_dashboard_soak.py --minutes $(DASHBOARD_SOAK_MINUTES)

# The benchmarks get their own environment: the peer (sysidentpy) pins an older numpy, which
# must not replace the one the tests run with.
BENCH_VENV ?= .venv-bench

$(BENCH_VENV)/.fuelid-installed: pyproject.toml
	$(PYTHON) -m venv $(BENCH_VENV)
	$(BENCH_VENV)/bin/python -m pip install --quiet --disable-pip-version-check --upgrade pip
	$(BENCH_VENV)/bin/python -m pip install --quiet --disable-pip-version-check -e '.[dev,bench,plc,dashboard,fleet]'
	@touch $@

bench: $(BENCH_VENV)/.fuelid-installed
	$(BENCH_VENV)/bin/python benchmarks/bench_simulate.py
	$(BENCH_VENV)/bin/python benchmarks/bench_identify_speed.py
	$(BENCH_VENV)/bin/python benchmarks/bench_day_log.py
	$(BENCH_VENV)/bin/python benchmarks/bench_identify_accuracy.py
	$(BENCH_VENV)/bin/python benchmarks/bench_default_path.py --runs 500
	$(BENCH_VENV)/bin/python benchmarks/bench_gate_study.py
	$(BENCH_VENV)/bin/python benchmarks/bench_refdata.py
	$(BENCH_VENV)/bin/python benchmarks/bench_tuning_sweep.py
	$(BENCH_VENV)/bin/python benchmarks/bench_cold_start.py
	$(BENCH_VENV)/bin/python benchmarks/bench_store.py
	$(BENCH_VENV)/bin/python benchmarks/bench_archive.py
	$(BENCH_VENV)/bin/python benchmarks/bench_virtual_plant.py
	$(BENCH_VENV)/bin/python benchmarks/bench_dashboard.py
	$(BENCH_VENV)/bin/python benchmarks/bench_window_report.py
	$(BENCH_VENV)/bin/python benchmarks/bench_dashboard_page.py
	$(BENCH_VENV)/bin/python benchmarks/bench_dashboard_soak.py
	$(BENCH_VENV)/bin/python benchmarks/bench_central.py
	$(BENCH_VENV)/bin/python benchmarks/bench_acquisition.py --minutes 2
	$(BENCH_VENV)/bin/python benchmarks/bench_online.py --minutes 2
	$(BENCH_VENV)/bin/python benchmarks/bench_window.py
	$(BENCH_VENV)/bin/python benchmarks/bench_greybox.py --runs 200
	$(BENCH_VENV)/bin/python benchmarks/bench_greybox_peer.py
	$(BENCH_VENV)/bin/python benchmarks/bench_calibration.py --timing
	$(BENCH_VENV)/bin/python benchmarks/bench_calibration.py --runs 200 --minutes 2
	$(BENCH_VENV)/bin/python benchmarks/bench_reidentify.py
	$(BENCH_VENV)/bin/python benchmarks/bench_trust.py
	$(BENCH_VENV)/bin/python benchmarks/bench_excitation.py

# The documentation site (mkdocs.yml): the docs extra goes into .venv once (again when
# pyproject.toml changes); the command reference is rendered from the CLI at build time.
DOCS_STAMP := $(VENV)/.fuelid-docs-installed

$(DOCS_STAMP): pyproject.toml $(STAMP)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[dev,plc,docs]'
	@touch $@

docs: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/python -m mkdocs build --strict

docs-serve: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/python -m mkdocs serve

# Generated pictures and pages are committed and written only here and by `make bench`, never by
# `make test`: the report screenshot (headless Chromium, see `make browser`) and the benchmark
# index with a "not yet run" page for each benchmark that has none.
docs-assets: $(STAMP) browser
	$(BIN)/python docs/scripts/assets.py
	$(BIN)/python benchmarks/_docs_table.py

clean:
	rm -rf $(VENV) $(BENCH_VENV) $(DEMO_DIR) site .pytest_cache .mypy_cache .ruff_cache
