"""A start off the flat spot: where the outputs do not depend on a parameter, search the bounds.

A start can sit where the outputs do not depend on a parameter at all: a level that never reaches
the rim the parameter describes, an output on its clip, a tank run empty. The sensitivities are
then exactly zero and no fit can move the parameter. Before the estimator refuses,
:class:`StartSearch` looks for a start where every free parameter acts:

1. at the given start, each parameter without sensitivity is stepped +10 % and −10 % and
   simulated: one the outputs follow neither way (a change of the weighted outputs under χ²₁'s
   95 % quantile) is on a flat spot, one they follow one way only at its edge (a limit just
   beyond the records' reach); one they follow both ways is hidden by a switch, which no start
   cures (the refusal says so);
2. a scrambled Sobol set of :data:`SEARCH_STARTS` starts fills a box in the bounds (log-scaled for
   positive parameters; a factor :data:`SEARCH_SPAN` either side of the start where a bound is
   open), each simulated coarsely (relative tolerance :data:`COARSE_RTOL`) with its
   sensitivities, which the fit steers by: a start qualifies where they see every free
   parameter (a column not exactly 0);
3. the :data:`REFINED_STARTS` qualifying starts of lowest cost are refined by a short coarse fit
   (:data:`REFINE_ITERATIONS` iterations of the normal least-squares fit), and the one of lowest
   cost where the sensitivities still see every parameter is the start of the fit.

The simulations run in worker processes over the cores (forked: a model file's functions cannot be
pickled; where the platform cannot fork they run one after another and the report says why). The
set is seeded, so the search is deterministic unless its time bound (:data:`SEARCH_SECONDS`) cuts
it short, which the report says too. Where no start acts, or the fit from every refined start
moves the parameter back to where nothing depends on it, the refusal stays and carries the
evidence (:meth:`StartSearchReport.evidence`).
"""

from __future__ import annotations

import math
import multiprocessing
import os
import time
from collections.abc import Iterable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from fuelid.greybox._fitting import Evaluation, FloatArray
from fuelid.greybox._identifiability import (
    CHI2_95,
    IdentifiabilityReport,
    NotIdentifiableError,
)
from fuelid.greybox._profile import EVIDENCE_STEP, ProfileLikelihood
from fuelid.greybox._solver_choice import SolverChoice
from fuelid.greybox._solvers import TRIAL_STEPS_PER_SAMPLE, SimulationError
from fuelid.greybox._system import Record

SEARCH_STARTS = 64
"""Starts of the space-filling set (a power of two: a Sobol set is balanced at 2^m points)."""
SEARCH_SEED = 42
"""The Sobol set's scrambling seed: the same records and model give the same starts."""
SEARCH_SPAN = 10.0
"""Where a parameter's bound is open, the box reaches this factor either side of its start
(positive parameters; others ± the start's size)."""
COARSE_RTOL = 1e-3
"""Relative tolerance of the search's simulations: a sensitivity that is exactly 0 (a limit not
reached: the same arithmetic runs) is 0 at any tolerance, and the costs only rank the starts."""
REFINED_STARTS = 3
"""Starts refined by a short fit; the best of them by cost is where the fit starts."""
REFINE_ITERATIONS = 5
"""Iterations (Jacobians) of each refinement: enough to leave a poor basin, not to converge."""
CHECK_BATCH = 4
"""Starts whose sensitivities are checked at a time, in order of cost (a constant, not the
number of workers: the search is the same on any machine)."""
SEARCH_SECONDS = 120.0
"""Wall-clock bound of the search; where it cuts the search short, the report says so."""
MAX_WORKERS = 8
"""Most worker processes of the search."""

_OWNER: Any = None
"""The estimator whose search the forked workers run (set in the parent before the fork)."""


def _run_in_worker(method: str, args: tuple[Any, ...]) -> Any:
    """In a worker: the inherited estimator's ``method`` on ``args`` (both picklable, it not)."""
    return getattr(_OWNER, method)(*args)


