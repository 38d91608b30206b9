"""Torque balance of the motor–pump shaft."""

from __future__ import annotations


def shaft_acceleration(T_e: float, T_load: float, omega_m: float, J: float, B: float) -> float:
    r"""Angular acceleration of the shaft from its torque balance.

    .. math:: J_T \dot\omega_m = T_e - B_T\,\omega_m - T_{load}

    Parameters
    ----------
    T_e : float
        Electromagnetic torque [N·m].
    T_load : float
        Load torque of the pump [N·m], see :func:`fuelid.plant.pump.pump_torque`.
    omega_m : float
        Shaft speed [rad/s].
    J : float
        Inertia of motor, coupling and pump [kg·m²].
    B : float
        Viscous damping [N·m·s/rad].

    Returns
    -------
    float
        dω_m/dt [rad/s²].

    Examples
    --------
    >>> shaft_acceleration(10.0, 8.0, 100.0, 0.05, 0.01)
    20.0
    """
    return (T_e - B * omega_m - T_load) / J
