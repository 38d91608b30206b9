"""Calibration of the plant's physical parameters from logs (the mechanism model's gray box).

:mod:`fuelid.calibration.plant_model` makes the plant ODE a gray-box model of the parameters
named free; :mod:`fuelid.greybox` fits it to one or several logs at their fuel temperatures.

The public API
--------------
The names in ``__all__``, each loaded on first use, so that importing
:mod:`~fuelid.calibration.plant_model` does not load the log readers. Promised at
:mod:`fuelid.calibration.calibrate`: :func:`~fuelid.calibration.calibrate.calibrate`,
:class:`~fuelid.calibration.calibrate.CalibrationResult`,
:func:`~fuelid.calibration.calibrate.load_calibration_log`,
:class:`~fuelid.calibration.calibrate.CalibrationRefused`; at
:mod:`fuelid.calibration.plant_model`: :class:`~fuelid.calibration.plant_model.PlantGreyBox`.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from fuelid.calibration._logs import calibration_log

_HOMES = {
    "calibration_log": "fuelid.calibration._logs",
}
"""Exported name → the private module that defines it, imported on first use (PEP 562)."""

__all__ = [
    "calibration_log",
]


def __getattr__(name: str) -> Any:
    # imported on use: importing the package loads none of its modules
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
