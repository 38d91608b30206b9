"""Loop health of one window: every metric family in one :class:`LoopHealth`."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from fuelid.io.jsonsafe import json_ready
from fuelid.numerics_mode import DEFAULT_NUMERICS, Numerics
from fuelid.online.health._arrays import BoolArray, FloatArray
from fuelid.online.health._harris import HarrisIndex, harris_index, harris_refusal
from fuelid.online.health._oscillation import (
    OSCILLATION_AMPLITUDE_FRACTION,
    Oscillation,
    hagglund_oscillation,
)
from fuelid.online.health._sensor import SensorHealth, sensor_health
from fuelid.online.health._setpoint import (
    MIN_STEP_LPM,
    SETTLING_FRACTION,
    SETTLING_NOISE_LEVELS,
    SetpointResponse,
    setpoint_responses,
)
from fuelid.online.health._shares import AUTO, U_LIMITS_V, time_at_limits, time_in_auto
from fuelid.plc import LOW_END_FRACTION, STUCK_AFTER_S


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

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dictionary, the units in the key names, NaN as None.

        Examples
        --------
        >>> t = np.arange(0.0, 60.0, 0.02)
        >>> y = 40.0 + np.random.default_rng(0).normal(scale=0.05, size=t.size)
        >>> d = loop_health(t, np.full(t.size, 3.0), y, np.full(t.size, 40.0),
        ...                 np.ones(t.size), np.ones(t.size, bool), ti_s=1.0, delay_s=0.1,
        ...                 y_span=120.0).to_json()
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
    numerics: Numerics = DEFAULT_NUMERICS,
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
    numerics : Numerics
        How the Harris index's AR model is computed (:mod:`fuelid.numerics_mode`).

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
        harris_index(spg[a:b] - yg[a:b], delay, numerics=numerics)
        if b > a
        else harris_refusal(
            "no regulatory stretch: no good AUTO samples at a settled setpoint", delay, 0
        )
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


__all__ = ["LoopHealth", "loop_health"]
