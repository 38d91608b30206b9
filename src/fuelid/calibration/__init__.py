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

from typing import TYPE_CHECKING

import lazy_loader

if TYPE_CHECKING:
    from fuelid.calibration._logs import calibration_log

# Each name is imported from its private module on first use (lazy_loader, SPEC 1), so
# that importing the package stays cheap.
__getattr__ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "_logs": ["calibration_log"],
    },
)[0]

__all__ = [
    "calibration_log",
]
