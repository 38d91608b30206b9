"""Fixtures shared by tests/unit, tests/integration and tests/system.

Plain helpers (statistical bands, the test PLC, site files) live in tests/support; fixtures live
here and in each folder's conftest.py, so no test module imports another.
"""

from __future__ import annotations

import pytest

from fuelid.plant import PlantConfig, load_plant_config


@pytest.fixture(scope="session")
def cfg() -> PlantConfig:
    """The packaged reference plant, loaded once per process (tests only read it)."""
    return load_plant_config()
