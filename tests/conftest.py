"""Fixtures shared by tests/unit, tests/integration and tests/system.

Plain helpers (statistical bands, the test PLC, site files) live in tests/support; fixtures live
here and in each folder's conftest.py, so no test module imports another.
"""

from __future__ import annotations

import os
from typing import Any

# BLAS on one thread for the whole run, in every worker and every fuelid process a test starts
# (set before numpy loads: this file is imported before any test module). fuelid's matrices are
# small (scipy's expm of a plant's state matrix, thousands of times in a gain schedule), and a
# multi-threaded OpenBLAS on a loaded 2-core machine spends its time waiting for its other
# thread: measured 0.14 ms an 8×8 expm on one thread against 28 ms with the default threads while
# a second worker ran (200×); the gain-schedule tests went from 2 min to seconds. The commands
# limit BLAS themselves (fuelid.blas); tests/unit/cli/test_guarded_blas.py checks that with the
# limit lifted. A developer's own setting wins.
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import pytest  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from fuelid.plant import PlantConfig, load_plant_config  # noqa: E402

# and for a BLAS some plugin already loaded (the variables above act only on the next load)
threadpool_limits(limits=1, user_api="blas")


@pytest.fixture(scope="session")
def cfg() -> PlantConfig:
    """The packaged reference plant, loaded once per process (tests only read it)."""
    return load_plant_config()


# Two xdist groups, by pytest-xdist's public mark (`pytestmark =
# pytest.mark.xdist_group(...)` in each module; `grep -rl xdist_group tests` lists them). Under
# `pytest -n auto --dist loadgroup` (`make test`) one worker runs a group's tests one after
# another while the other workers run the rest; tests/unit/test_xdist_grouping.py checks that the
# installed pytest and pytest-xdist still group (pytest 9.2 with xdist 3.8 does not:
# pytest-dev/pytest-xdist#1386, hence the pin in pyproject.toml).
#
# "real-time": the tests that run a PLC (the virtual PLC, the Modbus test PLC, OPC UA and S7
# servers) against a recorder or the online service at 20-50x real time: their checks assume the
# recorder keeps up, so two of them never compete for the same cores (two at once on a loaded
# 2-core machine lost samples and missed restarts).
#
# "dashboard": the dashboard's tests share one store made by a short virtual run (the session
# fixture `dashboard_store`): one worker runs them all, so the run is made once.


DASHBOARD_ONLINE = 'identify_every_s = 60\nwindow_s = 120\nwrite_back = "approve"\n'
"""The [online] table of the dashboard tests' virtual run: a window every minute of plant time."""


@pytest.fixture(scope="session")
def dashboard_store(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """A store written by ``fuelid online --virtual``: 9 min of plant time at 25x.

    Windows, a proposal left pending (write_back "approve"; 9 min leave room for a window a
    loaded machine refuses: the proposal needs two agreeing windows after the first), events.
    Tests that change the store copy it first.
    """
    pytest.importorskip("pymodbus")
    from support.browser import Process

    folder = tmp_path_factory.mktemp("dashboard-store")
    config = folder / "online.toml"
    config.write_text("[online]\n" + DASHBOARD_ONLINE)
    store = folder / "loop.db"
    proc = Process(
        ["online", "--virtual", "--speed", "25", "--hours", "0.15", "--store", str(store),
         "--config", str(config)],
        folder,
    )  # fmt: skip
    code = proc.wait(timeout=120.0)
    assert code == 0, "\n".join(proc.output[-20:])
    return store


FLEET_HOURS = 3.0
"""Plant hours of each of the two fleet tests' loops (issue 26: "two loops, a few hours each")."""


@pytest.fixture(scope="session")
def fleet_loops(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """Two sites' stores, written offline by the simulator and analysed as the service would.

    ``line-a``: AUTO, the fuel warming from 15 to 25 °C over the run, seed 1. ``line-b``: MAN,
    20 °C, seed 2, with samples whose values are missing (NULL, quality bad_value) in the first
    30 s of its second and third hours (599 samples). Each store has its samples, a
    ``restart`` event, and every window of the service's schedule (default ``[online]``: 10 min
    windows every 5 min) with the accepted ones' models. Tests that change a store copy it
    first (:func:`support.fleet.copy_loop`).
    """
    import fcntl
    import pickle

    from support.fleet import analyse_loop, checkpoint, simulate_loop

    # built once for the whole run: the xdist workers share the folder above their own base
    # temp (a lock, then the pickled loops when another worker built them already); a run
    # without workers builds in its own base temp
    base = tmp_path_factory.getbasetemp()
    shared = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "fleet-loops"
    shared.mkdir(exist_ok=True)
    with open(shared / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        built = shared / "loops.pickle"
        if built.exists():
            loops: dict[str, Any] = pickle.loads(built.read_bytes())
            return loops
        seconds = FLEET_HOURS * 3600.0
        a = simulate_loop(
            shared / "line-a.db", "line-a", hours=FLEET_HOURS, seed=1,
            fuel_temp_profile=([0.0, seconds], [15.0, 25.0]),
        )  # fmt: skip
        b = simulate_loop(
            shared / "line-b.db", "line-b", hours=FLEET_HOURS, seed=2, mode="MAN",
            bad=lambda t: ((t - a.t_first) % 3600.0 < 30.0) & (t - a.t_first > 3600.0),
        )  # fmt: skip
        for loop in (a, b):
            analyse_loop(loop)
            checkpoint(loop.path)
        loops = {"line-a": a, "line-b": b}
        built.write_bytes(pickle.dumps(loops))
        return loops
