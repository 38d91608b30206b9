"""The closed loop's responses to the setpoint moves made in AUTO: IAE, overshoot, settling, rise.

K. J. Åström, T. Hägglund, *Advanced PID Control* (ISA, 2006), §7.2 (step-response measures).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from fuelid import lti
from fuelid.online._moves import RAMP_GAP_S, MergeRule, detect_moves
from fuelid.online.health._sensor import noise_level
from fuelid.online.health._shares import AUTO

SETTLING_FRACTION = 0.05
"""Settling band of a setpoint step: ±5 % of the step [-]."""
SETTLING_NOISE_LEVELS = 4.0
"""The settling band is at least this many noise levels wide (half width) [-]."""
MIN_STEP_LPM = 0.5
"""Smallest setpoint step analysed [L/min] (or three noise levels when that is larger)."""


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
    :func:`fuelid.lti.settling_time`, the measures those of :func:`fuelid.lti.step_measures`
    (fuelid's one implementation). For a ramped move the times count from its first change,
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
    step = target - start
    if step == 0.0:
        raise ValueError("a setpoint step needs a non-zero size")
    half = abs(band) if band is not None else band_fraction * abs(step)
    measures = lti.step_measures(tt, y, start, target, band=half / abs(step), reference=setpoint)
    return SetpointResponse(
        time=float(tt[0]),
        start=start,
        target=target,
        duration=float(tt[-1] - tt[0]),
        iae=measures.iae,
        overshoot_percent=measures.overshoot_percent,
        settling_time=_or_none(measures.settling_time),
        rise_time=_or_none(measures.rise_time),
        band=half,
    )


def _or_none(value: float) -> float | None:
    return value if math.isfinite(value) else None


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

    The moves are those of :func:`~fuelid.online._moves.detect_moves` under
    :meth:`~fuelid.online._moves.MergeRule.ramp_or_unsettled`. A move begins with a change of
    the setpoint between successive samples. A further change
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
    found = detect_moves(
        tt,
        sp,
        MergeRule.ramp_or_unsettled(ramp_gap_s),
        y=yy,
        band=band,
        band_fraction=band_fraction,
        min_band=min_band,
    )
    moves = [(m.first, m.end) for m in found]  # (first change, end of the move's last stretch)
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


__all__ = [
    "MIN_STEP_LPM",
    "RAMP_GAP_S",
    "SETTLING_FRACTION",
    "SETTLING_NOISE_LEVELS",
    "SetpointResponse",
    "setpoint_responses",
    "step_response_measures",
]
