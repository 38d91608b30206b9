"""The flow reading's health: noise level, stuck readings, quantisation step.

P. J. Rousseeuw, C. Croux, "Alternatives to the median absolute deviation", J. Am. Stat. Assoc.
88 (1993) 1273–1283 (robust scale).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from fuelid.online.health._arrays import _ok_mask
from fuelid.plc import STUCK_AFTER_S

_MAD_NORMAL = 0.6744897501960817
"""Median of |N(0, 1)|: the MAD of a normal sample is 0.6745 σ."""


def noise_level(y: ArrayLike) -> float:
    """Robust noise standard deviation: median |Δy| / (√2 · 0.6745).

    For white Gaussian noise of standard deviation σ the successive differences are N(0, 2σ²),
    whose absolute values have median 0.6745·√2·σ; the median ignores the few large
    differences of steps and the slow drift of the process (Rousseeuw & Croux 1993 on the MAD;
    the successive-difference form is von Neumann's, Ann. Math. Stat. 12 (1941) 367).

    Parameters
    ----------
    y : array
        Signal [any unit]; non-finite differences are ignored.

    Returns
    -------
    float
        σ [unit of y]; nan with fewer than two finite samples.

    Examples
    --------
    >>> y = np.random.default_rng(0).normal(scale=0.3, size=100_000) + np.linspace(0, 50, 100_000)
    >>> round(noise_level(y), 2)
    0.3
    """
    d = np.diff(np.asarray(y, dtype=float))
    d = d[np.isfinite(d)]
    if d.size == 0:
        return math.nan
    return float(np.median(np.abs(d))) / (math.sqrt(2.0) * _MAD_NORMAL)


def quantisation_step(y: ArrayLike, min_count: int = 3, min_share: float = 0.9) -> float | None:
    """The quantisation step of a reading: its smallest nonzero |Δy|, of which all are multiples.

    Successive differences of a quantised signal are integer multiples of the step q. Without
    noise, or with noise of about one q, the commonest nonzero |Δy| is q; with noise of many q
    (the virtual PLC's 0.1 L/min is 23 counts of 120 L/min on 27648) the counts of q, 2q, 3q, …
    are all about equal and the commonest is any of them, so the estimate is the smallest
    nonzero difference seen at least ``min_count`` times, accepted when at least ``min_share``
    of the nonzero differences are whole multiples of it. A reading with no repeated difference
    (unquantised, or quantised far below its noise) shows no step. Differences are compared
    after rounding to 1e-9 of the signal's magnitude (float scaling of counts leaves last-bit
    noise).

    Parameters
    ----------
    y : array
        Signal [any unit].
    min_count : int
        Fewest occurrences of the smallest difference [-].
    min_share : float
        Share of the nonzero differences that must be multiples of it [-].

    Returns
    -------
    float or None
        q [unit of y]; None when no quantisation shows.

    Examples
    --------
    >>> q = 120.0 / 27648  # a 0–120 L/min flow on 27648 counts
    >>> x = 40.0 + np.random.default_rng(0).normal(scale=0.1, size=30_000)
    >>> round(quantisation_step(np.round(x / q) * q) / q, 6), quantisation_step(x)
    (1.0, None)
    """
    v = np.asarray(y, dtype=float)
    d = np.abs(np.diff(v))
    d = d[np.isfinite(d)]
    scale = float(np.max(np.abs(v[np.isfinite(v)]), initial=0.0))
    resolution = 1e-9 * max(scale, 1e-300)
    d = d[d > resolution]
    if d.size == 0:
        return None
    keys = np.round(d / resolution)
    values, counts = np.unique(keys, return_counts=True)
    repeated = values[counts >= min_count]
    if repeated.size == 0:
        return None
    q = float(np.mean(d[keys == repeated[0]]))
    ratio = d / q
    if np.mean(np.abs(ratio - np.round(ratio)) <= 1e-6 * np.maximum(ratio, 1.0)) < min_share:
        return None
    return q


@dataclass(frozen=True)
class SensorHealth:
    """The flow reading's own health over one window."""

    noise: float
    """Robust noise standard deviation (:func:`noise_level`) [L/min]."""
    longest_run: float
    """Longest time the reading stayed exactly unchanged [s]."""
    longest_run_start: float | None
    """When that run began [s]; None for an empty window."""
    stuck: bool
    """A run of at least ``stuck_after`` seconds above the span's low end."""
    stuck_after: float
    """The stuck rule's run length [s]."""
    quantum: float | None
    """Quantisation step (:func:`quantisation_step`) [L/min]; None when none shows."""


def sensor_health(
    t: ArrayLike,
    y: ArrayLike,
    ok: ArrayLike | None = None,
    *,
    stuck_after_s: float = STUCK_AFTER_S,
    low_end: float = -math.inf,
) -> SensorHealth:
    """Noise level, exactly repeated values and quantisation of a flow reading.

    A run is a stretch of successive samples with bit-for-bit the same value; its length is the
    time from its first to its last sample, as the recorder measures it
    (:class:`fuelid.plc._quality.StuckDetector`, whose rule this is: a run of
    ``stuck_after_s`` = 2 s is a frozen transmitter, unless the value sits at the low end of the
    span, where a stopped pump or a low-flow cut-off legitimately reads a constant). The
    recorder also waits for the reading to have moved once in the recording; a window does not
    know the recording, so a window frozen from its first sample counts as stuck here. The runs
    are sought in all samples (the recorder flags a stuck stretch bad, so the quality mask would
    hide it); the noise and the quantisation use the good ones.

    Parameters
    ----------
    t : array
        Times [s].
    y : array
        Flow [L/min].
    ok : array of bool, optional
        Quality mask for the noise and quantisation; None: all.
    stuck_after_s : float
        Run length that means stuck [s].
    low_end : float
        Values at or below this may be constant [L/min] (the recorder: 1 % of the span above
        its low end).

    Returns
    -------
    SensorHealth

    Examples
    --------
    >>> t = np.arange(0.0, 10.0, 0.02)
    >>> y = 40.0 + np.random.default_rng(0).normal(scale=0.1, size=t.size)
    >>> y[100:251] = y[100]  # 150 intervals of 0.02 s frozen
    >>> s = sensor_health(t, y)
    >>> round(s.longest_run, 6), s.stuck, round(s.longest_run_start, 6)
    (3.0, True, 2.0)
    """
    tt = np.asarray(t, dtype=float)
    yy = np.asarray(y, dtype=float)
    good = _ok_mask(yy.size, ok) & np.isfinite(yy)
    if yy.size == 0:
        return SensorHealth(math.nan, 0.0, None, False, stuck_after_s, None)
    change = np.flatnonzero(yy[1:] != yy[:-1]) + 1  # NaN != NaN: a NaN is a run of its own
    starts = np.r_[0, change]
    ends = np.r_[change - 1, yy.size - 1]
    lengths = tt[ends] - tt[starts]
    lengths = np.where(np.isfinite(yy[starts]), lengths, 0.0)
    i = int(np.argmax(lengths))
    stuck = bool(np.any((lengths >= stuck_after_s) & (yy[starts] > low_end)))
    return SensorHealth(
        noise=noise_level(np.where(good, yy, np.nan)),
        longest_run=float(lengths[i]),
        longest_run_start=float(tt[starts[i]]),
        stuck=stuck,
        stuck_after=float(stuck_after_s),
        quantum=quantisation_step(yy[good]),
    )


__all__ = ["SensorHealth", "noise_level", "quantisation_step", "sensor_health"]
