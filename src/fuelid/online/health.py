"""Loop health of one window of PLC samples: what a performance monitor reports per window.

Pure functions on numpy arrays of one window, sample by sample: the time ``t`` [s], the command
``u`` [V], the flow ``y`` [L/min], the setpoint [L/min], the controller's ``mode`` (0 MAN, 1 AUTO)
and the ``ok`` quality mask (True where the recorder found the sample good). The control error is
e = setpoint − y [L/min].

- :func:`time_in_auto`, :func:`time_at_limits`: the share of the window the loop was in AUTO and
  the share the output sat at one of its limits (the service's gates and freeze conditions);
- :func:`hagglund_oscillation`: Hägglund's oscillation detector (load disturbances recognised by
  the IAE between zero crossings of e, counted with exponential forgetting);
- :func:`setpoint_responses`: IAE, overshoot, settling and rise time of every setpoint step made
  in AUTO;
- :func:`harris_index`: the minimum-variance (Harris) performance index of a regulatory stretch;
- :func:`sensor_health`: noise level, exactly repeated values (a stuck transmitter) and the
  quantisation step of the flow reading;
- :func:`loop_health`: all of the above for one window, in one :class:`LoopHealth` with a
  JSON-ready :meth:`~LoopHealth.to_dict`.

References
----------
T. Hägglund, "A control-loop performance monitor", Control Engineering Practice 3(11) (1995)
1543–1551. L. Desborough, T. Harris, "Performance assessment measures for univariate feedback
control", Can. J. Chem. Eng. 70 (1992) 1186–1197. B. Huang, S. L. Shah, *Performance Assessment
of Control Loops* (Springer, 1999), ch. 2–3. K. J. Åström, T. Hägglund, *Advanced PID Control*
(ISA, 2006), §7.2 (step-response measures). P. J. Rousseeuw, C. Croux, "Alternatives to the
median absolute deviation", J. Am. Stat. Assoc. 88 (1993) 1273–1283 (robust scale).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
import scipy.signal
from numpy.typing import ArrayLike, NDArray

from fuelid import lti
from fuelid.identify.covariance import residual_ar
from fuelid.io.jsonsafe import json_ready
from fuelid.plc.quality import LOW_END_FRACTION, STUCK_AFTER_S

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

AUTO = 1
"""The controller mode value of AUTO (0 is MAN)."""
U_LIMITS_V = (1.0, 5.0)
"""The drive's command range [V]: the PI's output limits."""
LIMIT_TOLERANCE_V = 0.005
"""A command within this of a limit counts as at the limit [V] (about 14 counts of a 0–10 V,
27648-count analog output)."""
OSCILLATION_AMPLITUDE_FRACTION = 0.01
"""Hägglund's acceptable oscillation amplitude a: 1 % of the measurement span [-]."""
SUPERVISION_PERIODS = 50.0
"""Hägglund's supervision time T_sup in ultimate periods (here integral times) [-]."""
OSCILLATION_COUNT_LIMIT = 10.0
"""Hägglund's n_lim: the forgetting count of detections above which the loop oscillates [-]."""
SETTLING_FRACTION = 0.05
"""Settling band of a setpoint step: ±5 % of the step [-]."""
SETTLING_NOISE_LEVELS = 4.0
"""The settling band is at least this many noise levels wide (half width) [-]."""
RAMP_GAP_S = 2.0
"""Same-direction setpoint changes at most this far apart form one ramped move [s]."""
MIN_STEP_LPM = 0.5
"""Smallest setpoint step analysed [L/min] (or three noise levels when that is larger)."""
MAX_AR_ORDER = 30
"""Highest order of the error's AR model for the Harris index [-]."""
SAMPLES_PER_AR_ORDER = 20
"""A Harris index needs at least this many samples per AR coefficient tried [-]."""
_MAD_NORMAL = 0.6744897501960817
"""Median of |N(0, 1)|: the MAD of a normal sample is 0.6745 σ."""


