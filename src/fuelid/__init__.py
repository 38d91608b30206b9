"""fuelid: gray-box modelling, identification and PI tuning of fuel flow loops.

A variable-frequency drive turns a motor and a fixed-displacement pump that pushes kerosene
through a long pipeline to the combustor nozzles; a turbine flowmeter closes the loop through a
PLC. fuelid models that chain from physics, simulates it as the PLC sees it, identifies it from
logged data and tunes its PI controller.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

from fuelid.errors import ConfigError, DataError, FuelidError, NotFittedError, OutOfRangeError

try:
    __version__ = version("fuelid")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"

__all__ = [
    "ConfigError",
    "DataError",
    "FuelidError",
    "NotFittedError",
    "OutOfRangeError",
    "__version__",
]
