"""Two cascaded tanks, the smooth model: Torricelli outflows, no overflow, no clipped sensor.

The model of ``cascaded_tanks.py`` without its switch and its clip, for the real-like record of
``cascaded_tanks_data.py`` (and the benchmark's real one): a pump at u [V] fills the upper tank
(level x1), which drains into the lower one (x2), each outflow going with the square root of
the level; the sensor reads the lower level plus an offset c:

    dx1/dt = −k1·√x1 + k4·u        dx2/dt = k2·√x1 − k3·√x2        y = x2 + c

The upper level is not measured, so its scale is free: k4 is fixed. The start values are the
ones guessed in ``cascaded_tanks.py`` (k1 = k2 = k3 = 0.06 from the steady state at the mean
pump voltage). The record's plant overflows and its sensor clips now and then, which this model
leaves to its residuals: a fit of it has a model error, as on the real record. The speed
benchmark (benchmarks/bench_greybox_peer.py, row "real-like") fits it against a hand-written
least_squares + odeint script.

This file is plain Python and ``fuelid greybox`` runs it: only run model files you trust.
"""

import math

states = ["x1", "x2"]  # upper and lower level [V of the sensor]
inputs = ["u_V"]  # pump voltage [V]
outputs = ["y_V"]  # the lower tank's level sensor [V]

parameters = {
    "k1": {"value": 0.06, "lower": 0.0, "unit": "V^0.5/s"},  # upper outflow / upper area
    "k2": {"value": 0.06, "lower": 0.0, "unit": "V^0.5/s"},  # the same flow / lower area
    "k3": {"value": 0.06, "lower": 0.0, "unit": "V^0.5/s"},  # lower outflow / lower area
    "k4": {"value": 0.03, "lower": 0.0, "fixed": True, "unit": "1/s"},  # pump / upper area
    "c": {"value": 0.0, "unit": "V"},  # the sensor's offset
}


def f(t, x, u, p):
    """dx/dt [V/s] of the levels x [V] at the pump voltage u [V]."""
    x1 = max(x[0], 0.0)
    x2 = max(x[1], 0.0)
    dx1 = -p["k1"] * math.sqrt(x1) + p["k4"] * u[0]
    dx2 = p["k2"] * math.sqrt(x1) - p["k3"] * math.sqrt(x2)
    return [dx1, dx2]


def h(x, u, p):
    """The level sensor [V]: the lower level plus an offset."""
    return x[1] + p["c"]
