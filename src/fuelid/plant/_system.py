"""Assembly of the components: coefficients, nonlinear ODE, operating point, linearisation.

State vector (SI), in this order::

    x = [f, ω_m, p, q, q_m]
        f    drive output frequency                 [Hz]
        ω_m  shaft speed                            [rad/s]
        p    pump outlet pressure (gauge)           [Pa]
        q    line (and nozzle) flow                 [m³/s]
        q_m  flowmeter's lagged flow                [m³/s]

Input: u, the drive's command voltage [V]. Measured output: q_m delayed by the meter's τ (q itself
when the meter has no lag, :func:`measured_state`).

Topology: the pump discharges into the line's lumped capacitance C at its outlet; the fuel column
(inductance L) is driven by the difference between p and the friction drop plus the nozzles'
pressure. With the line capacitance the hydraulic mode sits at 1–3 Hz: the nonlinear simulation
keeps it, the equivalent low-order model leaves it out. See ``docs/explanation/physics.md`` §4.

This module writes no physical law itself: the right-hand side, its Jacobian and the steady state
are composed of the law functions of the component modules (:mod:`~fuelid.plant._vfd`,
:mod:`~fuelid.plant._motor`, :mod:`~fuelid.plant._shaft`, :mod:`~fuelid.plant._pump`,
:mod:`~fuelid.plant._pipeline`, :mod:`~fuelid.plant._nozzle`, :mod:`~fuelid.plant._flowmeter`) and
of the derivative functions next to them, fed with each component's SI parameter block built
once per fuel temperature by :func:`plant_coefficients`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from fuelid.errors import OutOfRangeError
from fuelid.fuel import fuel_properties
from fuelid.plant._config import PlantConfig
from fuelid.plant._flowmeter import FlowmeterCoefficients, flowmeter_rate, flowmeter_rate_partials
from fuelid.plant._motor import (
    MotorCoefficients,
    electromagnetic_torque,
    electromagnetic_torque_partials,
    synchronous_speed,
)
from fuelid.plant._nozzle import NozzleCoefficients, nozzle_inlet_pressure, orifice_resistance
from fuelid.plant._pipeline import (
    PipelineCoefficients,
    pipe_flow_rate,
    pipe_flow_rate_partials,
    pipe_pressure_drop,
    pipe_pressure_drop_slope,
    pipe_pressure_rate,
    pipe_pressure_rate_partials,
    reynolds_number,
)
from fuelid.plant._pump import (
    PumpCoefficients,
    pump_flow,
    pump_flow_partials,
    pump_torque,
    pump_torque_slope,
)
from fuelid.plant._shaft import ShaftCoefficients, shaft_acceleration, shaft_acceleration_partials
from fuelid.plant._vfd import (
    VFDCoefficients,
    vfd_command_slope,
    vfd_frequency_command,
    vfd_frequency_rate,
    vfd_frequency_rate_partials,
)
from fuelid.units import RAD_S_PER_RPM

STATE_NAMES = ("f", "omega_m", "p", "q", "q_m")
STATE_UNITS = ("Hz", "rad/s", "Pa", "m^3/s", "m^3/s")
N_STATES = len(STATE_NAMES)
StateVector = NDArray[np.float64] | Sequence[float]
"""A state ``[f, ω_m, p, q, q_m]`` as the ODE solvers pass it (an array) or as a plain sequence."""


@dataclass(frozen=True, slots=True)
class PlantCoefficients:
    """The plant's parameters in SI at one fuel temperature: one block per component.

    Build it with :func:`plant_coefficients`. Each block is made by its component's config section
    (``VFDConfig.coefficients()`` …) and read only by that component's law functions, which
    :func:`plant_rhs`, :func:`plant_jacobian` and :func:`steady_state` compose.
    """

    T_fuel: float
    """Fuel temperature [K]."""
    rho: float
    """Fuel density [kg/m³]."""
    mu: float
    """Fuel dynamic viscosity [Pa·s]."""
    vfd: VFDCoefficients
    motor: MotorCoefficients
    shaft: ShaftCoefficients
    pump: PumpCoefficients
    line: PipelineCoefficients
    nozzle: NozzleCoefficients
    meter: FlowmeterCoefficients

    @property
    def u_min(self) -> float:
        """Command at the bottom of the drive's signal range [V]."""
        return self.vfd.u_min

    @property
    def u_max(self) -> float:
        """Command at the top of the drive's signal range [V]."""
        return self.vfd.u_max

    @property
    def T_f(self) -> float:
        """Flowmeter lag [s] (0: none)."""
        return self.meter.T_f

    @property
    def delay(self) -> float:
        """Flowmeter plus PLC dead time [s]."""
        return self.meter.delay


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
    rho, mu = float(props.rho), float(props.mu)
    return PlantCoefficients(
        T_fuel=T_fuel,
        rho=rho,
        mu=mu,
        vfd=config.vfd.coefficients(),
        motor=config.motor.coefficients(),
        shaft=config.motor.shaft_coefficients(),
        pump=config.pump.coefficients(mu),
        line=config.pipeline.coefficients(rho, mu),
        nozzle=config.nozzle.coefficients(rho),
        meter=config.flowmeter.coefficients(),
    )


