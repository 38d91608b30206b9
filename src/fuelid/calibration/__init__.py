"""Calibration of the plant's physical parameters from logs (the mechanism model's gray box).

:mod:`fuelid.calibration.plant_model` makes the plant ODE a gray-box model of the parameters
named free; :mod:`fuelid.greybox` fits it to one or several logs at their fuel temperatures.

The public API
--------------
The package itself exports no names (``__all__`` is empty), so that importing
:mod:`~fuelid.calibration.plant_model` does not load the log readers. Promised at
:mod:`fuelid.calibration.calibrate`: :func:`~fuelid.calibration.calibrate.calibrate`,
:class:`~fuelid.calibration.calibrate.CalibrationResult`,
:func:`~fuelid.calibration.calibrate.load_calibration_log`,
:class:`~fuelid.calibration.calibrate.CalibrationRefused`; at
:mod:`fuelid.calibration.plant_model`: :class:`~fuelid.calibration.plant_model.PlantGreyBox`.
"""

__all__: list[str] = []
