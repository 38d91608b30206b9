"""Fixtures shared by tests/unit, tests/integration and tests/system.

Plain helpers (statistical bands, the test PLC, site files) live in tests/support; fixtures live
here and in each folder's conftest.py, so no test module imports another.
"""

from __future__ import annotations

import os

# BLAS on one thread for the whole run, in every worker and every fuelid process a test starts
# (set before numpy loads: this file is imported before any test module). fuelid's matrices are
# small (scipy's expm of a plant's state matrix, thousands of times in a gain schedule), and a
# multi-threaded OpenBLAS on a loaded 2-core machine spends its time waiting for its other
# thread: measured 0.14 ms an 8×8 expm on one thread against 28 ms with the default threads while
# a second worker ran (200×); the gain-schedule tests went from 2 min to seconds. The commands
# limit BLAS themselves (fuelid.blas); tests/system/test_cli_consistency.py checks that with the
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
