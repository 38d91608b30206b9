"""Deprecated: this module moved to :mod:`fuelid.identify.preprocess` in fuelid 0.2.0.

The old path still works and re-exports the module's names; importing it warns once
(DeprecationWarning). Import :mod:`fuelid.identify.preprocess` instead.
"""

from __future__ import annotations

from typing import Any

import fuelid.identify.preprocess as _moved
from fuelid._deprecated import warn_moved
from fuelid.identify.preprocess import (
    ANTIALIAS_FRACTION as ANTIALIAS_FRACTION,
)
from fuelid.identify.preprocess import (
    INTEGER_FACTOR_TOLERANCE as INTEGER_FACTOR_TOLERANCE,
)
from fuelid.identify.preprocess import (
    MIN_SELECTED_SAMPLES as MIN_SELECTED_SAMPLES,
)
from fuelid.identify.preprocess import (
    decimate as decimate,
)
from fuelid.identify.preprocess import (
    join_segments as join_segments,
)
from fuelid.identify.preprocess import (
    lowpass as lowpass,
)
from fuelid.identify.preprocess import (
    select as select,
)

warn_moved("fuelid.preprocess", "fuelid.identify.preprocess")


def __getattr__(name: str) -> Any:
    # anything else the old module had (a private helper a script reached for) comes from the new
    return getattr(_moved, name)


__all__ = [
    "ANTIALIAS_FRACTION",
    "INTEGER_FACTOR_TOLERANCE",
    "MIN_SELECTED_SAMPLES",
    "decimate",
    "join_segments",
    "lowpass",
    "select",
]
