"""Deprecated: this module moved to :mod:`fuelid.plant.simulate` in fuelid 0.2.0.

The old path still works and re-exports the module's names; importing it warns once
(DeprecationWarning). Import :mod:`fuelid.plant.simulate` instead.
"""

from __future__ import annotations

from typing import Any

import fuelid.plant.simulate as _moved
from fuelid._deprecated import warn_moved
from fuelid.plant.simulate import (
    ATOL as ATOL,
)
from fuelid.plant.simulate import (
    MAX_STEPS as MAX_STEPS,
)
from fuelid.plant.simulate import (
    PRESSURE_NOISE_STD as PRESSURE_NOISE_STD,
)
from fuelid.plant.simulate import (
    PRESSURE_RESOLUTION as PRESSURE_RESOLUTION,
)
from fuelid.plant.simulate import (
    PRESSURE_TRUTH_COLUMN as PRESSURE_TRUTH_COLUMN,
)
from fuelid.plant.simulate import (
    RTOL as RTOL,
)
from fuelid.plant.simulate import (
    SNAP as SNAP,
)
from fuelid.plant.simulate import (
    FloatArray as FloatArray,
)
from fuelid.plant.simulate import (
    FuelTemperature as FuelTemperature,
)
from fuelid.plant.simulate import (
    ProgressCallback as ProgressCallback,
)
from fuelid.plant.simulate import (
    SimulationResult as SimulationResult,
)
from fuelid.plant.simulate import (
    integrate_held as integrate_held,
)
from fuelid.plant.simulate import (
    simulate as simulate,
)

warn_moved("fuelid.simulate", "fuelid.plant.simulate")


def __getattr__(name: str) -> Any:
    # anything else the old module had (a private helper a script reached for) comes from the new
    return getattr(_moved, name)


__all__ = [
    "ATOL",
    "MAX_STEPS",
    "PRESSURE_NOISE_STD",
    "PRESSURE_RESOLUTION",
    "PRESSURE_TRUTH_COLUMN",
    "RTOL",
    "SNAP",
    "FloatArray",
    "FuelTemperature",
    "ProgressCallback",
    "SimulationResult",
    "integrate_held",
    "simulate",
]
