"""Calibration of the plant's physical parameters from logs (the mechanism model's gray box).

:mod:`fuelid.calibration.plant_model` makes the plant ODE a gray-box model of the parameters
named free; :mod:`fuelid.greybox` fits it to one or several logs at their fuel temperatures.
"""
