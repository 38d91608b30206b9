"""Does the output move before its input? A reversed clock or swapped columns, seen in the data.

A flow loop is causal: the flow answers a change of its command after the dead time, never
before it. A log whose rows run backwards in time (newest first with no time column, or a time
column that runs backwards) or whose input and output columns are swapped shows the opposite:
the output's changes come *before* the input's. Every estimator fits such a log anyway (a model
with T → 0 and an interval spanning decades, or a plausible-looking one), so the direction is
checked on the data themselves, apart from any model.

:func:`lead_check` measures it twice, from the cross-correlation of the input's and the output's
changes (the correlation analysis of Ljung, *System Identification*, 2nd ed., 1999, §6.1, with
differencing as the prewhitening filter of a held command, whose changes are nearly white):

* where the cross-correlation, smoothed over a window, **peaks** (the lag of the output's
  fastest change after, or before, a command change), and
* how far the output's level moves over the span **before** the command changes against the span
  **after** them, each per unit command change. Its noise telescopes (a sum of output changes is
  a difference of two levels), so it stays decisive on noisy logs where single lags do not.

The output leads when both agree: the peak lies at a negative lag and the level moves more
before the command changes than after them, by more than :data:`LEAD_Z` standard errors.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["LEAD_MIN_SPAN", "LEAD_Z", "LeadCheck", "lead_check"]

FloatArray = NDArray[np.float64]

LEAD_MIN_SPAN = 5.0
"""Shortest span [s] looked at on each side of a command change. The reference fuel loop
settles (98 %) in about 6 s, its dead time and the bulk of its response lie within 5 s, so a
mirrored response (a reversed log) lands inside the span whatever the fitted model says; the
procedure widens it to the fitted model's settling time for slower loops."""
LEAD_Z = 4.0
"""Standard errors by which the level must move more before the command changes than after
them. The statistic is a weighted sum over many samples, nearly normal under the null: one-sided
4σ is a 3·10⁻⁵ chance, and its noise is estimated from a median absolute deviation that the
responses themselves inflate (conservative). A causal log sits far on the other side (the level
moves by the gain after each change and not before: −7 to −30 σ on the reference plant's logs)."""
PEAK_WINDOW_FRACTION = 0.2
"""The smoothing window (and each level's averaging window) is this fraction of the span: 1 s
for the 5 s span, the width of the fuel loop's response, over which single-sample noise (a flow
change per sample no larger than the noise) averages out."""


@dataclass(frozen=True)
class LeadCheck:
    """Which way the output's changes follow the input's (see :func:`lead_check`)."""

    peak_lag: float
    """Lag [s] of the peak of the smoothed cross-correlation of the changes, signed by the
    gain: positive when the output changes after its input (dead time plus part of the lag),
    negative when before; NaN when the input never changes."""
    response_before: float
    """The output's level change over the span before the input's changes, per unit input
    change [output unit per input unit]: about 0 for a causal loop."""
    response_after: float
    """The same over the span after them: about the gain K for a causal loop."""
    z: float
    """(response_before − response_after)·sign(K) in standard errors: positive when the output
    moves more before its input than after it [-]."""
    span: float
    """Span looked at on each side of a change [s]."""
    leads: bool
    """True when the output moves before its input: the peak at a negative lag and ``z`` at
    least :data:`LEAD_Z`."""

    def to_json(self) -> dict[str, Any]:
        """``diagnostics.lead`` of ``fuelid identify --json``."""
        return {
            "leads": self.leads,
            "peak_lag_s": self.peak_lag,
            "response_before": self.response_before,
            "response_after": self.response_after,
            "z": self.z,
            "span_s": self.span,
        }

    def warning(self) -> str | None:
        """The identification warning when the output leads (None when it does not)."""
        if not self.leads:
            return None
        return (
            f"the flow moves before its command (the cross-correlation of their changes peaks "
            f"at {self.peak_lag:.3g} s, and the flow moves more in the {self.span:.3g} s before "
            f"the command's changes than in the {self.span:.3g} s after them): a reversed clock "
            "(rows newest first, or a time column running backwards) or swapped input and "
            "output columns; the model and any gains from it are meaningless: check the log's "
            "time order and which column is the command"
        )


