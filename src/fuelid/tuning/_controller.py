"""The PLC's PI as it runs in the controller: positional, limited, with anti-windup.

At each period h it reads the measurement, outputs u = sat(Kc·e + I) within the drive's signal
range and then updates the integral, I ← I + Kc·h/Ti·e + (h/Tt)·(u − v): forward Euler as in
Åström & Hägglund's PID code, plus back-calculation anti-windup with tracking time Tt. Gain changes
are bumpless: the integral absorbs the change of the proportional term so the output does not
jump (docs/explanation/tuning.md, sections 1 and 6; Åström & Hägglund, *Advanced PID Control*, ISA
2006).
"""

from __future__ import annotations

import numpy as np

from fuelid.errors import FuelidError
from fuelid.tuning._linearloop import CONTINUOUS_PERIOD
from fuelid.tuning._rules import PISettings


class DiscretePI:
    """The PLC's PI: positional, forward-Euler integral, output limits, back-calculation.

    Parameters
    ----------
    settings : PISettings
        Kc [V per L/min], Ti [s], control period h [s] (0: simulated at 0.02 s).
    u_min, u_max : float
        Output limits [V] (the 1–5 V signal).
    u0 : float
        Output at start-up [V]; the integral starts there (bumpless start from manual).
    tracking_time : float, optional
        Anti-windup tracking time Tt [s] (back-calculation). With the default Tt = h the output
        computed for the current error is brought back to the limit within one period, so the
        integral cannot run away while saturated (it settles where Kc·e + integral sits at the
        limit, which may itself lie outside the limits while the error is large).

    Examples
    --------
    >>> pi = DiscretePI(PISettings("simc", Kc=0.1, Ti=2.0, control_period=1.0), 1.0, 5.0, u0=2.0)
    >>> pi.update(setpoint=30.0, measurement=25.0)  # 2 V + 0.1·5
    2.5
    >>> pi.update(setpoint=30.0, measurement=-1000.0)  # saturated at the top
    5.0
    """

    def __init__(
        self,
        settings: PISettings,
        u_min: float,
        u_max: float,
        u0: float,
        tracking_time: float | None = None,
    ) -> None:
        if not u_min < u_max:
            raise FuelidError(f"output limits must satisfy u_min < u_max, got {u_min}…{u_max}")
        self.h = settings.control_period if settings.control_period > 0.0 else CONTINUOUS_PERIOD
        self.Kc = settings.Kc
        self.Ti = settings.Ti
        self.u_min = u_min
        self.u_max = u_max
        self.tracking_time = self.h if tracking_time is None else tracking_time
        if not self.tracking_time > 0.0:
            raise FuelidError("the anti-windup tracking time must be positive")
        self.integral = float(np.clip(u0, u_min, u_max))
        self._last_error = 0.0

    def update(self, setpoint: float, measurement: float) -> float:
        """One control period: read, output the limited command [V], update the integral."""
        e = setpoint - measurement
        v = self.Kc * e + self.integral
        u = min(max(v, self.u_min), self.u_max)
        self.integral += self.Kc * self.h / self.Ti * e + self.h / self.tracking_time * (u - v)
        self._last_error = e
        return u

    def set_gains(self, Kc: float, Ti: float) -> None:
        """Change the gains bumplessly: the output for the last error stays the same."""
        if not (Kc > 0.0 and Ti > 0.0):
            raise FuelidError("controller gains must be positive")
        self.integral += (self.Kc - Kc) * self._last_error
        self.Kc, self.Ti = Kc, Ti
