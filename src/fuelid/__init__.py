"""fuelid: gray-box modelling, identification and PI tuning of fuel flow loops.

A variable-frequency drive turns a motor and a fixed-displacement pump that pushes kerosene
through a long pipeline to the combustor nozzles; a turbine flowmeter closes the loop through a
PLC. fuelid models that chain from physics, simulates it as the PLC sees it, identifies it from
logged data and tunes its PI controller.
"""

from __future__ import annotations

from fuelid.errors import ConfigError, DataError, FuelidError, NotFittedError, OutOfRangeError

__version__ = "0.1.0"
"""The one place the version is written: pyproject.toml reads it from here (setuptools' dynamic
``attr``), so no command pays for importlib.metadata at start-up."""

__all__ = [
    "ConfigError",
    "DataError",
    "FuelidError",
    "NotFittedError",
    "OutOfRangeError",
    "__version__",
]
