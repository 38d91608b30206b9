"""Variable-frequency drive: the 1–5 V command to the stator frequency, with the drive's ramp.

The drive maps the standard signal linearly onto ``f_min … f_max`` and clips it there. Pump drives
are set with a minimum frequency (lubrication, motor cooling), so at the bottom of the signal range
the pump already delivers. The drive's acceleration ramp dominates the response time of a small
pump set; it is modelled as a first-order lag (which linearises) with an optional rate limit
(which does not, and is therefore left out of the linear model). See ``docs/explanation/physics.md``
§3.1.

The laws (:func:`vfd_frequency_command`, :func:`vfd_frequency_rate`) and their derivatives
(:func:`vfd_command_slope`, :func:`vfd_frequency_rate_partials`) are the only place the drive's
parameters enter the plant model; :class:`VFDCoefficients` carries them in SI.
"""

from __future__ import annotations

from dataclasses import dataclass

from pydantic import Field, model_validator

from fuelid.plant._section import Section


@dataclass(frozen=True, slots=True)
class VFDCoefficients:
    """The drive's parameters in SI, as the plant ODE uses them (:meth:`VFDConfig.coefficients`)."""

    u_min: float
    """Command at the bottom of the signal range [V]."""
    u_max: float
    """Command at the top of the signal range [V]."""
    f_min: float
    """Output frequency at ``u_min`` [Hz]."""
    f_max: float
    """Output frequency at ``u_max`` [Hz]."""
    lag: float
    """Time constant T_vfd of the acceleration lag [s]."""
    max_rate: float | None
    """Ramp-rate limit r_max [Hz/s]; None for none."""


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
        """Drive gain, frequency per volt [Hz/V] (:func:`vfd_gain`)."""
        return vfd_gain(self.u_min_V, self.u_max_V, self.f_min_Hz, self.f_max_Hz)

    def coefficients(self) -> VFDCoefficients:
        """The drive's parameters in SI."""
        return VFDCoefficients(
            u_min=self.u_min_V,
            u_max=self.u_max_V,
            f_min=self.f_min_Hz,
            f_max=self.f_max_Hz,
            lag=self.lag_s,
            max_rate=self.max_rate_Hz_per_s,
        )


def vfd_gain(u_min: float, u_max: float, f_min: float, f_max: float) -> float:
    r"""Drive gain: the signal range mapped linearly onto the frequency range.

    .. math:: K_f = \frac{f_{max} - f_{min}}{u_{max} - u_{min}}

    Parameters
    ----------
    u_min, u_max : float
        Signal range of the drive input [V], ``u_max > u_min``.
    f_min, f_max : float
        Output frequency at the ends of the signal range [Hz].

    Returns
    -------
    float
        K_f [Hz/V].

    References
    ----------
    ``docs/explanation/physics.md`` §3.1; IEC 60381-2 (the 1–5 V analogue signal).

    Examples
    --------
    >>> vfd_gain(1.0, 5.0, 10.0, 50.0)
    10.0
    """
    return (f_max - f_min) / (u_max - u_min)


def vfd_frequency_command(
    u: float, u_min: float, u_max: float, f_min: float, f_max: float
) -> float:
    r"""Frequency the drive is commanded to, from the control voltage.

    .. math:: f^* = \mathrm{clip}\left(f_{min} + K_f (u - u_{min}),\ f_{min},\ f_{max}\right)

    with :math:`K_f` from :func:`vfd_gain`.

    Parameters
    ----------
    u : float
        Control voltage [V]; any value (outside the signal range the drive clips).
    u_min, u_max : float
        Signal range of the drive input [V].
    f_min, f_max : float
        Output frequency at the ends of the signal range [Hz].

    Returns
    -------
    float
        Commanded stator frequency [Hz]; below ``u_min`` the drive holds ``f_min``, above
        ``u_max`` it holds ``f_max``.

    References
    ----------
    ``docs/explanation/physics.md`` §3.1.

    Examples
    --------
    >>> [vfd_frequency_command(u, 1.0, 5.0, 10.0, 50.0) for u in (0.5, 1.0, 1.5, 5.0, 6.0)]
    [10.0, 10.0, 15.0, 50.0, 50.0]
    """
    f = f_min + vfd_gain(u_min, u_max, f_min, f_max) * (u - u_min)
    if f < f_min:
        return f_min
    return f_max if f > f_max else f


def vfd_command_slope(u: float, u_min: float, u_max: float, f_min: float, f_max: float) -> float:
    r"""Derivative of :func:`vfd_frequency_command` with respect to the command.

    .. math:: \frac{\partial f^*}{\partial u} = K_f \text{ for } u_{min} \le u \le u_{max},
              \qquad 0 \text{ outside (the drive clips)}

    At the ends of the signal range the one-sided slope into the range is returned.

    Parameters
    ----------
    u : float
        Control voltage [V].
    u_min, u_max, f_min, f_max : float
        As in :func:`vfd_frequency_command`.

    Returns
    -------
    float
        ∂f*/∂u [Hz/V].

    Examples
    --------
    >>> [vfd_command_slope(u, 1.0, 5.0, 10.0, 50.0) for u in (0.5, 1.0, 3.0, 5.0, 6.0)]
    [0.0, 10.0, 10.0, 10.0, 0.0]
    """
    if u_min <= u <= u_max:
        return vfd_gain(u_min, u_max, f_min, f_max)
    return 0.0


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
        Commanded frequency f* [Hz], see :func:`vfd_frequency_command`.
    lag : float
        Time constant T_vfd of the acceleration lag [s], positive.
    max_rate : float or None
        Ramp-rate limit r_max [Hz/s]; ``None`` for none.

    Returns
    -------
    float
        df/dt [Hz/s].

    References
    ----------
    ``docs/explanation/physics.md`` §3.1.

    Examples
    --------
    >>> vfd_frequency_rate(10.0, 15.0, 1.0)
    5.0
    >>> vfd_frequency_rate(10.0, 50.0, 1.0, max_rate=20.0)
    20.0
    """
    rate = (f_command - f) / lag
    if max_rate is not None:
        if rate > max_rate:
            return max_rate
        if rate < -max_rate:
            return -max_rate
    return rate


def vfd_frequency_rate_partials(
    f: float, f_command: float, lag: float, max_rate: float | None = None
) -> tuple[float, float]:
    r"""Partial derivatives of :func:`vfd_frequency_rate`.

    .. math:: \left(\frac{\partial \dot f}{\partial f},\ \frac{\partial \dot f}{\partial f^*}\right)
              = \left(-\frac{1}{T_{vfd}},\ \frac{1}{T_{vfd}}\right)
              \text{ while } |f^* - f| < r_{max} T_{vfd}, \qquad (0,\ 0) \text{ where the ramp
              limit binds}

    Parameters
    ----------
    f, f_command, lag, max_rate
        As in :func:`vfd_frequency_rate`.

    Returns
    -------
    tuple of float
        (∂ḟ/∂f [1/s], ∂ḟ/∂f* [1/s]).

    Examples
    --------
    >>> vfd_frequency_rate_partials(10.0, 15.0, 0.5)
    (-2.0, 2.0)
    >>> vfd_frequency_rate_partials(10.0, 50.0, 1.0, max_rate=20.0)
    (0.0, 0.0)
    """
    if max_rate is not None and not abs(f_command - f) / lag < max_rate:
        return (0.0, 0.0)
    return (-1.0 / lag, 1.0 / lag)
