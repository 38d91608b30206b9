"""The segmented start: multiple shooting without continuity, for long records and local minima.

Over a short segment a wrong parameter cannot drift the prediction far (an oscillator's phase,
say), so a fit of the records cut into segments, each with its own initial state, is nearly
convex. :class:`SegmentedStart` fits in stages of a quarter as many segments, down to one, and
hands the result to the single-shooting fit (:mod:`fuelid.greybox._fitting`) as its start; with
``segments="auto"`` it is tried only when the single-shooting fit failed or is suspect.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

from fuelid.greybox._fitting import (
    ConvergenceError,
    Evaluation,
    FloatArray,
    OutOfBudget,
    ShootingFit,
    ShootingResult,
)
from fuelid.greybox._solvers import SimulationError
from fuelid.greybox._system import Record

SEGMENT_MIN_SAMPLES = 50
"""A segment of the segmented start holds at least this many samples."""
SEGMENT_MAX_STATES = 240
"""At most this many segment initial states (n_states × segments) are estimated at once."""
SEGMENT_SHRINK = 4
"""Each stage of the segmented start has a quarter of the last stage's segments."""
SUSPECT_NOISE_RATIO = 3.0
"""A fit whose residuals are this many times the first-difference noise level of an output is
suspected of a local minimum (or model error): ``segments="auto"`` then tries a segmented start."""


def _stages(count: int) -> list[int]:
    """Segments per record of each stage of a segmented start: count, count/4, … above 1.

    >>> _stages(60)
    [60, 15, 3]
    """
    stages = []
    while count > 1:
        stages.append(count)
        count //= SEGMENT_SHRINK
    return stages


class SegmentedStart(ShootingFit):
    """The segmented start of :class:`~fuelid.greybox._estimator.GreyBoxEstimator`."""

    start_: str
    """How the fit was started (set by the estimator's ``fit``, refined here)."""

    @staticmethod
    def _suspect(result: ShootingResult, floor: FloatArray) -> bool:
        """Residuals far above the noise the records show: a local minimum, or a wrong model."""
        return bool(np.any(result.sigma > SUSPECT_NOISE_RATIO * floor))

    def _retry_segmented(
        self,
        phi: FloatArray,
        records: Sequence[Record],
        sigma: FloatArray,
        evaluation: Evaluation,
        first: ShootingResult | None,
        allowance: int | None = None,
    ) -> ShootingResult | None:
        """Fit again from a segmented start; the better of the two fits (None: no better one).

        ``allowance``: the right-hand-side evaluations the segmented start's stages may spend
        (the fit from their result is not counted); None: no limit.
        """
        count = self._segment_count(records)
        if count < 2:
            return None
        try:
            if allowance is not None:
                self._work_limit = self._work[1] + allowance
            try:
                phi = self._segmented_start(phi, records, sigma, evaluation, count)
            finally:
                self._work_limit = None
            evaluation = self._evaluate_or_fall_back(
                phi, records, sigma, "the segmented start's end"
            )
            second = self._single_shooting(phi, records, sigma, evaluation)
        except (ConvergenceError, SimulationError, FloatingPointError, OverflowError):
            if first is not None:
                self.start_ = "single shooting (a segmented start did not converge)"
            return None
        # compare the fits by their likelihood: Σ log σ_c² over the outputs' samples
        if first is not None and self._log_likelihood_cost(
            first, records
        ) <= self._log_likelihood_cost(second, records):
            self.start_ = "single shooting (a segmented start found no better fit)"
            return None
        return second

    @staticmethod
    def _log_likelihood_cost(result: ShootingResult, records: Sequence[Record]) -> float:
        counts = np.sum([np.isfinite(record.y).sum(axis=0) for record in records], axis=0)
        return float(np.sum(counts * np.log(result.sigma**2)))

    def _segment_count(self, records: Sequence[Record]) -> int:
        """Segments per record of the first stage: ≥ SEGMENT_MIN_SAMPLES samples each."""
        shortest = min(len(record.t) for record in records)
        by_states = SEGMENT_MAX_STATES // max(self.n_states_ * len(records), 1)
        return int(min(shortest // SEGMENT_MIN_SAMPLES, by_states))

    def _segmented_start(
        self,
        phi: FloatArray,
        records: Sequence[Record],
        sigma: FloatArray,
        evaluation: Evaluation,
        count: int,
    ) -> FloatArray:
        """Start values from the records cut into segments, each with its own initial state.

        Multiple shooting without the continuity constraints: over a short segment a wrong
        parameter cannot drift the prediction far (an oscillator's phase, say), so the fit is
        nearly convex; each stage has a quarter of the last one's segments (their initial states
        taken from the last stage's trajectories), down to one. The whole records are then fitted
        from the result by :meth:`_single_shooting`, which alone gives the estimate.
        """
        p = len(self.free_names_)
        n = self.n_states_
        theta_phi = phi[:p]
        states = [trajectory.states.copy() for trajectory in evaluation.trajectories]
        saved = (self.estimate_x0_, self._budgets, self._held_states)
        self.estimate_x0_ = True
        self._held_states = []  # indices of the whole records' φ: not the segments'

        self.start_ = (
            "segmented start ("
            + ", ".join(str(c) for c in _stages(count))
            + " segments per record)"
        )
        try:
            for stage in _stages(count):
                pieces, spans, guesses = [], [], []
                for i, record in enumerate(records):
                    edges = np.linspace(0, len(record.t), stage + 1).round().astype(int)
                    for a, b in itertools.pairwise(edges):
                        if np.isfinite(record.y[a:b]).sum() <= n:
                            continue  # nothing to fit there: its states stay as they were
                        pieces.append(
                            Record(record.t[a:b], record.u[a:b], record.y[a:b], "", record.context)
                        )
                        spans.append((i, a, b))
                        guesses.append(states[i][a])
                if not pieces:
                    break
                # a piece's share of its record's budget (a chattering trial point stops early)
                self._budgets = [
                    max(saved[1][i] * (b - a) // len(records[i].t), 2_000) for i, a, b in spans
                ]
                phi_stage = np.concatenate([theta_phi, *guesses])
                try:
                    phi_stage, _, found = self._solve(
                        phi_stage, pieces, sigma, jacobian_scaled=True
                    )
                except (SimulationError, FloatingPointError, OverflowError, OutOfBudget):
                    break  # keep the last stage's values
                theta_phi = phi_stage[:p]
                for (i, a, b), trajectory in zip(spans, found.trajectories, strict=True):
                    states[i][a:b] = trajectory.states
                if self._work_limit is not None and self._work[1] >= self._work_limit:
                    self.start_ += " (stopped at its allowance of evaluations)"
                    break
        finally:
            self.estimate_x0_, self._budgets, self._held_states = saved
        if not self.estimate_x0_:
            return theta_phi
        out = np.concatenate([theta_phi, *[s[0] for s in states]])
        out[self._held_states] = phi[self._held_states]  # held initial states stay where held
        return out
