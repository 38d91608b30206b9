"""The residual-correlation gate's statistic: the largest |ρ(k)| of a window's residuals.

Over a few settling times of the model (:func:`acf_lags`), on output errors prewhitened by the
noise's own autoregressive model fitted where the output has settled (:func:`prewhiten`), so that
the statistic measures the model's error and not the meter noise's colour
(:func:`largest_residual_acf`). :func:`fuelid.online.gates.postfit_gates` compares it with
``[online] max_residual_acf``; why that default is 0.7 is docs/explanation/gate-study.md.

Units: time [s], command u [V], residuals [L/min].
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.signal
from numpy.typing import ArrayLike, NDArray

from fuelid.identify import (
    MAX_AR_ORDER,
    ResidualAR,
    residual_ar,
    residual_whiteness,
    settled_stretches,
)
from fuelid.numerics_mode import DEFAULT_NUMERICS, Numerics

FloatArray = NDArray[np.float64]

ACF_SETTLING_TIMES = 5.0
"""Residual autocorrelation is examined over this many settling times of the model [-]."""
MAX_ACF_LAGS = 5000
"""Cap on the lags examined [samples] (bounds the cost: 5000 lags of 30 000 samples ≈ 0.1 s)."""
MIN_SETTLED_SAMPLES = 500
"""Fewest settled samples the noise's AR model is fitted on (10 s at 50 Hz); fewer: the
residual-correlation gate judges the raw residuals [-]."""


def acf_lags(n: int, settling_time: float, sample_time: float) -> int:
    """Lags over which the residual autocorrelation matters: a few settling times, capped.

    L = min(n/4, 5·settling_time/h, 5000), at least 1.

    Parameters
    ----------
    n : int
        Residuals [-].
    settling_time : float
        The fitted model's settling time [s].
    sample_time : float
        h [s].

    Returns
    -------
    int
        L [samples].

    Examples
    --------
    >>> acf_lags(30_000, 4.4, 0.02)
    1100
    """
    span = ACF_SETTLING_TIMES * settling_time / sample_time if settling_time > 0.0 else 1.0
    span = span if math.isfinite(span) else float(MAX_ACF_LAGS)
    return max(1, min(n // 4, math.ceil(span), MAX_ACF_LAGS))


def largest_residual_acf(
    residuals: ArrayLike,
    max_lag: int,
    segment_starts: Sequence[int] = (),
    *,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> tuple[float, int]:
    """Largest |ρ(k)| of the residuals over lags 1…max_lag, and its lag.

    ρ(k) as ``identify`` computes it (:func:`fuelid.identify._diagnostics.residual_whiteness`:
    within segments, normalised by the whole record's variance).

    Parameters
    ----------
    residuals : array
        y − ŷ (or one-step prediction errors) [L/min].
    max_lag : int
        L [samples].
    segment_starts : sequence of int
        Where each segment after a gap begins.
    numerics : Numerics
        How the autocorrelation is summed (:mod:`fuelid.numerics_mode`).

    Returns
    -------
    (float, int)
        max |ρ(k)| [-] and the k where it occurs [samples].

    Examples
    --------
    >>> e = np.random.default_rng(0).normal(size=10_000)
    >>> rho, lag = largest_residual_acf(e, 50)
    >>> rho < 0.05
    True
    """
    test = residual_whiteness(residuals, max_lag, segment_starts, numerics=numerics)
    k = int(np.argmax(np.abs(test.values)))
    return float(abs(test.values[k])), int(test.lags[k])


@dataclass(frozen=True)
class Prewhitened:
    """Residuals filtered by the noise's own AR model, fitted where the output has settled."""

    residuals: FloatArray
    """A(q)·e, segment by segment, the first p samples of each segment left out [L/min]."""
    segment_starts: tuple[int, ...]
    """Where each segment of :attr:`residuals` after a gap begins."""
    noise: ResidualAR
    """The noise's model A(q)·v = e (order 0: the settled residuals are white)."""
    settled_samples: int
    """Samples it was fitted on [-]."""


def prewhiten(
    residuals: ArrayLike,
    u: ArrayLike,
    sample_time: float,
    settle: float,
    segment_starts: Sequence[int] = (),
    *,
    max_order: int = MAX_AR_ORDER,
    min_samples: int = MIN_SETTLED_SAMPLES,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> Prewhitened | None:
    """The residuals prewhitened by the *noise's* model: colour of the meter, not of the model.

    1. The settled stretches (:func:`~fuelid.identify._diagnostics.settled_stretches`: from two
       settling times of the model after each command change or gap on, at least 2·max_order
       + 1 samples long), each with its mean removed: there the model's error has decayed and
       the residual is the measurement noise.
    2. An AR model A(q) of them, its order ≤ ``max_order`` by BIC
       (:func:`~fuelid.identify._covariance.residual_ar`, Levinson–Durbin, pooled within the
       stretches).
    3. The whole residual filtered by A(q) within each segment, the first p samples of each
       segment left out (their filter has no past).

    The noise model is not fitted on the whole residual: that would describe the model's
    error as noise too and whiten it away. A model error concentrated in the transients keeps
    its correlation through A(q) (a smooth misfit is scaled by about A(1), the noise by its
    innovation's share), so the largest |ρ(k)| of the result measures the model's error.

    Parameters
    ----------
    residuals : array
        y − ŷ of an output-error fit [L/min].
    u : array
        The command, one per residual [V].
    sample_time : float
        h [s].
    settle : float
        The fitted model's 98 % settling time [s].
    segment_starts : sequence of int
        Where each segment after a gap begins.
    max_order : int
        Highest AR order [-].
    min_samples : int
        Fewest settled samples to fit the noise's model on [-].
    numerics : Numerics
        How the AR model's autocovariance is summed (:mod:`fuelid.numerics_mode`).

    Returns
    -------
    Prewhitened or None
        None when the settled stretches hold fewer than ``min_samples`` samples.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> u = np.repeat([0.0, 1.0] * 10, 1500)
    >>> v = scipy.signal.lfilter([1.0], [1.0, -0.8], rng.normal(size=u.size))
    >>> out = prewhiten(v, u, 0.02, 2.0)
    >>> out.noise.order, round(float(out.noise.a[1]), 2), out.settled_samples
    (1, -0.8, 26000)
    >>> largest_residual_acf(v, 50)[0] > 0.75, largest_residual_acf(out.residuals, 50)[0] < 0.05
    (True, True)
    """
    e = np.asarray(residuals, dtype=float)
    stretches = settled_stretches(u, sample_time, settle, segment_starts, 2 * max_order + 1)
    settled = [e[a:b] - e[a:b].mean() for a, b in stretches]
    n = sum(part.size for part in settled)
    if not settled or n < min_samples:
        return None
    sizes = np.cumsum([part.size for part in settled])
    bounds = list(itertools.pairwise([0, *sizes.tolist()]))
    noise = residual_ar(np.concatenate(settled), bounds, max_order, numerics)
    p = noise.order
    centred = e - e.mean()
    edges = [0, *(int(i) for i in segment_starts), e.size]
    pieces = [
        scipy.signal.lfilter(noise.a, [1.0], centred[a:b])[p:]
        for a, b in itertools.pairwise(edges)
        if b - a > p
    ]
    starts = tuple(np.cumsum([piece.size for piece in pieces])[:-1].tolist())
    return Prewhitened(np.concatenate(pieces), starts, noise, n)


__all__ = [
    "ACF_SETTLING_TIMES",
    "MAX_ACF_LAGS",
    "MIN_SETTLED_SAMPLES",
    "Prewhitened",
    "acf_lags",
    "largest_residual_acf",
    "prewhiten",
]
