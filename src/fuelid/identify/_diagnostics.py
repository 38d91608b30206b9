"""Diagnostics of a fitted model.

Residual whiteness, input–residual correlation, steady-state error on steps, feedback
(closed-loop) suspicion and sample-time advice.

The correlation tests follow Ljung, *System Identification* (2nd ed., 1999), §16.6: for white
residuals uncorrelated with the input, every normalised correlation is asymptotically N(0, 1/N),
so ±1.96/√N bounds 95 % of them, and N·Σr² over M lags is χ²(M).

For a record with gaps (``segment_starts``, the indices where a segment begins) every lagged
product pairs two samples of the same segment: nothing is correlated across a join, where the
samples are not τ apart in time. The sums are pooled over the segments and normalised by the
whole record's N and variances, so a record without gaps gives exactly the classical values.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.special
from numpy.typing import ArrayLike, NDArray

from fuelid.blas import single_threaded_blas
from fuelid.numerics_mode import DEFAULT_NUMERICS, Numerics

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class CorrelationTest:
    """Normalised correlation at lags, with its 95 % bound and a χ² whiteness statistic."""

    lags: FloatArray
    """Lags [samples]."""
    values: FloatArray
    """Normalised correlation at each lag [-]."""
    bound: float
    """95 % confidence bound ±1.96/√N [-]."""
    statistic: float
    """N·Σ r² over the lags tested (lag 0 excluded for the autocorrelation) [-]."""
    p_value: float
    """Probability of a statistic this large for white, uncorrelated residuals [-]."""

    @property
    def passed(self) -> bool:
        """True unless the χ² test rejects at the 1 % level."""
        return self.p_value >= 0.01

    @property
    def fraction_outside(self) -> float:
        """Share of lags outside the bound (about 5 % expected when the test passes)."""
        return float(np.mean(np.abs(self.values) > self.bound))


def _chi2_sf(statistic: float, dof: int) -> float:
    """P(χ²(dof) > statistic): ``scipy.stats.chi2.sf`` without importing scipy.stats (slow)."""
    return float(scipy.special.chdtrc(dof, statistic))


def _bounds(n: int, segment_starts: Sequence[int]) -> list[tuple[int, int]]:
    edges = [0, *(int(i) for i in segment_starts), n]
    return list(itertools.pairwise(edges))


FFT_LAGS = 64
"""Autocorrelations over more lags than this are computed by FFT (cheaper than dot products)."""


def _normalised_xcorr(
    a: FloatArray,
    b: FloatArray,
    lags: FloatArray,
    segment_starts: Sequence[int] = (),
    numerics: Numerics = DEFAULT_NUMERICS,
) -> FloatArray:
    """r_ab(τ) = Σ_k a[k+τ]·b[k] / (N·σ_a·σ_b) for integer lags τ, k and k+τ in one segment.

    An autocorrelation over more than :data:`FFT_LAGS` lags by FFT, anything else (and every
    one with ``numerics.reference``, as before issue 26) by a dot product per lag.
    """
    a_is_b = a is b
    a = a - a.mean()
    b = b - b.mean()
    n = a.size
    denom = n * a.std() * b.std()
    out = np.zeros(lags.size)
    if a_is_b and lags.size > FFT_LAGS and not numerics.reference:
        # one FFT per segment instead of a dot product per lag: the residual-correlation gate
        # asks for ~1000 lags of 30,000 samples (0.02 s by dot products, 2 ms by FFT; the same
        # sums to rounding)
        index = np.abs(lags.astype(int))
        for start, stop in _bounds(n, segment_starts):
            aa, m = a[start:stop], stop - start
            if m == 0:
                continue
            size = 1 << math.ceil(math.log2(2 * m))
            spectrum = np.fft.rfft(aa, size)
            full = np.fft.irfft(spectrum * np.conj(spectrum), size)
            inside = index < m
            out[inside] += full[index[inside]]
        return out / denom if denom > 0.0 else np.zeros(lags.size)
    with single_threaded_blas():
        for start, stop in _bounds(n, segment_starts):
            aa, bb, m = a[start:stop], b[start:stop], stop - start
            for i, lag in enumerate(lags.astype(int)):
                if abs(lag) >= m:
                    continue
                if lag >= 0:
                    out[i] += aa[lag:] @ bb[: m - lag]
                else:
                    out[i] += aa[: m + lag] @ bb[-lag:]
    return out / denom if denom > 0.0 else np.zeros(lags.size)


def residual_whiteness(
    residuals: ArrayLike,
    max_lag: int = 25,
    segment_starts: Sequence[int] = (),
    *,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> CorrelationTest:
    """Autocorrelation of the residuals at lags 1…max_lag (within segments, see above).

    ``numerics``: how a long one is summed (:func:`_normalised_xcorr`); the same to rounding.

    Examples
    --------
    >>> e = np.random.default_rng(0).normal(size=5000)
    >>> residual_whiteness(e).passed
    True
    """
    e = np.asarray(residuals, dtype=float)
    lags = np.arange(1, max_lag + 1, dtype=float)
    r = _normalised_xcorr(e, e, lags, segment_starts, numerics)
    n = e.size
    stat = float(n * np.sum(r**2))
    return CorrelationTest(lags, r, 1.96 / math.sqrt(n), stat, _chi2_sf(stat, lags.size))


def settled_stretches(
    u: ArrayLike,
    sample_time: float,
    settle: float,
    segment_starts: Sequence[int] = (),
    min_length: int = 1,
    min_change: float = 0.0,
) -> list[tuple[int, int]]:
    """The stretches where the output has settled: from twice ``settle`` after a change on.

    A stretch begins ``ceil(2·settle/h)`` samples after each command change (|Δu| above
    ``min_change``) or gap (``segment_starts``) and ends at the next one; only stretches of at
    least ``min_length`` samples are kept. After two settling times of the model even a 2 % misfit
    of the response's tail has decayed to 0.04 % of the step, so what the residuals hold there
    is the noise (and the steady-state error, a constant per stretch).

    Parameters
    ----------
    u : array
        The command [input unit], one per sample.
    sample_time : float
        h [s].
    settle : float
        98 % settling time of the model [s].
    segment_starts : sequence of int
        Where each segment after a gap begins.
    min_length : int
        Shortest stretch kept [samples].
    min_change : float
        Command changes of at most this size [input unit] do not start a transient (0: every
        change does). In closed loop the PI moves the command at every scan in reaction to the
        noise; the response to such a move is a small signal the model describes, and counting
        it would leave no settled sample at all.

    Returns
    -------
    list of (int, int)
        (start, stop) sample indices of each settled stretch, in order; empty when ``settle``
        is not a finite non-negative number.

    Examples
    --------
    >>> settled_stretches(np.repeat([0.0, 1.0, 0.0], 100), 0.1, 2.5, min_length=10)
    [(50, 100), (150, 200), (250, 300)]
    """
    if not (math.isfinite(settle) and settle >= 0.0):
        return []
    u_arr = np.asarray(u, dtype=float)
    edges = np.union1d(
        np.r_[0, np.flatnonzero(np.abs(np.diff(u_arr)) > max(min_change, 0.0)) + 1, u_arr.size],
        np.asarray(segment_starts, dtype=int),
    )
    skip = math.ceil(2.0 * settle / sample_time)
    return [
        (a + skip, b)
        for a, b in itertools.pairwise(edges.tolist())
        if b - (a + skip) >= max(min_length, 1)
    ]


def settled_residuals(
    residuals: ArrayLike,
    stretches: Sequence[tuple[int, int]],
    *,
    detrend: bool = False,
) -> tuple[FloatArray, tuple[int, ...], int]:
    """The residuals of the settled ``stretches`` (:func:`settled_stretches`), each on its own.

    Each stretch is kept with its mean removed (a steady-state error is a constant, not colour)
    or, with ``detrend``, its least-squares line (a steady-state error that drifts slowly, as a
    plant gain following the fuel temperature under a PI that holds the output, is a line, not
    colour).

    Returns
    -------
    (residuals, starts, removed)
        The settled residuals concatenated, where each stretch after the first starts in them,
        and the number of values removed (one or two per stretch: the degrees of freedom a
        variance of them loses).
    """
    e_all = np.asarray(residuals, dtype=float)
    parts = []
    for a, b in stretches:
        x = e_all[a:b]
        if detrend:
            # the least-squares line in closed form (np.polyfit's Vandermonde lstsq per stretch
            # was a tenth of a window's colour test; the same line to rounding)
            t = np.arange(x.size, dtype=float) - 0.5 * (x.size - 1)
            tt = float(t @ t)
            slope = float(t @ x) / tt if tt > 0.0 else 0.0
            parts.append(x - x.mean() - slope * t)
        else:
            parts.append(x - x.mean())
    if not parts:
        return np.zeros(0), (), 0
    starts = tuple(int(k) for k in np.cumsum([p.size for p in parts])[:-1])
    return np.concatenate(parts), starts, (2 if detrend else 1) * len(parts)


def settled_whiteness(
    residuals: ArrayLike,
    u: ArrayLike,
    sample_time: float,
    settle: float,
    segment_starts: Sequence[int] = (),
    max_lag: int = 25,
    min_samples: int = 200,
) -> CorrelationTest | None:
    """Whiteness of the residuals where the output has settled (is the *noise* coloured?).

    The residuals of a model whose dynamics miss part of the response are coloured during the
    transients after command changes; coloured measurement noise (or a drift) is coloured
    everywhere. This tests only the samples at least twice ``settle`` after the last command
    change (or gap), :func:`settled_stretches`: the settling time is the fitted model's, and a
    model that misses a lag also misjudges how long the response lasts; after two settling
    times even a 2 % misfit of the tail has decayed to 0.04 % of the step. Each settled stretch
    is tested on its own with its mean removed (a steady-state error is a constant, not
    colour), as :func:`residual_whiteness` does.

    Parameters
    ----------
    residuals, u : array
        Residuals [output unit] and the command [input unit], one per sample.
    sample_time : float
        h [s].
    settle : float
        98 % settling time of the model [s].
    segment_starts : sequence of int
        Where each segment after a gap begins.
    max_lag : int
        Lags tested [samples]; a stretch must be longer than twice this to count.
    min_samples : int
        Fewest settled samples for a test (None below).

    Returns
    -------
    CorrelationTest or None
        None when the record holds too few settled samples.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> u = np.repeat([0.0, 1.0, 0.0, 1.0], 500)
    >>> e = rng.normal(size=u.size)
    >>> e[500:520] += 5.0  # a transient misfit after one step: not noise colour
    >>> residual_whiteness(e).passed, settled_whiteness(e, u, 0.1, 2.5).passed
    (False, True)
    """
    stretches = settled_stretches(u, sample_time, settle, segment_starts, 2 * max_lag + 1)
    parts, starts, _ = settled_residuals(residuals, stretches)
    if parts.size < min_samples:
        return None
    return residual_whiteness(parts, max_lag, starts)


def input_residual_correlation(
    u: ArrayLike, residuals: ArrayLike, max_lag: int = 25, segment_starts: Sequence[int] = ()
) -> CorrelationTest:
    """Cross-correlation r_εu(τ) of residuals ε[k+τ] with input u[k], τ = −max_lag…max_lag.

    Positive lags (residual after the input) test for unmodelled dynamics; significant negative
    lags (input after the residual) mean the input reacts to the output: feedback.
    The input is differenced first (a held command is strongly autocorrelated, which would inflate
    the correlations; its changes are nearly white in a test sequence). With segments the input
    is differenced within each segment (the jump across a gap is not an input change).
    """
    u_arr = np.asarray(u, dtype=float)
    e_all = np.asarray(residuals, dtype=float)
    if segment_starts:
        bounds = _bounds(u_arr.size, segment_starts)
        du = np.concatenate([np.diff(u_arr[a:b]) for a, b in bounds])
        e = np.concatenate([e_all[a + 1 : b] for a, b in bounds])
        starts = tuple(np.cumsum([b - a - 1 for a, b in bounds])[:-1].tolist())
    else:
        du, e, starts = np.diff(u_arr), e_all[1:], ()
    lags = np.arange(-max_lag, max_lag + 1, dtype=float)
    r = _normalised_xcorr(e, du, lags, starts)
    n = e.size
    positive = r[lags >= 0]
    stat = float(n * np.sum(positive**2))
    return CorrelationTest(lags, r, 1.96 / math.sqrt(n), stat, _chi2_sf(stat, positive.size))


def feedback_suspected(test: CorrelationTest) -> bool:
    """True when the residual correlates with LATER inputs beyond chance (χ², 1 % level)."""
    negative = test.values[test.lags < 0]
    n = (1.96 / test.bound) ** 2
    stat = float(n * np.sum(negative**2))
    return _chi2_sf(stat, negative.size) < 0.01


@dataclass(frozen=True)
class StepError:
    """Steady-state error of the model at the end of one constant-input plateau."""

    measured: float
    """Mean measured output over the plateau's last fifth [output unit]."""
    model: float
    """Mean model output over the same samples [output unit]."""

    @property
    def error_percent(self) -> float:
        """100·|model − measured|/|measured| (the article's criterion: about 1 %)."""
        return (
            100.0 * abs(self.model - self.measured) / abs(self.measured)
            if self.measured
            else math.nan
        )


