"""Identification of the equivalent model from logged input/output data.

- :mod:`~fuelid.identify.step_ls`: the source article's method (truncated step-response least
  squares, then K and T by Newton iteration with the flowmeter's T_f and τ known);
- :mod:`~fuelid.identify.oe`: output-error (maximum-likelihood under white noise) fit of the
  continuous-time gray-box model on the raw samples, with exact ZOH discretisation and a
  fractional dead time.
"""
