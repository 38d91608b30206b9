r"""The process model family used everywhere in fuelid.

.. math:: G(s) = \frac{K\,e^{-\theta s}}{(T s + 1)(T_2 s + 1)(T_f s + 1)}

``T2 = 0`` for a first-order process, ``T_f = 0`` without a flowmeter prior, θ the total dead
time (it includes the flowmeter's delay). For the fuel loop K is in (L/min)/V and times are in s;
the class itself is unit-agnostic (output unit per input unit).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import control
import numpy as np
from numpy.typing import ArrayLike, NDArray

from fuelid import lti
from fuelid.errors import FuelidError
from fuelid.identify.discrete import discretise, lag_chain


@dataclass(frozen=True)
class ProcessModel:
    """K·e^(−θs)/((T·s+1)(T2·s+1)(T_f·s+1)).

    Parameters
    ----------
    K : float
        Static gain [output unit / input unit].
    T : float
        Main process time constant [s], > 0.
    T2 : float
        Second process time constant [s], 0 for a first-order process.
    T_f : float
        Flowmeter time constant [s], 0 without one.
    delay : float
        Total dead time θ [s].

    Examples
    --------
    >>> m = ProcessModel(K=2.0, T=1.0)
    >>> round(float(m.step_response([3.912023005428146])[0]), 4)
    1.96
    """

    K: float
    T: float
    T2: float = 0.0
    T_f: float = 0.0
    delay: float = 0.0

    def __post_init__(self) -> None:
        for name in ("K", "T", "T2", "T_f", "delay"):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise FuelidError(f"model parameter {name} must be finite, got {value}")
        if self.T <= 0.0:
            raise FuelidError(f"model time constant T must be positive, got {self.T:g} s")
        for name in ("T2", "T_f", "delay"):
            if getattr(self, name) < 0.0:
                raise FuelidError(f"model parameter {name} must not be negative")

    @property
    def time_constants(self) -> tuple[float, ...]:
        """The non-zero lags T, T2, T_f [s]."""
        return tuple(tc for tc in (self.T, self.T2, self.T_f) if tc > 0.0)

    def to_control(self) -> control.TransferFunction:
        """Delay-free part as a :class:`control.TransferFunction`; the dead time is ``.delay``.

        The dead time is kept explicit and never Padé-approximated here; use
        ``control.pade(model.delay, n)`` yourself if a rational approximation is wanted.

        Examples
        --------
        >>> ProcessModel(K=2.0, T=4.0, delay=1.0).to_control().num[0][0].tolist()
        [2.0]
        """
        den = np.array([1.0])
        for tc in self.time_constants:
            den = np.polymul(den, [tc, 1.0])
        return control.tf([self.K], den.tolist())

    def state_space(self) -> tuple[NDArray[np.float64], ...]:
        """(A, B, C, D) of the delay-free part as a chain of first-order lags."""
        A, B, C = lag_chain(self.time_constants)
        return A, self.K * B, C, np.zeros((1, 1))

    def step_response(self, t: ArrayLike) -> NDArray[np.float64]:
        """Response to a unit step at t = 0, exact, dead time included.

        Parameters
        ----------
        t : array
            Sorted times [s].

        Returns
        -------
        ndarray
            Output deviation [output unit].
        """
        times = np.asarray(t, dtype=float)
        if times.size > 2 and times[0] == 0.0:
            dt = np.diff(times)
            if np.all(np.abs(dt - dt[0]) <= 1e-9 * dt[0]):
                # uniform grid from 0: the exact ZOH recursion as one lfilter pass
                shape = discretise(self.time_constants, self.delay, float(dt[0]))
                return self.K * shape.response(np.ones(times.size))
        A, B, C, _ = self.state_space()
        return lti.step_response(A, B, C, 0.0, times, delay=self.delay)

    def settling_time(self, band: float = 0.02) -> float:
        """Time for a unit step response to enter and stay within ``band`` of K [s].

        Examples
        --------
        >>> round(ProcessModel(K=1.0, T=1.0, delay=0.5).settling_time(), 3)
        4.412
        """
        horizon = self.delay + 12.0 * sum(self.time_constants)
        t = np.linspace(0.0, horizon, 24_001)
        return lti.settling_time(t, self.step_response(t), self.K, band)

    def as_dict(self) -> dict[str, float]:
        """Parameters as a plain dictionary (for JSON)."""
        return asdict(self)