def _segments(n: int, segment_starts: Sequence[int]) -> list[tuple[int, int]]:
    return list(itertools.pairwise([0, *(int(i) for i in segment_starts), n]))


def _xcorr(du: FloatArray, dy: FloatArray, max_lag: int) -> FloatArray:
    """Σ_k du[k]·dy[k+τ] for τ = −max_lag…max_lag (zero beyond the record), by FFT.

    A long record whose command changes at few samples (a day of held levels: one sample in
    a thousand) is summed over those samples only, lag by lag: (2M + 1)·(changes) products
    instead of FFTs of 2²³ points.
    """
    n = du.size
    changes = np.flatnonzero(du)
    if n > SPARSE_XCORR_SAMPLES and changes.size * (2 * max_lag + 1) < n:
        out = np.zeros(2 * max_lag + 1)
        for i, lag in enumerate(range(-max_lag, max_lag + 1)):
            at = changes[(changes + lag >= 0) & (changes + lag < n)]
            out[i] = du[at] @ dy[at + lag]
        return out
    size = 1 << math.ceil(math.log2(n + max_lag + 1))
    full = np.fft.irfft(np.conj(np.fft.rfft(du, size)) * np.fft.rfft(dy, size), size)
    lags = np.arange(-max_lag, max_lag + 1)
    out = full[lags % size]
    out[np.abs(lags) >= n] = 0.0
    return out


SPARSE_XCORR_SAMPLES = 1 << 20
"""Records longer than this [samples] may sum the cross-correlation over the command's changes
only (:func:`_xcorr`); shorter ones are computed exactly as before, by FFT."""


