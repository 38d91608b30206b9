"""The gates on a window's samples before any fit: lost and flagged samples, limits, excitation.

Excitation is judged by mode: command steps that hold in MAN, setpoint moves in AUTO (the one
detector of :mod:`fuelid.online._moves`), larger than three noise levels of their signal.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fuelid.online._moves import MergeRule, detect_moves
from fuelid.online._settings import Online
from fuelid.online.gates._verdict import WindowVerdict
from fuelid.online.health import (
    AUTO,
    MIN_STEP_LPM,
    RAMP_GAP_S,
    U_LIMITS_V,
    noise_level,
    time_at_limits,
)
from fuelid.store import Quality, SampleArrays

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


MAN = 0
"""The controller mode value of MAN (1 is AUTO; −1 in a store: not recorded)."""
MIN_COMMAND_STEP_V = 0.05
"""Smallest command step that counts as a move in MAN [V] (or three command noise levels)."""
NOISE_LEVELS = 3.0
"""A move must exceed this many noise levels of its signal [-]."""
STEP_HOLD_S = 0.5
"""A command step must hold: the mean command this long after it differs from the mean this
long before it by more than the threshold [s] (a noise spike does not)."""
GAP_PERIODS = 1.5
"""A time step longer than this many sample periods is a gap [-]."""


def lost_samples(
    t: ArrayLike, seq: ArrayLike | None = None, sample_time: float | None = None
) -> int:
    """Samples missing between the window's first and last stored sample.

    With a sequence counter (every value ≥ 0) a jump of the counter by m > 1 is m − 1 lost
    samples; without one a time step Δt longer than 1.5 periods is round(Δt/h) − 1 lost.

    Parameters
    ----------
    t : array
        Sample times [s], increasing.
    seq : array of int, optional
        The PLC's sequence numbers, unwrapped (−1 where none: then the times are used).
    sample_time : float, optional
        h [s]; default the median time step.

    Returns
    -------
    int
        Lost samples [-].

    Examples
    --------
    >>> lost_samples([0.0, 0.02, 0.04, 0.12, 0.14])
    3
    >>> lost_samples([0.0, 0.02, 0.04], seq=[7, 8, 12])
    3
    """
    tt = np.asarray(t, dtype=float)
    if seq is not None:
        s = np.asarray(seq, dtype=np.int64)
        if s.size == tt.size and s.size > 1 and np.all(s >= 0):
            return int(np.sum(np.clip(np.diff(s) - 1, 0, None)))
    if tt.size < 2:
        return 0
    dt = np.diff(tt)
    h = float(np.median(dt)) if sample_time is None else float(sample_time)
    if not h > 0.0:
        return 0
    gaps = dt[dt > GAP_PERIODS * h]
    return int(np.sum(np.maximum(np.round(gaps / h) - 1.0, 0.0)))


def bad_share(
    t: ArrayLike,
    ok: ArrayLike,
    seq: ArrayLike | None = None,
    sample_time: float | None = None,
) -> float:
    """Share of the window's samples that are lost or flagged.

    share = (flagged + lost) / (stored + lost): a gap is as bad as a flagged sample.

    Parameters
    ----------
    t : array
        Sample times [s].
    ok : array of bool
        Quality mask (True: good).
    seq : array of int, optional
        Sequence numbers (see :func:`lost_samples`).
    sample_time : float, optional
        h [s].

    Returns
    -------
    float
        Share in [0, 1] [-]; 1 for an empty window.

    Examples
    --------
    >>> bad_share([0.0, 0.02, 0.04, 0.08], [True, False, True, True])
    0.4
    """
    good = np.asarray(ok, dtype=bool)
    lost = lost_samples(t, seq, sample_time)
    total = good.size + lost
    return float((np.sum(~good) + lost) / total) if total else 1.0


def _merge(times: FloatArray, gap_s: float) -> list[float]:
    """The first of each run of times no more than ``gap_s`` apart [s] (a ramp is one move)."""
    out: list[float] = []
    last = -math.inf
    for when in times.tolist():
        if when - last > gap_s:
            out.append(float(when))
        last = float(when)
    return out


def command_steps(u: ArrayLike, threshold: float, hold: int) -> NDArray[np.intp]:
    """Indices of the command steps: sample changes |Δu| > threshold that hold.

    A change at sample k counts when the mean of u over the ``hold`` samples from k on differs
    from the mean over the ``hold`` samples before k by more than ``threshold`` as well: an
    operator's step does, the rare large difference of a noisy command does not (the means of
    25 samples carry a fifth of the noise).

    Parameters
    ----------
    u : array
        Command [V], the good samples in order.
    threshold : float
        Smallest step [V].
    hold : int
        Samples averaged on each side [-].

    Returns
    -------
    ndarray of int
        k: the first sample with the new command.

    Examples
    --------
    >>> u = np.r_[np.full(50, 3.0), np.full(50, 3.2)]
    >>> u[20] = 3.5  # a spike
    >>> command_steps(u, 0.05, 10).tolist()
    [50]
    """
    x = np.asarray(u, dtype=float)
    k = np.flatnonzero(np.abs(np.diff(x)) > threshold) + 1
    if k.size == 0:
        return k
    c = np.r_[0.0, np.cumsum(x)]
    lo = np.maximum(k - hold, 0)
    hi = np.minimum(k + hold, x.size)
    before = (c[k] - c[lo]) / (k - lo)
    after = (c[hi] - c[k]) / (hi - k)
    held: NDArray[np.intp] = k[np.abs(after - before) > threshold]
    return held


def setpoint_moves(
    t: ArrayLike, setpoint: ArrayLike, threshold: float, ramp_gap_s: float = RAMP_GAP_S
) -> list[float]:
    """Times of the setpoint moves larger than ``threshold``, a ramp counted as one move.

    Changes of the setpoint between successive samples, each no more than ``ramp_gap_s``
    after the previous one, form one move (the staircase a ramped setpoint becomes in the
    PLC; :meth:`MergeRule.ramp <fuelid.online._moves.MergeRule.ramp>` of the one detector,
    :func:`~fuelid.online._moves.detect_moves`); a move counts when its net change, last value
    minus the value before it, exceeds ``threshold``. Unlike
    :func:`~fuelid.online.health.setpoint_responses` this does not ask whether the flow
    settled between two moves: a slow disturbance must not merge two steps into one piece of
    evidence.

    Parameters
    ----------
    t : array
        Times of the samples to examine [s] (good samples in AUTO).
    setpoint : array
        Setpoint [L/min].
    threshold : float
        Smallest net move [L/min].
    ramp_gap_s : float
        Changes at most this far apart are one move [s].

    Returns
    -------
    list of float
        Time of each move's first change (the first sample with the new setpoint) [s].

    Examples
    --------
    >>> t = np.arange(0.0, 30.0, 0.5)
    >>> sp = np.where(t < 10.0, 40.0, np.where(t < 20.0, 45.0, 45.2))
    >>> setpoint_moves(t, sp, 0.5)
    [10.0]
    """
    moves = detect_moves(t, setpoint, MergeRule.ramp(ramp_gap_s))
    tt = np.asarray(t, dtype=float)
    return [float(tt[m.first]) for m in moves if abs(m.size) > threshold]


SIGNAL_SWITCH_SHARE = 0.5
"""A change of the applied test signal larger than this share of its largest level is a switch."""


def signal_switches(t: ArrayLike, signal: ArrayLike, mask: ArrayLike) -> list[float]:
    """Times of the test signal's switches between successive samples in ``mask`` [s].

    The signal is the one the PLC applied (``tags.excitation``, read back with every sample):
    a change larger than :data:`SIGNAL_SWITCH_SHARE` of its largest level over the samples is a
    switch, counted at the first sample with the new level; a signal that never left 0 has
    none.

    Examples
    --------
    >>> t = np.arange(8.0)
    >>> s = np.array([0.0, 0.0, 0.1, 0.1, -0.1, -0.1, 0.0, 0.0])
    >>> signal_switches(t, s, np.ones(8, dtype=bool))
    [2.0, 4.0, 6.0]
    """
    tt = np.asarray(t, dtype=float)
    ss = np.asarray(signal, dtype=float)
    keep = np.asarray(mask, dtype=bool) & np.isfinite(ss)
    tt, ss = tt[keep], ss[keep]
    if ss.size < 2:
        return []
    level = float(np.max(np.abs(ss)))
    if not level > 0.0:
        return []
    changes = np.flatnonzero(np.abs(np.diff(ss)) > SIGNAL_SWITCH_SHARE * level) + 1
    return [float(x) for x in tt[changes]]


def judged_mode(mode: ArrayLike, ok: ArrayLike) -> str:
    """The mode a window is judged in: the one the majority of its good samples is in.

    Parameters
    ----------
    mode : array of int
        1 AUTO, 0 MAN, negative where not recorded.
    ok : array of bool
        Quality mask.

    Returns
    -------
    str
        "AUTO" (ties included), "MAN", or "unknown" when no good sample has a mode.

    Examples
    --------
    >>> judged_mode([1, 1, 0, 0, 0], [True, True, True, False, False])
    'AUTO'
    >>> judged_mode([-1, -1], [True, True])
    'unknown'
    """
    m = np.asarray(mode, dtype=float)
    known = np.asarray(ok, dtype=bool) & np.isfinite(m) & (m >= 0)
    if not known.any():
        return "unknown"
    return "AUTO" if np.mean(m[known] == AUTO) >= 0.5 else "MAN"


def prefit_gates(
    t: ArrayLike,
    u: ArrayLike,
    y: ArrayLike,
    setpoint: ArrayLike,
    mode: ArrayLike,
    ok: ArrayLike,
    settings: Online,
    *,
    seq: ArrayLike | None = None,
    sample_time: float | None = None,
    u_limits: tuple[float, float] = U_LIMITS_V,
    excitation: ArrayLike | None = None,
) -> WindowVerdict:
    """Gates on one window's samples, before any fit.

    1. **Gaps and quality**: :func:`bad_share` (lost samples count) > ``max_bad_share``.
    2. **Output limits**: share of good samples with u at a limit
       (:func:`~fuelid.online.health.time_at_limits`) > ``max_limit_share``.
    3. **Excitation**, by the mode most good samples are in (:func:`judged_mode`):

       - MAN: a command step |Δu| > max(0.05 V, 3 × the command's noise level) between good
         successive samples in MAN that holds for 0.5 s (:func:`command_steps`); none: "MAN
         without command moves";
       - AUTO: a setpoint move begun in AUTO larger than max(0.5 L/min, 3 × the flow's noise
         level) between good samples in AUTO (:func:`setpoint_moves`, a ramp merged into
         one move), or a switch of the test signal the PLC applied in AUTO
         (:func:`signal_switches`: a designed signal is an external input, as a setpoint
         move is; whether it carried enough is for the standard-error gates, since it is
         designed to be small); none: "no excitation: the setpoint did not move";
       - unknown (no mode recorded): judged as MAN, by command steps.

    Parameters
    ----------
    t : array
        Sample times [s], increasing.
    u : array
        Command [V].
    y : array
        Flow [L/min].
    setpoint : array
        Setpoint [L/min] (NaN where not recorded).
    mode : array
        Controller mode: 1 AUTO, 0 MAN, negative where not recorded.
    ok : array of bool
        Quality mask (True: good).
    settings : Online
        The ``[online]`` table (``max_bad_share``, ``max_limit_share``).
    seq : array of int, optional
        Sequence numbers for the gap count (:func:`lost_samples`).
    sample_time : float, optional
        h [s]; default the median time step.
    u_limits : (float, float)
        The command's limits [V].
    excitation : array, optional
        The test signal the PLC applied (``tags.excitation``) [V], NaN where not recorded.

    Returns
    -------
    WindowVerdict
        With ``excitation_events`` (first sample with the new command, setpoint or signal
        level [s]).

    Notes
    -----
    Why only setpoint moves excite a window in AUTO: in closed loop the command is a function
    of the measured flow, u = C·(r − y). Without a change of the reference r, the data hold
    only the loop's reaction to its own noise and disturbances, and a model fitted to them is
    not determined by the plant (the fit may as well return the inverse controller; Ljung
    1999, §13.4). The command's moves in AUTO are therefore never counted as excitation; a
    setpoint move is an external signal that does determine the model. Estimators fed such
    windows drift, and a tuner trusting them bursts (Anderson 1985).

    Why the majority of good samples: a window that switches mode holds two experiments; the
    larger one decides which excitation rule applies (an AUTO majority needs a setpoint move,
    a MAN majority a command step made in MAN). Events of the minority mode are not counted,
    which errs on the side of rejecting.

    Without a mode tag the window is judged by command steps, as in MAN: a PI reacting to
    noise moves its command by far less than 0.05 V per sample, so steady closed-loop data
    still fail, but a closed loop following setpoint steps passes on its command's reaction;
    the post-fit gates (standard errors, residual correlation) are then the guard.
    """
    tt = np.asarray(t, dtype=float)
    uu = np.asarray(u, dtype=float)
    yy = np.asarray(y, dtype=float)
    sp = np.asarray(setpoint, dtype=float)
    md = np.asarray(mode, dtype=float)
    good = np.asarray(ok, dtype=bool) & np.isfinite(tt) & np.isfinite(uu) & np.isfinite(yy)
    reasons: list[str] = []
    lost = lost_samples(tt, seq, sample_time)
    share = bad_share(tt, good, seq, sample_time)
    measured: dict[str, Any] = {
        "samples": int(tt.size),
        "lost_samples": lost,
        "flagged_samples": int(np.sum(~good)),
        "bad_share": share,
    }
    if share > settings.max_bad_share:
        reasons.append(
            f"gaps or bad quality: {100.0 * share:.1f} % of the window "
            f"(limit {100.0 * settings.max_bad_share:g} %)"
        )
    limit_share = time_at_limits(uu, *u_limits, ok=good)
    measured["limit_share"] = limit_share
    if limit_share > settings.max_limit_share:  # nan (no good sample): the first gate failed
        reasons.append(
            f"output at a limit: {100.0 * limit_share:.1f} % of the window "
            f"(limit {100.0 * settings.max_limit_share:g} %)"
        )
    mode_name = judged_mode(md, good)
    measured["mode"] = mode_name
    events: list[float]
    if mode_name == "AUTO":
        auto = good & (md == AUTO) & np.isfinite(sp)
        flow_noise = noise_level(yy[good & (md == AUTO)])
        noise = flow_noise if math.isfinite(flow_noise) else 0.0
        threshold = max(MIN_STEP_LPM, NOISE_LEVELS * noise)
        measured["flow_noise_Lpm"] = flow_noise
        measured["setpoint_threshold_Lpm"] = threshold
        events = setpoint_moves(tt[auto], sp[auto], threshold)
        if excitation is not None:
            switches = signal_switches(tt, excitation, good & (md == AUTO))
            measured["signal_switches"] = len(switches)
            events = sorted(events + switches)
        if not events:
            if not np.any(auto):
                reasons.append(
                    "no excitation: the setpoint is not recorded, so closed-loop excitation "
                    "cannot be told from noise"
                )
            else:
                reasons.append(
                    f"no excitation: the setpoint did not move (no move above {threshold:.3g} "
                    "L/min in AUTO)"
                )
    else:
        man = good & ((md == MAN) | (md < 0) | ~np.isfinite(md))
        command_noise = noise_level(uu[man])
        noise = command_noise if math.isfinite(command_noise) else 0.0
        threshold = max(MIN_COMMAND_STEP_V, NOISE_LEVELS * noise)
        measured["command_noise_V"] = command_noise
        measured["command_step_threshold_V"] = threshold
        tg, ug, mg = tt[good], uu[good], man[good]
        period = float(np.median(np.diff(tg))) if tg.size > 1 else 1.0
        steps = command_steps(ug, threshold, max(1, round(STEP_HOLD_S / period)))
        events = _merge(tg[steps[mg[steps]]], RAMP_GAP_S)
        if not events:
            head = "MAN" if mode_name == "MAN" else "no mode recorded:"
            reasons.append(f"{head} without command moves (no step above {threshold:.3g} V)")
    measured["excitation_events"] = len(events)
    return WindowVerdict.of(reasons, measured, excitation_events=events, mode=mode_name)


def prefit_samples(
    samples: SampleArrays,
    settings: Online,
    *,
    sample_time: float | None = None,
    u_limits: tuple[float, float] = U_LIMITS_V,
) -> WindowVerdict:
    """:func:`prefit_gates` on samples read from the store (good: quality OK).

    Parameters
    ----------
    samples : SampleArrays
        One window, sorted by time.
    settings : Online
        The ``[online]`` table.
    sample_time : float, optional
        h [s]; default the median time step.
    u_limits : (float, float)
        The command's limits [V].

    Returns
    -------
    WindowVerdict
    """
    return prefit_gates(
        samples.time,
        samples.u,
        samples.y,
        samples.setpoint,
        samples.mode,
        samples.quality == Quality.OK,
        settings,
        seq=samples.seq,
        sample_time=sample_time,
        u_limits=u_limits,
        excitation=samples.excitation,
    )


__all__ = [
    "GAP_PERIODS",
    "MAN",
    "MIN_COMMAND_STEP_V",
    "NOISE_LEVELS",
    "STEP_HOLD_S",
    "bad_share",
    "command_steps",
    "judged_mode",
    "lost_samples",
    "prefit_gates",
    "prefit_samples",
    "setpoint_moves",
    "signal_switches",
]
