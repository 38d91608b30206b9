"""A tank with an overflow pipe above its rim: a model file for ``fuelid greybox`` with a kink.

A pump driven by the voltage u [V] fills a tank of level x [m]; the tank drains through an
orifice at its bottom (Torricelli: the outflow goes with the square root of the level) and,
once the level is above the rim of an overflow pipe at RIM = 2 m, through that pipe as well,
in proportion to the height above the rim:

    dx/dt = a·u − b·√x − c·max(x − RIM, 0)

a is the pump's flow per volt over the tank's area [m/(s·V)], b the orifice's [m^0.5/s], c the
overflow pipe's [1/s]. The outflow through the pipe is continuous in the level, only its slope
jumps at the rim (a kink): every solver integrates it, and the fit's sensitivities follow it.

The functions are written for scalars (``math.sqrt``, ``max``): the fit calls them one state at
a time. This file is plain Python and ``fuelid greybox`` runs it: only run model files you trust.
"""

import math

RIM = 2.0  # height of the overflow pipe's rim above the tank's bottom [m]

states = ["level"]  # the tank's level [m]
inputs = ["u_V"]  # the data file's input column: pump voltage [V]
outputs = ["level_m"]  # the data file's output column: the measured level [m]

# start values about 30 % off the values the example data are simulated with (0.2, 0.1, 0.3)
parameters = {
    "a": {"value": 0.26, "lower": 0.0, "unit": "m/(s·V)"},  # pump flow per volt / tank area
    "b": {"value": 0.13, "lower": 0.0, "unit": "m^0.5/s"},  # bottom orifice / tank area
    "c": {"value": 0.39, "lower": 0.0, "unit": "1/s"},  # overflow pipe / tank area
}

state_scale = 1.0  # typical level [m]: sets the finite-difference steps and tolerances


def f(t, x, u, p):
    """dx/dt [m/s] of the level x [m] at the pump voltage u [V]."""
    level = max(x[0], 0.0)  # an empty tank stays empty: no √ of a negative level
    overflow = p["c"] * max(x[0] - RIM, 0.0)  # zero below the rim, a kink at it
    return [p["a"] * u[0] - p["b"] * math.sqrt(level) - overflow]
