"""What a cold ``fuelid`` process imports: help and version load no numerical library.

Each case runs in a fresh interpreter (``sys.executable -c``), calls the command line's entry
point and reports which heavy modules ended up in ``sys.modules``. These are behaviour tests:
how long a start takes is measured in benchmarks/bench_cold_start.py.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

HEAVY = ("matplotlib", "control", "scipy.signal", "scipy.optimize", "pandas")
"""Modules ``fuelid --help`` and ``--version`` must not import."""

PROBE = """
import contextlib, io, json, sys
from fuelid.cli import main
codes = []
for argv in {argv!r}:
    with contextlib.redirect_stdout(io.StringIO()):
        codes.append(main(argv))
print(json.dumps({{"codes": codes, "loaded": sorted(m for m in {names!r} if m in sys.modules)}}))
"""


def _loaded(*argv: list[str], names: tuple[str, ...] = HEAVY) -> tuple[list[int], list[str]]:
    """Exit codes of the command lines ``argv`` run in one fresh process, and what they loaded."""
    code = PROBE.format(argv=list(argv), names=names)
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    result = json.loads(done.stdout.strip().splitlines()[-1])
    return result["codes"], result["loaded"]


def test_help_and_version_import_no_numerical_library():
    codes, loaded = _loaded(["--help"], ["--version"])
    assert codes == [0, 0]
    assert loaded == []


@pytest.mark.parametrize(
    "command", [["identify"], ["tune"], ["report"], ["simulate"], ["plant", "info"]]
)
def test_command_help_imports_no_numerical_library(command: list[str]):
    codes, loaded = _loaded([*command, "--help"], names=(*HEAVY, "numpy", "jinja2"))
    assert codes == [0]
    assert loaded == []


def test_identify_help_imports_neither_matplotlib_nor_control():
    codes, loaded = _loaded(["identify", "--help"], names=("matplotlib", "control"))
    assert codes == [0]
    assert loaded == []


@pytest.mark.parametrize(
    ("command", "option"),
    [
        (["identify"], "--flowmeter-T"),
        (["tune"], "--tau-c"),
        (["report"], "--fuel-temp"),
        (["simulate"], "--noise-std"),
    ],
)
def test_command_help_still_lists_its_options_with_units(
    command: list[str], option: str, capsys: pytest.CaptureFixture[str]
):
    from fuelid.cli import main

    assert main([*command, "--help"]) == 0
    text = capsys.readouterr().out
    assert option in text
    assert "[s]" in text or "[°C]" in text or "[L/min]" in text


@pytest.fixture(scope="module")
def log_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A first-order step response with noise: enough for ``fuelid identify`` to fit."""
    t = np.arange(0.0, 60.0, 0.05)
    u = np.where(t < 10.0, 2.0, 3.0)
    rng = np.random.default_rng(1)
    q = 30.0 + 13.0 * np.where(t < 10.0, 0.0, 1.0 - np.exp(-(t - 10.0) / 1.3))
    q = q + rng.normal(0.0, 0.05, t.size)
    path = tmp_path_factory.mktemp("startup") / "log.csv"
    np.savetxt(path, np.column_stack([t, u, q]), delimiter=",", header="t_s,u_V,q_Lpm", comments="")
    return path


def test_identify_without_plot_does_not_import_matplotlib(log_csv: Path):
    codes, loaded = _loaded(["identify", str(log_csv), "--json"], names=("matplotlib", "jinja2"))
    assert codes == [0]
    assert loaded == []


def test_identify_does_not_import_control(log_csv: Path):
    codes, loaded = _loaded(["identify", str(log_csv), "--json"], names=("control",))
    assert codes == [0]
    assert loaded == []


TUNE = [
    "tune", "--K", "13.5", "--T", "1.26", "--T-f", "0.3", "--delay", "0.2",
    "--control-period", "1",  # never assumed (issue 37)
    "--json",
]  # fmt: skip


def test_tune_does_not_import_the_report_template_engine():
    codes, loaded = _loaded(TUNE, names=("jinja2", "fuelid.htmlreport"))
    assert codes == [0]
    assert loaded == []


def test_tune_without_plot_does_not_import_matplotlib():
    codes, loaded = _loaded(TUNE, names=("matplotlib",))
    assert codes == [0]
    assert loaded == []
