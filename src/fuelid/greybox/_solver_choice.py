"""Which solver a gray-box fit runs with: the user's, or ``auto``'s choice at the start values.

``auto`` (the default) simulates the records at the start values with LSODA. Where LSODA fails
(a right-hand side that switches on a state, say, where its error control shrinks the step
without end) it tries BDF with its step bounded by the sample interval, then fixed-step RK4 with
1, 2, 4, … steps per sample until a result agrees with the next doubling within
:data:`RK4_AGREEMENT`; beyond :data:`~fuelid.greybox._solvers.MAX_SUBSTEPS` it refuses with the
reason, since a model that needs more is stiff and RK4 would crawl (or diverge) where an
implicit method strides. The fit then runs with the solver chosen, and says which.

``rk4`` without a number of substeps chooses them by the same doubling; with one, it is used as
given. A variable-step solver is checked the same way against its tolerance divided by 100
(:func:`verified`), which is tightened (down to 1e-10) until the two agree: an error-controlled
solver's global error over a long record of short input pieces can reach a sizeable share of a
standard error at the default 1e-6. The estimator repeats the check at the estimate and refits
with a finer solver where it fails there.

The agreement is measured against the noise: ‖(y_s − y_2s)/σ‖₂ over every sample of every
record, σ each output's sample-to-sample noise level. A systematic simulation error e moves no
estimate by more than ‖e/σ‖₂ standard errors (the projection of e/σ on the sensitivities' span
is no longer than e/σ), and the error of y_s is at most about twice the difference (where RK4
converges only at first order, across a switch; 16/15 of it where it is fourth order): 0.05
keeps the integration's share of any estimate under about 0.1 standard error.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from fuelid.errors import ConfigError
from fuelid.greybox._solvers import (
    CHOICES,
    MAX_SUBSTEPS,
    TRIAL_STEPS_PER_SAMPLE,
    FloatArray,
    SimulationError,
    Solver,
    check_max_step,
    check_substeps,
)
from fuelid.greybox._switching import UnlocatedSwitches
from fuelid.greybox._system import Record

RK4_AGREEMENT = 0.05
"""‖(y_s − y_2s)/σ‖₂ below which RK4 with s steps per sample is accurate enough (module
docstring)."""


@dataclass(frozen=True)
class SolverChoice:
    """The solver a fit runs with and why."""

    solver: Solver
    requested: str
    """What the user asked for: ``auto`` or a method."""
    reason: str
    """One line: why this solver (empty when it is simply the one asked for)."""

    def to_json(self) -> dict[str, object]:
        """The JSON ``solver`` object: method, max_step, substeps, requested, reason."""
        return {**self.solver.to_json(), "requested": self.requested, "reason": self.reason}

    def describe(self) -> str:
        """E.g. ``rk4 (8 steps per sample; auto: lsoda failed: …)``."""
        text = self.solver.describe()
        if self.requested == "auto":
            return f"{text}, chosen by auto" + (f" ({self.reason})" if self.reason else "")
        return text + (f" ({self.reason})" if self.reason else "")


def check_request(method: str, max_step: float | None, substeps: int | None) -> None:
    """Refuse an unknown solver, a bad max step or bad substeps (ConfigError)."""
    if method not in CHOICES:
        raise ConfigError(f"solver must be one of {', '.join(CHOICES)}, not {method!r}")
    check_max_step(max_step)
    check_substeps(substeps)
    if substeps is not None and method not in {"rk4", "auto"}:
        raise ConfigError(f"substeps apply to the rk4 solver only, not to {method}")


Simulate = Callable[[Solver], Sequence[FloatArray]]
"""Simulate every record with a solver: the outputs of each (raises SimulationError)."""


def choose_solver(
    method: str,
    max_step: float | None,
    substeps: int | None,
    simulate: Simulate,
    records: Sequence[Record],
    noise: FloatArray,
) -> SolverChoice:
    """The solver for a fit, from the user's request and trial simulations at the start values.

    Parameters
    ----------
    method : str
        ``auto`` or one of :data:`~fuelid.greybox._solvers.METHODS`.
    max_step : float or None
        The user's longest step [s] (None: none).
    substeps : int or None
        The user's RK4 steps per sample (None: chosen by doubling).
    simulate : callable
        Simulates every record (outputs only) with a solver; raises SimulationError.
    records : sequence of Record
        The records (for the sample interval that bounds BDF's step).
    noise : ndarray
        Each output's noise level σ, the scale of RK4's agreement test.

    Raises
    ------
    SimulationError
        When no solver can integrate the model at the start values; the message gives each
        one's reason.
    """
    check_request(method, max_step, substeps)
    interval = float(min(np.median(np.diff(record.t)) for record in records))
    if max_step is not None and (method in {"rk4", "auto"}):
        # RK4's step is the interval over its substeps: at most max_step
        fewest = min(math.ceil(interval / max_step - 1e-9), MAX_SUBSTEPS)
        substeps = max(substeps or 1, fewest) if substeps is not None else None
        first_substeps = fewest
    else:
        first_substeps = 1
    if method == "rk4" and substeps is not None:
        return SolverChoice(Solver("rk4", max_step, substeps), "rk4", "")
    if method == "rk4":
        solver, agreement = _rk4_by_doubling(simulate, noise, [], max_step, first_substeps)
        return SolverChoice(solver, "rk4", agreement)
    if method != "auto":
        solver, note = verified(simulate, Solver(method, max_step), noise)
        return SolverChoice(solver, method, note)
    failures: list[str] = []
    lsoda = Solver("lsoda", max_step)
    try:
        simulate(Solver("lsoda", max_step, steps_per_sample=TRIAL_STEPS_PER_SAMPLE))
        solver, note = verified(simulate, lsoda, noise)
        return SolverChoice(solver, "auto", note)
    except SimulationError as exc:
        failures.append(f"lsoda: {exc}")
    bdf = Solver("bdf", interval if max_step is None else min(max_step, interval))
    try:
        simulate(Solver(bdf.method, bdf.max_step, steps_per_sample=TRIAL_STEPS_PER_SAMPLE))
        solver, note = verified(simulate, bdf, noise)
        reason = f"lsoda failed: {_short(failures[0])}" + (f"; {note}" if note else "")
        return SolverChoice(solver, "auto", reason)
    except SimulationError as exc:
        failures.append(f"bdf: {exc}")
    if substeps is not None:  # the user's steps per sample, as given
        given = Solver("rk4", max_step, substeps)
        try:
            simulate(given)
        except SimulationError as exc:
            tried = "; ".join(_short(text) for text in failures)
            raise SimulationError(f"{tried}; rk4 as given: {_short(str(exc))}") from None
        return SolverChoice(
            given, "auto", f"lsoda and bdf failed ({_short(failures[0])}); rk4 as given"
        )
    solver, agreement = _rk4_by_doubling(simulate, noise, failures, max_step, first_substeps)
    return SolverChoice(
        solver, "auto", f"lsoda and bdf failed ({_short(failures[0])}); {agreement}"
    )


def fall_back(
    choice: SolverChoice,
    failure: SimulationError,
    simulate: Simulate,
    records: Sequence[Record],
    noise: FloatArray,
    max_step: float | None,
    where: str,
) -> SolverChoice:
    """The solver ``auto`` chooses where the fit's own solver failed (a validation record, say).

    The chain of :func:`choose_solver` (LSODA, BDF, RK4 by doubling, each with bounded work)
    without the solver that just failed; the reason says what failed where and what it fell
    back to. A solver the user asked for is not replaced: its failure is raised again.

    Raises
    ------
    SimulationError
        When the user chose the solver, or no solver simulates the records.
    """
    if choice.requested != "auto":
        raise failure

    def others(solver: Solver) -> Sequence[FloatArray]:
        if solver.method == choice.solver.method:
            raise failure  # it just failed here: its trial proves nothing
        return simulate(solver)

    text = f"{choice.solver.method} failed at {where}: {_short(str(failure))}"
    try:
        fallback = choose_solver("auto", max_step, None, others, records, noise)
    except SimulationError as exc:
        raise SimulationError(f"{text}; no fallback solver simulates it ({exc})") from None
    return SolverChoice(
        fallback.solver, "auto", f"{text}; fell back to {fallback.solver.describe()}"
    )


def _model_failed(failure: str) -> bool:
    """Whether a solver's failure was the model's own (an exception in f, a NaN), not stiffness."""
    return any(mark in failure for mark in ("NaN or infinite", "(raised in f)", "model raised"))


def _rk4_by_doubling(
    simulate: Simulate,
    noise: FloatArray,
    failures: list[str],
    max_step: float | None,
    first: int = 1,
) -> tuple[Solver, str]:
    """RK4 with the fewest steps per sample that agree with twice as many (see the module).

    ``first``: the fewest to try (the interval over ``max_step``, when given).
    """
    scale = np.asarray(noise, dtype=float)
    substeps = first
    try:
        coarse = _outputs(simulate, Solver("rk4", max_step, substeps))
    except UnlocatedSwitches as exc:  # no number of steps helps: say so, not "too stiff"
        tried = "; ".join(_short(text) for text in failures)
        raise SimulationError((f"{tried}; " if tried else "") + str(exc)) from None
    differences: list[float] = []
    while substeps <= MAX_SUBSTEPS:
        fine = _outputs(simulate, Solver("rk4", max_step, 2 * substeps))
        difference = math.inf
        if coarse is not None and fine is not None:
            difference = _distance(coarse, fine, scale)
            if difference <= RK4_AGREEMENT:
                return Solver("rk4", max_step, substeps), (
                    f"rk4 with {substeps} step{'s' if substeps != 1 else ''} per sample agrees "
                    f"with {2 * substeps} to {difference:.2g} noise standard deviations"
                )
        differences.append(difference)
        coarse = fine
        substeps *= 2
    tried = "; ".join(_short(text) for text in failures)
    last = differences[-1]
    implicit_failed = any(text.startswith("bdf") for text in failures)
    if math.isfinite(last) and len(differences) > 1 and differences[-2] < 4.0 * last:
        # halving the step only halves the difference: first order, the mark of a state held
        # at a switch (or at a kink so steep it acts as one), not of a smooth stiff mode
        remedy = (
            "declare a switch (switches = [g], see the gray-box guide) or write it as a kink "
            "(max(level - rim, 0) times a coefficient)"
            if implicit_failed
            else "use an implicit solver (--solver bdf or radau) for a steep kink, declare a "
            "switch (switches = [g]) or write it as a kink (see the gray-box guide)"
        )
        reason = (
            f"rk4 converges only at first order here (with {MAX_SUBSTEPS} steps per sample it "
            f"still differs from {2 * MAX_SUBSTEPS} by {last:.3g} noise standard deviations; "
            f"agreement needs {RK4_AGREEMENT:g}): a state is held at a switch (an if that "
            "reverses dx/dt across a level) or at a kink too steep for the step; "
            f"{remedy}, or give --substeps N to accept RK4's error"
        )
    elif not math.isfinite(last) and any(_model_failed(text) for text in failures):
        reason = (
            "rk4 did not give a finite result either: the model itself fails or gives NaN or "
            "infinite derivatives at the start values (a square root of a negative value, a "
            "division by zero?), which no solver mends"
        )
    else:
        shown = (
            "did not give a finite result"
            if not math.isfinite(last)
            else f"still differs from {2 * MAX_SUBSTEPS} by {last:.3g} noise standard "
            f"deviations (agreement needs {RK4_AGREEMENT:g})"
        )
        remedy = (
            "remove its fastest mode or make it algebraic"
            if implicit_failed
            else "give it an implicit solver (--solver bdf or radau), or remove its fastest mode"
        )
        reason = (
            f"rk4 with {MAX_SUBSTEPS} steps per sample {shown}: the model is too stiff for a "
            f"fixed step; {remedy}"
        )
    raise SimulationError((f"{tried}; " if tried else "") + reason)


def verified(
    simulate: Simulate,
    solver: Solver,
    noise: FloatArray,
    outputs: Sequence[FloatArray] | None = None,
) -> tuple[Solver, str]:
    """The solver refined until it agrees with its refinement within :data:`RK4_AGREEMENT`.

    ``outputs``: the solver's outputs, when already simulated. Returns the solver and a note
    (empty when the solver as given agreed; else what it took, or that it could not be verified
    at the finest setting).

    Raises
    ------
    SimulationError
        When the solver as given cannot simulate at all.
    """
    scale = np.asarray(noise, dtype=float)
    current = simulate(solver) if outputs is None else outputs
    start = solver
    while True:
        finer = solver.refined()
        if finer is None:
            return solver, (
                f"{solver.describe()} could not be checked against a finer setting (the finest "
                "allowed)"
                if solver != start
                else ""
            )
        fine = _outputs(simulate, finer)
        if fine is None:
            return solver, f"{solver.describe()} not checked: the finer {finer.describe()} failed"
        difference = _distance(current, fine, scale)
        if difference <= RK4_AGREEMENT:
            if solver == start:
                return solver, ""
            return solver, (
                f"{start.describe()} differed from a finer setting by more than "
                f"{RK4_AGREEMENT:g} noise standard deviations; {solver.describe()} agrees with "
                f"{finer.describe()} to {difference:.2g}"
            )
        solver, current = finer, fine


def _outputs(simulate: Simulate, solver: Solver) -> Sequence[FloatArray] | None:
    """The records' outputs with this solver, or None where it failed."""
    try:
        return simulate(solver)
    except UnlocatedSwitches:
        raise
    except SimulationError:
        return None


def _distance(
    first: Sequence[FloatArray], second: Sequence[FloatArray], scale: FloatArray
) -> float:
    """‖(y₁ − y₂)/σ‖₂ over every finite sample of every record."""
    total = 0.0
    for a, b in zip(first, second, strict=True):
        diff = (np.asarray(a) - np.asarray(b)) / scale
        finite = np.isfinite(diff)
        if not np.all(finite):  # a non-finite run on either side cannot agree
            return math.inf
        total += float(np.sum(diff[finite] ** 2))
    return math.sqrt(total)


def _short(text: str, limit: int = 160) -> str:
    """A failure's message cut to one readable clause (without odepack's guess at a cause)."""
    text = " ".join(str(text).replace(" (perhaps wrong Dfun type)", "").split())
    return text if len(text) <= limit else text[: limit - 1] + "…"
