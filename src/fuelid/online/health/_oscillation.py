"""Hägglund's oscillation detector: load disturbances by the IAE between zero crossings of e.

T. Hägglund, "A control-loop performance monitor", Control Engineering Practice 3(11) (1995)
1543–1551.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from fuelid.online.health._arrays import FloatArray

OSCILLATION_AMPLITUDE_FRACTION = 0.01
"""Hägglund's acceptable oscillation amplitude a: 1 % of the measurement span [-]."""
SUPERVISION_PERIODS = 50.0
"""Hägglund's supervision time T_sup in ultimate periods (here integral times) [-]."""
OSCILLATION_COUNT_LIMIT = 10.0
"""Hägglund's n_lim: the forgetting count of detections above which the loop oscillates [-]."""


def half_period_iae(t: ArrayLike, e: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """IAE of the control error between successive zero crossings: one value per half period.

    The error is taken as linear between samples (each crossing interpolated), so the integral
    of a sampled sinusoid is exact to O(h²). A NaN sample breaks the record: the half periods
    that touch it are incomplete and left out, as are the partial ones at both ends.

    Parameters
    ----------
    t : array
        Times [s], increasing.
    e : array
        Control error [L/min]; NaN where it is not to be assessed.

    Returns
    -------
    ends : array
        Time of the zero crossing that ends each complete half period [s].
    iae : array
        ∫|e| dt over it [L/min·s].

    Examples
    --------
    A sinusoid of amplitude A and period P gives A·P/π per half period:

    >>> t = np.arange(0.0, 20.0, 0.001)
    >>> ends, iae = half_period_iae(t, 2.0 * np.sin(2 * np.pi * t / 4.0 + 0.3))
    >>> ends.size, np.allclose(iae, 2.0 * 4.0 / np.pi, rtol=1e-6)
    (9, True)
    """
    tt = np.asarray(t, dtype=float)
    x = np.asarray(e, dtype=float)
    if x.size < 2:
        return np.empty(0), np.empty(0)
    dt = np.diff(tt)
    a, b = np.abs(x[:-1]), np.abs(x[1:])
    valid = np.isfinite(x[:-1]) & np.isfinite(x[1:])
    positive = x > 0.0
    cross = valid & (positive[:-1] != positive[1:])
    # interval k: area before the crossing (to the old half period) and after it (to the new)
    with np.errstate(invalid="ignore", divide="ignore"):
        before = np.where(cross, 0.5 * a * a / (a + b) * dt, 0.5 * (a + b) * dt)
        after = np.where(cross, 0.5 * b * b / (a + b) * dt, 0.0)
    before = np.where(valid, before, 0.0)
    frac = np.where(cross, a / np.where(cross, a + b, 1.0), 0.0)
    total = np.r_[0.0, np.cumsum(before + after)]  # ∫|e| from t[0] to t[k]
    broken = np.r_[0, np.cumsum(~valid)]  # invalid intervals before t[k]
    k = np.flatnonzero(cross)
    if k.size < 2:
        return np.empty(0), np.empty(0)
    k0, k1 = k[:-1], k[1:]
    iae = after[k0] + (total[k1] - total[k0 + 1]) + before[k1]
    complete = broken[k1] == broken[k0 + 1]
    ends = tt[k1] + frac[k1] * dt[k1]
    return ends[complete], iae[complete]


@dataclass(frozen=True)
class Oscillation:
    """Verdict of Hägglund's oscillation detector over one window."""

    oscillating: bool
    """True when the forgetting count exceeded ``n_lim`` at some time in the window."""
    detections: int
    """Load disturbances detected (half periods with IAE above the limit) [-]."""
    count: float
    """Forgetting count of detections at the window's end [-]."""
    peak_count: float
    """Largest forgetting count in the window [-]."""
    half_periods: int
    """Complete half periods (intervals between zero crossings) assessed [-]."""
    iae_limit: float
    """IAE_lim = 2a/ω_u [L/min·s]."""
    amplitude: float
    """Acceptable amplitude a [L/min]."""
    ultimate_frequency: float
    """ω_u used, 2π/Ti [rad/s]."""
    supervision_time: float
    """T_sup [s]."""
    n_lim: float
    """Count above which the loop oscillates [-]."""


def hagglund_oscillation(
    t: ArrayLike,
    e: ArrayLike,
    *,
    ti_s: float,
    y_span: float,
    amplitude_fraction: float = OSCILLATION_AMPLITUDE_FRACTION,
    supervision_periods: float = SUPERVISION_PERIODS,
    n_lim: float = OSCILLATION_COUNT_LIMIT,
) -> Oscillation:
    """Oscillation detection after Hägglund (1995): load disturbances counted with forgetting.

    Between two successive zero crossings of the control error, its integral
    IAE = ∫|e| dt is compared with IAE_lim = 2a/ω_u, the IAE of half a period of a sinusoid of
    the acceptable amplitude a at the ultimate frequency ω_u. A larger IAE is a load
    disturbance. The detections are counted with exponential forgetting over the supervision
    time T_sup, x ← x·exp(−Δt/T_sup) + 1 at each detection (the continuous-time form of
    Hägglund's x(t) = γ·x(t − h) + load(t), γ = 1 − h/T_sup); more than n_lim detections per
    T_sup means the loop oscillates. As Hägglund suggests for a PI controller whose ultimate
    period is not known, ω_u = 2π/Ti, and T_sup = 50·Ti, a = 1 % of the measurement span,
    n_lim = 10 are his defaults.

    Parameters
    ----------
    t : array
        Times [s], increasing.
    e : array
        Control error setpoint − y [L/min]; NaN where the loop is not assessed (MAN, bad
        samples): half periods touching a NaN are not counted.
    ti_s : float
        The PI controller's integral time Ti [s].
    y_span : float
        Measurement span [L/min] (the acceptable amplitude is a fraction of it).
    amplitude_fraction : float
        a / y_span [-].
    supervision_periods : float
        T_sup / Ti [-].
    n_lim : float
        Detections per supervision time above which the loop oscillates [-].

    Returns
    -------
    Oscillation
        The verdict with the parameters used.

    Notes
    -----
    A setpoint step also gives one large half period (one detection); a single one never
    reaches the limit. The count starts at zero at the window's start, so a window shorter
    than about n_lim half periods of an oscillation cannot flag it.

    References
    ----------
    T. Hägglund, "A control-loop performance monitor", Control Engineering Practice 3(11)
    (1995) 1543–1551.

    Examples
    --------
    >>> t = np.arange(0.0, 300.0, 0.02)
    >>> osc = hagglund_oscillation(t, 5.0 * np.sin(2 * np.pi * t / 8.0), ti_s=2.0, y_span=120.0)
    >>> osc.oscillating, osc.detections, round(osc.iae_limit, 4)
    (True, 74, 0.7639)
    """
    if not (ti_s > 0.0 and math.isfinite(ti_s)):
        raise ValueError(f"the integral time must be positive, not {ti_s!r}")
    amplitude = amplitude_fraction * abs(y_span)
    omega_u = 2.0 * math.pi / ti_s
    iae_limit = 2.0 * amplitude / omega_u
    t_sup = supervision_periods * ti_s
    ends, iae = half_period_iae(t, e)
    hits = ends[iae > iae_limit]
    count, peak, last = 0.0, 0.0, -math.inf
    for when in hits.tolist():  # a short loop over the detections only
        count = count * math.exp(-(when - last) / t_sup) + 1.0
        peak, last = max(peak, count), when
    tt = np.asarray(t, dtype=float)
    if hits.size and tt.size:
        count *= math.exp(-max(float(tt[-1]) - last, 0.0) / t_sup)
    return Oscillation(
        oscillating=peak > n_lim,
        detections=int(hits.size),
        count=count,
        peak_count=peak,
        half_periods=int(ends.size),
        iae_limit=iae_limit,
        amplitude=amplitude,
        ultimate_frequency=omega_u,
        supervision_time=t_sup,
        n_lim=n_lim,
    )


__all__ = [
    "OSCILLATION_AMPLITUDE_FRACTION",
    "OSCILLATION_COUNT_LIMIT",
    "SUPERVISION_PERIODS",
    "Oscillation",
    "hagglund_oscillation",
    "half_period_iae",
]
