"""The tank of ``overflow_tank.py`` with its overflow written as a switch: how not to model it.

Here a dump valve takes a fixed d [m/s] whenever the level is above the rim (RIM = 2 m):

    dx/dt = a·u − b·√x − (d if x > RIM else 0)

The right-hand side jumps at the rim. When the inflow's excess over the orifice is less than d,
the level rises below the rim and falls above it: it slides along the rim, switching at every
step, where an error-controlled solver shrinks its step without end, fixed-step RK4 converges
only at first order, and the sensitivities do not follow. ``overflow_tank.py`` writes the same
tank with a kink instead (an outflow c·max(x − RIM, 0) that grows from zero at the rim), which
every solver integrates. The gray-box guide runs both on the same data.

This file is plain Python and ``fuelid greybox`` runs it: only run model files you trust.
"""

import math

RIM = 2.0  # the rim above which the dump valve opens [m]

states = ["level"]  # the tank's level [m]
inputs = ["u_V"]  # the data file's input column: pump voltage [V]
outputs = ["level_m"]  # the data file's output column: the measured level [m]

parameters = {
    "a": {"value": 0.26, "lower": 0.0, "unit": "m/(s·V)"},  # pump flow per volt / tank area
    "b": {"value": 0.13, "lower": 0.0, "unit": "m^0.5/s"},  # bottom orifice / tank area
    "d": {"value": 0.05, "lower": 0.0, "unit": "m/s"},  # dump valve's flow / tank area
}


def f(t, x, u, p):
    """dx/dt [m/s] of the level x [m] at the pump voltage u [V]: it jumps at the rim."""
    rate = p["a"] * u[0] - p["b"] * math.sqrt(max(x[0], 0.0))
    if x[0] > RIM:  # a switch: the derivative jumps by d, and reverses where rate < d
        rate -= p["d"]
    return [rate]
