"""Gates on one identification window: the verdict, each failed gate with its reason.

The online service identifies the loop on a rolling window every few minutes; a window it
should not trust is skipped, and why is recorded (docs online.md §5: adaptive tuning that trusts
every window bursts). Two sets of gates, both judged against the site's ``[online]`` table
(:class:`fuelid.plc.site.Online`), both returning a :class:`WindowVerdict`:

- :func:`prefit_gates`, on the window's samples before any fit: the share of lost or flagged
  samples, the share of the command at an output limit, and excitation (command steps in MAN,
  setpoint moves in AUTO), with the times of the excitation events;
- :func:`postfit_gates`, on a fitted model: the relative standard errors of K and T, the
  validation fit, the size of the residual autocorrelation (of output errors prewhitened by
  the noise's own model, :mod:`fuelid.online.residual_acf`); and the plant-ratio *event*,
  which flags but never rejects. :func:`gate_estimator` and :func:`gate_result` feed it from a
  fitted estimator or an ``identify`` result; :func:`excitation_refusal` turns the estimator's own
  :class:`~fuelid.errors.NotExcitingError` into a rejection.

:meth:`WindowVerdict.combine` joins the two; every failed gate is listed, not only the first.

Units: time [s], command u [V], flow y and setpoint [L/min], K [(L/min)/V], T [s].

References
----------
L. Ljung, *System Identification: Theory for the User* (2nd ed., Prentice Hall, 1999), §13.4
(closed-loop identifiability) and §16.6 (residual analysis). B. D. O. Anderson, "Adaptive
systems, lack of persistency of excitation and bursting phenomena", Automatica 21 (1985)
247–258. G. E. P. Box, G. M. Jenkins, *Time Series Analysis* (1976), §8.2.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fuelid.errors import NotExcitingError
from fuelid.identify.oe import OutputError
from fuelid.identify.procedure import IdentificationResult
from fuelid.io.jsonsafe import json_ready
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel
from fuelid.online.health import (
    AUTO,
    MIN_STEP_LPM,
    RAMP_GAP_S,
    U_LIMITS_V,
    noise_level,
    time_at_limits,
)
from fuelid.online.moves import MergeRule, detect_moves
from fuelid.online.residual_acf import (
    MIN_SETTLED_SAMPLES,
    Prewhitened,
    acf_lags,
    largest_residual_acf,
    prewhiten,
)
from fuelid.plc.site import Online
from fuelid.store.base import Quality, SampleArrays

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


# --- the verdict ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class WindowVerdict:
    """The gates' verdict on one identification window.

    Attributes
    ----------
    accepted : bool
        True when no gate failed (events do not count against a window).
    reasons : tuple of str
        One line per failed gate, in the order the gates run; empty when accepted.
    measured : dict
        What each gate measured, keyed with the unit in the name (``bad_share``,
        ``limit_share``, ``command_step_threshold_V``, ``rel_stderr_K``, ``residual_acf_max``,
        …); None where a gate could not measure.
    excitation_events : tuple of float
        Times of the excitation events [s]: setpoint moves when judged in AUTO, command steps
        in MAN. Two windows rest on separate evidence only when their events differ.
    events : tuple of str
        Flags that do not reject the window but must be seen (the identified K far from the
        plant model's: pump wear).
    mode : str
        "AUTO", "MAN" or "unknown": the mode the window was judged in ("" for post-fit only).
    """

    accepted: bool
    reasons: tuple[str, ...] = ()
    measured: Mapping[str, Any] = field(default_factory=dict)
    excitation_events: tuple[float, ...] = ()
    events: tuple[str, ...] = ()
    mode: str = ""

    @classmethod
    def of(
        cls,
        reasons: Sequence[str],
        measured: Mapping[str, Any],
        *,
        excitation_events: Sequence[float] = (),
        events: Sequence[str] = (),
        mode: str = "",
    ) -> WindowVerdict:
        """A verdict accepted exactly when ``reasons`` is empty."""
        return cls(
            accepted=not reasons,
            reasons=tuple(reasons),
            measured=dict(measured),
            excitation_events=tuple(float(x) for x in excitation_events),
            events=tuple(events),
            mode=mode,
        )

    @property
    def reason(self) -> str:
        """All reasons in one line, or "passed every gate" (the history's ``reason``)."""
        return "; ".join(self.reasons) if self.reasons else "passed every gate"

    def combine(self, other: WindowVerdict) -> WindowVerdict:
        """Both verdicts in one: accepted only if both are; reasons, numbers and events joined.

        Examples
        --------
        >>> a = WindowVerdict.of([], {"bad_share": 0.0}, excitation_events=[12.0], mode="MAN")
        >>> b = WindowVerdict.of(["poor validation fit: 61.0 % < 80 %"], {"fit_percent": 61.0})
        >>> c = a.combine(b)
        >>> c.accepted, c.mode, c.excitation_events, sorted(c.measured)
        (False, 'MAN', (12.0,), ['bad_share', 'fit_percent'])
        """
        return WindowVerdict.of(
            [*self.reasons, *other.reasons],
            {**self.measured, **other.measured},
            excitation_events=sorted({*self.excitation_events, *other.excitation_events}),
            events=[*self.events, *other.events],
            mode=self.mode or other.mode,
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (non-finite numbers as None).

        Examples
        --------
        >>> WindowVerdict.of([], {"rel_stderr_K": float("nan")}).to_dict()["measured"]
        {'rel_stderr_K': None}
        """
        out: dict[str, Any] = json_ready(
            {
                "accepted": self.accepted,
                "reason": self.reason,
                "reasons": list(self.reasons),
                "mode": self.mode,
                "measured": dict(self.measured),
                "excitation_events_s": list(self.excitation_events),
                "events": list(self.events),
            }
        )
        return out


# --- pre-fit gates --------------------------------------------------------------------------------


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
    PLC; :meth:`MergeRule.ramp <fuelid.online.moves.MergeRule.ramp>` of the one detector,
    :func:`~fuelid.online.moves.detect_moves`); a move counts when its net change, last value
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
         one move); none: "no excitation: the setpoint did not move";
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

    Returns
    -------
    WindowVerdict
        With ``excitation_events`` (first sample with the new command or setpoint [s]).

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
    )


# --- post-fit gates -------------------------------------------------------------------------------


def _rel(value: float, se: float | None) -> float:
    if se is None or not math.isfinite(se) or value == 0.0:
        return math.nan
    return abs(se / value)


def postfit_gates(
    model: ProcessModel,
    stderr: Mapping[str, float | None],
    fit_percent: float | None,
    residuals: ArrayLike,
    sample_time: float,
    settings: Online,
    *,
    segment_starts: Sequence[int] = (),
    plant_K: float | None = None,
    u: ArrayLike | None = None,
) -> WindowVerdict:
    """Gates on a fitted model of one window.

    1. **Standard errors**: se(K)/|K| > ``max_rel_stderr_K`` or se(T)/T > ``max_rel_stderr_T``
       (a missing or non-finite standard error fails: the parameter is not determined).
    2. **Validation fit**: ``fit_percent`` < ``min_fit_percent`` (a missing fit fails).
    3. **Residual correlation**: max |ρ(k)|, k = 1…L (:func:`acf_lags`), > ``max_residual_acf``,
       of the residuals prewhitened by the noise's own model
       (:func:`~fuelid.online.residual_acf.prewhiten`) when they are output errors (``u``
       given) and the window has settled stretches enough; else of the residuals as they are
       (prediction errors are whitened by their fit's noise model).
    4. **Plant ratio** (an event, never a rejection): K outside ``plant_ratio_event`` × the
       plant model's K at the window's operating point and temperature.

    Parameters
    ----------
    model : ProcessModel
        The fitted model (K [(L/min)/V], T [s]).
    stderr : mapping
        Standard error by parameter name ("K", "T") [(L/min)/V, s].
    fit_percent : float or None
        Validation fit [%] (the held-out part's, else the fit's own).
    residuals : array
        y − ŷ, or a noise-model fit's one-step prediction errors [L/min].
    sample_time : float
        h [s].
    settings : Online
        The ``[online]`` table.
    segment_starts : sequence of int
        Where each segment after a gap begins (nothing is correlated across a gap).
    plant_K : float, optional
        The plant model's K at the window's operating point and temperature [(L/min)/V].
    u : array, optional
        The command, one per residual [V], when the residuals are output errors y − ŷ: the
        residual correlation is then judged after prewhitening them by the noise's model. None
        for prediction errors (judged as they are).

    Returns
    -------
    WindowVerdict
        ``measured`` holds the gated statistic (``residual_acf_max``, ``residual_acf_lag``,
        ``residual_acf_lags``), the raw residuals' (``residual_acf_raw_max``,
        ``residual_acf_raw_lag``), ``residual_acf_basis`` ("prewhitened", "raw: no command
        given (prediction errors)" or "raw: too few settled samples (n < 500)"), and the
        noise's AR order and settled samples (None when not prewhitened).

    Notes
    -----
    Why a bound on the *size* of the residual autocorrelation and not a p-value: a whiteness
    test (Box–Jenkins, Ljung 1999 §16.6) bounds each ρ(k) by ±1.96/√N, which for a 10-minute
    window at 50 Hz (N = 30 000) is ±0.011. Every real window has residual colour larger than
    that (a slightly nonlinear gain, quantisation, slow drifts), so the test rejects every
    window whatever the model's use. What matters for tuning is whether the colour is large
    enough to bias the model or make its standard errors meaningless. The lags span a few
    settling times of the model, where unmodelled dynamics and closed-loop colour show; a
    residual correlated beyond that is drift, which the output offset and the covariance absorb.

    Why prewhitened: output errors carry the meter noise's colour whatever the model (AR(1)
    noise with pole 0.8 per sample gives ρ(1) = 0.8 on a perfect model), and in open loop that
    colour is no reason to reject: the output-error estimate stays consistent and its HAC
    covariance keeps the standard errors honest. The noise's model is fitted where the output
    has settled, not on the whole residual, which would whiten the model's error away too;
    what correlation is left after it is the model's. A smooth misfit is scaled by about A(1)
    as well, so under strongly coloured noise a small misfit shows less: the noise has more
    power where the misfit lies.

    Where the default comes from: docs/gate_study.md (``benchmarks/bench_gate_study.py``),
    on two plants the gate was not tuned on (``benchmarks/gate_plants/``), 100 ten-minute
    windows per plant × noise (white; AR(1), pole 0.8) × loop (MAN, output error; AUTO,
    prediction error), fitted by the service's own analyser. 0.7 is the smallest value that in
    every condition rejects at most 5 % of the good windows (|K error| ≤ 3 %) and keeps the
    95th percentile of the accepted windows' |K error| at or below 5 %. The binding condition
    is white noise in MAN on the fast plant: windows spanning most of the drive's range reach
    0.66 (95th percentile) from the gain's nonlinearity, with K still within 0.5 %; coloured
    noise needs only 0.2 once prewhitened (the raw statistic, ≥ 0.79, rejected every MAN
    window with it). At 0.7 the gate catches 38 % of the MAN windows whose fit misses the
    meter's lag (step response off by 8–15 % of K, K itself within a few per cent), those with
    large moves, and 15 % of the AUTO ones: prediction errors are whitened by their noise
    model, which absorbs the misfit of a missing lag too, so in closed loop this gate does not
    see a wrong structure.
    """
    reasons: list[str] = []
    events: list[str] = []
    se_K, se_T = stderr.get("K"), stderr.get("T")
    rel_K, rel_T = _rel(model.K, se_K), _rel(model.T, se_T)
    measured: dict[str, Any] = {
        "K": model.K,
        "T_s": model.T,
        "rel_stderr_K": rel_K,
        "rel_stderr_T": rel_T,
    }
    for name, rel, bound in (
        ("K", rel_K, settings.max_rel_stderr_K),
        ("T", rel_T, settings.max_rel_stderr_T),
    ):
        if math.isnan(rel):
            reasons.append(f"{name} is not determined: no standard error")
        elif rel > bound:
            reasons.append(
                f"relative standard error of {name} {100.0 * rel:.1f} % > {100.0 * bound:g} %"
            )
    measured["fit_percent"] = fit_percent
    if fit_percent is None or not math.isfinite(fit_percent):
        reasons.append("no validation fit")
    elif fit_percent < settings.min_fit_percent:
        reasons.append(f"poor validation fit: {fit_percent:.1f} % < {settings.min_fit_percent:g} %")
    e = np.asarray(residuals, dtype=float)
    settle = model.settling_time()
    lags = acf_lags(e.size, settle, sample_time)
    raw_rho, raw_lag = largest_residual_acf(e, lags, segment_starts)
    rho, lag = raw_rho, raw_lag
    white = None if u is None else prewhiten(e, u, sample_time, settle, segment_starts)
    if white is not None:
        rho, lag = largest_residual_acf(white.residuals, lags, white.segment_starts)
        basis = "prewhitened"
        how = f", prewhitened by the noise's AR({white.noise.order})"
    elif u is None:
        basis = "raw: no command given (prediction errors)"
        how = ""
    else:
        basis = f"raw: too few settled samples (n < {MIN_SETTLED_SAMPLES})"
        how = ", raw: too few settled samples to model the noise"
    measured["residual_acf_max"] = rho
    measured["residual_acf_lag"] = lag
    measured["residual_acf_lags"] = lags
    measured["residual_acf_raw_max"] = raw_rho
    measured["residual_acf_raw_lag"] = raw_lag
    measured["residual_acf_basis"] = basis
    measured["residual_acf_noise_ar_order"] = None if white is None else white.noise.order
    measured["residual_acf_settled_samples"] = None if white is None else white.settled_samples
    if not rho <= settings.max_residual_acf:
        reasons.append(
            f"residual correlation too large: |ρ({lag})| = {rho:.3f} > "
            f"{settings.max_residual_acf:g} (lags 1–{lags}{how})"
        )
    if plant_K is not None and plant_K != 0.0 and math.isfinite(plant_K):
        ratio = model.K / plant_K
        low, high = settings.plant_ratio_event
        measured["plant_K"] = plant_K
        measured["plant_ratio"] = ratio
        if not low <= ratio <= high:
            events.append(
                f"plant_ratio: the identified K is {ratio:.2f} × the plant model's "
                f"(outside {low:g}–{high:g}): pump wear or a model far from the plant"
            )
    return WindowVerdict.of(reasons, measured, events=events)


def gate_estimator(
    estimator: OutputError,
    data: IOData,
    settings: Online,
    *,
    validation_fit_percent: float | None = None,
    plant_K: float | None = None,
) -> WindowVerdict:
    """:func:`postfit_gates` on an :class:`~fuelid.identify.OutputError` fitted to ``data``.

    The residuals are ``data.y − estimator.y_hat_``, judged after prewhitening by the noise's
    model (``u = data.u``); the fit is ``validation_fit_percent`` when given, else the
    estimator's own ``fit_percent_``.

    Parameters
    ----------
    estimator : OutputError
        Fitted on ``data``.
    data : IOData
        The fitting record.
    settings : Online
        The ``[online]`` table.
    validation_fit_percent : float, optional
        Fit on held-out data [%].
    plant_K : float, optional
        The plant model's K [(L/min)/V].

    Returns
    -------
    WindowVerdict
    """
    fit = estimator.fit_percent_ if validation_fit_percent is None else validation_fit_percent
    return postfit_gates(
        estimator.model_,
        estimator.stderr_,
        fit,
        data.y - estimator.y_hat_,
        estimator.sample_time_,
        settings,
        segment_starts=data.segment_starts,
        plant_K=plant_K,
        u=data.u,
    )


def gate_result(
    result: IdentificationResult,
    settings: Online,
    *,
    plant_K: float | None = None,
    u: ArrayLike | None = None,
) -> WindowVerdict:
    """:func:`postfit_gates` on an ``identify`` result.

    The fit is ``validation_fit_percent`` when the result has one, else ``fit_percent``; the
    residuals are the one-step prediction errors of a noise-model fit, else y − ŷ over the
    fitted samples.

    Parameters
    ----------
    result : IdentificationResult
        What :func:`fuelid.identify.identify` returned.
    settings : Online
        The ``[online]`` table.
    plant_K : float, optional
        The plant model's K [(L/min)/V].
    u : array, optional
        The command over the fitted samples [V]: y − ŷ residuals are then judged after
        prewhitening (ignored for prediction errors, which their noise model whitens).

    Returns
    -------
    WindowVerdict
    """
    command = None
    if result.prediction_errors is not None:
        residuals = np.asarray(result.prediction_errors, dtype=float)
    else:
        n = result.n_samples
        residuals = np.asarray(result.y[:n] - result.y_hat[:n], dtype=float)
        command = None if u is None else np.asarray(u, dtype=float)[:n]
    fit = (
        result.validation_fit_percent
        if result.validation_fit_percent is not None
        else result.fit_percent
    )
    return postfit_gates(
        result.model,
        result.stderr,
        fit,
        residuals,
        result.sample_time,
        settings,
        plant_K=plant_K,
        u=command,
    )


def excitation_refusal(error: NotExcitingError) -> WindowVerdict:
    """The estimator refused the window for lack of excitation: a rejection with its message.

    Examples
    --------
    >>> excitation_refusal(NotExcitingError("the input never changes")).reasons
    ('no excitation: the input never changes',)
    """
    return WindowVerdict.of([f"no excitation: {error}"], {"estimator_refused": True})


__all__ = [
    "Prewhitened",
    "WindowVerdict",
    "acf_lags",
    "bad_share",
    "command_steps",
    "excitation_refusal",
    "gate_estimator",
    "gate_result",
    "judged_mode",
    "largest_residual_acf",
    "lost_samples",
    "postfit_gates",
    "prefit_gates",
    "prefit_samples",
    "prewhiten",
    "setpoint_moves",
]