@dataclass(frozen=True)
class Probe:
    """One start of the set, simulated coarsely with its sensitivities."""

    index: int
    phi: FloatArray
    cost: float
    """Σ of the squared weighted residuals (inf: it could not be simulated)."""
    unseen: tuple[str, ...] | None
    """Free parameters whose sensitivity is exactly 0 here (None: not checked)."""
    outputs: FloatArray
    """Each output's simulated (min, max) over the records, shape (n_y, 2) (NaN: failed)."""
    evaluations: int
    failure: str = ""

    def sees(self, names: Iterable[str]) -> bool:
        """The sensitivities were checked here and see every one of ``names``."""
        return self.unseen is not None and not set(names) & set(self.unseen)


@dataclass(frozen=True)
class RefinedStart:
    """A start after its short fit: its cost and the parameters the outputs stopped following."""

    index: int
    phi: FloatArray
    cost: float
    lost: tuple[str, ...]
    """Free parameters without sensitivity where the refinement ended, and flat ones at the edge
    of their flat spot there (a ±10 % step moves the outputs one way only)."""
    values: dict[str, float]
    evaluations: int
    failure: str = ""


@dataclass(frozen=True)
class StartSearchReport:
    """What the search for a start off the flat spot did, and why its start was used (or none)."""

    flat: dict[str, tuple[float, float]]
    """At the given start: each parameter without sensitivity whose outputs do not follow a step
    both ways, and its weighted output change over the step up and down (NaN: beyond a bound)."""
    given_states: dict[str, tuple[float, float]]
    """The given start's simulated states' range over the records, by state name."""
    box: dict[str, tuple[float, float]]
    """The box the starts fill, by searched parameter (natural units)."""
    held: tuple[str, ...]
    """Free parameters not varied (no bound and no size to scale a box by)."""
    n_starts: int
    n_simulated: int
    n_failed: int
    n_checked: int
    """Starts whose sensitivities were checked (in order of cost, until enough qualified)."""
    n_acting: int
    """Starts where the sensitivities see every flat parameter."""
    n_qualified: int
    """Starts where they see every free parameter."""
    seen_in: dict[str, int]
    """Per free parameter, the starts checked whose sensitivities see it."""
    outputs_range: dict[str, tuple[float, float]]
    """Each output's simulated range over every start simulated."""
    refined: tuple[RefinedStart, ...]
    chosen: int | None
    """The start used (its index in the set, from 1), or None."""
    workers: int
    serial_reason: str
    """Why the starts were simulated one after another ("" when in parallel)."""
    seconds: float
    truncated: bool
    """The time bound cut the search short."""
    values: dict[str, float] = field(default_factory=dict)
    """The start used: every parameter's value (empty when none)."""

    def _flat_words(self) -> str:
        states = ", ".join(f"{n} {lo:.3g}…{hi:.3g}" for n, (lo, hi) in self.given_states.items())
        changes = ", ".join(_sides(name, pair) for name, pair in self.flat.items())
        return (
            f"the given start left {', '.join(self.flat)} without sensitivity (a ±10 % step moved "
            f"the weighted outputs by {changes}; {CHI2_95:.2f} is seen; its simulated states "
            f"stayed within {states})"
        )

    def line(self) -> str:
        """One line: which start was used and why, or what the search found."""
        if self.chosen is None:
            return f"start search: none used: {self._flat_words()}; {self.evidence()}"
        shown = ", ".join(f"{n} = {self.values[n]:.4g}" for n in self.box)
        best = next(r for r in self.refined if r.index == self.chosen)
        return (
            f"start search: start {self.chosen} of {self.n_starts}, refined to {shown}: "
            f"{self._flat_words()}; of {self.n_starts} starts in the bounds the "
            f"{self.n_checked} of lowest cost were checked, in {self.n_acting} {_act(self.flat)} "
            f"(the sensitivities see {'it' if len(self.flat) == 1 else 'them'}), the best "
            f"{len(self.refined)} where every parameter does were refined and this one fitted "
            f"best (weighted cost {best.cost:.4g}); "
            f"{self._how()}"
        )

    def _how(self) -> str:
        where = "one after another" if self.serial_reason else f"on {self.workers} processes"
        text = f"{self.seconds:.1f} s, {where}"
        if self.serial_reason:
            text += f" ({self.serial_reason})"
        if self.truncated:
            text += f"; cut short at its time bound of {SEARCH_SECONDS:g} s"
        return text

    def evidence(self) -> str:
        """Why no start was used: how many starts, what the outputs did."""
        if self.chosen is not None:
            return ""
        box = ", ".join(f"{n} {lo:.3g}…{hi:.3g}" for n, (lo, hi) in self.box.items())
        outputs = ", ".join(f"{n} {lo:.4g}…{hi:.4g}" for n, (lo, hi) in self.outputs_range.items())
        head = (
            f"a search of {self.n_starts} starts in the bounds ({box}; {self.n_simulated} "
            f"simulated, {self.n_failed} of them failed; simulated outputs {outputs})"
        )
        seen = ", ".join(f"{n} at {k}" for n, k in self.seen_in.items())
        if self.n_acting == 0:
            text = (
                f"{head} found none where the outputs depend on {', '.join(self.flat)}: the "
                f"sensitivities saw {seen} of the {self.n_checked} starts checked"
            )
        elif self.n_qualified == 0:
            text = (
                f"{head}: of the {self.n_checked} checked, {_act(self.flat)} in {self.n_acting}, "
                "but in none do the "
                f"sensitivities the fit steers by see every parameter (they saw {seen} of the "
                f"{self.n_checked} starts checked)"
            )
        else:
            moved = "; ".join(
                f"start {r.index}: {r.failure}"
                if r.failure
                else f"start {r.index}: "
                + (", ".join(f"{n} → {r.values[n]:.4g}" for n in r.lost) or "none lost")
                + f", weighted cost {r.cost:.4g}"
                for r in sorted(self.refined, key=lambda r: (r.cost, r.index))
            )
            text = (
                f"{head}: of the {self.n_checked} of lowest cost checked, {_act(self.flat)} in "
                f"{self.n_acting}, but the fit from the best of the {len(self.refined)} refined "
                "moved a parameter to where the outputs do not depend on it, or follow a ±10 % "
                f"step of it one way only, the edge of what the records reach ({moved}): the "
                "records do not determine it"
            )
        return f"{text}; {self._how()}"

    def to_json(self) -> dict[str, Any]:
        """The report as plain JSON types (``start_search`` of ``fuelid greybox --json``)."""
        return {
            "used": self.chosen is not None,
            "start": self.chosen,
            "n_starts": self.n_starts,
            "n_simulated": self.n_simulated,
            "n_failed": self.n_failed,
            "n_checked": self.n_checked,
            "n_acting": self.n_acting,
            "n_qualified": self.n_qualified,
            "seen_in": dict(self.seen_in),
            "flat_at_given_start": {
                n: {"up": _finite(up), "down": _finite(down)} for n, (up, down) in self.flat.items()
            },
            "given_states_range": {n: list(r) for n, r in self.given_states.items()},
            "box": {n: list(r) for n, r in self.box.items()},
            "held": list(self.held),
            "outputs_range": {n: [_finite(v) for v in r] for n, r in self.outputs_range.items()},
            "refined": [
                {
                    "start": r.index,
                    "cost": _finite(r.cost),
                    "lost": list(r.lost),
                    "parameters": dict(r.values),
                    "failure": r.failure or None,
                }
                for r in self.refined
            ],
            "values": dict(self.values) or None,
            "change_seen": CHI2_95,
            "workers": self.workers,
            "serial_reason": self.serial_reason or None,
            "wall_time_s": self.seconds,
            "truncated": self.truncated,
            "reason": self.line(),
        }


