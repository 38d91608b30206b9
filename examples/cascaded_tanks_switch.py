"""The cascaded tanks of ``cascaded_tanks.py`` with the overflow's switch declared.

``cascaded_tanks.py`` is the model as a user first writes it, the overflow an ``if`` on the
upper level (which fuelid names with its line when it loads the file). Here the same branch
reads two declared switches instead: ``full`` (the upper level at or above xmax) and
``filling`` (the pump's inflow above the upper outflow). Each is located as a solver event, the
sensitivities jump there, and while the tank is full and filling its level stays at xmax
exactly. Everything else is ``cascaded_tanks.py``'s:

The model a user writes for the cascaded-tanks benchmark (Schoukens & Noël, 2017) and for its
real-like stand-in made by ``cascaded_tanks_data.py``. A pump at u [V] fills the upper tank
(level x1), which drains into the lower tank (x2); by Torricelli each outflow goes with the
square root of the level:

    dx1/dt = −k1·√x1 + k4·u        dx2/dt = k2·√x1 − k3·√x2

When the upper tank is full (x1 ≥ xmax) and still filling, it overflows: its level stays, and a
share kov of the inflow it cannot hold falls into the lower tank. The sensor reads the lower
level plus an offset c and saturates at 10 V: y = min(x2 + c, 10). The levels are in the
sensor's volts. The upper level is not measured, so its scale is free (see the gray-box guide,
"Fit: first refused"): k4 is fixed.

How the start values were guessed, as a user would from the estimation record:

- k4 = 0.03 V/(s·V): the pump's flow per volt over the upper tank's area, from a bucket test
  (what fixes the upper level's scale);
- k1 = k2 = k3 = 0.06: at the record's mean pump voltage (5 V) the level sensor reads about
  5.7 V; taking the two tanks alike (x1 ≈ x2 ≈ 5.7 V, c ≈ 0) the steady state k1·√x1 = k4·u
  gives k1 = 0.03·5/√5.7 ≈ 0.06, and k2 = k3 = k1;
- xmax = 8: the upper tank is seen to overflow at the highest inflows; guessed a little above
  the lower tank's typical high level;
- kov = 0.5: half of the overflow guessed to reach the lower tank; c = 0: no offset.

This file is plain Python and ``fuelid greybox`` runs it: only run model files you trust.
"""

import math

Y_MAX = 10.0  # the sensor saturates here [V]

states = ["x1", "x2"]  # upper and lower level [V of the sensor]
inputs = ["u_V"]  # the data file's input column: pump voltage [V]
outputs = ["y_V"]  # the data file's output column: the lower tank's level sensor [V]

parameters = {
    "k1": {"value": 0.06, "lower": 0.0, "unit": "V^0.5/s"},  # upper outflow / upper area
    "k2": {"value": 0.06, "lower": 0.0, "unit": "V^0.5/s"},  # the same flow / lower area
    "k3": {"value": 0.06, "lower": 0.0, "unit": "V^0.5/s"},  # lower outflow / lower area
    "k4": {"value": 0.03, "lower": 0.0, "fixed": True, "unit": "1/s"},  # pump / upper area
    "xmax": {"value": 8.0, "lower": 0.0, "unit": "V"},  # the upper tank's overflow level
    "kov": {"value": 0.5, "lower": 0.0, "upper": 1.0, "unit": "1"},  # share into the lower tank
    "c": {"value": 0.0, "unit": "V"},  # the sensor's offset
}


def full(t, x, u, p):
    """The switch [V]: positive while the upper level is above the overflow's."""
    return x[0] - p["xmax"]


def filling(t, x, u, p):
    """The switch [V/s]: positive while the pump fills the upper tank faster than it drains."""
    return p["k4"] * u[0] - p["k1"] * math.sqrt(max(x[0], 0.0))


switches = [full, filling]  # located as solver events; f reads on["full"], on["filling"]


def f(t, x, u, p, on):
    """dx/dt [V/s] of the levels x [V] at the pump voltage u [V]."""
    x1 = max(x[0], 0.0)
    x2 = max(x[1], 0.0)
    dx1 = -p["k1"] * math.sqrt(x1) + p["k4"] * u[0]
    dx2 = p["k2"] * math.sqrt(x1) - p["k3"] * math.sqrt(x2)
    if on["full"] and on["filling"]:  # full and filling: the upper tank overflows
        dx2 += p["kov"] * dx1
        dx1 = 0.0
    return [dx1, dx2]


def h(x, u, p):
    """The level sensor [V]: the lower level plus an offset, saturating at 10 V."""
    return min(x[1] + p["c"], Y_MAX)
