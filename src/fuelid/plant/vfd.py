"""Variable-frequency drive: the 1–5 V command to the stator frequency, with the drive's ramp.

The drive maps the standard signal linearly onto ``f_min … f_max`` and clips it there. Pump drives
are set with a minimum frequency (lubrication, motor cooling), so at the bottom of the signal range
the pump already delivers. The drive's acceleration ramp dominates the response time of a small
pump set; it is modelled as a first-order lag (which linearises) with an optional rate limit
(which does not, and is therefore left out of the linear model).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydantic import Field, model_validator

from fuelid.plant._section import Section


class VFDConfig(Section):
    """Parameters of the drive (TOML section ``[vfd]``)."""

    u_min_V: float = Field(1.0, description="command at the bottom of the signal range [V]")
    u_max_V: float = Field(5.0, description="command at the top of the signal range [V]")
    f_min_Hz: float = Field(
        ge=0.0, description="output frequency at u_min_V (minimum frequency) [Hz]"
    )
    f_max_Hz: float = Field(gt=0.0, le=400.0, description="output frequency at u_max_V [Hz]")
    lag_s: float = Field(gt=0.0, le=60.0, description="time constant of the acceleration lag [s]")
    max_rate_Hz_per_s: float | None = Field(
        None, gt=0.0, description="optional ramp-rate limit of the output frequency [Hz/s]"
    )

    @model_validator(mode="after")
    def _check_ranges(self) -> VFDConfig:
        if not self.u_max_V > self.u_min_V:
            raise ValueError("u_max_V must be greater than u_min_V")
        if not self.f_max_Hz > self.f_min_Hz:
            raise ValueError("f_max_Hz must be greater than f_min_Hz")
        return self

    @property
    def K_f(self) -> float:
        """Drive gain, frequency per volt [Hz/V]."""
        return (self.f_max_Hz - self.f_min_Hz) / (self.u_max_V - self.u_min_V)


def vfd_frequency_command(
    u: ArrayLike, u_min: float, u_max: float, f_min: float, f_max: float
) -> NDArray[np.float64]:
    r"""Frequency the drive is commanded to, from the control voltage.

    .. math:: f^* = \mathrm{clip}\left(f_{min} + K_f (u - u_{min}),\ f_{min},\ f_{max}\right),
              \qquad K_f = \frac{f_{max} - f_{min}}{u_{max} - u_{min}}

    Parameters
    ----------
    u : float or array
        Control voltage [V].
    u_min, u_max : float
        Signal range of the drive input [V].
    f_min, f_max : float
        Output frequency at the ends of the signal range [Hz].

    Returns
    -------
    ndarray
        Commanded stator frequency [Hz]; below ``u_min`` the drive holds ``f_min``, above
        ``u_max`` it holds ``f_max``.

    Examples
    --------
    >>> vfd_frequency_command([0.5, 1.0, 1.5, 5.0, 6.0], 1.0, 5.0, 10.0, 50.0).tolist()
    [10.0, 10.0, 15.0, 50.0, 50.0]
    """
    K_f = (f_max - f_min) / (u_max - u_min)
    return np.clip(f_min + K_f * (np.asarray(u, dtype=float) - u_min), f_min, f_max)


def vfd_frequency_rate(
    f: float, f_command: float, lag: float, max_rate: float | None = None
) -> float:
    r"""Rate of change of the drive's output frequency (first-order ramp lag).

    .. math:: \dot f = \mathrm{clip}\left(\frac{f^* - f}{T_{vfd}},\ -r_{max},\ r_{max}\right)

    Parameters
    ----------
    f : float
        Present output frequency [Hz].
    f_command : float
        Commanded frequency [Hz].
    lag : float
        Time constant of the acceleration lag [s].
    max_rate : float or None
        Ramp-rate limit [Hz/s]; ``None`` for none.

    Returns
    -------
    float
        df/dt [Hz/s].

    Examples
    --------
    >>> vfd_frequency_rate(10.0, 15.0, 1.0)
    5.0
    >>> vfd_frequency_rate(10.0, 50.0, 1.0, max_rate=20.0)
    20.0
    """
    rate = (f_command - f) / lag
    if max_rate is not None:
        rate = min(max(rate, -max_rate), max_rate)
    return rate