def measured_state(c: PlantCoefficients) -> int:
    """Index of the state the flowmeter reports: q_m, or the line flow q when T_f = 0."""
    return STATE_NAMES.index("q_m") if c.meter.T_f > 0.0 else STATE_NAMES.index("q")


def plant_rhs(t: float, x: StateVector, u: float, c: PlantCoefficients) -> list[float]:
    """The nonlinear plant ODE dx/dt = f(t, x, u, params), composed of the component laws.

    ===========  ==========================================================================
    dx/dt        component laws
    ===========  ==========================================================================
    df/dt        :func:`~fuelid.plant._vfd.vfd_frequency_rate` of
                 :func:`~fuelid.plant._vfd.vfd_frequency_command`
    dω_m/dt      :func:`~fuelid.plant._shaft.shaft_acceleration` of
                 :func:`~fuelid.plant._motor.electromagnetic_torque` and
                 :func:`~fuelid.plant._pump.pump_torque`
    dp/dt        :func:`~fuelid.plant._pipeline.pipe_pressure_rate` of
                 :func:`~fuelid.plant._pump.pump_flow` and the line flow
    dq/dt        :func:`~fuelid.plant._pipeline.pipe_flow_rate` of the pump pressure,
                 :func:`~fuelid.plant._nozzle.nozzle_inlet_pressure` and
                 :func:`~fuelid.plant._pipeline.pipe_pressure_drop`
    dq_m/dt      :func:`~fuelid.plant._flowmeter.flowmeter_rate`
    ===========  ==========================================================================

    Parameters
    ----------
    t : float
        Time [s] (the plant is time-invariant; kept for the solvers' signature).
    x : array or sequence, shape (5,)
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
    # plain floats: arithmetic on numpy scalars is several times slower (this is the inner loop)
    f, omega, p, q, q_m = x.tolist() if isinstance(x, np.ndarray) else x
    vfd, pump, line, nozzle = c.vfd, c.pump, c.line, c.nozzle
    f_command = vfd_frequency_command(u, vfd.u_min, vfd.u_max, vfd.f_min, vfd.f_max)
    torque_e = electromagnetic_torque(f, omega, c.motor.K_T, c.motor.m_p)
    torque_p = pump_torque(p, pump.D_p, pump.eta_m)
    dp_line = pipe_pressure_drop(
        q, line.rho, line.mu, line.length, line.d, line.roughness, line.method
    )
    p_nozzle = nozzle_inlet_pressure(q, nozzle.rho, nozzle.Cd, nozzle.A0, nozzle.p_back)
    return [
        vfd_frequency_rate(f, f_command, vfd.lag, vfd.max_rate),
        shaft_acceleration(torque_e, torque_p, omega, c.shaft.J, c.shaft.B),
        pipe_pressure_rate(pump_flow(omega, p, pump.D_p, pump.C_p), q, line.C),
        pipe_flow_rate(p, p_nozzle, dp_line, line.L),
        flowmeter_rate(q, q_m, c.meter.T_f),
    ]


def plant_jacobian(t: float, x: StateVector, u: float, c: PlantCoefficients) -> NDArray[np.float64]:
    """Analytic Jacobian ∂f/∂x of :func:`plant_rhs` (for the stiff solver and linearisation).

    The chain rule over the component laws' own derivatives (the ``*_partials``, ``*_slope`` and
    :func:`~fuelid.plant._nozzle.orifice_resistance` functions next to each law). Only the pipe
    friction slope for a correlation other than Churchill's is numerical. Where the drive's rate
    limit binds, the frequency row is zero.

    Parameters
    ----------
    t, x, u, c
        As in :func:`plant_rhs`.

    Returns
    -------
    ndarray, shape (5, 5)
    """
    f, q = float(x[0]), float(x[3])
    vfd, motor, shaft, pump, line, nozzle = c.vfd, c.motor, c.shaft, c.pump, c.line, c.nozzle
    jac = np.zeros((N_STATES, N_STATES))
    # drive: ḟ(f, f*(u))
    f_command = vfd_frequency_command(u, vfd.u_min, vfd.u_max, vfd.f_min, vfd.f_max)
    jac[0, 0] = vfd_frequency_rate_partials(f, f_command, vfd.lag, vfd.max_rate)[0]
    # shaft: ω̇(T_e(f, ω), T_p(p), ω)
    dTe_df, dTe_domega = electromagnetic_torque_partials(motor.K_T, motor.m_p)
    da_dTe, da_dTload, da_domega = shaft_acceleration_partials(shaft.J, shaft.B)
    jac[1, 0] = da_dTe * dTe_df
    jac[1, 1] = da_dTe * dTe_domega + da_domega
    jac[1, 2] = da_dTload * pump_torque_slope(pump.D_p, pump.eta_m)
    # line capacitance: ṗ(q_p(ω, p), q)
    dqp_domega, dqp_dp = pump_flow_partials(pump.D_p, pump.C_p)
    dpdot_dqin, dpdot_dqout = pipe_pressure_rate_partials(line.C)
    jac[2, 1] = dpdot_dqin * dqp_domega
    jac[2, 2] = dpdot_dqin * dqp_dp
    jac[2, 3] = dpdot_dqout
    # fuel column: q̇(p, p_nozzle(q), Δp_f(q))
    dqdot_dpin, dqdot_dpout, dqdot_dfriction = pipe_flow_rate_partials(line.L)
    friction_slope = pipe_pressure_drop_slope(
        q, line.rho, line.mu, line.length, line.d, line.roughness, line.method
    )
    nozzle_slope = orifice_resistance(q, nozzle.rho, nozzle.Cd, nozzle.A0)
    jac[3, 2] = dqdot_dpin
    jac[3, 3] = dqdot_dpout * nozzle_slope + dqdot_dfriction * friction_slope
    # meter: q̇_m(q, q_m)
    jac[4, 3], jac[4, 4] = flowmeter_rate_partials(c.meter.T_f)
    return jac


def input_jacobian(u: float, c: PlantCoefficients) -> NDArray[np.float64]:
    """∂f/∂u [per V]: only the drive's frequency equation depends on the command.

    The chain ∂ḟ/∂f* · ∂f*/∂u at rest (f = f*): K_f/T_vfd inside the signal range, 0 outside it
    where the drive clips; at the range ends the one-sided slope into the range.
    """
    vfd = c.vfd
    f_command = vfd_frequency_command(u, vfd.u_min, vfd.u_max, vfd.f_min, vfd.f_max)
    dfdot_dcommand = vfd_frequency_rate_partials(f_command, f_command, vfd.lag, vfd.max_rate)[1]
    b = np.zeros((N_STATES, 1))
    b[0, 0] = dfdot_dcommand * vfd_command_slope(u, vfd.u_min, vfd.u_max, vfd.f_min, vfd.f_max)
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
        return self.omega_m / RAD_S_PER_RPM


def check_command(u: float, c: PlantCoefficients) -> None:
    """Refuse a command outside the drive's signal range (the linear model is meaningless there)."""
    if not (math.isfinite(u) and c.u_min <= u <= c.u_max):
        raise OutOfRangeError(
            f"command u = {u:g} V lies outside the drive's signal range {c.u_min:g}…{c.u_max:g} V"
        )


