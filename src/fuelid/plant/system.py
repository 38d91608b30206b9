"""Assembly of the components: coefficients, nonlinear ODE, operating point, linearisation.

State vector (SI), in this order::

    x = [f, ω_m, p, q, q_m]
        f    drive output frequency                 [Hz]
        ω_m  shaft speed                            [rad/s]
        p    pump outlet pressure (gauge)           [Pa]
        q    line (and nozzle) flow                 [m³/s]
        q_m  flowmeter's lagged flow                [m³/s]

Input: u, the drive's command voltage [V]. Measured output: q_m delayed by the meter's τ.

Topology: the pump discharges into the line's lumped capacitance C at its outlet; the fuel column
(inductance L) is driven by the difference between p and the friction drop plus the nozzles'
pressure. With the line capacitance the hydraulic mode sits at 1–3 Hz: the nonlinear simulation
keeps it, the equivalent low-order model leaves it out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from fuelid.errors import OutOfRangeError
from fuelid.fuel import fuel_properties
from fuelid.plant.config import PlantConfig
from fuelid.plant.nozzle import orifice_pressure_drop, orifice_resistance
from fuelid.plant.pipeline import (
    darcy_friction_factor,
    laminar_resistance,
    pipe_capacitance,
    pipe_inductance,
    pipe_pressure_drop_slope,
)
from fuelid.plant.pump import leakage_coefficient, pump_torque

STATE_NAMES = ("f", "omega_m", "p", "q", "q_m")
STATE_UNITS = ("Hz", "rad/s", "Pa", "m^3/s", "m^3/s")
N_STATES = len(STATE_NAMES)
TWO_PI = 2.0 * math.pi


@dataclass(frozen=True, slots=True)
class PlantCoefficients:
    """SI numbers of the plant's ODE at one fuel temperature (everything the RHS needs).

    Build it with :func:`plant_coefficients`; the fields are documented there by symbol.
    """

    T_fuel: float
    rho: float
    mu: float
    u_min: float
    u_max: float
    f_min: float
    f_max: float
    K_f: float
    T_vfd: float
    max_rate: float | None
    K_T: float
    m_p: int
    J: float
    B: float
    D_rad: float
    eta_m: float
    C_p: float
    C_line: float
    L_line: float
    length: float
    d: float
    roughness: float
    friction_method: str
    Cd_A0: float
    p_back: float
    T_f: float
    delay: float
    # derived once so the ODE right-hand side is a handful of multiplications
    Re_per_flow: float = 0.0
    """Reynolds number per unit flow 4ρ/(π d μ) [s/m³]."""
    friction_per_flow2: float = 0.0
    """Δp_pipe/(f_D·q|q|) = (l/d)·ρ/2·(4/(π d²))² [Pa·s²/m⁶]."""
    R_laminar: float = 0.0
    """Hagen–Poiseuille resistance [Pa·s/m³]."""
    nozzle_per_flow2: float = 0.0
    """Δp_nozzle/(q|q|) = ρ/(2 (C_d A_0)²) [Pa·s²/m⁶]."""

    def __post_init__(self) -> None:
        area = math.pi * self.d**2 / 4.0
        object.__setattr__(self, "Re_per_flow", self.rho * self.d / (area * self.mu))
        object.__setattr__(
            self, "friction_per_flow2", (self.length / self.d) * 0.5 * self.rho / area**2
        )
        object.__setattr__(self, "R_laminar", laminar_resistance(self.mu, self.length, self.d))
        object.__setattr__(self, "nozzle_per_flow2", 0.5 * self.rho / self.Cd_A0**2)

    def frequency_command(self, u: float) -> float:
        """Commanded drive frequency [Hz] for command ``u`` [V], clipped to the drive range."""
        f = self.f_min + self.K_f * (u - self.u_min)
        return min(max(f, self.f_min), self.f_max)

    def line_pressure_drop(self, q: float) -> float:
        """Friction drop along the line plus nozzle pressure (with back pressure) [Pa].

        The same as :func:`~fuelid.plant.pipeline.pipe_pressure_drop` +
        :func:`~fuelid.plant.nozzle.orifice_pressure_drop` + back pressure, with the constant
        factors precomputed (this runs in the ODE's inner loop).
        """
        Re = self.Re_per_flow * abs(q)
        if Re < 1e-6:
            friction = self.R_laminar * q
        else:
            f_D = darcy_friction_factor(Re, self.roughness / self.d, self.friction_method)
            friction = f_D * self.friction_per_flow2 * q * abs(q)
        return friction + self.nozzle_per_flow2 * q * abs(q) + self.p_back

    def line_resistance(self, q: float) -> float:
        """Incremental resistance of line plus nozzles d(Δp)/dq at flow q [Pa·s/m³]."""
        return pipe_pressure_drop_slope(
            q, self.rho, self.mu, self.length, self.d, self.roughness, self.friction_method
        ) + orifice_resistance(q, self.rho, 1.0, self.Cd_A0)


def plant_coefficients(config: PlantConfig, T_fuel: float) -> PlantCoefficients:
    """Evaluate every temperature-dependent coefficient of the plant at fuel temperature T_fuel.

    Parameters
    ----------
    config : PlantConfig
        The plant.
    T_fuel : float
        Fuel temperature [K].

    Returns
    -------
    PlantCoefficients

    Raises
    ------
    OutOfRangeError
        If T_fuel lies outside the fuel correlation's range and the config does not allow
        extrapolation.
    """
    try:
        props = fuel_properties(
            T_fuel, config.fuel.name, allow_extrapolation=config.fuel.allow_extrapolation
        )
    except OutOfRangeError as exc:
        reason = str(exc).split("; pass allow_extrapolation")[0]
        raise OutOfRangeError(
            f"{reason} (to extrapolate, set allow_extrapolation = true in the plant config's "
            "[fuel] table)"
        ) from None
    vfd, motor, pump = config.vfd, config.motor, config.pump
    line, nozzle, meter = config.pipeline, config.nozzle, config.flowmeter
    return PlantCoefficients(
        T_fuel=T_fuel,
        rho=props.rho,
        mu=props.mu,
        u_min=vfd.u_min_V,
        u_max=vfd.u_max_V,
        f_min=vfd.f_min_Hz,
        f_max=vfd.f_max_Hz,
        K_f=vfd.K_f,
        T_vfd=vfd.lag_s,
        max_rate=vfd.max_rate_Hz_per_s,
        K_T=motor.K_T,
        m_p=motor.pole_pairs,
        J=motor.inertia_kg_m2,
        B=motor.damping_N_m_s_per_rad,
        D_rad=pump.D_p / TWO_PI,
        eta_m=pump.mechanical_efficiency,
        C_p=leakage_coefficient(props.mu, pump.C_p_ref, pump.mu_ref),
        C_line=pipe_capacitance(line.length_m, line.d, line.beta),
        L_line=pipe_inductance(props.rho, line.length_m, line.d),
        length=line.length_m,
        d=line.d,
        roughness=line.roughness,
        friction_method=line.friction_method,
        Cd_A0=nozzle.discharge_coefficient * nozzle.A0,
        p_back=nozzle.p_back,
        T_f=meter.time_constant_s,
        delay=meter.delay_s,
    )


def plant_rhs(t: float, x: NDArray[np.float64], u: float, c: PlantCoefficients) -> list[float]:
    """The nonlinear plant ODE dx/dt = f(t, x, u, params).

    Parameters
    ----------
    t : float
        Time [s] (the plant is time-invariant; kept for the solvers' signature).
    x : array, shape (5,)
        State ``[f, ω_m, p, q, q_m]`` in SI units (see the module docstring).
    u : float
        Drive command [V], held constant over the integration step.
    c : PlantCoefficients
        The plant at the present fuel temperature.

    Returns
    -------
    list of float
        dx/dt.
    """
    f, omega, p, q, q_m = x
    df = (c.frequency_command(u) - f) / c.T_vfd
    if c.max_rate is not None:
        df = min(max(df, -c.max_rate), c.max_rate)
    torque_e = c.K_T * (TWO_PI * f / c.m_p - omega)
    domega = (torque_e - c.B * omega - c.D_rad * p / c.eta_m) / c.J
    q_pump = c.D_rad * omega - c.C_p * p
    dp = (q_pump - q) / c.C_line
    dq = (p - c.line_pressure_drop(q)) / c.L_line
    dq_m = (q - q_m) / c.T_f if c.T_f > 0.0 else 0.0
    return [df, domega, dp, dq, dq_m]


def plant_jacobian(
    t: float, x: NDArray[np.float64], u: float, c: PlantCoefficients
) -> NDArray[np.float64]:
    """Analytic Jacobian ∂f/∂x of :func:`plant_rhs` (for the stiff solver and linearisation).

    The only numerical piece is the pipe friction slope (a central difference of the friction
    correlation). Where the drive's rate limit binds, the frequency row is zero.

    Parameters
    ----------
    t, x, u, c
        As in :func:`plant_rhs`.

    Returns
    -------
    ndarray, shape (5, 5)
    """
    jac = np.zeros((N_STATES, N_STATES))
    f, q = x[0], x[3]
    rate = (c.frequency_command(u) - f) / c.T_vfd
    if c.max_rate is None or abs(rate) < c.max_rate:
        jac[0, 0] = -1.0 / c.T_vfd
    jac[1, 0] = c.K_T * TWO_PI / (c.m_p * c.J)
    jac[1, 1] = -(c.K_T + c.B) / c.J
    jac[1, 2] = -c.D_rad / (c.eta_m * c.J)
    jac[2, 1] = c.D_rad / c.C_line
    jac[2, 2] = -c.C_p / c.C_line
    jac[2, 3] = -1.0 / c.C_line
    jac[3, 2] = 1.0 / c.L_line
    jac[3, 3] = -c.line_resistance(q) / c.L_line
    if c.T_f > 0.0:
        jac[4, 3] = 1.0 / c.T_f
        jac[4, 4] = -1.0 / c.T_f
    return jac


def input_jacobian(u: float, c: PlantCoefficients) -> NDArray[np.float64]:
    """∂f/∂u [per V]: only the drive's frequency equation depends on the command.

    Inside the signal range the slope is K_f/T_vfd; outside it the drive clips and the slope is 0.
    At the range ends the one-sided slope into the range is used.
    """
    b = np.zeros((N_STATES, 1))
    if c.u_min <= u <= c.u_max:
        b[0, 0] = c.K_f / c.T_vfd
    return b


@dataclass(frozen=True)
class OperatingPoint:
    """Steady state of the plant for a constant command and fuel temperature (SI units)."""

    u: float
    """Command [V]."""
    T_fuel: float
    """Fuel temperature [K]."""
    f: float
    """Drive frequency [Hz]."""
    omega_m: float
    """Shaft speed [rad/s]."""
    q: float
    """Flow delivered to the nozzles (= measured flow at rest) [m³/s]."""
    p_pump: float
    """Pump outlet pressure (gauge) [Pa]."""
    p_nozzle: float
    """Pressure upstream of the nozzles (gauge) [Pa]."""
    torque: float
    """Electromagnetic (shaft) torque [N·m]."""
    q_leak: float
    """Pump internal leakage [m³/s]."""
    reynolds: float
    """Reynolds number in the line [-]."""
    mass_balance: float
    """Residual of q_geometric − q_leak − q [m³/s] (zero to rounding)."""
    torque_balance: float
    """Residual of T_e − B·ω − T_pump [N·m] (zero to rounding)."""

    @property
    def state(self) -> NDArray[np.float64]:
        """State vector ``[f, ω_m, p, q, q_m]`` at rest."""
        return np.array([self.f, self.omega_m, self.p_pump, self.q, self.q])

    @property
    def speed_rpm(self) -> float:
        """Shaft speed [rpm]."""
        return self.omega_m * 60.0 / TWO_PI


def check_command(u: float, c: PlantCoefficients) -> None:
    """Refuse a command outside the drive's signal range (the linear model is meaningless there)."""
    if not (math.isfinite(u) and c.u_min <= u <= c.u_max):
        raise OutOfRangeError(
            f"command u = {u:g} V lies outside the drive's signal range {c.u_min:g}…{c.u_max:g} V"
        )


def steady_state(u: float, c: PlantCoefficients) -> OperatingPoint:
    """Solve the steady state for command ``u`` with the plant coefficients ``c``.

    With every derivative zero the state reduces to one equation in the flow q: the line fixes
    the pump pressure p(q), the torque balance then fixes the shaft speed ω(p), and the pump's
    flow equation must deliver q. The residual is monotonic in q, so Brent's method on a
    bracket [0, geometric flow at synchronous speed] finds the unique root.

    Parameters
    ----------
    u : float
        Command [V].
    c : PlantCoefficients
        Plant at the fuel temperature of interest.

    Returns
    -------
    OperatingPoint
    """
    f = c.frequency_command(u)
    omega_sync = TWO_PI * f / c.m_p

    def shaft_speed(p: float) -> float:
        # K_T(ω_s − ω) = B ω + D_rad p/η_m  →  ω
        return (c.K_T * omega_sync - c.D_rad * p / c.eta_m) / (c.K_T + c.B)

    def residual(q: float) -> float:
        p = c.line_pressure_drop(q)
        return c.D_rad * shaft_speed(p) - c.C_p * p - q

    q_hi = c.D_rad * omega_sync
    if q_hi <= 0.0:
        q = 0.0
    else:
        q = float(
            scipy.optimize.brentq(residual, 0.0, q_hi, xtol=1e-15, rtol=4 * np.finfo(float).eps)
        )
    p = c.line_pressure_drop(q)
    omega = shaft_speed(p)
    torque_e = c.K_T * (omega_sync - omega)
    q_leak = c.C_p * p
    return OperatingPoint(
        u=u,
        T_fuel=c.T_fuel,
        f=f,
        omega_m=omega,
        q=q,
        p_pump=p,
        p_nozzle=orifice_pressure_drop(q, c.rho, 1.0, c.Cd_A0) + c.p_back,
        torque=torque_e,
        q_leak=q_leak,
        reynolds=4.0 * c.rho * q / (math.pi * c.d * c.mu),
        mass_balance=c.D_rad * omega - q_leak - q,
        torque_balance=torque_e - c.B * omega - pump_torque(p, TWO_PI * c.D_rad, c.eta_m),
    )


def operating_point(config: PlantConfig, u: float, T_fuel: float) -> OperatingPoint:
    """Steady operating point of a plant for command ``u`` [V] and fuel temperature [K].

    Examples
    --------
    >>> from fuelid.plant.config import load_plant_config
    >>> op = operating_point(load_plant_config(), u=5.0, T_fuel=293.15)
    >>> abs(op.mass_balance) < 1e-15 and abs(op.torque_balance) < 1e-9
    True
    """
    c = plant_coefficients(config, T_fuel)
    check_command(u, c)
    return steady_state(u, c)
