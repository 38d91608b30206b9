"""Whether a segmented start would pay: a local minimum told from a model error.

A single-shooting fit whose residuals are far above the records' sample-to-sample noise is at a
local minimum of a right model (an oscillator whose phase was lost), or at the best fit of a
model that misses something (any real record). The segmented start
(:mod:`fuelid.greybox._multiple_shooting`) helps only in the first case, and costs about as
much as the fit again; this module decides which case it is for the price of one evaluation.

The test. At the plain estimate θ̂ the records are cut into the segmented start's first stage
(segments of ≥ 50 samples), each segment started from the plain trajectory's state at its
first sample, and simulated with sensitivities (one evaluation: the residuals are the plain
fit's). On those segments the segmented start's problem is linearised: the states reset at
each segment remove part of the misfit (``after_resets``: what is left once the segments'
initial states are fitted, θ held); the parameters then remove a further share (the
Gauss–Newton gain of θ with the states free). The share is taken of the *excess* misfit, what
is left above the noise floor the records show:

    share = (after_resets − after_resets_and_θ) / (after_resets − noise floor)

- A local minimum of a right model: within short segments the phase cannot drift, the
  segments' fit is nearly convex, and the parameters that fit the segments fit the data: they
  remove most of the excess (share → 1);
- a model error: no parameter value makes the model right, on segments as on the whole
  record; the resets take the slow drift (a pump that wanders, a missed leak) and what is left
  is shape the model cannot make (share ≪ 1).

The segmented start runs where the share is at least :data:`PARAMETER_SHARE`. A linearised
gain errs towards trying (it may promise more than a far step would give), which costs time,
not accuracy; directions the segments do not determine (singular values below
:data:`RANK_CUT` of the largest) promise nothing.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fuelid.greybox._fitting import Evaluation, FloatArray
from fuelid.greybox._system import Record

PARAMETER_SHARE = 0.5
"""The share of the excess misfit (above the noise floor) the parameters must remove on the
segments, once the states are reset, for the segmented start to be tried (module docstring)."""
RANK_CUT = 1e-8
"""Directions of the parameters' (column-scaled) segment Jacobian below this share of the
largest singular value are not counted: they change the fit by rounding only."""


@dataclass(frozen=True)
class Pieces:
    """Records cut into segments: the segments, where each lies, each one's initial state."""

    records: list[Record]
    spans: list[tuple[int, int, int]]
    """(record index, first sample, end sample) of each segment."""
    states: list[FloatArray]


def cut(
    records: Sequence[Record], states: Sequence[FloatArray], count: int, n_states: int
) -> Pieces:
    """Each record cut into ``count`` segments, started from ``states`` at their first sample.

    Segments with no more finite outputs than states are left out (nothing to fit there).
    """
    pieces, spans, guesses = [], [], []
    for i, record in enumerate(records):
        edges = np.linspace(0, len(record.t), count + 1).round().astype(int)
        for a, b in itertools.pairwise(edges):
            if np.isfinite(record.y[a:b]).sum() <= n_states:
                continue
            pieces.append(Record(record.t[a:b], record.u[a:b], record.y[a:b], "", record.context))
            spans.append((i, a, b))
            guesses.append(np.asarray(states[i][a], dtype=float))
    return Pieces(pieces, spans, guesses)


@dataclass(frozen=True)
class TriggerTest:
    """The test's figures, in weighted squared residuals."""

    segments: int
    misfit: float
    """Σr² at the plain estimate."""
    after_resets: float
    """Σr² left when each segment's initial state is fitted (linearised), θ held."""
    after_parameters: float
    """Σr² left when θ is fitted too (linearised)."""
    floor: float
    """Σr² the records' sample-to-sample noise alone would leave."""

    @property
    def share(self) -> float:
        """The share of the excess misfit the parameters remove (0 when there is no excess)."""
        excess = self.after_resets - self.floor
        if excess <= 0.0:
            return 0.0
        return max(self.after_resets - self.after_parameters, 0.0) / excess

    @property
    def pays(self) -> bool:
        """Whether the segmented start is worth its cost (a local minimum, not a model error)."""
        return self.share >= PARAMETER_SHARE

    def describe(self) -> str:
        """One clause for the fit's ``start``."""
        return (
            f"with the states reset at {self.segments} segments the parameters would remove "
            f"{self.share:.0%} of the misfit above the noise ({PARAMETER_SHARE:.0%} needed): "
            + ("a local minimum" if self.pays else "a model error, not a local minimum")
        )


def trigger_test(
    evaluation: Evaluation,
    pieces: Pieces,
    n_parameters: int,
    n_states: int,
    floor_weights: FloatArray,
) -> TriggerTest:
    """The test on the segments' evaluation (residuals and Jacobian, θ then each x0).

    ``floor_weights``: each output's (noise floor / fit's σ)², the weighted squared residual
    the noise alone leaves per sample.
    """
    jacobian = evaluation.jacobian
    assert jacobian is not None
    r = evaluation.residuals
    j_theta = jacobian[:, :n_parameters]
    left_r, left_theta = [], []
    row = 0
    floor = 0.0
    for k, piece in enumerate(pieces.records):
        keep = np.isfinite(piece.y)
        floor += float(np.sum(keep * floor_weights[None, :]))
        rows = slice(row, row + int(keep.sum()))
        row += int(keep.sum())
        columns = slice(n_parameters + k * n_states, n_parameters + (k + 1) * n_states)
        basis = _orthonormal(jacobian[rows, columns])
        # what the segment's own initial state cannot take: the residual off its columns' span
        left_r.append(r[rows] - basis @ (basis.T @ r[rows]))
        left_theta.append(j_theta[rows] - basis @ (basis.T @ j_theta[rows]))
    r_left = np.concatenate(left_r)
    after_resets = float(r_left @ r_left)
    basis = _orthonormal(np.vstack(left_theta))
    gain = basis.T @ r_left
    return TriggerTest(
        segments=len(pieces.records),
        misfit=float(r @ r),
        after_resets=after_resets,
        after_parameters=after_resets - float(gain @ gain),
        floor=floor,
    )


def _orthonormal(columns: FloatArray) -> FloatArray:
    """An orthonormal basis of the columns' span, directions below RANK_CUT left out."""
    if columns.size == 0:
        return np.zeros((columns.shape[0], 0))
    norms = np.linalg.norm(columns, axis=0)
    scaled = columns[:, norms > 0.0] / norms[norms > 0.0]
    if scaled.shape[1] == 0:
        return np.zeros((columns.shape[0], 0))
    u, s, _ = np.linalg.svd(scaled, full_matrices=False)
    return np.asarray(u[:, s > RANK_CUT * s[0]])