class NoStartFound(NotIdentifiableError):
    """A refusal that stands after the start search; ``search`` is its evidence."""

    def __init__(self, report: IdentifiabilityReport, search: StartSearchReport) -> None:
        super().__init__(report)
        self.search = search


def _sides(name: str, pair: tuple[float, float]) -> str:
    """``c 0`` (no change either way) or ``xmax 0 up, 1.2e+03 down``."""
    up, down = (0.0 if math.isnan(c) else c for c in pair)
    if up <= CHI2_95 and down <= CHI2_95:
        return f"{name} {max(up, down):.3g}"
    return f"{name} {up:.3g} up, {down:.3g} down"


def _one_way(sides: tuple[float, float]) -> bool:
    """A step moves the outputs one way and not the other: the edge of a flat spot."""
    changes = [0.0 if math.isnan(c) else c for c in sides]
    return min(changes) <= CHI2_95 < max(changes)


def _act(names: Iterable[str]) -> str:
    """``c acts``, ``c, d act``."""
    listed = list(names)
    return f"{', '.join(listed)} act{'s' if len(listed) == 1 else ''}"


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


@dataclass(frozen=True)
class _SearchRun:
    """What the search's simulations found (before it is told as a report)."""

    probes: list[Probe]
    refined: list[RefinedStart]
    workers: int
    serial_reason: str
    truncated: bool

    def best(self) -> RefinedStart | None:
        """The refined start of lowest cost, if the sensitivities see every parameter there.

        Where the one that fits best lost a parameter, the fit would go where it went: a start
        that kept it only because its short fit had not got as far is no answer.
        """
        fitted = [r for r in self.refined if not r.failure]
        if not fitted:
            return None
        best = min(fitted, key=lambda r: (r.cost, r.index))
        return None if best.lost else best