def _levels(y: FloatArray, span: int, window: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Window means of ``y`` just before each sample k = 1…n−1, ``span`` earlier and later.

    Each level is the mean of ``window`` samples: ȳ₀[k] over y[k−w … k−1], ȳ₋[k] over
    y[k−M−w … k−M−1], ȳ₊[k] over y[k+M−w … k+M−1]; a window that would leave the segment is
    moved back inside it (a shorter span, never across the change). NaN where the segment
    cannot hold a window before and after k.
    """
    n = y.size
    csum = np.concatenate(([0.0], np.cumsum(y)))
    k = np.arange(1, n)
    ok = (k >= window) & (k + window <= n)

    def mean_from(start: NDArray[np.int64]) -> FloatArray:
        start = np.clip(start, 0, n - window)
        return (csum[start + window] - csum[start]) / window

    now = mean_from(k - window)
    before = mean_from(np.clip(k - span - window, 0, k - window))
    after = mean_from(np.clip(k + span - window, k, n - window))
    nan = np.full(k.size, np.nan)
    return np.where(ok, before, nan), np.where(ok, now, nan), np.where(ok, after, nan)


def lead_check(
    u: ArrayLike,
    y: ArrayLike,
    sample_time: float,
    span: float = LEAD_MIN_SPAN,
    segment_starts: Sequence[int] = (),
    sign: float = 1.0,
) -> LeadCheck:
    """Whether the output ``y`` moves before its input ``u``: a reversed clock or swapped columns.

    With the changes Δu[k] = u[k] − u[k−1] and Δy[k] = y[k] − y[k−1] (within each segment;
    nothing is paired across a gap), M = span/h lags and a window W = M/5:

    * the cross-correlation of the changes, per unit input change,

      r(τ) = Σ_k Δu[k]·Δy[k+τ] / Σ_k Δu[k]²,   τ = −M…M,

      is for well separated steps the output's change τ samples after a unit command change
      (the loop's impulse response: zero before the dead time). Smoothed by a centred moving
      mean over W lags, r_W(τ), its peak τ* = argmax_τ sign·r_W(τ) (``peak_lag``, in s) is
      where the output changes fastest: after the command (τ* > 0) in a causal loop;
    * with the levels ȳ₀[k], ȳ₋[k], ȳ₊[k] (means of W samples just before k, M samples
      earlier, M samples later), the level changes per unit command change

      b = Σ_k Δu[k]·(ȳ₀[k] − ȳ₋[k]) / Σ_k Δu[k]²   (``response_before``),
      a = Σ_k Δu[k]·(ȳ₊[k] − ȳ₀[k]) / Σ_k Δu[k]²   (``response_after``),

      are about 0 and K for a causal loop (K before and about 0 after for a reversed one).
      Their difference D = sign·(b − a) = Σ_k Δu[k]·sign·s[k] / Σ_k Δu[k]² with
      s[k] = 2ȳ₀[k] − ȳ₋[k] − ȳ₊[k] has, for output noise independent of the command, the
      standard error σ_s/√(Σ_k Δu[k]²), σ_s = 1.4826·MAD(s) over all samples (a robust
      estimate the responses inflate only a little, which makes the test conservative);
      z = D/σ_D.

    The output leads (``leads``) when τ* < 0 and z ≥ :data:`LEAD_Z`. ``sign`` is the sign of
    the fitted gain: a closed loop's command reacts to the flow's earlier changes with the
    opposite sign, and does not count as the flow leading.

    Parameters
    ----------
    u, y : array
        Input [input unit] and output [output unit], one sample per ``sample_time``.
    sample_time : float
        h [s].
    span : float
        M·h [s]: how far before and after each command change the output is followed.
    segment_starts : sequence of int
        Where each segment after a gap begins.
    sign : float
        Sign of the gain K (its magnitude is ignored; 0 counts as positive).

    Returns
    -------
    LeadCheck

    Examples
    --------
    >>> u = np.repeat([1.0, 2.0, 1.0, 2.0], 100)
    >>> y = 10.0 * np.r_[np.ones(5), u[:-5]]  # the output follows 5 samples later
    >>> y = y + np.random.default_rng(0).normal(0.0, 0.1, y.size)
    >>> forward = lead_check(u, y, 0.1, span=2.0)
    >>> forward.leads, forward.peak_lag > 0.0, round(forward.response_after, 1)
    (False, True, 10.0)
    >>> backward = lead_check(u[::-1], y[::-1], 0.1, span=2.0)
    >>> backward.leads, backward.peak_lag < 0.0, round(backward.response_before, 1)
    (True, True, 10.0)
    """
    u_arr = np.asarray(u, dtype=float)
    y_arr = np.asarray(y, dtype=float)
    s_sign = -1.0 if sign < 0.0 else 1.0
    bounds = _segments(u_arr.size, segment_starts)
    longest = max(b - a for a, b in bounds)
    max_lag = max(1, min(round(span / sample_time), (longest - 1) // 4))
    window = 2 * round(PEAK_WINDOW_FRACTION * max_lag / 2.0) + 1  # odd: centred on a lag
    r = np.zeros(2 * max_lag + 1)
    energy = before = after = 0.0
    spreads = []
    for a, b in bounds:
        if b - a < 2:
            continue
        du = np.diff(u_arr[a:b])
        r += _xcorr(du, np.diff(y_arr[a:b]), max_lag)
        lo, now, hi = _levels(y_arr[a:b], max_lag, window)
        ok = ~np.isnan(now)
        energy += float(du[ok] @ du[ok])
        before += float(du[ok] @ (now[ok] - lo[ok]))
        after += float(du[ok] @ (hi[ok] - now[ok]))
        spreads.append(2.0 * now[ok] - lo[ok] - hi[ok])
    span_s = round(max_lag * sample_time, 9)
    if energy <= 0.0:
        return LeadCheck(math.nan, math.nan, math.nan, math.nan, span_s, False)
    r /= energy
    response_before, response_after = before / energy, after / energy
    s = np.concatenate(spreads)
    sigma_s = 1.4826 * float(np.median(np.abs(s - np.median(s))))
    # a noise-free output (a command logged as the output) has no spread: a floor keeps z finite
    scale = float(np.ptp(y_arr)) or 1.0
    sigma_d = max(sigma_s, 1e-9 * scale) / math.sqrt(energy)
    z = s_sign * (response_before - response_after) / sigma_d
    # centred moving mean over the window: differences of the running sum
    csum = np.concatenate(([0.0], np.cumsum(s_sign * r)))
    half = window // 2
    centre = np.arange(half, r.size - (window - half) + 1)
    smoothed = (csum[centre + window - half] - csum[centre - half]) / window
    peak_lag = round(float(centre[int(np.argmax(smoothed))] - max_lag) * sample_time, 9)
    leads = peak_lag < 0.0 and z >= LEAD_Z
    return LeadCheck(peak_lag, response_before, response_after, z, span_s, leads)