# --- shares of the window -------------------------------------------------------------------------


def _ok_mask(n: int, ok: ArrayLike | None) -> BoolArray:
    return np.ones(n, dtype=bool) if ok is None else np.asarray(ok, dtype=bool)


def time_in_auto(mode: ArrayLike, ok: ArrayLike | None = None) -> float:
    """Share of the good samples in which the controller is in AUTO.

    Parameters
    ----------
    mode : array
        Controller mode per sample (1 AUTO, 0 MAN) [-].
    ok : array of bool, optional
        Quality mask; None: every sample counts.

    Returns
    -------
    float
        Share in [0, 1] [-]; nan without good samples.

    Notes
    -----
    The "time in normal mode" of control-loop performance monitors (Jelali, *Control
    Performance Management in Industrial Automation*, Springer 2013, §2.4): a loop that spends
    its time in MAN is not being assessed, whatever its other numbers say.

    Examples
    --------
    >>> time_in_auto([1, 1, 0, 1], ok=[True, True, True, False])
    0.6666666666666666
    """
    m = np.asarray(mode, dtype=float)
    good = _ok_mask(m.size, ok) & np.isfinite(m)
    if not good.any():
        return math.nan
    return float(np.mean(m[good] == AUTO))


def time_at_limits(
    u: ArrayLike,
    u_min: float = U_LIMITS_V[0],
    u_max: float = U_LIMITS_V[1],
    tol: float = LIMIT_TOLERANCE_V,
    ok: ArrayLike | None = None,
) -> float:
    """Share of the good samples with the command at (within ``tol`` of) an output limit.

    Parameters
    ----------
    u : array
        Command [V].
    u_min, u_max : float
        Output limits [V].
    tol : float
        Distance from a limit that still counts as at it [V].
    ok : array of bool, optional
        Quality mask; None: every sample counts.

    Returns
    -------
    float
        Share in [0, 1] [-]; nan without good samples.

    Notes
    -----
    A saturated output opens the loop: no control-performance measure means anything over such
    a stretch, and an identification window dominated by it carries no closed-loop information
    (Jelali 2013, §2.4; Huang & Shah 1999, §2.4 assume an unsaturated linear loop).

    Examples
    --------
    >>> time_at_limits([1.0, 1.002, 3.0, 5.0])
    0.75
    """
    v = np.asarray(u, dtype=float)
    good = _ok_mask(v.size, ok) & np.isfinite(v)
    if not good.any():
        return math.nan
    x = v[good]
    return float(np.mean((x <= u_min + tol) | (x >= u_max - tol)))


# --- Hägglund's oscillation detector --------------------------------------------------------------


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


# --- setpoint steps -------------------------------------------------------------------------------


@dataclass(frozen=True)
class SetpointResponse:
    """The closed loop's response to one setpoint step made in AUTO."""

    time: float
    """Time of the first sample with the new setpoint [s]."""
    start: float
    """Setpoint before the step [L/min]."""
    target: float
    """Setpoint after the step [L/min]."""
    duration: float
    """Time assessed: until the next setpoint step, MAN or the window's end [s]."""
    iae: float
    """∫|setpoint − y| dt over the duration [L/min·s]."""
    overshoot_percent: float
    """Peak of y beyond the new setpoint in % of the step (0 without overshoot) [%]."""
    settling_time: float | None
    """Time after the step from which |y − target| stays within the band [s]; None when it
    does not settle before the duration ends."""
    rise_time: float | None
    """Time from 10 % to 90 % of the step (first crossings) [s]; None when 90 % is not reached."""
    band: float
    """Settling band, half width [L/min]."""

    @property
    def step(self) -> float:
        """Setpoint change [L/min]."""
        return self.target - self.start