def steady_state(u: float, c: PlantCoefficients) -> OperatingPoint:
    """Solve the steady state for command ``u`` with the plant coefficients ``c``.

    With every derivative zero the state reduces to one equation in the flow q: the line fixes
    the pump pressure p(q) (nozzle inlet pressure plus friction drop), the shaft's torque balance
    then fixes the shaft speed ω(p), and the pump's flow at (ω, p) must be q. The residual is
    monotonic in q, so Brent's method on a bracket [0, geometric flow at synchronous speed] finds
    the unique root. Every term is a component law; the torque balance is affine in ω (torque
    linear in slip, viscous damping), so one Newton step from ω = 0 with the laws' own partial
    derivatives solves it exactly.

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
    vfd, motor, shaft, pump, line, nozzle = c.vfd, c.motor, c.shaft, c.pump, c.line, c.nozzle
    f = vfd_frequency_command(u, vfd.u_min, vfd.u_max, vfd.f_min, vfd.f_max)
    da_dTe, _, da_domega = shaft_acceleration_partials(shaft.J, shaft.B)
    da_domega_total = da_dTe * electromagnetic_torque_partials(motor.K_T, motor.m_p)[1] + da_domega

    def shaft_acceleration_at(omega: float, p: float) -> float:
        torque_e = electromagnetic_torque(f, omega, motor.K_T, motor.m_p)
        torque_p = pump_torque(p, pump.D_p, pump.eta_m)
        return shaft_acceleration(torque_e, torque_p, omega, shaft.J, shaft.B)

    def shaft_speed(p: float) -> float:
        # the torque balance is affine in ω: one Newton step from ω = 0 is exact
        return -shaft_acceleration_at(0.0, p) / da_domega_total

    def pump_pressure(q: float) -> float:
        # at rest the line's momentum balance reads p = p_nozzle(q) + Δp_f(q)
        return nozzle_inlet_pressure(
            q, nozzle.rho, nozzle.Cd, nozzle.A0, nozzle.p_back
        ) + pipe_pressure_drop(
            q, line.rho, line.mu, line.length, line.d, line.roughness, line.method
        )

    def residual(q: float) -> float:
        p = pump_pressure(q)
        return pump_flow(shaft_speed(p), p, pump.D_p, pump.C_p) - q

    # geometric flow at synchronous speed: no slip, no back pressure, so no leakage
    q_hi = pump_flow(synchronous_speed(f, motor.m_p), 0.0, pump.D_p, pump.C_p)
    if q_hi <= 0.0:
        q = 0.0
    else:
        q = float(
            scipy.optimize.brentq(residual, 0.0, q_hi, xtol=1e-15, rtol=4 * np.finfo(float).eps)
        )
    p = pump_pressure(q)
    omega = shaft_speed(p)
    q_pump = pump_flow(omega, p, pump.D_p, pump.C_p)
    return OperatingPoint(
        u=u,
        T_fuel=c.T_fuel,
        f=f,
        omega_m=omega,
        q=q,
        p_pump=p,
        p_nozzle=nozzle_inlet_pressure(q, nozzle.rho, nozzle.Cd, nozzle.A0, nozzle.p_back),
        torque=electromagnetic_torque(f, omega, motor.K_T, motor.m_p),
        # leakage: the geometric flow (the delivery at zero pressure) minus the delivery at p
        q_leak=pump_flow(omega, 0.0, pump.D_p, pump.C_p) - q_pump,
        reynolds=reynolds_number(q, line.d, line.rho, line.mu),
        mass_balance=q_pump - q,
        torque_balance=shaft.J * shaft_acceleration_at(omega, p),
    )


def operating_point(config: PlantConfig, u: float, T_fuel: float) -> OperatingPoint:
    """Steady operating point of a plant for command ``u`` [V] and fuel temperature [K].

    Examples
    --------
    >>> from fuelid.plant import load_plant_config
    >>> op = operating_point(load_plant_config(), u=5.0, T_fuel=293.15)
    >>> abs(op.mass_balance) < 1e-15 and abs(op.torque_balance) < 1e-9
    True
    """
    c = plant_coefficients(config, T_fuel)
    check_command(u, c)
    return steady_state(u, c)
