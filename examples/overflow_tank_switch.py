"""The tank of ``overflow_tank.py`` with its overflow written as a switch, declared.

Here a dump valve takes a fixed d [m/s] whenever the level is above the rim (RIM = 2 m):

    dx/dt = a·u − b·√x − (d if x > RIM else 0)

The right-hand side jumps at the rim. The file declares the switch: ``above_rim`` is positive
above the rim, ``switches = [above_rim]``, and f takes the switch's mode as a fifth argument
instead of testing the level itself. fuelid then locates every crossing of the rim as a solver
event, restarts the integration on the other side, and makes the sensitivities jump there as
the crossing time moves with the parameters. When the inflow's excess over the orifice is less
than d, the level rises below the rim and falls above it: it slides along the rim, and the
valve passes just what holds it there (Filippov's sliding mode). Written as an undeclared
``if x[0] > RIM:`` the same model defeats the error-controlled solvers and its sensitivities
miss the switch; ``overflow_tank.py`` writes the overflow as a kink instead (an outflow
c·max(x − RIM, 0) that grows from zero at the rim). The gray-box guide runs both on the same
data.

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


def above_rim(t, x, u, p):
    """The switch [m]: positive while the level is above the rim (the dump valve open)."""
    return x[0] - RIM


switches = [above_rim]  # located as solver events; f reads the mode as on["above_rim"]


def f(t, x, u, p, on):
    """dx/dt [m/s] of the level x [m] at the pump voltage u [V]: it jumps at the rim."""
    rate = p["a"] * u[0] - p["b"] * math.sqrt(max(x[0], 0.0))
    if on["above_rim"]:  # the declared switch: the derivative jumps by d at the rim
        rate -= p["d"]
    return [rate]
