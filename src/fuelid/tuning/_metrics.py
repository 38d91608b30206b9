"""Quality of a closed-loop response: one setpoint step or one load disturbance.

Both simulators of :mod:`fuelid.tuning._linearloop` (the process model) and
:mod:`fuelid.tuning.closedloop` (the nonlinear plant) score their responses with these, so the
numbers of ``fuelid tune`` and ``fuelid report`` mean the same everywhere
(docs/explanation/tuning.md, section 6).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.integrate
from numpy.typing import NDArray

from fuelid import lti
from fuelid.errors import FuelidError

FloatArray = NDArray[np.float64]
SETTLING_BAND = lti.SETTLING_BAND
"""Settling band: 2 % of the step (setpoint) or of the setpoint (disturbance)."""


@dataclass(frozen=True)
class StepMetrics:
    """Quality of one setpoint step or one load disturbance."""

    kind: str
    """"setpoint" or "disturbance"."""
    start: float
    """When the step was applied [s]."""
    size: float
    """Setpoint change [L/min] or disturbance step [V]."""
    overshoot_percent: float
    """Setpoint: peak beyond the new setpoint in % of the step; disturbance: nan."""
    peak_deviation: float
    """Largest |setpoint − measurement| after a disturbance [L/min]; for a step, beyond it."""
    settling_time: float
    """Setpoint: time to stay within 2 % of the step; disturbance: within 2 % of the setpoint
    [s]; nan if not settled before the next event."""
    iae: float
    """Integral of |setpoint − measurement| over the event's window [(L/min)·s]."""

    def to_json(self) -> dict[str, float | str]:
        """Plain dictionary for JSON."""
        return {
            "kind": self.kind,
            "start": self.start,
            "size": self.size,
            "overshoot_percent": self.overshoot_percent,
            "peak_deviation": self.peak_deviation,
            "settling_time": self.settling_time,
            "iae": self.iae,
        }


def setpoint_step_metrics(
    t: FloatArray, y: FloatArray, r0: float, r1: float, start: float = 0.0
) -> StepMetrics:
    """Overshoot, 2 % settling time and IAE of a response y(t) to a setpoint step r0 → r1.

    The measures of :func:`fuelid.lti.step_measures` (fuelid's one implementation), the
    settling time counted from ``start`` [s].

    Examples
    --------
    A first-order response with T = 1 s: no overshoot, settles at ln 50 = 3.91 s, IAE = T.

    >>> t = np.linspace(0.0, 20.0, 200_001)
    >>> m = setpoint_step_metrics(t, 1 - np.exp(-t), 0.0, 1.0)
    >>> m.overshoot_percent, round(m.settling_time, 3), round(m.iae, 4)
    (0.0, 3.912, 1.0)
    """
    step = r1 - r0
    if step == 0.0:
        raise FuelidError("a setpoint step needs a non-zero size")
    measures = lti.step_measures(t, y, r0, r1, band=SETTLING_BAND, step_time=start)
    return StepMetrics(
        kind="setpoint",
        start=start,
        size=step,
        overshoot_percent=measures.overshoot_percent,
        peak_deviation=measures.overshoot_percent / 100.0 * abs(step),
        settling_time=measures.settling_time,
        iae=measures.iae,
    )


def disturbance_metrics(
    t: FloatArray,
    y: FloatArray,
    r: float,
    size: float,
    start: float = 0.0,
    band: float | None = None,
) -> StepMetrics:
    """Peak deviation, recovery time and IAE after a load step.

    Recovery is back within ``band`` of the setpoint for good; by default 2 % of the setpoint.
    A deviation model (setpoint 0) needs an absolute ``band`` [output unit].
    """
    e = r - y
    if band is None:
        band = SETTLING_BAND * max(abs(r), 1e-12)
    outside = np.flatnonzero(np.abs(e) > band)
    if outside.size == 0:
        settle = 0.0
    elif outside[-1] == t.size - 1:
        settle = math.nan
    else:
        settle = float(t[outside[-1] + 1] - start)
    return StepMetrics(
        kind="disturbance",
        start=start,
        size=size,
        overshoot_percent=math.nan,
        peak_deviation=float(np.max(np.abs(e))),
        settling_time=settle,
        iae=float(scipy.integrate.trapezoid(np.abs(e), t)),
    )