def steady_state_errors(
    u: ArrayLike,
    y: ArrayLike,
    y_hat: ArrayLike,
    sample_time: float,
    settle: float,
    segment_starts: Sequence[int] = (),
) -> list[StepError]:
    """Steady-state error at the end of every plateau that lasts longer than ``settle`` [s].

    A gap ends a plateau (``segment_starts``: where each segment after a gap begins).

    Examples
    --------
    >>> u = np.repeat([1.0, 2.0], 100)
    >>> errs = steady_state_errors(u, 10 * u, 10.1 * u, 0.1, 5.0)
    >>> [round(e.error_percent, 6) for e in errs]
    [1.0, 1.0]
    """
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    y_hat = np.asarray(y_hat, dtype=float)
    edges = np.union1d(
        np.r_[0, np.flatnonzero(np.diff(u) != 0.0) + 1, u.size],
        np.asarray(segment_starts, dtype=int),
    )
    out = []
    for a, b in itertools.pairwise(edges):
        if (b - a) * sample_time < settle:
            continue
        tail = slice(b - max(1, (b - a) // 5), b)
        out.append(StepError(float(y[tail].mean()), float(y_hat[tail].mean())))
    return out


def sample_time_advice(
    settling_time: float, sample_time: float, raw_sample_time: float | None = None
) -> str | None:
    """Advice when the settling time spans too few or very many samples (None when fine).

    Below 20 samples per settling time the samples resolve the response poorly (the article's
    1 s period gives only 5–6 for the fuel loop); the advice then depends on where the samples
    came from: decimated data (``raw_sample_time`` shorter than ``sample_time``) are better fitted
    raw, with the output-error fit; a log that is already that coarse must be logged faster.
    Above 5000 decimating with anti-alias filtering fits as well and faster
    (docs/explanation/identification.md §5, the sample-time check).

    Examples
    --------
    >>> sample_time_advice(5.3, 1.0, 0.02).split(": ")[1]
    'fit the raw samples (every 0.02 s) with the output-error method'
    >>> sample_time_advice(5.3, 1.0, 1.0).split(": ")[1]
    'the log itself is that coarse; log faster (0.02 s is typical for a PLC)'
    >>> sample_time_advice(5.3, 0.02) is None
    True
    """
    if not (math.isfinite(settling_time) and settling_time > 0.0):
        return None
    per_settle = settling_time / sample_time
    if per_settle < 20:
        head = f"the settling time ({settling_time:.3g} s) spans only {per_settle:.1f} samples"
        raw = sample_time if raw_sample_time is None else raw_sample_time
        if raw < sample_time * (1.0 - 1e-9):
            return f"{head}: fit the raw samples (every {raw:g} s) with the output-error method"
        return f"{head}: the log itself is that coarse; log faster (0.02 s is typical for a PLC)"
    if per_settle > 5000:
        return (
            f"the settling time spans {per_settle:.0f} samples: decimating (with anti-alias "
            "filtering) would fit as well and faster"
        )
    return None
