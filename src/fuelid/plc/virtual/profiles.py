"""Deprecated: this module moved to :mod:`fuelid.profiles.runs` in fuelid 0.2.0.

The old path still works and re-exports the module's names; importing it warns once
(DeprecationWarning). Import :mod:`fuelid.profiles.runs` instead.
"""

from __future__ import annotations

from typing import Any

import fuelid.profiles.runs as _moved
from fuelid._deprecated import warn_moved
from fuelid.profiles.runs import (
    DEMO_DAY_S as DEMO_DAY_S,
)
from fuelid.profiles.runs import (
    DEMO_TEMPERATURE_C as DEMO_TEMPERATURE_C,
)
from fuelid.profiles.runs import (
    DEMO_TEST_POINTS_LPM as DEMO_TEST_POINTS_LPM,
)
from fuelid.profiles.runs import (
    PROFILE_COLUMNS as PROFILE_COLUMNS,
)
from fuelid.profiles.runs import (
    STEP_DWELL_S as STEP_DWELL_S,
)
from fuelid.profiles.runs import (
    STEP_LEVELS_V as STEP_LEVELS_V,
)
from fuelid.profiles.runs import (
    TIME_COLUMNS as TIME_COLUMNS,
)
from fuelid.profiles.runs import (
    FloatArray as FloatArray,
)
from fuelid.profiles.runs import (
    Profile as Profile,
)
from fuelid.profiles.runs import (
    demo_run_profile as demo_run_profile,
)
from fuelid.profiles.runs import (
    demo_temperature as demo_temperature,
)
from fuelid.profiles.runs import (
    load_profile as load_profile,
)
from fuelid.profiles.runs import (
    run_profile as run_profile,
)
from fuelid.profiles.runs import (
    steps_profile as steps_profile,
)

warn_moved("fuelid.plc.virtual.profiles", "fuelid.profiles.runs")


def __getattr__(name: str) -> Any:
    # anything else the old module had (a private helper a script reached for) comes from the new
    return getattr(_moved, name)


__all__ = [
    "DEMO_DAY_S",
    "DEMO_TEMPERATURE_C",
    "DEMO_TEST_POINTS_LPM",
    "PROFILE_COLUMNS",
    "STEP_DWELL_S",
    "STEP_LEVELS_V",
    "TIME_COLUMNS",
    "FloatArray",
    "Profile",
    "demo_run_profile",
    "demo_temperature",
    "load_profile",
    "run_profile",
    "steps_profile",
]
