"""Three-phase induction motor fed at constant volts per hertz, torque linear in slip.

The electromagnetic transients are far faster than the hydraulics and are neglected (the article
does the same). Near the operating point the steady-state equivalent circuit gives a torque that
is linear in the slip speed,

    T_e = K_T · (ω_1/m_p − ω_m),    ω_1 = 2π f,

with the same K_T at every frequency because the drive keeps U_1/f constant. K_T comes from the
nameplate (rated torque over rated slip speed) or, equivalently, from the circuit parameters.
See ``docs/explanation/physics.md`` §3.2. The motor section also carries the shaft's inertia and
damping, which :mod:`fuelid.plant._shaft` uses.
"""

from __future__ import annotations

from dataclasses import dataclass

from pydantic import Field, model_validator

from fuelid.plant._section import Section
from fuelid.plant._shaft import ShaftCoefficients
from fuelid.units import RAD_S_PER_RPM, TWO_PI, W_PER_KW


@dataclass(frozen=True, slots=True)
class MotorCoefficients:
    """The motor's parameters in SI (:meth:`MotorConfig.coefficients`)."""

    K_T: float
    """Slip torque constant [N·m·s/rad]."""
    m_p: int
    """Pole pairs [-]."""


MIN_RATED_SLIP = 1e-9
"""Smallest rated slip 1 − n_rated/n_sync accepted [-]: a nameplate speed at the synchronous
speed, to the rounding of the rpm → rad/s conversion, is refused (K_T would be unbounded)."""
MAX_RATED_SLIP = 0.3
"""Largest rated slip accepted [-]; more means wrong pole pairs or rated frequency."""


class MotorConfig(Section):
    """Nameplate and mechanical data of the motor (TOML section ``[motor]``)."""

    rated_power_kW: float = Field(gt=0.0, le=10_000.0, description="rated shaft power [kW]")
    rated_speed_rpm: float = Field(gt=0.0, description="rated (full-load) speed [rpm]")
    rated_frequency_Hz: float = Field(50.0, gt=0.0, description="rated supply frequency [Hz]")
    pole_pairs: int = Field(ge=1, le=12, description="number of pole pairs m_p [-]")
    inertia_kg_m2: float = Field(
        gt=0.0, description="inertia of motor, coupling and pump together J_T [kg·m²]"
    )
    damping_N_m_s_per_rad: float = Field(
        0.0, ge=0.0, description="viscous damping of the shaft B_T [N·m·s/rad]"
    )

    @model_validator(mode="after")
    def _check_slip(self) -> MotorConfig:
        # the rated slip from the same speeds in rad/s that slip_torque_constant divides by
        omega_sync = synchronous_speed(self.rated_frequency_Hz, self.pole_pairs)
        slip = 1.0 - self.rated_speed_rpm * RAD_S_PER_RPM / omega_sync
        if not slip > MIN_RATED_SLIP:
            raise ValueError(
                f"rated_speed_rpm ({self.rated_speed_rpm:g}) must be below the synchronous speed "
                f"{omega_sync / RAD_S_PER_RPM:g} rpm of {self.pole_pairs} pole pairs at "
                f"{self.rated_frequency_Hz:g} Hz"
            )
        if slip > MAX_RATED_SLIP:
            raise ValueError(
                f"rated_speed_rpm ({self.rated_speed_rpm:g}) implies a rated slip over "
                f"{100.0 * MAX_RATED_SLIP:g} %; check pole_pairs and rated_frequency_Hz"
            )
        return self

    @property
    def K_T(self) -> float:
        """Slip torque constant [N·m·s/rad], from the nameplate."""
        return slip_torque_constant(
            self.rated_power_kW * W_PER_KW,
            self.rated_speed_rpm,
            self.rated_frequency_Hz,
            self.pole_pairs,
        )

    def coefficients(self) -> MotorCoefficients:
        """The motor's electromagnetic parameters in SI."""
        return MotorCoefficients(K_T=self.K_T, m_p=self.pole_pairs)

    def shaft_coefficients(self) -> ShaftCoefficients:
        """Inertia and damping of the motor–pump shaft in SI."""
        return ShaftCoefficients(J=self.inertia_kg_m2, B=self.damping_N_m_s_per_rad)


def synchronous_speed(f: float, m_p: int) -> float:
    r"""Mechanical synchronous speed of an induction motor fed at frequency ``f``.

    .. math:: \omega_{sync} = \frac{2\pi f}{m_p}

    Parameters
    ----------
    f : float
        Stator frequency [Hz].
    m_p : int
        Pole pairs [-], at least 1.

    Returns
    -------
    float
        ω_sync [rad/s].

    References
    ----------
    Fitzgerald, Kingsley & Umans, *Electric Machinery*, 6th ed., ch. 4 (rotating magnetic
    fields).

    Examples
    --------
    Two pole pairs on 50 Hz turn at 1500 rpm:

    >>> from fuelid.units import RAD_S_PER_RPM
    >>> round(synchronous_speed(50.0, 2) / RAD_S_PER_RPM, 9)
    1500.0
    """
    return TWO_PI * f / m_p