class _Pool:
    """The search's simulations, on forked worker processes or one after another."""

    def __init__(self, owner: Any, n_tasks: int, deadline: float) -> None:
        self.deadline = deadline
        self.truncated = False
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
        cores = cores or 1
        self.workers = max(1, min(cores, MAX_WORKERS, n_tasks))
        self.serial_reason = ""
        if self.workers == 1:
            self.serial_reason = "one core available" if cores == 1 else "one worker allowed"
        elif "fork" not in multiprocessing.get_all_start_methods():
            # spawned workers would need the model pickled, and a model file's functions are not
            self.workers = 1
            self.serial_reason = "no forked worker processes on this platform"
        self.owner = owner
        self.executor: ProcessPoolExecutor | None = None

    def __enter__(self) -> _Pool:
        if self.workers > 1:
            global _OWNER
            _OWNER = self.owner  # inherited by the forked workers: nothing of it is pickled
            self.executor = ProcessPoolExecutor(
                self.workers, mp_context=multiprocessing.get_context("fork")
            )
        return self

    def __exit__(self, *exc: object) -> None:
        global _OWNER
        if self.executor is not None:
            self.executor.shutdown(wait=True, cancel_futures=True)
        _OWNER = None

    def map(self, method: str, calls: Sequence[tuple[Any, ...]]) -> list[Any]:
        """``owner.method(*args)`` per call, in order; calls the time bound cut are left out."""
        if self.executor is None:
            out = []
            for args in calls:
                if time.monotonic() > self.deadline:
                    self.truncated = True
                    break
                out.append(getattr(self.owner, method)(*args))
            return out
        futures: list[Future[Any]] = [
            self.executor.submit(_run_in_worker, method, args) for args in calls
        ]
        results = []
        for future in futures:
            try:
                results.append(future.result(timeout=max(self.deadline - time.monotonic(), 0.0)))
            except TimeoutError:
                self.truncated = True
                for rest in futures:
                    rest.cancel()
                break
        return results


