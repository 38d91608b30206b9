"""The ODE solvers a gray-box simulation can run with, one held-input piece at a time.

The inputs are held between samples (the PLC's zero-order hold), so
:func:`~fuelid.greybox._sensitivity.simulate_record` integrates the span piece by piece between
input changes; inside a piece the right-hand side is smooth unless the model itself has kinks
(``max``, ``min``, ``clip``, an ``if`` on a state). :func:`integrate_piece` integrates one piece
with the chosen method:

- ``lsoda`` (:func:`scipy.integrate.odeint`): Adams while the problem is non-stiff, BDF when it
  turns stiff; the default, and the first try of ``auto``;
- ``bdf``, ``radau``, ``rk45`` (:func:`scipy.integrate.solve_ivp`): variable-step, with the
  Newton matrix given to the implicit two;
- ``rk4``: the classical fixed-step Runge–Kutta method, ``substeps`` equal steps per sample
  interval. It never fails on a discontinuous right-hand side (a branch that switches the
  derivative's sign on a state, where an error-controlled solver shrinks its step without end),
  and is accurate only where the step resolves the model's fastest mode: the estimator's
  ``auto`` checks that by doubling the substeps (:mod:`fuelid.greybox._solver_choice`).

Every method stops with :class:`SimulationError` when a piece needs more right-hand-side
evaluations than its budget: a trial point where the solution chatters costs no
more than that.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.integrate
from numpy.typing import NDArray

from fuelid.errors import ConfigError, FuelidError

FloatArray = NDArray[np.float64]
Rhs = Callable[[float, FloatArray, FloatArray], FloatArray]
Newton = Callable[[float, FloatArray, FloatArray], FloatArray]

METHODS = ("lsoda", "bdf", "radau", "rk45", "rk4")
"""The solvers a simulation runs with."""
CHOICES = ("auto", *METHODS)
"""What a user may ask for: a solver, or ``auto`` (the estimator picks one, see
:mod:`fuelid.greybox._solver_choice`)."""
RTOL = 1e-6
"""Relative tolerance of the variable-step methods before the accuracy check tightens it."""
FINEST_RTOL = 1e-10
"""The tightest relative tolerance the accuracy check goes to."""
MAX_SUBSTEPS = 64
"""Most RK4 steps per sample interval: a model that needs more is stiff, and RK4 would take
ever smaller steps where an implicit method takes large ones."""
STEPS_PER_SAMPLE = 5000
"""An error-controlled solver may take this many steps in one sample interval before it gives up
(LSODA; solve_ivp's methods this many evaluations per sample of a piece): a smooth model needs
about one, a stiff one a few hundred while LSODA finds it stiff, a model with a switch (a clamp
at a rim) many more near it."""
TRIAL_STEPS_PER_SAMPLE = 500
"""The same for ``auto``'s trial of a solver at the start values: a model that needs more there
is handed to the next solver rather than left to grind."""
_SOLVED = "Integration successful."


class SimulationError(FuelidError):
    """The ODE could not be integrated at these parameter values."""


@dataclass(frozen=True)
class Solver:
    """How a record is integrated.

    Attributes
    ----------
    method : str
        One of :data:`METHODS`.
    max_step : float or None
        Longest step [s] a variable-step method may take (None: no limit).
    substeps : int
        RK4 steps per sample interval (ignored by the others).
    rtol : float
        Relative tolerance of a variable-step method (the accuracy check of
        :mod:`fuelid.greybox._solver_choice` tightens it where the data need it).
    steps_per_sample : int
        Most steps a variable-step method may take per sample interval (not part of the
        solver's identity: a trial with fewer allowed is the same solver).
    """

    method: str = "lsoda"
    max_step: float | None = None
    substeps: int = 1
    rtol: float = RTOL
    steps_per_sample: int = field(default=STEPS_PER_SAMPLE, compare=False)

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ConfigError(f"solver must be one of {', '.join(CHOICES)}, not {self.method!r}")
        check_max_step(self.max_step)
        # twice the cap is allowed here: auto's check of the cap compares it with its doubling
        if not 1 <= self.substeps <= 2 * MAX_SUBSTEPS:
            raise ConfigError(f"substeps {self.substeps} outside 1…{2 * MAX_SUBSTEPS}")

    def describe(self) -> str:
        """E.g. ``lsoda``, ``bdf (max step 0.5 s)``, ``rk4 (8 steps per sample)``."""
        if self.method == "rk4":
            return f"rk4 ({self.substeps} step{'s' if self.substeps != 1 else ''} per sample)"
        details = [] if self.rtol == RTOL else [f"rtol {self.rtol:g}"]
        if self.max_step is not None:
            details.append(f"max step {self.max_step:g} s")
        return f"{self.method} ({', '.join(details)})" if details else self.method

    def to_json(self) -> dict[str, object]:
        """``method``, ``max_step`` [s] (None: none) and ``substeps`` (RK4 only, else None)."""
        return {
            "method": self.method,
            "max_step": self.max_step,
            "substeps": self.substeps if self.method == "rk4" else None,
            "rtol": None if self.method == "rk4" else self.rtol,
        }

    def refined(self) -> Solver | None:
        """The same solver made more accurate (None: already the most accurate allowed).

        Twice the RK4 steps (up to :data:`MAX_SUBSTEPS`), or 1/100 of a variable-step method's
        tolerance (down to :data:`FINEST_RTOL`).
        """
        if self.method == "rk4":
            if self.substeps >= MAX_SUBSTEPS:
                return None
            return Solver("rk4", self.max_step, 2 * self.substeps)
        if self.rtol <= FINEST_RTOL:
            return None
        return Solver(self.method, self.max_step, rtol=max(self.rtol / 100.0, FINEST_RTOL))


def check_max_step(value: float | None) -> None:
    """Refuse a max step that is not a positive finite number of seconds."""
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"max_step must be a number of seconds, got {value!r}")
    if not (math.isfinite(value) and value > 0.0):
        raise ConfigError(f"max_step must be a positive number of seconds, got {value!r}")


def check_substeps(value: int | None) -> None:
    """Refuse RK4 substeps that are not an integer 1…:data:`MAX_SUBSTEPS`."""
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_SUBSTEPS:
        raise ConfigError(
            f"substeps must be an integer from 1 to {MAX_SUBSTEPS} (RK4 steps per sample), "
            f"got {value!r}"
        )


class BudgetSpent(Exception):
    """Raised inside a solve_ivp right-hand side when the piece's budget is spent."""


def budgeted(
    rhs: Rhs, u: FloatArray, limit: int
) -> tuple[Callable[[float, FloatArray], FloatArray], list[int]]:
    """``rhs`` with ``u`` held, for solve_ivp, and its count of calls (one cell).

    Past ``limit`` calls it raises :class:`BudgetSpent`: solve_ivp has no step limit of its own.
    """
    count = [0]

    def fun(t: float, state: FloatArray) -> FloatArray:
        count[0] += 1
        if count[0] > limit:
            raise BudgetSpent
        return np.array(rhs(t, state, u), dtype=float)

    return fun, count


def integrate_piece(
    solver: Solver,
    rhs: Rhs,
    newton: Newton | None,
    z: FloatArray,
    times: FloatArray,
    u: FloatArray,
    rtol: float | FloatArray,
    atol: FloatArray,
    budget: int | None = None,
) -> tuple[FloatArray, int]:
    """Integrate dz/dt = rhs(t, z, u) from ``times[0]`` through ``times``, u held.

    Returns the solution at ``times[1:]`` (one row each) and the right-hand-side evaluations.
    ``rtol`` may give each component of z its own relative tolerance (LSODA; the solve_ivp
    methods take the smallest for all). The steps a variable-step method may take are limited
    to the solver's ``steps_per_sample`` per interval of ``times`` (at least ten times that a
    piece), and to ``budget`` (what is left of the record's right-hand-side evaluations, None:
    no limit): a trial point where the solution grinds at a switch fails after that, not after
    the whole step allowance.

    Raises
    ------
    SimulationError
        When the solver fails, runs out of steps, or the solution is not finite.
    """
    intervals = len(times) - 1
    # odeint's mxstep is per output interval (a sample); solve_ivp's budget is per piece
    max_steps = solver.steps_per_sample * max(10, intervals)
    if budget is not None:
        max_steps = max(1, min(max_steps, budget))
    per_interval = max(1, min(solver.steps_per_sample, max_steps))
    if solver.method == "rk4":
        needed = 4 * solver.substeps * intervals
        if budget is not None and needed > budget:
            raise SimulationError(f"rk4 needs {needed} evaluations here, over the {budget} left")
        return _rk4(rhs, z, times, u, solver.substeps), needed
    if solver.method == "lsoda":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", scipy.integrate.ODEintWarning)
            solution, info = scipy.integrate.odeint(
                rhs,
                z,
                times,
                args=(u,),
                Dfun=newton,
                tfirst=True,
                rtol=rtol,
                atol=atol,
                mxstep=per_interval,
                hmax=0.0 if solver.max_step is None else solver.max_step,
                full_output=True,
            )
        if info["message"] != _SOLVED:
            # odepack's "(perhaps wrong Dfun type)" guesses at a cause that is not ours
            message = str(info["message"]).replace(" (perhaps wrong Dfun type)", "")
            raise SimulationError(f"the ODE solver (lsoda) failed: {message}")
        # the Newton matrices count too: at a switch LSODA asks for far more of them than of f
        return solution[1:], int(info["nfe"][-1]) + int(info["nje"][-1])
    return _solve_ivp(solver, rhs, newton, z, times, u, rtol, atol, max_steps)


def _solve_ivp(
    solver: Solver,
    rhs: Rhs,
    newton: Newton | None,
    z: FloatArray,
    times: FloatArray,
    u: FloatArray,
    rtol: float | FloatArray,
    atol: FloatArray,
    max_steps: int,
) -> tuple[FloatArray, int]:
    # a budget of evaluations rather than steps: solve_ivp has no step limit of its own
    budget = max_steps
    fun, count = budgeted(rhs, u, budget)

    implicit = solver.method in {"bdf", "radau"}
    jac = None
    if implicit and newton is not None:
        newton_matrix = newton

        def jac(t: float, state: FloatArray) -> FloatArray:
            return np.array(newton_matrix(t, state, u), dtype=float)

    method = {"bdf": "BDF", "radau": "Radau", "rk45": "RK45"}[solver.method]
    # solve_ivp's implicit methods take one relative tolerance: the tightest (the state's)
    rtol = float(np.min(rtol))
    try:
        result = scipy.integrate.solve_ivp(
            fun,
            (float(times[0]), float(times[-1])),
            z,
            method=method,
            t_eval=times[1:],
            rtol=rtol,
            atol=atol,
            max_step=math.inf if solver.max_step is None else solver.max_step,
            **({"jac": jac} if jac is not None else {}),
        )
    except BudgetSpent:
        raise SimulationError(
            f"the ODE solver ({solver.method}) needed more than {budget} evaluations "
            f"on {times[0]:g}…{times[-1]:g} s"
        ) from None
    if not result.success or result.y.shape[1] != len(times) - 1:
        raise SimulationError(f"the ODE solver ({solver.method}) failed: {result.message}")
    return np.ascontiguousarray(result.y.T), count[0]


def _rk4(rhs: Rhs, z: FloatArray, times: FloatArray, u: FloatArray, substeps: int) -> FloatArray:
    """Classical RK4, ``substeps`` equal steps per interval of ``times``."""
    out = np.empty((len(times) - 1, len(z)))
    state = np.array(z, dtype=float)
    for i in range(len(times) - 1):
        h = (times[i + 1] - times[i]) / substeps
        t = float(times[i])
        for _ in range(substeps):
            # the right-hand side may reuse its output buffer: each stage is copied
            k1 = np.array(rhs(t, state, u))
            k2 = np.array(rhs(t + 0.5 * h, state + (0.5 * h) * k1, u))
            k3 = np.array(rhs(t + 0.5 * h, state + (0.5 * h) * k2, u))
            k4 = np.array(rhs(t + h, state + h * k3, u))
            state = state + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            t += h
        out[i] = state
    if not np.all(np.isfinite(out)):
        raise SimulationError(
            f"rk4 with {substeps} step(s) per sample diverged (the model is stiffer than the "
            "step resolves, or its derivatives are not finite)"
        )
    return out
