"""Torque balance of the motor–pump shaft (``docs/explanation/physics.md`` §3.3).

Its parameters, the inertia J_T and the viscous damping B_T, are read from the plant file's
``[motor]`` section (:meth:`fuelid.plant._motor.MotorConfig.shaft_coefficients`).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class ShaftCoefficients:
    """The shaft's parameters in SI, as the plant ODE uses them."""

    J: float
    """Inertia of motor, coupling and pump J_T [kg·m²]."""
    B: float
    """Viscous damping B_T [N·m·s/rad]."""


def shaft_acceleration(T_e: float, T_load: float, omega_m: float, J: float, B: float) -> float:
    r"""Angular acceleration of the shaft from its torque balance.

    .. math:: J_T \dot\omega_m = T_e - B_T\,\omega_m - T_{load}

    Parameters
    ----------
    T_e : float
        Electromagnetic torque [N·m], see :func:`fuelid.plant._motor.electromagnetic_torque`.
    T_load : float
        Load torque of the pump [N·m], see :func:`fuelid.plant._pump.pump_torque`.
    omega_m : float
        Shaft speed [rad/s].
    J : float
        Inertia of motor, coupling and pump [kg·m²], positive.
    B : float
        Viscous damping [N·m·s/rad], zero or positive.

    Returns
    -------
    float
        dω_m/dt [rad/s²].

    Notes
    -----
    A rigid shaft (no torsional mode) and friction proportional to speed.

    References
    ----------
    Ogata, K., *Modern Control Engineering*, 5th ed., Prentice Hall 2010, ch. 3 (rotational
    mechanical systems); ``docs/explanation/physics.md`` §3.3.

    Examples
    --------
    >>> shaft_acceleration(10.0, 8.0, 100.0, 0.05, 0.01)
    20.0
    """
    return (T_e - B * omega_m - T_load) / J


def shaft_acceleration_partials(J: float, B: float) -> tuple[float, float, float]:
    r"""Partial derivatives of :func:`shaft_acceleration` (constant: the balance is linear).

    .. math:: \left(\frac{\partial \dot\omega_m}{\partial T_e},\
              \frac{\partial \dot\omega_m}{\partial T_{load}},\
              \frac{\partial \dot\omega_m}{\partial \omega_m}\right)
              = \left(\frac{1}{J_T},\ -\frac{1}{J_T},\ -\frac{B_T}{J_T}\right)

    Parameters
    ----------
    J, B : float
        As in :func:`shaft_acceleration`.

    Returns
    -------
    tuple of float
        (∂ω̇/∂T_e [1/(kg·m²)], ∂ω̇/∂T_load [1/(kg·m²)], ∂ω̇/∂ω_m [1/s]).

    Examples
    --------
    >>> shaft_acceleration_partials(0.5, 0.1)
    (2.0, -2.0, -0.2)
    """
    return (1.0 / J, -1.0 / J, -B / J)
