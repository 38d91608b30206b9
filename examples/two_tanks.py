"""Two cascaded water tanks with Torricelli outflow: a model file for ``fuelid greybox``.

A pump driven by the voltage u [V] fills the upper tank; it drains through an orifice into the
lower tank, which drains through its own orifice. By Torricelli the outflow of a tank goes with
the square root of its level, so with the levels x1 (upper) and x2 (lower) [dm]

    dx1/dt = −k1·√x1 + k4·u
    dx2/dt =  k2·√x1 − k3·√x2

k1 and k2 both describe the flow from the upper tank to the lower one, divided by each tank's
cross-section [dm^0.5/s]; k3 the lower tank's outflow [dm^0.5/s]; k4 the pump's flow per volt
over the upper cross-section [dm/(s·V)]. A tank that is full (H_MAX, 10 dm) overflows through a
pipe above its rim (K_OVERFLOW), which drains what rises above it within seconds. Only the lower
level is measured.

The functions are written with numpy (``np.sqrt``, ``np.maximum``) so that they work on a whole
batch of states at once (each column one state), which makes the fit several times faster; a
function written for scalars (``math.sqrt``, ``if``) works too, one state at a time.

This file is plain Python and ``fuelid greybox`` runs it: only run model files you trust.
"""

import numpy as np

H_MAX = 10.0  # height of each tank's rim [dm]: above it the tank overflows
K_OVERFLOW = 1.0  # overflow pipe [1/s]: drains what rises above the rim within seconds

states = ["x1", "x2"]  # upper and lower level [dm]
inputs = ["u_V"]  # the data file's input column: pump voltage [V]
outputs = ["h2_dm"]  # the data file's output column: the measured lower level [dm]

# name: {"value": start value, "lower": bound, "upper": bound, "fixed": bool, "unit": text}, or
# the short forms (start, lower, upper), (start, lower) or a bare start value; None = unbounded.
# k1…k3 start from guesses (about 30 % above the values the example data were simulated with);
# k4 starts at the pump's gain as a bucket test measured it (volume pumped per volt and second
# over the tank's area), the value to hold with --fix k4 when the data cannot tell it apart.
parameters = {
    "k1": {"value": 0.065, "lower": 0.0, "unit": "dm^0.5/s"},  # upper outflow / upper area
    "k2": {"value": 0.052, "lower": 0.0, "unit": "dm^0.5/s"},  # the same flow / lower area
    "k3": {"value": 0.065, "lower": 0.0, "unit": "dm^0.5/s"},  # lower outflow / lower area
    "k4": {"value": 0.06, "lower": 0.0, "unit": "dm/(s·V)"},  # pump flow per volt / upper area
}

state_scale = 1.0  # typical level [dm]: sets the finite-difference steps and tolerances


def f(t, x, u, p):
    """dx/dt [dm/s] of the levels x [dm] at the pump voltage u [V]."""
    x1 = np.maximum(x[0], 0.0)  # an empty tank stays empty: no √ of a negative level
    x2 = np.maximum(x[1], 0.0)
    dx1 = -p["k1"] * np.sqrt(x1) + p["k4"] * u[0]
    dx2 = p["k2"] * np.sqrt(x1) - p["k3"] * np.sqrt(x2)
    # a full tank overflows through a pipe above its rim (a kink, not a switch: see the guide)
    dx1 = dx1 - K_OVERFLOW * np.maximum(x[0] - H_MAX, 0.0)
    dx2 = dx2 - K_OVERFLOW * np.maximum(x[1] - H_MAX, 0.0)
    return [dx1, dx2]


def h(x, u, p):
    """The measured output: the lower level [dm]."""
    return x[1]