class StartSearch(ProfileLikelihood):
    """The search for a start off a flat spot (see the module's docstring)."""

    start_search: bool
    start_search_: StartSearchReport | None

    # --- the hook -------------------------------------------------------------------------------
    def _search_start(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray, start: Evaluation
    ) -> tuple[FloatArray, Evaluation]:
        """A start where the outputs depend on every free parameter, if the given one is flat.

        Returns φ and its evaluation (with sensitivities): the given ones when no parameter is
        flat there or no start was found (``start_search_`` then says why), else the search's.
        """
        self.start_search_ = None
        if not self.start_search:
            return phi, start
        began = time.monotonic()
        sides = self._given_sides(phi, records, sigma, start)
        # a step that moves the outputs both ways while the sensitivity is 0: a switch hides the
        # parameter from the sensitivities, which no start cures (the refusal says so); no
        # change (a flat spot) or a change one way only (the edge of one) is searched away from
        flat = {name: pair for name, pair in sides.items() if not min(pair) > CHI2_95}
        if not flat:
            return phi, start
        box, held = self._search_box(phi)
        starts = self._sobol_starts(phi, box, records)
        run = self._run_search(starts, list(flat), records, sigma, began + SEARCH_SECONDS)
        best = run.best()
        simulated = [probe for probe in run.probes if not probe.failure]
        self.start_search_ = StartSearchReport(
            flat=flat,
            given_states=self._state_ranges(start),
            box=self._natural_box(box),
            held=tuple(held),
            n_starts=len(starts),
            n_simulated=len(run.probes),
            n_failed=len(run.probes) - len(simulated),
            n_checked=sum(1 for probe in simulated if probe.unseen is not None),
            n_acting=sum(1 for probe in simulated if probe.sees(flat)),
            n_qualified=sum(1 for probe in simulated if probe.sees(self.free_names_)),
            seen_in={
                name: sum(1 for probe in simulated if probe.sees([name]))
                for name in self.free_names_
            },
            outputs_range=self._outputs_range(run.probes),
            refined=tuple(run.refined),
            chosen=None if best is None else best.index,
            workers=run.workers,
            serial_reason=run.serial_reason,
            seconds=time.monotonic() - began,
            truncated=run.truncated,
            values={} if best is None else best.values,
        )
        if best is None:
            return phi, start
        return best.phi, self._evaluate(best.phi, records, sigma, jacobian=True)

    def _given_sides(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray, start: Evaluation
    ) -> dict[str, tuple[float, float]]:
        """Per free parameter without sensitivity at φ: the output change of a step up and down.

        What is claimed about the given start is simulated as the fit simulates (not coarsely).
        Empty where every parameter has a sensitivity, or the start cannot be simulated so.
        """
        report, _ = self._structural(phi, start)
        idle = [name for name in self.free_names_ if name in report.zero_sensitivity]
        if not idle:
            return {}
        try:
            base = self._evaluate(phi, records, sigma, jacobian=False)
        except (SimulationError, FloatingPointError, OverflowError):
            return {}
        return {name: self._output_change(phi, name, base, records, sigma) for name in idle}

    def _run_search(
        self,
        starts: Sequence[FloatArray],
        flat: Sequence[str],
        records: Sequence[Record],
        sigma: FloatArray,
        deadline: float,
    ) -> _SearchRun:
        """Simulate every start; check the sensitivities in order of cost; refine the best.

        A simulation with sensitivities costs several plain ones (more where a start is stiff),
        so only the cheap plain simulation runs at every start, and the sensitivities at the
        lowest-cost starts, CHECK_BATCH at a time, until REFINED_STARTS qualify (at every
        start where none does: the refusal's evidence).
        """
        with _Pool(self, len(starts), deadline) as pool:
            probes = pool.map(
                "_probe_start", [(i + 1, start, records, sigma) for i, start in enumerate(starts)]
            )
            self._work[1] += sum(probe.evaluations for probe in probes)
            ranked = sorted(
                (probe for probe in probes if not probe.failure),
                key=lambda probe: (probe.cost, probe.index),
            )
            checked: dict[int, Probe] = {}
            for begin in range(0, len(ranked), CHECK_BATCH):
                batch = ranked[begin : begin + CHECK_BATCH]
                for probe, (unseen, spent) in zip(
                    batch,
                    pool.map("_coarse_unseen", [(p.phi, records, sigma) for p in batch]),
                    strict=False,
                ):
                    self._work[1] += spent
                    checked[probe.index] = replace(probe, unseen=unseen)
                qualified = [p for p in checked.values() if p.sees(self.free_names_)]
                if len(qualified) >= REFINED_STARTS or pool.truncated:
                    break
            qualified = [p for p in checked.values() if p.sees(self.free_names_)]
            refined = pool.map(
                "_coarse_refine",
                [(p.index, p.phi, flat, records, sigma) for p in qualified[:REFINED_STARTS]],
            )
            self._work[1] += sum(r.evaluations for r in refined)
            probes = [checked.get(probe.index, probe) for probe in probes]
            return _SearchRun(probes, refined, pool.workers, pool.serial_reason, pool.truncated)

    def _with_search_evidence(self, refusal: NotIdentifiableError) -> NotIdentifiableError:
        """The refusal with the search's evidence in its advice (itself when no search ran)."""
        search = vars(self).get("start_search_")
        if search is None or search.chosen is not None:
            return refusal
        report = refusal.report
        return NoStartFound(report.with_advice((*report.advice, search.evidence())), search)

    # --- the steps ------------------------------------------------------------------------------
    def _probe_start(
        self, index: int, phi: FloatArray, records: Sequence[Record], sigma: FloatArray
    ) -> Probe:
        """One start simulated coarsely, without sensitivities (what a worker runs)."""
        spent = self._work[1]
        try:
            with self._coarse():
                evaluation = self._evaluate(phi, records, sigma, jacobian=False)
        except (SimulationError, FloatingPointError, OverflowError) as exc:
            n_y = len(self.model.output_names)
            return Probe(
                index,
                phi,
                math.inf,
                None,
                np.full((n_y, 2), np.nan),
                self._work[1] - spent,
                str(exc) or type(exc).__name__,
            )
        outputs = np.vstack([t.outputs for t in evaluation.trajectories])
        return Probe(
            index,
            phi,
            float(evaluation.residuals @ evaluation.residuals),
            None,
            np.column_stack([np.nanmin(outputs, axis=0), np.nanmax(outputs, axis=0)]),
            self._work[1] - spent,
        )

    def _coarse_unseen(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray
    ) -> tuple[tuple[str, ...], int]:
        """The free parameters whose sensitivity vanishes at φ (coarse), and the work it took.

        A start whose simulation with sensitivities fails sees none of them.
        """
        spent = self._work[1]
        try:
            with self._coarse():
                evaluation = self._evaluate(phi, records, sigma, jacobian=True)
        except (SimulationError, FloatingPointError, OverflowError):
            return tuple(self.free_names_), self._work[1] - spent
        return self._unseen(phi, evaluation), self._work[1] - spent

    def _unseen(self, phi: FloatArray, evaluation: Evaluation) -> tuple[str, ...]:
        report, _ = self._structural(phi, evaluation)
        return tuple(name for name in self.free_names_ if name in report.zero_sensitivity)

    def _output_change(
        self,
        phi: FloatArray,
        name: str,
        base: Evaluation,
        records: Sequence[Record],
        sigma: FloatArray,
    ) -> tuple[float, float]:
        """The weighted output change a step of +10 % and of −10 % in ``name`` makes at φ.

        The change is Σ((ŷ(φ + step) − ŷ(φ))/σ)² over the samples fitted: above χ²₁'s 95 %
        quantile the records would tell the two apart. NaN for a side beyond a bound; inf for a
        step that cannot be simulated (a change, as in :meth:`_simulated_rises`).
        """
        names, scale = self._report_columns(phi)
        j = names[name]
        lower, upper = self.map_.bounds()
        sides = [math.nan, math.nan]
        for side, sign in enumerate((1.0, -1.0)):
            trial = phi.copy()
            trial[j] += sign * EVIDENCE_STEP * scale[j]
            if not lower[j] < trial[j] < upper[j]:
                continue
            try:
                moved = self._evaluate(trial, records, sigma, jacobian=False).residuals
                sides[side] = float(np.sum((moved - base.residuals) ** 2))
            except (SimulationError, FloatingPointError, OverflowError):
                sides[side] = math.inf
        return sides[0], sides[1]

    def _coarse_refine(
        self,
        index: int,
        phi: FloatArray,
        flat: Sequence[str],
        records: Sequence[Record],
        sigma: FloatArray,
    ) -> RefinedStart:
        """A short coarse fit from a start, and the parameters the outputs stopped following.

        A parameter is lost where the fit ended when its sensitivity vanishes there (the fit
        carried it past the records' reach, where nothing brings it back), or, for one that was
        flat at the given start, when it sits at the edge of that flat spot: a ±10 % step moves
        the outputs one way only. A limit fitted to the records' extreme sample is such an
        edge: the records bound it on one side and say nothing on the other.
        """
        spent = self._work[1]
        p = len(self.free_names_)
        saved = self.max_iterations
        self.max_iterations = REFINE_ITERATIONS
        try:
            with self._coarse():
                fitted, _, evaluation = self._solve(phi, records, sigma)
                unseen = self._unseen(fitted, evaluation)
                edges = [
                    name
                    for name in flat
                    if name not in unseen
                    and _one_way(self._output_change(fitted, name, evaluation, records, sigma))
                ]
        except (SimulationError, FloatingPointError, OverflowError) as exc:
            return RefinedStart(
                index, phi, math.inf, (), {}, self._work[1] - spent, str(exc) or "failed"
            )
        finally:
            self.max_iterations = saved
        return RefinedStart(
            index,
            fitted,
            float(evaluation.residuals @ evaluation.residuals),
            tuple(name for name in self.free_names_ if name in unseen or name in edges),
            self.map_.values(fitted[:p]),
            self._work[1] - spent,
        )

    @contextmanager
    def _coarse(self) -> Iterator[None]:
        """The fit's solver at the search's loose tolerance and trial step limit, for a while."""
        choice = self.solver_
        solver = choice.solver
        if solver.method != "rk4":
            solver = replace(
                solver,
                rtol=max(solver.rtol, COARSE_RTOL),
                steps_per_sample=TRIAL_STEPS_PER_SAMPLE,
            )
        self.solver_ = SolverChoice(solver, choice.requested, choice.reason)
        try:
            yield
        finally:
            self.solver_ = choice

    # --- the set of starts ----------------------------------------------------------------------
    def _search_box(self, phi: FloatArray) -> tuple[FloatArray, list[str]]:
        """Per free parameter, (low, high) in φ the starts fill; the names held at their start.

        Both bounds finite: the bounds (in log space for a positive parameter). A bound open:
        a factor SEARCH_SPAN either side of the start for a positive parameter, ± the start's
        size (or the distance to the finite bound) for another, within the bounds; a parameter
        at 0 without any bound has no size to search over and is held.
        """
        lower, upper = self.map_.bounds()
        p = len(self.free_names_)
        box = np.empty((p, 2))
        held = []
        for j, spec in enumerate(self.map_.free):
            if math.isfinite(lower[j]) and math.isfinite(upper[j]):
                box[j] = lower[j], upper[j]
                continue
            if spec.log_scale:
                width = math.log(SEARCH_SPAN)
            else:
                sizes = [abs(phi[j])] + [abs(b - phi[j]) for b in (lower[j], upper[j])]
                width = max((s for s in sizes if math.isfinite(s)), default=0.0)
            if width == 0.0:
                held.append(spec.name)
            box[j] = max(phi[j] - width, lower[j]), min(phi[j] + width, upper[j])
        return box, held

    def _sobol_starts(
        self, phi: FloatArray, box: FloatArray, records: Sequence[Record]
    ) -> list[FloatArray]:
        """SEARCH_STARTS starts (φ) filling the box; initial states at each one's steady state."""
        from scipy.stats import qmc  # 0.3 s to import: only when a search runs

        p = len(self.free_names_)
        points = qmc.Sobol(p, scramble=True, seed=SEARCH_SEED).random_base2(
            int(math.log2(SEARCH_STARTS))
        )
        # strictly inside the bounds: the fit's trust region needs room on both sides
        span = box[:, 1] - box[:, 0]
        thetas = box[:, 0] + span * (1e-6 + (1.0 - 2e-6) * points)
        out = []
        for theta_phi in thetas:
            if not self.estimate_x0_:
                out.append(theta_phi)
                continue
            values = self.map_.values(theta_phi)
            guesses = [self.model.steady_state_guess(values, record) for record in records]
            start = np.concatenate([theta_phi, *guesses])
            # held initial states stay where they are held
            start[self._held_states] = phi[self._held_states]
            out.append(start)
        return out

    # --- the report's numbers -------------------------------------------------------------------
    def _natural_box(self, box: FloatArray) -> dict[str, tuple[float, float]]:
        low = self.map_.to_theta(box[:, 0])
        high = self.map_.to_theta(box[:, 1])
        return {
            name: (float(low[j]), float(high[j]))
            for j, name in enumerate(self.free_names_)
            if box[j, 1] > box[j, 0]
        }

    def _state_ranges(self, evaluation: Evaluation) -> dict[str, tuple[float, float]]:
        states = np.vstack([t.states for t in evaluation.trajectories])
        return {
            name: (float(np.min(states[:, i])), float(np.max(states[:, i])))
            for i, name in enumerate(self.model.state_names)
        }

    def _outputs_range(self, probes: Sequence[Probe]) -> dict[str, tuple[float, float]]:
        ranges = [p.outputs for p in probes if not p.failure]
        names = self.model.output_names
        if not ranges:
            return dict.fromkeys(names, (math.nan, math.nan))
        stacked = np.stack(ranges)
        return {
            name: (float(np.min(stacked[:, i, 0])), float(np.max(stacked[:, i, 1])))
            for i, name in enumerate(names)
        }