def _first_crossing(t: FloatArray, rel: FloatArray, level: float) -> float | None:
    """Time at which ``rel`` first reaches ``level`` (linear interpolation), None if never."""
    above = np.flatnonzero(rel >= level)
    if above.size == 0:
        return None
    k = int(above[0])
    if k == 0:
        return float(t[0])
    r0, r1 = float(rel[k - 1]), float(rel[k])
    return float(t[k - 1] + (level - r0) / (r1 - r0) * (t[k] - t[k - 1]))


def step_response_measures(
    t: ArrayLike,
    y: ArrayLike,
    start: float,
    target: float,
    *,
    band: float | None = None,
    band_fraction: float = SETTLING_FRACTION,
    setpoint: ArrayLike | None = None,
) -> SetpointResponse:
    """IAE, overshoot, settling time and 10–90 % rise time of one response to a setpoint step.

    Parameters
    ----------
    t : array
        Times [s] from the first sample with the new setpoint on.
    y : array
        Flow [L/min] at those times.
    start, target : float
        Setpoint before and after the step [L/min].
    band : float, optional
        Settling band's half width [L/min]; default ``band_fraction`` of the step.
    band_fraction : float
        Settling band as a fraction of the step [-].
    setpoint : array, optional
        The setpoint at those times [L/min], for the IAE of a ramped move; default ``target``.

    Returns
    -------
    SetpointResponse
        Times relative to ``t[0]``.

    Notes
    -----
    The measures of Åström & Hägglund, *Advanced PID Control* (2006), §7.2: overshoot beyond
    the new setpoint relative to the step, the settling time after which the output stays
    within a band, the rise time between 10 % and 90 % of the step (from the old setpoint), and
    the integrated absolute error (against the setpoint of each moment). The settling rule is
    :func:`fuelid.lti.settling_time`. For a ramped move the times count from its first change,
    so its rise and settling times include the ramp's own duration.

    Examples
    --------
    A first-order response with τ = 2 s: IAE = Δ·τ, 5 % settling τ·ln 20, rise τ·ln 9.

    >>> t = np.arange(0.0, 60.0, 0.001)
    >>> r = step_response_measures(t, 20.0 - 10.0 * np.exp(-t / 2.0), 10.0, 20.0)
    >>> round(r.iae, 4), round(r.settling_time, 4), round(r.rise_time, 4), r.overshoot_percent
    (20.0, 5.9915, 4.3944, 0.0)
    """
    tt = np.asarray(t, dtype=float)
    yy = np.asarray(y, dtype=float)
    step = target - start
    if step == 0.0:
        raise ValueError("a setpoint step needs a non-zero size")
    half = abs(band) if band is not None else band_fraction * abs(step)
    r = np.full(tt.size, target) if setpoint is None else np.asarray(setpoint, dtype=float)
    tr = tt - tt[0]
    rel = (yy - start) / step
    overshoot = max(0.0, float(np.max(rel)) - 1.0) * 100.0
    settle = lti.settling_time(tr, rel, 1.0, half / abs(step))
    t10 = _first_crossing(tr, rel, 0.1)
    t90 = _first_crossing(tr, rel, 0.9)
    return SetpointResponse(
        time=float(tt[0]),
        start=start,
        target=target,
        duration=float(tr[-1]),
        iae=float(np.trapezoid(np.abs(r - yy), tt)),
        overshoot_percent=overshoot,
        settling_time=settle if math.isfinite(settle) else None,
        rise_time=None if t10 is None or t90 is None else t90 - t10,
        band=half,
    )


