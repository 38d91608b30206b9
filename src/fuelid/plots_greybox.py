"""Deprecated: this module moved to :mod:`fuelid.plots.greybox` in fuelid 0.2.0.

The old path still works and re-exports the module's names; importing it warns once
(DeprecationWarning). Import :mod:`fuelid.plots.greybox` instead, and save the figure with
:func:`fuelid.plots.save_figure` (``save_greybox_figure`` was the same function under a second
name).
"""

from __future__ import annotations

from typing import Any

import fuelid.plots.greybox as _moved
from fuelid._deprecated import warn_moved
from fuelid.plots._common import save_figure as save_greybox_figure
from fuelid.plots.greybox import (
    FitPanel as FitPanel,
)
from fuelid.plots.greybox import (
    plot_greybox_fit as plot_greybox_fit,
)

warn_moved("fuelid.plots_greybox", "fuelid.plots.greybox")


def __getattr__(name: str) -> Any:
    # anything else the old module had (a private helper a script reached for) comes from the new
    return getattr(_moved, name)


__all__ = [
    "FitPanel",
    "plot_greybox_fit",
    "save_greybox_figure",
]