def slip_torque_constant(P_rated: float, n_rated: float, f_rated: float, m_p: int) -> float:
    r"""Slip torque constant of an induction motor from its nameplate.

    .. math:: K_T = \frac{T_{rated}}{\omega_{sync} - \omega_{rated}},\qquad
              T_{rated} = \frac{P_{rated}}{\omega_{rated}},\qquad
              \omega_{sync} = \frac{2\pi f_{rated}}{m_p}

    Parameters
    ----------
    P_rated : float
        Rated shaft power [W].
    n_rated : float
        Rated speed [rpm].
    f_rated : float
        Rated supply frequency [Hz].
    m_p : int
        Pole pairs [-].

    Returns
    -------
    float
        K_T [N·m·s/rad], torque per unit of mechanical slip speed.

    Notes
    -----
    Valid near the operating point, where torque is linear in slip (well below breakdown torque).

    References
    ----------
    Fitzgerald, Kingsley & Umans, *Electric Machinery*, 6th ed., ch. 6 (induction machine
    equivalent circuit, small-slip region).

    Examples
    --------
    A 7.5 kW, 4-pole (2 pole pairs), 1450 rpm motor on 50 Hz: 49.4 N·m rated torque over a
    5.24 rad/s slip speed.

    >>> round(slip_torque_constant(7500.0, 1450.0, 50.0, 2), 3)
    9.433
    """
    omega_rated = n_rated * RAD_S_PER_RPM
    omega_sync = synchronous_speed(f_rated, m_p)
    return (P_rated / omega_rated) / (omega_sync - omega_rated)


def torque_constant_from_circuit(K_int: float, R_re: float, m_p: int) -> float:
    r"""Slip torque constant from the equivalent circuit at constant volts per hertz.

    With phase voltage :math:`U_1 = K_{int} f` and small slip, the torque
    :math:`T_e = 3 m_p U_1^2 s / (\omega_1 R_{re})` becomes linear in the mechanical slip speed:

    .. math:: K_T = \frac{3\, m_p^2\, K_{int}^2}{4\pi^2 R_{re}}

    Parameters
    ----------
    K_int : float
        Volts-per-hertz ratio of the drive, phase voltage [V/Hz].
    R_re : float
        Equivalent rotor resistance referred to the stator [Ω].
    m_p : int
        Pole pairs [-].

    Returns
    -------
    float
        K_T [N·m·s/rad], consistent with :func:`slip_torque_constant`.

    Examples
    --------
    230 V phase at 50 Hz (4.6 V/Hz), 2 pole pairs, 0.5 Ω rotor:

    >>> round(torque_constant_from_circuit(4.6, 0.5, 2), 3)
    12.864
    """
    return 3.0 * m_p**2 * K_int**2 / (TWO_PI**2 * R_re)


def electromagnetic_torque(f: float, omega_m: float, K_T: float, m_p: int) -> float:
    r"""Electromagnetic torque, linear in slip speed.

    .. math:: T_e = K_T\left(\omega_{sync}(f) - \omega_m\right),
              \qquad \omega_{sync} = \frac{2\pi f}{m_p}

    Parameters
    ----------
    f : float
        Stator frequency [Hz].
    omega_m : float
        Mechanical shaft speed [rad/s].
    K_T : float
        Slip torque constant [N·m·s/rad].
    m_p : int
        Pole pairs [-].

    Returns
    -------
    float
        Torque [N·m]; negative (braking) above synchronous speed.

    Notes
    -----
    Valid near the operating point, at small slip (well below breakdown torque).

    References
    ----------
    Fitzgerald, Kingsley & Umans, *Electric Machinery*, 6th ed., ch. 6;
    ``docs/explanation/physics.md`` §3.2.

    Examples
    --------
    At synchronous speed the motor gives no torque:

    >>> from fuelid.units import TWO_PI
    >>> electromagnetic_torque(50.0, TWO_PI * 25.0, 9.43, 2)
    0.0
    """
    return K_T * (synchronous_speed(f, m_p) - omega_m)


def electromagnetic_torque_partials(K_T: float, m_p: int) -> tuple[float, float]:
    r"""Partial derivatives of :func:`electromagnetic_torque` (constant: the law is linear).

    .. math:: \left(\frac{\partial T_e}{\partial f},\ \frac{\partial T_e}{\partial \omega_m}\right)
              = \left(\frac{2\pi K_T}{m_p},\ -K_T\right)

    Parameters
    ----------
    K_T : float
        Slip torque constant [N·m·s/rad].
    m_p : int
        Pole pairs [-].

    Returns
    -------
    tuple of float
        (∂T_e/∂f [N·m/Hz], ∂T_e/∂ω_m [N·m·s/rad]).

    Examples
    --------
    >>> dT_df, dT_domega = electromagnetic_torque_partials(10.0, 2)
    >>> round(dT_df, 6), dT_domega
    (31.415927, -10.0)
    """
    return (K_T * synchronous_speed(1.0, m_p), -K_T)