def setpoint_responses(
    t: ArrayLike,
    y: ArrayLike,
    setpoint: ArrayLike,
    mode: ArrayLike | None = None,
    *,
    threshold: float | None = None,
    band: float | None = None,
    band_fraction: float = SETTLING_FRACTION,
    min_band: float = 0.0,
    ramp_gap_s: float = RAMP_GAP_S,
    min_samples: int = 3,
) -> list[SetpointResponse]:
    """Every setpoint move made in AUTO in the window, each with its response's measures.

    A move begins with a change of the setpoint between successive samples. A further change
    in the same direction made within ``ramp_gap_s`` of the previous one, or before the flow
    has settled into the band around the setpoint of the moment, extends the move (a ramp, the
    staircase of small changes a ramped setpoint becomes in the PLC, is one move from its first
    value to its last); a change in the other direction, or one after a pause in which the
    flow settled, begins a new move. A move larger than
    ``threshold`` and begun in AUTO is assessed from its first change until the next move, the
    first sample in MAN or the window's end (:func:`step_response_measures`).

    Parameters
    ----------
    t : array
        Times [s] (good samples only).
    y, setpoint : arrays
        Flow and setpoint [L/min].
    mode : array, optional
        Controller mode (1 AUTO); None: all in AUTO.
    threshold : float, optional
        Smallest move [L/min]; default max(0.5 L/min, 3 × :func:`noise_level` of y).
    band, band_fraction : float
        Settling band (see :func:`step_response_measures`).
    min_band : float
        Narrowest settling band's half width [L/min]: a band inside the noise is never
        settled into for good (:func:`loop_health` passes four noise levels).
    ramp_gap_s : float
        Same-direction changes at most this far apart are one ramped move [s].
    min_samples : int
        Fewest samples a response needs to be assessed.

    Returns
    -------
    list of SetpointResponse

    Examples
    --------
    >>> t = np.arange(0.0, 40.0, 0.01)
    >>> sp = np.where(t < 10.0, 30.0, 40.0)
    >>> y = np.where(t < 10.0, 30.0, 40.0 - 10.0 * np.exp(-(t - 10.0) / 1.5))
    >>> [(r.time, round(r.iae, 3)) for r in setpoint_responses(t, y, sp)]
    [(10.0, 15.0)]
    """
    tt = np.asarray(t, dtype=float)
    yy = np.asarray(y, dtype=float)
    sp = np.asarray(setpoint, dtype=float)
    n = tt.size
    auto = np.ones(n, dtype=bool) if mode is None else np.asarray(mode) == AUTO
    if threshold is None:
        threshold = max(MIN_STEP_LPM, 3.0 * noise_level(yy))
    resolution = 1e-9 * max(1.0, float(np.max(np.abs(sp), initial=0.0)))
    changes = (np.flatnonzero(np.abs(np.diff(sp)) > resolution) + 1).tolist()
    nexts = [*changes[1:], n] if changes else []
    moves: list[tuple[int, int]] = []  # (first change, end of the move's last stretch)
    settled, prev = True, 0
    for k, nxt in zip(changes, nexts, strict=True):
        first = moves[-1][0] if moves else 0
        direction = np.sign(sp[k] - sp[k - 1])
        ramp = bool(moves) and tt[k] - tt[prev] <= ramp_gap_s
        if (settled and not ramp) or not moves or np.sign(sp[k] - sp[first - 1]) != direction:
            moves.append((k, nxt))
            first = k
        else:
            moves[-1] = (first, nxt)
        half = abs(band) if band is not None else band_fraction * abs(sp[k] - sp[first - 1])
        settled = bool(abs(yy[nxt - 1] - sp[k]) <= max(half, min_band))
        prev = k
    manual = np.flatnonzero(~auto)
    out: list[SetpointResponse] = []
    for first, end in moves:
        start, target = float(sp[first - 1]), float(sp[end - 1])
        if not auto[first] or abs(target - start) <= threshold:
            continue
        j = int(np.searchsorted(manual, first))
        stop = min(end, int(manual[j])) if j < manual.size else end
        if stop - first < min_samples:
            continue
        half = abs(band) if band is not None else band_fraction * abs(target - start)
        out.append(
            step_response_measures(
                tt[first:stop],
                yy[first:stop],
                start,
                target,
                band=max(half, min_band),
                setpoint=sp[first:stop],
            )
        )
    return out


