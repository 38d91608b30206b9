"""Records with gaps: how the estimators treat their contiguous segments.

A log with gaps is one :class:`~fuelid.io.timeseries.IOData` whose segments are concatenated
(``segment_starts``). fuelid identifies it the way identification toolboxes merge experiments
(MATLAB's ``merge`` of ``iddata`` experiments): one model (K, T, T2, delay, T_f) for all
segments, each segment with its own initial state, nothing simulated, filtered or correlated
across a gap. What each part does:

- :class:`~fuelid.identify._oe.OutputError`: the free-run simulation restarts at every segment,
  from rest at the segment's first command plus the free response of an unknown initial state
  (one amplitude per lag, estimated per segment). The output offset is *common*: one plant,
  one flowmeter, one offset; a segment at another operating level is then tied to the others
  through K·Δu, which is what makes the segments inform K jointly. The Jacobian and the
  covariance run over all segments.
- :class:`~fuelid.identify._step_ls.StepResponseLS`: regression rows only where the row's N
  past inputs lie in the same segment; decimation segment by segment.
- Diagnostics: correlations summed within segments only.

A segment needs at least :data:`MIN_SEGMENT_SAMPLES` samples: its initial state costs up to
three parameters, and with fewer samples they would fit it exactly and say nothing about the
model. :func:`drop_short_segments` leaves shorter segments out, with a warning.
"""

from __future__ import annotations

import math

import numpy as np

from fuelid.identify.preprocess import join_segments
from fuelid.io.timeseries import FloatArray, IOData
from fuelid.lti import DiscreteLagModel

MIN_SEGMENT_SAMPLES = 20
"""Fewest samples a segment of a record with gaps must have to be fitted [samples]."""


def drop_short_segments(
    data: IOData, min_samples: int = MIN_SEGMENT_SAMPLES
) -> tuple[IOData, list[str]]:
    """The record without its segments shorter than ``min_samples``, and a warning per drop.

    Examples
    --------
    >>> import numpy as np
    >>> d = IOData(np.ones(60), np.ones(60), 0.1, segment_starts=(30, 35), segment_t0=(5.0, 9.0))
    >>> kept, why = drop_short_segments(d)
    >>> kept.n_samples, kept.n_segments, why[0].split(":")[0]
    (55, 2, 'segment 2 of 3 (t = 5 … 5.4 s) has only 5 samples')
    """
    if data.n_segments == 1:
        return data, []
    parts = data.segments()
    kept = [p for p in parts if p.n_samples >= min_samples]
    warnings = [
        f"segment {i + 1} of {len(parts)} (t = {p.t0:g} … {float(p.t[-1]):g} s) has only "
        f"{p.n_samples} samples: fewer than {min_samples}, too few to estimate its initial "
        "state; left out"
        for i, p in enumerate(parts)
        if p.n_samples < min_samples
    ]
    if not kept:
        return data, warnings
    return join_segments(kept, notes=data.notes), warnings


def offset_and_free_responses(
    discrete: DiscreteLagModel, bounds: list[tuple[int, int]]
) -> FloatArray:
    """Regressors of one output offset and each segment's own free response (initial state).

    Column 0 is the offset (1 everywhere); then, per segment, one column per lag with that lag's
    free response from the segment's first sample (zero outside the segment): least squares on
    them fits the initial state of every segment and the one offset of the record.
    """
    n_lags = discrete.poles.size
    n = bounds[-1][1] if bounds else 0
    basis = np.zeros((n, 1 + n_lags * len(bounds)))
    basis[:, 0] = 1.0
    for j, (a, b) in enumerate(bounds):
        basis[a:b, 1 + j * n_lags : 1 + (j + 1) * n_lags] = discrete.modes(b - a)
    return basis


RESTART_WINDOW_TIME_CONSTANTS = 3.0
"""Fewest slowest-lag time constants a segment's own first samples must span for its initial
state to be read from them (e^(−3) ≈ 5 % of a transient left at the window's end) [-]."""


def state_from_first_samples(
    discrete: DiscreteLagModel, y: FloatArray, response: FloatArray
) -> FloatArray | None:
    """A later segment's start as its own first samples show it: level plus free response.

    ``y`` is the segment's measured output and ``response`` the model's response to the
    segment's command changes (zero until the first change reaches the output). Until then the
    output is the free response of the state at the restart: the level where it settles and
    one amplitude per lag, fitted by least squares on those samples, as the record's first
    segment starts from the measured steady state before its first change. Returns that
    initial-state part of ŷ over the whole segment, or None when those samples are too few
    (fewer than twice the parameters) or span less than
    :data:`RESTART_WINDOW_TIME_CONSTANTS` of the slowest lag (level and free response would
    not be told apart).

    Examples
    --------
    A segment at rest at 5.0 for 30 samples, then a unit command change (lag T = 2 samples):

    >>> from fuelid.lti import discretise
    >>> d = discretise([2.0], 0.0, 1.0)
    >>> response = d.response(np.r_[np.zeros(30), np.ones(30)])
    >>> state = state_from_first_samples(d, 5.0 + response, response)
    >>> [round(float(v), 6) for v in state[[0, -1]]]
    [5.0, 5.0]
    """
    reached = np.flatnonzero(response != 0.0)
    window = int(reached[0]) if reached.size else y.size
    n_lags = discrete.poles.size
    slowest = float(discrete.poles.max()) if n_lags else 0.0
    if window < 2 * (1 + n_lags) or slowest**window > math.exp(-RESTART_WINDOW_TIME_CONSTANTS):
        return None
    basis = np.column_stack((np.ones(y.size), discrete.modes(y.size)))
    coefficients = np.linalg.lstsq(basis[:window], y[:window], rcond=None)[0]
    return np.asarray(basis @ coefficients, dtype=float)
