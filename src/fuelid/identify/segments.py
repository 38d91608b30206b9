"""Records with gaps: how the estimators treat their contiguous segments.

A log with gaps is one :class:`~fuelid.io.timeseries.IOData` whose segments are concatenated
(``segment_starts``). fuelid identifies it the way identification toolboxes merge experiments
(MATLAB's ``merge`` of ``iddata`` experiments): one model (K, T, T2, delay, T_f) for all
segments, each segment with its own initial state, nothing simulated, filtered or correlated
across a gap. What each part does:

- :class:`~fuelid.identify.oe.OutputError`: the free-run simulation restarts at every segment,
  from rest at the segment's first command plus the free response of an unknown initial state
  (one amplitude per lag, estimated per segment). The output offset is *common*: one plant,
  one flowmeter, one offset; a segment at another operating level is then tied to the others
  through K·Δu, which is what makes the segments inform K jointly. The Jacobian and the
  covariance run over all segments.
- :class:`~fuelid.identify.step_ls.StepResponseLS`: regression rows only where the row's N
  past inputs lie in the same segment; decimation segment by segment.
- Diagnostics: correlations summed within segments only.

A segment needs at least :data:`MIN_SEGMENT_SAMPLES` samples: its initial state costs up to
three parameters, and with fewer samples they would fit it exactly and say nothing about the
model. :func:`drop_short_segments` leaves shorter segments out, with a warning.
"""

from __future__ import annotations

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