# --- Harris index ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class HarrisIndex:
    """The minimum-variance performance index of a regulatory stretch, or why there is none."""

    index: float | None
    """η = σ²_mv / var(e) in (0, 1]; 1 is minimum-variance control; None when refused."""
    order: int
    """Order of the error's AR model (0: white) [-]."""
    delay_samples: int
    """b, the process dead time in samples (at least 1) [-]."""
    samples: int
    """Length of the stretch [-]."""
    variance: float
    """var(e) [(L/min)²]."""
    minimum_variance: float
    """σ²_mv = σ²_a·Σ_{i<b} ψ_i² [(L/min)²]."""
    reason: str
    """Why the index was refused ("" when it was computed)."""


def _refuse(reason: str, b: int, n: int) -> HarrisIndex:
    return HarrisIndex(None, 0, b, n, math.nan, math.nan, reason)


def harris_index(
    error: ArrayLike,
    delay_samples: int,
    *,
    order: int | None = None,
    max_order: int = MAX_AR_ORDER,
    mode: ArrayLike | None = None,
    setpoint: ArrayLike | None = None,
) -> HarrisIndex:
    """Harris's minimum-variance index of the control error of a regulatory stretch.

    The mean-removed error is modelled as an autoregression A(q)·e = a (Yule–Walker by the
    Levinson–Durbin recursion of :func:`fuelid.identify.covariance.residual_ar`, the order
    chosen by BIC up to ``max_order``, or a given ``order``). Its impulse response ψ (the
    error's moving-average form e = Σ ψ_i a_{t−i}, ψ_0 = 1) splits the error into the part no
    controller can affect, the first b terms (the feedback-invariant part), and the rest. So
    σ²_mv = σ²_a·Σ_{i<b} ψ_i² is the variance under minimum-variance control and
    η = σ²_mv / var(e) the index: 1 for a loop at minimum variance, near 0 for a poor one.

    Parameters
    ----------
    error : array
        Control error setpoint − y of one stretch, equally sampled [L/min].
    delay_samples : int
        b: the process dead time in samples, including the sample-and-hold's one (at least 1).
    order : int, optional
        AR order; default chosen by BIC.
    max_order : int
        Highest order tried [-].
    mode, setpoint : arrays, optional
        When given, the stretch must be all AUTO with a constant setpoint (regulatory).

    Returns
    -------
    HarrisIndex
        With ``index`` None and a ``reason`` when the stretch has non-finite values, is shorter
        than 20 samples per AR order tried, has no variance, or is not regulatory.

    Notes
    -----
    BIC rather than AIC: with the tens of thousands of samples of a window AIC keeps adding
    coefficients (covariance.py), which at most lower σ²_a and raise ψ's tail, both
    of which leave the first b ψ's and so η essentially unchanged. The Yule–Walker model
    reproduces the sample variance exactly, so η ≤ 1 by construction.

    References
    ----------
    L. Desborough, T. Harris, "Performance assessment measures for univariate feedback
    control", Can. J. Chem. Eng. 70 (1992) 1186–1197; B. Huang, S. L. Shah, *Performance
    Assessment of Control Loops* (Springer, 1999), §3.3.

    Examples
    --------
    An AR(1) error with pole φ = 0.5 and b = 1: η = 1 − φ² = 0.75.

    >>> a = np.random.default_rng(0).normal(size=50_000)
    >>> e = scipy.signal.lfilter([1.0], [1.0, -0.5], a)
    >>> h = harris_index(e, 1)
    >>> h.order, round(h.index, 2)
    (1, 0.75)
    """
    e = np.asarray(error, dtype=float)
    b = max(1, int(delay_samples))
    n = e.size
    if not np.all(np.isfinite(e)):
        return _refuse("the error has non-finite values", b, n)
    if mode is not None and np.any(np.asarray(mode) != AUTO):
        return _refuse("not regulatory: the stretch has samples in MAN", b, n)
    if setpoint is not None and np.ptp(np.asarray(setpoint, dtype=float)) > 0.0:
        return _refuse("not regulatory: the setpoint changes in the stretch", b, n)
    tried = order if order is not None else max_order
    if n < SAMPLES_PER_AR_ORDER * max(tried, 1):
        return _refuse(
            f"{n} samples: too short for an AR model of order {tried} "
            f"(needs {SAMPLES_PER_AR_ORDER * max(tried, 1)})",
            b,
            n,
        )
    v = e - e.mean()
    variance = float(v @ v) / n
    if not variance > 0.0:
        return _refuse("the error does not vary", b, n)
    if order is None:
        model = residual_ar(v, max_order=max_order)
        a, sigma2 = model.a, model.sigma_e**2
    elif order == 0:
        a, sigma2 = np.array([1.0]), variance
    else:
        r = np.fft.irfft(np.abs(np.fft.rfft(v, 2 * n)) ** 2)[: order + 1] / n
        phi = scipy.linalg.solve_toeplitz(r[:order], r[1 : order + 1])
        a, sigma2 = np.r_[1.0, -phi], float(r[0] - phi @ r[1 : order + 1])
    psi = scipy.signal.lfilter([1.0], a, np.r_[1.0, np.zeros(b - 1)])
    sigma2_mv = sigma2 * float(psi @ psi)
    index = min(max(sigma2_mv / variance, 0.0), 1.0)
    return HarrisIndex(index, int(a.size - 1), b, n, variance, sigma2_mv, "")


# --- sensor ---------------------------------------------------------------------------------------


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
    (:class:`fuelid.plc.quality.StuckDetector`, whose rule this is: a run of
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


# --- one window -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class LoopHealth:
    """Loop health of one window of PLC samples (:func:`loop_health`)."""

    start: float
    """First sample's time [s]."""
    end: float
    """Last sample's time [s]."""
    samples: int
    """Samples in the window [-]."""
    ok_share: float
    """Share of samples of good quality [-]."""
    time_in_auto: float
    """Share of good samples in AUTO [-]."""
    time_at_limits: float
    """Share of good samples with the command at an output limit [-]."""
    oscillation: Oscillation
    """Hägglund's detector over the AUTO samples."""
    setpoint_changes: tuple[SetpointResponse, ...]
    """Responses to the setpoint steps made in AUTO."""
    harris: HarrisIndex
    """Harris index of the longest regulatory stretch."""
    sensor: SensorHealth
    """The flow reading's health."""

    @property
    def iae_per_unit_step(self) -> float:
        """Mean IAE of the setpoint changes per L/min of step [s]; nan without changes."""
        if not self.setpoint_changes:
            return math.nan
        return float(np.mean([r.iae / abs(r.step) for r in self.setpoint_changes]))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary, the units in the key names, NaN as None.

        Examples
        --------
        >>> t = np.arange(0.0, 60.0, 0.02)
        >>> y = 40.0 + np.random.default_rng(0).normal(scale=0.05, size=t.size)
        >>> d = loop_health(t, np.full(t.size, 3.0), y, np.full(t.size, 40.0),
        ...                 np.ones(t.size), np.ones(t.size, bool), ti_s=1.0, delay_s=0.1,
        ...                 y_span=120.0).to_dict()
        >>> d["time_in_auto"], d["oscillation"]["oscillating"], d["setpoint_changes"]
        (1.0, False, [])
        """
        osc, h, s = self.oscillation, self.harris, self.sensor
        out: dict[str, Any] = json_ready(
            {
                "start_s": self.start,
                "end_s": self.end,
                "samples": self.samples,
                "ok_share": self.ok_share,
                "time_in_auto": self.time_in_auto,
                "time_at_limits": self.time_at_limits,
                "oscillation": {
                    "oscillating": osc.oscillating,
                    "detections": osc.detections,
                    "count": osc.count,
                    "peak_count": osc.peak_count,
                    "half_periods": osc.half_periods,
                    "iae_limit_Lpm_s": osc.iae_limit,
                    "amplitude_Lpm": osc.amplitude,
                    "ultimate_frequency_rad_s": osc.ultimate_frequency,
                    "supervision_time_s": osc.supervision_time,
                    "n_lim": osc.n_lim,
                },
                "setpoint_changes": [
                    {
                        "time_s": r.time,
                        "from_Lpm": r.start,
                        "to_Lpm": r.target,
                        "step_Lpm": r.step,
                        "duration_s": r.duration,
                        "iae_Lpm_s": r.iae,
                        "overshoot_percent": r.overshoot_percent,
                        "settling_time_s": r.settling_time,
                        "rise_time_s": r.rise_time,
                        "band_Lpm": r.band,
                    }
                    for r in self.setpoint_changes
                ],
                "iae_per_unit_step_s": self.iae_per_unit_step,
                "harris": {
                    "index": h.index,
                    "ar_order": h.order,
                    "delay_samples": h.delay_samples,
                    "samples": h.samples,
                    "variance_Lpm2": h.variance,
                    "minimum_variance_Lpm2": h.minimum_variance,
                    "reason": h.reason,
                },
                "sensor": {
                    "noise_Lpm": s.noise,
                    "longest_run_s": s.longest_run,
                    "longest_run_start_s": s.longest_run_start,
                    "stuck": s.stuck,
                    "stuck_after_s": s.stuck_after,
                    "quantum_Lpm": s.quantum,
                },
            }
        )
        return out


def _regulatory_stretch(
    t: FloatArray,
    sp: FloatArray,
    auto: BoolArray,
    responses: list[SetpointResponse],
) -> tuple[int, int]:
    """[a, b) of the longest stretch in AUTO with a constant setpoint, past any settling.

    A stretch after a setpoint move (:func:`setpoint_responses`) begins once the move has
    settled, and is not used when it does not settle; one after a change too small to be a
    move begins at the change (its transient is within the noise). The arrays hold the good
    samples only; a gap (a time step over 1.5 sample periods) ends a stretch, as the AR model
    needs equally spaced samples.
    """
    n = t.size
    if n < 2:
        return 0, 0
    dt = np.diff(t)
    period = float(np.median(dt))
    cut = (sp[1:] != sp[:-1]) | (auto[1:] != auto[:-1]) | (dt > 1.5 * period)
    edges = np.r_[0, np.flatnonzero(cut) + 1, n]
    best = (0, 0)
    for a, b in zip(edges[:-1].tolist(), edges[1:].tolist(), strict=True):
        if not auto[a]:
            continue
        if a > 0 and sp[a] != sp[a - 1]:  # after a setpoint change: skip its move's transient
            move = [r for r in responses if r.time <= t[a] <= r.time + r.duration]
            if move:
                if move[0].settling_time is None:
                    continue
                a = max(a, int(np.searchsorted(t, move[0].time + move[0].settling_time)))
        if b - a > best[1] - best[0]:
            best = (a, b)
    return best


def loop_health(
    t: ArrayLike,
    u: ArrayLike,
    y: ArrayLike,
    setpoint: ArrayLike,
    mode: ArrayLike,
    ok: ArrayLike,
    *,
    ti_s: float,
    delay_s: float,
    y_span: float,
    u_limits: tuple[float, float] = U_LIMITS_V,
    y_low: float = 0.0,
    stuck_after_s: float = STUCK_AFTER_S,
    amplitude_fraction: float = OSCILLATION_AMPLITUDE_FRACTION,
    settling_fraction: float = SETTLING_FRACTION,
) -> LoopHealth:
    """Loop health of one window of PLC samples.

    Parameters
    ----------
    t : array
        Sample times [s], increasing.
    u : array
        Command [V].
    y : array
        Flow [L/min].
    setpoint : array
        Setpoint [L/min].
    mode : array
        Controller mode (1 AUTO, 0 MAN).
    ok : array of bool
        Quality mask.
    ti_s : float
        The PI's integral time [s] (Hägglund's stand-in for the ultimate period).
    delay_s : float
        The process dead time [s]; b = max(1, round(delay_s / h)) for the Harris index.
    y_span : float
        Flow measurement span [L/min].
    u_limits : (float, float)
        Output limits [V].
    y_low : float
        Low end of the flow span [L/min] (a constant reading within 1 % of the span above it is
        not stuck).
    stuck_after_s : float
        Stuck rule's run length [s].
    amplitude_fraction : float
        Hägglund's acceptable amplitude as a share of ``y_span`` [-].
    settling_fraction : float
        Settling band of setpoint steps as a share of the step [-].

    Returns
    -------
    LoopHealth

    Notes
    -----
    The error is assessed on the good samples in AUTO (:func:`hagglund_oscillation`,
    :func:`setpoint_responses`, moves larger than max(0.5 L/min, 3 noise levels), settling
    bands at least 4 noise levels wide); the Harris index on the longest stretch of good,
    equally spaced AUTO samples with a constant setpoint, a stretch after a setpoint move
    starting once that move has settled (:func:`harris_index`), with b = max(1, round(delay_s/h))
    (pass the hold's extra sample in ``delay_s`` to count it); the stuck rule on all samples,
    the noise level on the good ones (:func:`sensor_health`).
    """
    tt = np.asarray(t, dtype=float)
    uu = np.asarray(u, dtype=float)
    yy = np.asarray(y, dtype=float)
    sp = np.asarray(setpoint, dtype=float)
    md = np.asarray(mode, dtype=float)
    good = np.asarray(ok, dtype=bool) & np.isfinite(tt) & np.isfinite(yy) & np.isfinite(sp)
    n = tt.size
    sensor = sensor_health(
        tt, yy, good, stuck_after_s=stuck_after_s, low_end=y_low + LOW_END_FRACTION * y_span
    )
    auto = md == AUTO
    e = np.where(good & auto, sp - yy, np.nan)
    oscillation = hagglund_oscillation(
        tt, e, ti_s=ti_s, y_span=y_span, amplitude_fraction=amplitude_fraction
    )
    tg, yg, spg, autog = tt[good], yy[good], sp[good], auto[good]
    noise = sensor.noise if math.isfinite(sensor.noise) else 0.0
    responses = setpoint_responses(
        tg,
        yg,
        spg,
        autog.astype(float),
        threshold=max(MIN_STEP_LPM, 3.0 * noise),
        band_fraction=settling_fraction,
        min_band=SETTLING_NOISE_LEVELS * noise,
    )
    a, b = _regulatory_stretch(tg, spg, autog, responses)
    period = float(np.median(np.diff(tg))) if tg.size > 1 else math.nan
    delay = max(1, round(delay_s / period)) if period > 0.0 else 1
    harris = (
        harris_index(spg[a:b] - yg[a:b], delay)
        if b > a
        else _refuse("no regulatory stretch: no good AUTO samples at a settled setpoint", delay, 0)
    )
    return LoopHealth(
        start=float(tt[0]) if n else math.nan,
        end=float(tt[-1]) if n else math.nan,
        samples=n,
        ok_share=float(np.mean(good)) if n else math.nan,
        time_in_auto=time_in_auto(md, good),
        time_at_limits=time_at_limits(uu, *u_limits, ok=good),
        oscillation=oscillation,
        setpoint_changes=tuple(responses),
        harris=harris,
        sensor=sensor,
    )


__all__ = [
    "HarrisIndex",
    "LoopHealth",
    "Oscillation",
    "SensorHealth",
    "SetpointResponse",
    "hagglund_oscillation",
    "half_period_iae",
    "harris_index",
    "loop_health",
    "noise_level",
    "quantisation_step",
    "sensor_health",
    "setpoint_responses",
    "step_response_measures",
    "time_at_limits",
    "time_in_auto",
]
