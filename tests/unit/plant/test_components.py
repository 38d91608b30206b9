"""Plant components against hand calculations and textbook laws.

Every expected value is computed here from the textbook formula (or the ``fluids`` library for a
friction factor), never read back from the function under test. The fuel state used for the
pipe and nozzle checks is RP-3 (TS-1 correlations) at 20 °C, worked by hand:
ρ = 794 − 0.72·20 = 779.6 kg/m³, ν = 1.3096 mm²/s, μ = ρ·ν = 1.02096e-3 Pa·s.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import fluids.friction
import numpy as np
import pytest

from fuelid.plant import measure_flow
from fuelid.plant._flowmeter import FlowmeterConfig, flowmeter_rate, flowmeter_rate_partials
from fuelid.plant._motor import (
    MAX_RATED_SLIP,
    MotorConfig,
    electromagnetic_torque,
    electromagnetic_torque_partials,
    slip_torque_constant,
    synchronous_speed,
    torque_constant_from_circuit,
)
from fuelid.plant._nozzle import (
    NozzleConfig,
    nozzle_inlet_pressure,
    orifice_flow,
    orifice_pressure_drop,
    orifice_resistance,
)
from fuelid.plant._pipeline import (
    ZERO_FLOW_RE,
    PipelineConfig,
    circle_area,
    darcy_friction_factor,
    darcy_friction_factor_log_slope,
    laminar_resistance,
    pipe_capacitance,
    pipe_flow_rate,
    pipe_flow_rate_partials,
    pipe_inductance,
    pipe_pressure_drop,
    pipe_pressure_drop_slope,
    pipe_pressure_rate,
    pipe_pressure_rate_partials,
    reynolds_number,
)
from fuelid.plant._pump import (
    LPM_PER_M3S,
    PumpConfig,
    leakage_coefficient,
    pump_flow,
    pump_flow_partials,
    pump_torque,
    pump_torque_slope,
)
from fuelid.plant._shaft import shaft_acceleration, shaft_acceleration_partials
from fuelid.plant._vfd import (
    VFDConfig,
    vfd_command_slope,
    vfd_frequency_command,
    vfd_frequency_rate,
    vfd_frequency_rate_partials,
    vfd_gain,
)

RHO = 794.0 - 0.72 * 20.0  # 779.6 kg/m³
MU = RHO * 1.3096e-6  # 1.02096e-3 Pa·s
LENGTH = 80.0  # m
D = 0.032  # m
EPS = 0.045e-3  # m, commercial steel
TWO_PI = 2.0 * math.pi


def _q_for_reynolds(Re: float) -> float:
    """Volume flow [m³/s] giving Reynolds number Re in the 32 mm line: Re = 4ρq/(πdμ)."""
    return Re * math.pi * D * MU / (4.0 * RHO)


# --------------------------------------------------------------------------------------------
# pipeline


def test_reynolds_number_by_hand() -> None:
    q = 1e-3  # 60 L/min
    v = q / (math.pi * D**2 / 4.0)  # 1.2434 m/s
    assert reynolds_number(q, D, RHO, MU) == pytest.approx(RHO * v * D / MU, rel=1e-14)
    # ≈ 30 400: the line is turbulent at realistic flows, as docs/explanation/physics.md §3.5 says
    assert 3.0e4 < reynolds_number(q, D, RHO, MU) < 3.1e4


@pytest.mark.parametrize("method", ["Clamond", "Colebrook", "Haaland", "Swamee_Jain_1976"])
@pytest.mark.parametrize("q", [4e-4, 1e-3, 2.5e-3])
def test_darcy_weisbach_by_hand(method: str, q: float) -> None:
    # Δp = f·(l/d)·ρv²/2 with f taken straight from the fluids correlation of that name
    v = 4.0 * q / (math.pi * D**2)
    Re = RHO * v * D / MU
    f = getattr(fluids.friction, method)(Re, EPS / D)
    expected = f * (LENGTH / D) * RHO * v**2 / 2.0
    got = pipe_pressure_drop(q, RHO, MU, LENGTH, D, EPS, method=method)
    assert got == pytest.approx(expected, rel=1e-12)


def test_darcy_weisbach_default_is_churchill() -> None:
    q = 1e-3
    v = 4.0 * q / (math.pi * D**2)
    f = fluids.friction.Churchill_1977(RHO * v * D / MU, EPS / D)
    expected = f * (LENGTH / D) * RHO * v**2 / 2.0
    assert pipe_pressure_drop(q, RHO, MU, LENGTH, D, EPS) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("Re", [1e4, 3e4, 1e5, 1e6])
@pytest.mark.parametrize("eD", [0.0, 1e-4, 1.4e-3])
def test_churchill_matches_colebrook_in_turbulent_flow(Re: float, eD: float) -> None:
    # Churchill (1977) reproduces the Colebrook–White equation within ~1 % in fully turbulent
    # flow (Re ≥ 1e4) for the roughness of drawn to commercial pipe (ε/d ≤ 1.4e-3).
    assert darcy_friction_factor(Re, eD) == pytest.approx(
        fluids.friction.Colebrook(Re, eD), rel=0.02
    )


@pytest.mark.parametrize("Re", [10.0, 100.0, 500.0, 1000.0])
def test_churchill_laminar_limit_is_64_over_re(Re: float) -> None:
    assert darcy_friction_factor(Re, 1e-3) == pytest.approx(64.0 / Re, rel=1e-9)


def test_laminar_resistance_hagen_poiseuille() -> None:
    # R = 128 μ l/(π d⁴) = 128·1e-3·80/(π·0.032⁴) = 10.24/(π·1.048576e-6) = 3.1085e6 Pa·s/m³
    assert laminar_resistance(1e-3, 80.0, 0.032) == pytest.approx(3.1085e6, rel=1e-4)
    assert laminar_resistance(MU, LENGTH, D) == pytest.approx(
        128.0 * MU * LENGTH / (math.pi * D**4), rel=1e-14
    )


@pytest.mark.parametrize("method", ["Churchill_1977", "Clamond"])
@pytest.mark.parametrize("Re", [1.0, 200.0, 1500.0])
def test_laminar_pressure_drop_is_hagen_poiseuille(method: str, Re: float) -> None:
    q = _q_for_reynolds(Re)
    # Δp = 128 μ l q/(π d⁴), the same as f = 64/Re in Darcy–Weisbach
    expected = 128.0 * MU * LENGTH * q / (math.pi * D**4)
    got = pipe_pressure_drop(q, RHO, MU, LENGTH, D, EPS, method=method)
    assert got == pytest.approx(expected, rel=1e-7)


def test_pressure_drop_is_odd_in_flow_and_zero_at_rest() -> None:
    q = 1.2e-3
    assert pipe_pressure_drop(-q, RHO, MU, LENGTH, D, EPS) == pytest.approx(
        -pipe_pressure_drop(q, RHO, MU, LENGTH, D, EPS), rel=1e-14
    )
    assert pipe_pressure_drop(0.0, RHO, MU, LENGTH, D, EPS) == 0.0


def test_pipe_inductance_by_hand() -> None:
    # L = 4ρl/(πd²) = 4·800·80/(π·0.001024) = 256000/3.21699e-3 = 7.9577e7 kg/m⁴
    assert pipe_inductance(800.0, 80.0, 0.032) == pytest.approx(7.9577e7, rel=1e-4)
    # equivalently ρl/A: the mass of the fuel column per area squared
    area = math.pi * D**2 / 4.0
    assert pipe_inductance(RHO, LENGTH, D) == pytest.approx(RHO * LENGTH / area, rel=1e-14)


def test_pipe_capacitance_by_hand() -> None:
    # C = πd²l/(4β) = π·0.001024·80/(4·1.2e9) = 0.257359/4.8e9 = 5.3617e-11 m³/Pa
    assert pipe_capacitance(80.0, 0.032, 1.2e9) == pytest.approx(5.3617e-11, rel=1e-4)
    # equivalently V/β: 1 MPa compresses 64.3 L of fuel by 1e6/1.2e9 = 0.083 %
    # (docs/explanation/physics.md §3.4: ~0.1 %)
    volume = math.pi * D**2 / 4.0 * LENGTH
    dV = pipe_capacitance(LENGTH, D, 1.2e9) * 1e6
    assert dV / volume == pytest.approx(1e6 / 1.2e9, rel=1e-14)


def test_slope_is_laminar_resistance_in_laminar_flow() -> None:
    # Churchill's turbulent/transition term is below 1e-13 of f for Re ≤ 1000
    R_L = 128.0 * MU * LENGTH / (math.pi * D**4)
    for Re in (0.5, 300.0, 1000.0):
        slope = pipe_pressure_drop_slope(_q_for_reynolds(Re), RHO, MU, LENGTH, D, EPS)
        assert slope == pytest.approx(R_L, rel=1e-6)


def test_zero_flow_cut_off_is_far_below_the_laminar_transition() -> None:
    # the cut-off only guards the 0/0 at rest; the laminar switch of the correlations is 2040
    assert ZERO_FLOW_RE < 1e-3 * fluids.friction.LAMINAR_TRANSITION_PIPE
    R_L = 128.0 * MU * LENGTH / (math.pi * D**4)
    # Hagen–Poiseuille on both sides of the cut-off, and continuous across it
    for Re in (0.5 * ZERO_FLOW_RE, 2.0 * ZERO_FLOW_RE):
        q = _q_for_reynolds(Re)
        assert pipe_pressure_drop(q, RHO, MU, LENGTH, D, EPS) == pytest.approx(R_L * q, rel=1e-12)
        assert pipe_pressure_drop_slope(q, RHO, MU, LENGTH, D, EPS) == pytest.approx(R_L, rel=1e-12)
    assert pipe_pressure_drop_slope(0.0, RHO, MU, LENGTH, D, EPS) == pytest.approx(R_L, rel=1e-14)


def test_circle_area_is_the_one_cross_section() -> None:
    # A = πd²/4: 32 mm bore 8.0425e-4 m²; the line's laws and the nozzle area all use it
    area = math.pi * D**2 / 4.0
    assert circle_area(D) == pytest.approx(area, rel=1e-15)
    assert circle_area(D) == pytest.approx(8.0425e-4, rel=1e-5)
    q = 1e-3
    assert reynolds_number(q, D, RHO, MU) == pytest.approx(RHO * (q / area) * D / MU, rel=1e-14)
    assert pipe_inductance(RHO, LENGTH, D) == pytest.approx(RHO * LENGTH / area, rel=1e-14)
    assert pipe_capacitance(LENGTH, D, 1.2e9) == pytest.approx(area * LENGTH / 1.2e9, rel=1e-14)
    area_of_8 = NozzleConfig(count=8, diameter_mm=2.25, discharge_coefficient=0.7).A0
    assert area_of_8 == pytest.approx(8 * math.pi * 2.25e-3**2 / 4.0, rel=1e-14)


def test_slope_tends_to_quadratic_law_when_fully_rough() -> None:
    # fully rough (ε/d = 0.05, Re = 1e7): f no longer depends on Re, so Δp ∝ q² and the
    # incremental resistance is 2Δp/q
    eps = 0.05 * D
    q = _q_for_reynolds(1e7)
    dp = pipe_pressure_drop(q, RHO, MU, LENGTH, D, eps)
    assert pipe_pressure_drop_slope(q, RHO, MU, LENGTH, D, eps) == pytest.approx(
        2.0 * dp / q, rel=1e-3
    )


@pytest.mark.parametrize("Re", [1e4, 3e4, 1e5, 1e6])
def test_slope_exponent_between_blasius_and_quadratic(Re: float) -> None:
    # turbulent: Δp ∝ q^n, n = 2 + d ln f/d ln Re, from about 1.75 (smooth, Blasius f ∝ Re^−¼)
    # to 2 (fully rough); near Re = 1e4 the Colebrook curve is a little steeper than Blasius,
    # so the lower bound is 1.7
    q = _q_for_reynolds(Re)
    n = (
        q
        * pipe_pressure_drop_slope(q, RHO, MU, LENGTH, D, EPS)
        / pipe_pressure_drop(q, RHO, MU, LENGTH, D, EPS)
    )
    assert 1.7 < n < 2.0


@pytest.mark.parametrize("q", [2.5e-4, 1e-3, 2e-3])
def test_slope_agrees_with_richardson_difference(q: float) -> None:
    # independent derivative: Richardson extrapolation of central differences with h = 1e-3·q
    def dp(x: float) -> float:
        return pipe_pressure_drop(x, RHO, MU, LENGTH, D, EPS)

    h = 1e-3 * q
    d1 = (dp(q + h) - dp(q - h)) / (2 * h)
    d2 = (dp(q + h / 2) - dp(q - h / 2)) / h
    expected = (4.0 * d2 - d1) / 3.0
    assert pipe_pressure_drop_slope(q, RHO, MU, LENGTH, D, EPS) == pytest.approx(expected, rel=1e-7)


# --------------------------------------------------------------------------------------------
# nozzle


def test_nozzle_area_by_hand() -> None:
    # 8 nozzles of 2.25 mm: 8·π·(2.25e-3)²/4 = 8·3.97608e-6 = 3.18086e-5 m²
    nozzle = NozzleConfig(count=8, diameter_mm=2.25, discharge_coefficient=0.7)
    area = nozzle.A0
    assert area == pytest.approx(3.18086e-5, rel=1e-5)
    assert nozzle.p_back == 0.0


def test_orifice_flow_by_hand() -> None:
    # 1 MPa, ρ = 800: v = √(2·1e6/800) = 50 m/s; q = 0.7·30e-6·50 = 1.05e-3 m³/s = 63 L/min
    assert orifice_flow(1e6, 800.0, 0.7, 30e-6) == pytest.approx(1.05e-3, rel=1e-14)
    assert orifice_flow(-1e6, 800.0, 0.7, 30e-6) == pytest.approx(-1.05e-3, rel=1e-14)


@pytest.mark.parametrize("q", [1e-6, 2.5e-4, 1e-3, -7e-4])
def test_orifice_round_trip(q: float) -> None:
    cd, a0 = 0.7, 3.18086e-5
    dp = orifice_pressure_drop(q, RHO, cd, a0)
    # inverse law by hand: Δp = ρ q|q| /(2 (C_d A_0)²)
    assert dp == pytest.approx(RHO * q * abs(q) / (2.0 * (cd * a0) ** 2), rel=1e-14)
    assert orifice_flow(dp, RHO, cd, a0) == pytest.approx(q, rel=1e-12)


@pytest.mark.parametrize("q", [2.5e-4, 1e-3])
def test_orifice_resistance_is_twice_dp_over_q(q: float) -> None:
    cd, a0 = 0.7, 3.18086e-5
    dp = RHO * q**2 / (2.0 * (cd * a0) ** 2)
    assert orifice_resistance(q, RHO, cd, a0) == pytest.approx(2.0 * dp / q, rel=1e-13)
    # and it is the derivative of the square law (central difference exact for a parabola)
    h = 1e-3 * q
    fd = (orifice_pressure_drop(q + h, RHO, cd, a0) - orifice_pressure_drop(q - h, RHO, cd, a0)) / (
        2 * h
    )
    assert orifice_resistance(q, RHO, cd, a0) == pytest.approx(fd, rel=1e-8)


# --------------------------------------------------------------------------------------------
# pump


def test_pump_geometric_flow() -> None:
    # 50 cm³/rev at 1450 rpm: 50e-3 L · 1450 /min = 72.5 L/min
    omega = TWO_PI * 1450.0 / 60.0
    assert pump_flow(omega, 0.0, 50e-6, 1e-10) * LPM_PER_M3S == pytest.approx(72.5, rel=1e-13)


def test_pump_leakage_from_config() -> None:
    pump = PumpConfig(
        displacement_cm3_per_rev=50.0,
        leakage_Lpm_per_MPa=7.0,
        leakage_ref_viscosity_mPa_s=1.0,
        mechanical_efficiency=0.9,
    )
    # 7 (L/min)/MPa = 7/60000 m³/s per 1e6 Pa = 1.16667e-10 m³/(s·Pa)
    assert pump.C_p_ref == pytest.approx(7.0 / 60_000.0 / 1e6, rel=1e-14)
    assert pump.D_p == pytest.approx(50e-6, rel=1e-14)
    assert pump.mu_ref == pytest.approx(1e-3, rel=1e-14)
    omega = TWO_PI * 1450.0 / 60.0
    # at 1 MPa and the reference viscosity: 72.5 − 7 = 65.5 L/min
    q = pump_flow(omega, 1e6, pump.D_p, pump.C_p_ref) * LPM_PER_M3S
    assert q == pytest.approx(65.5, rel=1e-12)


@pytest.mark.parametrize("mu", [0.5e-3, 1e-3, 2.3e-3, 4e-3])
def test_leakage_inversely_proportional_to_viscosity(mu: float) -> None:
    c_ref, mu_ref = 1.16667e-10, 1e-3
    # laminar clearance flow: C_p·μ is constant
    assert leakage_coefficient(mu, c_ref, mu_ref) * mu == pytest.approx(c_ref * mu_ref, rel=1e-14)
    assert leakage_coefficient(mu_ref / 2.0, c_ref, mu_ref) == pytest.approx(2.0 * c_ref, rel=1e-14)


def test_pump_torque_by_hand_and_energy_balance() -> None:
    # D·p/(2π·η) = 50e-6·1e6/(2π·0.9) = 50/5.65487 = 8.8419 N·m
    assert pump_torque(1e6, 50e-6, 0.9) == pytest.approx(8.8419, rel=1e-4)
    # shaft power times η_m equals the ideal hydraulic power D·n·p
    p, omega, eta = 0.8e6, TWO_PI * 1400.0 / 60.0, 0.88
    shaft_power = pump_torque(p, 50e-6, eta) * omega
    assert shaft_power * eta == pytest.approx(50e-6 * (1400.0 / 60.0) * p, rel=1e-13)


# --------------------------------------------------------------------------------------------
# motor and shaft

T_RATED = 7500.0 / (TWO_PI * 1450.0 / 60.0)  # 7500/151.844 = 49.393 N·m
SLIP_SPEED = TWO_PI * 50.0 / 2 - TWO_PI * 1450.0 / 60.0  # 157.080 − 151.844 = 5.236 rad/s


def test_slip_torque_constant_from_nameplate() -> None:
    assert pytest.approx(49.393, rel=1e-4) == T_RATED
    assert pytest.approx(5.2360, rel=1e-4) == SLIP_SPEED
    # 49.393/5.2360 = 9.4333 N·m·s/rad
    assert slip_torque_constant(7500.0, 1450.0, 50.0, 2) == pytest.approx(9.4333, rel=1e-4)
    assert slip_torque_constant(7500.0, 1450.0, 50.0, 2) == pytest.approx(
        T_RATED / SLIP_SPEED, rel=1e-13
    )
    motor = MotorConfig(
        rated_power_kW=7.5, rated_speed_rpm=1450.0, pole_pairs=2, inertia_kg_m2=0.06
    )
    k_t = motor.K_T
    assert k_t == pytest.approx(T_RATED / SLIP_SPEED, rel=1e-13)


def test_torque_linear_in_slip_reproduces_nameplate() -> None:
    K_T = T_RATED / SLIP_SPEED
    omega_rated = TWO_PI * 1450.0 / 60.0
    assert electromagnetic_torque(50.0, omega_rated, K_T, 2) == pytest.approx(T_RATED, rel=1e-12)
    # no torque at synchronous speed, braking above it
    assert electromagnetic_torque(50.0, TWO_PI * 25.0, K_T, 2) == pytest.approx(0.0, abs=1e-12)
    assert electromagnetic_torque(50.0, TWO_PI * 25.0 + 1.0, K_T, 2) == pytest.approx(-K_T)


def _circuit_torque(U1: float, f: float, slip_speed: float, R_re: float, m_p: int) -> float:
    """Air-gap torque of the equivalent circuit at small slip, independent of the code.

    Rotor current I₂ ≈ U₁·s/R_re, air-gap power P = 3·U₁²·s/R_re, T = P/(ω₁/m_p), with slip
    s = slip_speed/(ω₁/m_p).
    """
    omega_sync = TWO_PI * f / m_p
    s = slip_speed / omega_sync
    return 3.0 * U1**2 * s / R_re / omega_sync


def test_circuit_constant_consistent_with_nameplate() -> None:
    K_int = 400.0 / math.sqrt(3.0) / 50.0  # 230.9 V phase at 50 Hz: 4.6188 V/Hz
    # choose R_re so that the circuit delivers the rated torque at the rated slip:
    # T = 3 U² s m_p/(ω₁ R_re)  →  R_re = 3 U² s m_p/(ω₁ T_rated) ≈ 0.687 Ω
    U1, s = K_int * 50.0, (1500.0 - 1450.0) / 1500.0
    R_re = 3.0 * U1**2 * s * 2 / (TWO_PI * 50.0 * T_RATED)
    assert R_re == pytest.approx(0.687, rel=2e-3)
    k_t = torque_constant_from_circuit(K_int, R_re, 2)
    assert k_t == pytest.approx(slip_torque_constant(7500.0, 1450.0, 50.0, 2), rel=1e-12)
    # constant V/f: the same slip speed gives the same torque at any frequency
    for f in (10.0, 25.0, 50.0):
        omega_m = TWO_PI * f / 2 - SLIP_SPEED
        expected = _circuit_torque(K_int * f, f, SLIP_SPEED, R_re, 2)
        assert electromagnetic_torque(f, omega_m, k_t, 2) == pytest.approx(expected, rel=1e-12)
        assert expected == pytest.approx(T_RATED, rel=1e-12)


def test_shaft_acceleration_by_hand() -> None:
    # J ω̇ = T_e − B ω − T_load:  (49.393 − 0.02·151.844 − 8.842)/0.06 = 625.2 rad/s²
    omega = TWO_PI * 1450.0 / 60.0
    expected = (T_RATED - 0.02 * omega - 8.842) / 0.06
    assert shaft_acceleration(T_RATED, 8.842, omega, 0.06, 0.02) == pytest.approx(
        expected, rel=1e-14
    )
    assert expected == pytest.approx(625.2, rel=1e-3)
    # balanced torques: no acceleration
    assert shaft_acceleration(10.0 + 0.02 * omega, 10.0, omega, 0.06, 0.02) == pytest.approx(
        0.0, abs=1e-12
    )


# --------------------------------------------------------------------------------------------
# drive


@pytest.mark.parametrize(
    ("u", "f"),
    [(0.0, 10.0), (1.0, 10.0), (1.5, 15.0), (2.5, 25.0), (3.0, 30.0), (5.0, 50.0), (7.0, 50.0)],
)
def test_vfd_mapping_and_clipping(u: float, f: float) -> None:
    # K_f = (50 − 10)/(5 − 1) = 10 Hz/V, f = 10 + 10(u − 1), clipped to 10…50 Hz
    assert float(vfd_frequency_command(u, 1.0, 5.0, 10.0, 50.0)) == pytest.approx(f, rel=1e-14)


def test_vfd_gain_from_config() -> None:
    vfd = VFDConfig(f_min_Hz=10.0, f_max_Hz=50.0, lag_s=1.2)
    assert vfd.K_f == pytest.approx(10.0, rel=1e-14)
    vfd2 = VFDConfig(u_min_V=0.0, u_max_V=10.0, f_min_Hz=5.0, f_max_Hz=60.0, lag_s=1.0)
    assert vfd2.K_f == pytest.approx(5.5, rel=1e-14)  # 55 Hz over 10 V


def test_vfd_rate_first_order_lag() -> None:
    # ḟ = (f* − f)/T: (15 − 10)/1.2 = 4.1667 Hz/s
    assert vfd_frequency_rate(10.0, 15.0, 1.2) == pytest.approx(5.0 / 1.2, rel=1e-14)
    assert vfd_frequency_rate(30.0, 30.0, 1.2) == 0.0


def test_vfd_rate_limit() -> None:
    # unlimited rate would be ±40 Hz/s; the 20 Hz/s ramp binds both ways
    assert vfd_frequency_rate(10.0, 50.0, 1.0, max_rate=20.0) == 20.0
    assert vfd_frequency_rate(50.0, 10.0, 1.0, max_rate=20.0) == -20.0
    # inside the limit the lag is untouched: (12 − 10)/1 = 2 Hz/s
    assert vfd_frequency_rate(10.0, 12.0, 1.0, max_rate=20.0) == pytest.approx(2.0, rel=1e-14)


# --------------------------------------------------------------------------------------------
# flowmeter


def test_flowmeter_noise_statistics() -> None:
    n, sigma, level = 400_000, 0.1, 30.0
    y = measure_flow(np.full(n, level), noise_std=sigma, rng=np.random.default_rng(12345))
    # sample mean: sd σ/√n; sample sd: relative sd 1/√(2(n−1)); allow 5 standard errors
    assert abs(y.mean() - level) < 5.0 * sigma / math.sqrt(n)
    assert y.std(ddof=1) == pytest.approx(sigma, rel=5.0 / math.sqrt(2.0 * (n - 1)))


def test_flowmeter_quantisation_grid_and_error() -> None:
    r = 0.05
    x = np.linspace(10.0, 20.0, 10_001)
    y = measure_flow(x, resolution=r)
    k = y / r
    assert np.max(np.abs(k - np.round(k))) < 1e-9  # every reading on the grid
    assert np.max(np.abs(y - x)) <= r / 2.0 + 1e-12  # rounding to nearest


def test_flowmeter_noise_then_quantisation_sheppard() -> None:
    # quantising Gaussian noise with step r ≤ σ adds a nearly uniform error: var = σ² + r²/12
    # (Sheppard's correction; the residual term ∝ exp(−2π²σ²/r²) ≈ 3e-9 here)
    n, sigma, r = 400_000, 0.1, 0.1
    y = measure_flow(np.full(n, 25.03), noise_std=sigma, resolution=r, rng=np.random.default_rng(7))
    expected_var = sigma**2 + r**2 / 12.0  # 0.0108333, 8.3 % above σ²
    # relative sd of a sample variance: √(2/(n−1)) = 0.22 %; allow 5 of them
    assert y.var(ddof=1) == pytest.approx(expected_var, rel=5.0 * math.sqrt(2.0 / (n - 1)))


def test_flowmeter_without_noise_is_identity() -> None:
    x = np.array([1.0, 2.5, 99.99])
    assert np.array_equal(measure_flow(x), x)


# --------------------------------------------------------------------------------------------
# derivatives next to their laws (the Jacobian of the plant is built from these)


def _central(fn: Callable[[float], float], x: float, h: float) -> float:
    """Central difference of fn at x with step h (exact for a linear or quadratic law)."""
    return (fn(x + h) - fn(x - h)) / (2.0 * h)


def test_vfd_gain_and_command_slope() -> None:
    # K_f = (50 − 10) Hz/(5 − 1) V = 10 Hz/V
    assert vfd_gain(1.0, 5.0, 10.0, 50.0) == 10.0
    for u in (1.5, 3.0, 4.5):
        slope = _central(lambda v: vfd_frequency_command(v, 1.0, 5.0, 10.0, 50.0), u, 1e-3)
        assert slope == pytest.approx(10.0, rel=1e-9)
        assert vfd_command_slope(u, 1.0, 5.0, 10.0, 50.0) == 10.0
    # one-sided into the range at its ends, nothing where the drive clips
    assert vfd_command_slope(1.0, 1.0, 5.0, 10.0, 50.0) == 10.0
    assert vfd_command_slope(5.0, 1.0, 5.0, 10.0, 50.0) == 10.0
    assert vfd_command_slope(0.5, 1.0, 5.0, 10.0, 50.0) == 0.0
    assert vfd_command_slope(5.5, 1.0, 5.0, 10.0, 50.0) == 0.0


def test_vfd_rate_partials() -> None:
    # free lag: ∂ḟ/∂f = −1/T, ∂ḟ/∂f* = 1/T with T = 1.2 s
    d_f, d_cmd = vfd_frequency_rate_partials(20.0, 25.0, 1.2, max_rate=10.0)
    assert (d_f, d_cmd) == (pytest.approx(-1.0 / 1.2, rel=1e-15), pytest.approx(1.0 / 1.2))
    assert _central(lambda f: vfd_frequency_rate(f, 25.0, 1.2, 10.0), 20.0, 1e-3) == pytest.approx(
        d_f, rel=1e-9
    )
    # rate limit binding: (40 − 10)/1.2 = 25 Hz/s > 10 Hz/s, so ḟ is constant in f and f*
    assert vfd_frequency_rate_partials(10.0, 40.0, 1.2, max_rate=10.0) == (0.0, 0.0)
    assert _central(lambda f: vfd_frequency_rate(f, 40.0, 1.2, 10.0), 10.0, 1e-3) == 0.0


def test_synchronous_speed_by_hand() -> None:
    # 2 pole pairs at 50 Hz: 1500 rpm = 157.08 rad/s; 1 pole pair at 60 Hz: 3600 rpm
    assert synchronous_speed(50.0, 2) == pytest.approx(TWO_PI * 1500.0 / 60.0, rel=1e-15)
    assert synchronous_speed(60.0, 1) == pytest.approx(TWO_PI * 3600.0 / 60.0, rel=1e-15)


@pytest.mark.parametrize("f_rated", [50.0, 60.0, 49.5, 400.0 / 3.0])
@pytest.mark.parametrize("m_p", [1, 2, 3, 4, 6, 12])
def test_nameplate_at_synchronous_speed_refused(f_rated: float, m_p: int) -> None:
    # written the way a nameplate states it, n_sync = 60·f/m_p in rpm: refused whatever the
    # rounding of the rpm → rad/s conversion (K_T would be unbounded); 3 % slip is a motor
    n_sync = 60.0 * f_rated / m_p

    def motor(rated_speed_rpm: float) -> MotorConfig:
        return MotorConfig(
            rated_power_kW=7.5,
            rated_speed_rpm=rated_speed_rpm,
            rated_frequency_Hz=f_rated,
            pole_pairs=m_p,
            inertia_kg_m2=0.06,
        )

    for refused in (n_sync, 1.01 * n_sync, 0.69 * n_sync):
        with pytest.raises(ValueError, match="rated_speed_rpm"):
            motor(refused)
    omega_sync = TWO_PI * f_rated / m_p
    slip_speed = 0.03 * omega_sync
    expected = 7500.0 / (0.97 * omega_sync) / slip_speed
    k_t = motor(0.97 * n_sync).K_T
    assert k_t == pytest.approx(expected, rel=1e-9)
    assert MAX_RATED_SLIP == 0.3


def test_electromagnetic_torque_partials() -> None:
    K_T = T_RATED / SLIP_SPEED  # 9.4333 N·m·s/rad
    dT_df, dT_domega = electromagnetic_torque_partials(K_T, 2)
    # ∂T_e/∂f = 2π·K_T/m_p = π·9.4333 = 29.635 N·m/Hz, ∂T_e/∂ω = −K_T
    assert dT_df == pytest.approx(math.pi * K_T, rel=1e-14)
    assert dT_df == pytest.approx(29.635, rel=1e-4)
    assert dT_domega == -K_T
    omega = TWO_PI * 1450.0 / 60.0
    fd_f = _central(lambda f: electromagnetic_torque(f, omega, K_T, 2), 50.0, 1e-3)
    fd_omega = _central(lambda w: electromagnetic_torque(50.0, w, K_T, 2), omega, 1e-3)
    assert fd_f == pytest.approx(dT_df, rel=1e-9)
    assert fd_omega == pytest.approx(dT_domega, rel=1e-9)


def test_shaft_acceleration_partials() -> None:
    # (1/J, −1/J, −B/J) for J = 0.06 kg·m², B = 0.02 N·m·s/rad
    d_te, d_load, d_omega = shaft_acceleration_partials(0.06, 0.02)
    assert d_te == pytest.approx(1.0 / 0.06, rel=1e-15)
    assert d_load == pytest.approx(-1.0 / 0.06, rel=1e-15)
    assert d_omega == pytest.approx(-0.02 / 0.06, rel=1e-15)
    fd = _central(lambda w: shaft_acceleration(40.0, 8.0, w, 0.06, 0.02), 150.0, 1e-2)
    assert fd == pytest.approx(d_omega, rel=1e-9)


def test_pump_partials_by_hand() -> None:
    D_p, C_p, eta = 50e-6, 1.16667e-10, 0.9
    dq_domega, dq_dp = pump_flow_partials(D_p, C_p)
    # 50 cm³/rev = 7.9577e-6 m³/rad of geometric flow; each Pa costs C_p of leakage
    assert dq_domega == pytest.approx(D_p / TWO_PI, rel=1e-15)
    assert dq_domega == pytest.approx(7.9577e-6, rel=1e-4)
    assert dq_dp == -C_p
    # D_p/(2π·η) = 50e-6/5.65487 = 8.8419e-6 N·m/Pa (8.84 N·m per MPa, as pump_torque says)
    assert pump_torque_slope(D_p, eta) == pytest.approx(8.8419e-6, rel=1e-4)
    assert pump_torque_slope(D_p, eta) == pytest.approx(
        _central(lambda p: pump_torque(p, D_p, eta), 5e5, 1e3), rel=1e-9
    )
    assert _central(lambda p: pump_flow(150.0, p, D_p, C_p), 5e5, 1e3) == pytest.approx(
        dq_dp, rel=1e-9
    )


@pytest.mark.parametrize("eD", [0.0, EPS / D, 0.05])
@pytest.mark.parametrize("Re", [0.5, 300.0, 2000.0, 4000.0, 3e4, 1e6, 1e8])
def test_churchill_log_slope_against_richardson(Re: float, eD: float) -> None:
    # independent derivative: Richardson extrapolation of central differences in ln Re of the
    # fluids library's own Churchill_1977
    def ln_f(x: float) -> float:
        return math.log(fluids.friction.Churchill_1977(math.exp(x), eD))

    h, x = 1e-3, math.log(Re)
    d1 = (ln_f(x + h) - ln_f(x - h)) / (2.0 * h)
    d2 = (ln_f(x + h / 2) - ln_f(x - h / 2)) / h
    expected = (4.0 * d2 - d1) / 3.0
    assert darcy_friction_factor_log_slope(Re, eD) == pytest.approx(expected, abs=1e-9)


def test_friction_log_slope_limits() -> None:
    # laminar: f = 64/Re, slope −1; fully rough: f independent of Re, slope 0; smooth turbulent
    # near Re = 1e5: close to Blasius' −1/4 (Colebrook's local exponent there is about −0.2)
    for Re in (1.0, 100.0, 1000.0):
        assert darcy_friction_factor_log_slope(Re, EPS / D) == pytest.approx(-1.0, abs=1e-9)
    assert abs(darcy_friction_factor_log_slope(1e9, 0.05)) < 1e-3
    assert -0.3 < darcy_friction_factor_log_slope(1e5, 0.0) < -0.15


@pytest.mark.parametrize("Re", [5e3, 3e4, 1e6])
def test_other_correlation_log_slope_against_richardson(Re: float) -> None:
    def ln_f(x: float) -> float:
        return math.log(fluids.friction.Clamond(math.exp(x), EPS / D))

    h, x = 1e-3, math.log(Re)
    d1 = (ln_f(x + h) - ln_f(x - h)) / (2.0 * h)
    d2 = (ln_f(x + h / 2) - ln_f(x - h / 2)) / h
    expected = (4.0 * d2 - d1) / 3.0
    got = darcy_friction_factor_log_slope(Re, EPS / D, method="Clamond")
    assert got == pytest.approx(expected, abs=1e-7)


@pytest.mark.parametrize("q", [2.5e-4, 1e-3, 2e-3])
def test_slope_of_other_correlation_agrees_with_richardson_difference(q: float) -> None:
    def dp(x: float) -> float:
        return pipe_pressure_drop(x, RHO, MU, LENGTH, D, EPS, method="Clamond")

    h = 1e-3 * q
    d1 = (dp(q + h) - dp(q - h)) / (2 * h)
    d2 = (dp(q + h / 2) - dp(q - h / 2)) / h
    expected = (4.0 * d2 - d1) / 3.0
    got = pipe_pressure_drop_slope(q, RHO, MU, LENGTH, D, EPS, method="Clamond")
    assert got == pytest.approx(expected, rel=1e-6)


def test_other_correlations_switch_to_laminar_at_2040() -> None:
    # fluids.friction.friction_factor returns 64/Re below LAMINAR_TRANSITION_PIPE = 2040 (Avila
    # et al. 2011), not below the textbook 2320; Churchill's one expression has no switch
    assert fluids.friction.LAMINAR_TRANSITION_PIPE == 2040.0
    for Re in (1000.0, 2039.0):
        assert darcy_friction_factor(Re, EPS / D, "Clamond") == pytest.approx(64.0 / Re, rel=1e-14)
    for Re in (2041.0, 2320.0):
        f = darcy_friction_factor(Re, EPS / D, "Clamond")
        assert f == pytest.approx(fluids.friction.Clamond(Re, EPS / D), rel=1e-14)
        assert f > 1.5 * 64.0 / Re  # the turbulent correlation, well above the laminar value
    assert darcy_friction_factor(2039.0, EPS / D) == pytest.approx(
        fluids.friction.Churchill_1977(2039.0, EPS / D), rel=1e-15
    )


# --------------------------------------------------------------------------------------------
# lumped line dynamics, nozzle inlet pressure, meter lag


def test_line_continuity_by_hand() -> None:
    # C ṗ = q_in − q_out: a 1 L/min surplus into the 80 m, 32 mm line at β = 1.2 GPa
    # (C = 5.3617e-11 m³/Pa) raises the pressure by (1/60000)/5.3617e-11 = 3.108e5 Pa/s
    C = math.pi * D**2 * LENGTH / (4.0 * 1.2e9)
    rate = pipe_pressure_rate(31.0 / LPM_PER_M3S, 30.0 / LPM_PER_M3S, C)
    assert rate == pytest.approx((1.0 / LPM_PER_M3S) / C, rel=1e-12)
    assert rate == pytest.approx(3.108e5, rel=1e-3)
    assert pipe_pressure_rate_partials(C) == (pytest.approx(1.0 / C), pytest.approx(-1.0 / C))


def test_line_momentum_by_hand() -> None:
    # L q̇ = p_in − p_out − Δp_f: 0.1 MPa net on the column of L = 4ρl/(πd²) = 7.755e7 kg/m⁴
    inductance = 4.0 * RHO * LENGTH / (math.pi * D**2)
    assert inductance == pytest.approx(7.755e7, rel=1e-3)
    rate = pipe_flow_rate(1.0e6, 0.85e6, 0.05e6, inductance)
    assert rate == pytest.approx(1e5 / inductance, rel=1e-12)
    assert pipe_flow_rate_partials(inductance) == (
        pytest.approx(1.0 / inductance),
        pytest.approx(-1.0 / inductance),
        pytest.approx(-1.0 / inductance),
    )


@pytest.mark.parametrize("p_back", [0.0, 0.3e6])
def test_nozzle_inlet_pressure_by_hand(p_back: float) -> None:
    cd, a0, q = 0.7, 3.18086e-5, 1e-3
    # p₂ = p_back + ρ q|q|/(2 (C_d A_0)²)
    expected = p_back + RHO * q**2 / (2.0 * (cd * a0) ** 2)
    assert nozzle_inlet_pressure(q, RHO, cd, a0, p_back) == pytest.approx(expected, rel=1e-14)
    # its derivative is the orifice resistance ρ|q|/(C_d A_0)² (central difference exact)
    fd = _central(lambda x: nozzle_inlet_pressure(x, RHO, cd, a0, p_back), q, 1e-3 * q)
    assert orifice_resistance(q, RHO, cd, a0) == pytest.approx(fd, rel=1e-8)


def test_flowmeter_lag_by_hand() -> None:
    # T_f q̇_m = q − q_m: 10 L/min behind with T_f = 0.3 s → 33.3 (L/min)/s
    rate = flowmeter_rate(40.0 / LPM_PER_M3S, 30.0 / LPM_PER_M3S, 0.3)
    assert rate * LPM_PER_M3S == pytest.approx(10.0 / 0.3, rel=1e-12)
    assert flowmeter_rate_partials(0.3) == (pytest.approx(1.0 / 0.3), pytest.approx(-1.0 / 0.3))
    # no lag: the reading is the flow itself, the lagged state stays put
    assert flowmeter_rate(40.0 / LPM_PER_M3S, 30.0 / LPM_PER_M3S, 0.0) == 0.0
    assert flowmeter_rate_partials(0.0) == (0.0, 0.0)


# --------------------------------------------------------------------------------------------
# config sections to the SI parameter blocks the ODE reads


def test_sections_convert_to_si_blocks() -> None:
    vfd = VFDConfig(f_min_Hz=10.0, f_max_Hz=50.0, lag_s=1.2, max_rate_Hz_per_s=20.0).coefficients()
    assert (vfd.u_min, vfd.u_max, vfd.f_min, vfd.f_max) == (1.0, 5.0, 10.0, 50.0)
    assert (vfd.lag, vfd.max_rate) == (1.2, 20.0)

    motor_cfg = MotorConfig(
        rated_power_kW=7.5,
        rated_speed_rpm=1450.0,
        pole_pairs=2,
        inertia_kg_m2=0.06,
        damping_N_m_s_per_rad=0.02,
    )
    motor, shaft = motor_cfg.coefficients(), motor_cfg.shaft_coefficients()
    k_t = motor.K_T
    assert k_t == pytest.approx(T_RATED / SLIP_SPEED, rel=1e-13)
    assert motor.m_p == 2
    assert (shaft.J, shaft.B) == (0.06, 0.02)

    # 7 (L/min)/MPa at 1 mPa·s; fuel half as viscous leaks twice as much
    pump = PumpConfig(
        displacement_cm3_per_rev=50.0,
        leakage_Lpm_per_MPa=7.0,
        leakage_ref_viscosity_mPa_s=1.0,
        mechanical_efficiency=0.9,
    ).coefficients(mu=0.5e-3)
    assert pump.C_p == pytest.approx(2.0 * 7.0 / 60_000.0 / 1e6, rel=1e-14)
    assert pump.D_p == pytest.approx(50e-6, rel=1e-14)
    assert pump.eta_m == 0.9

    line = PipelineConfig(length_m=80.0, inner_diameter_mm=32.0).coefficients(RHO, MU)
    inductance, capacitance = line.L, line.C
    assert inductance == pytest.approx(4.0 * RHO * LENGTH / (math.pi * D**2), rel=1e-14)
    assert capacitance == pytest.approx(math.pi * D**2 * LENGTH / (4.0 * 1.2e9), rel=1e-14)
    assert (line.rho, line.mu, line.length, line.method) == (RHO, MU, 80.0, "Churchill_1977")
    assert line.d == pytest.approx(D, rel=1e-15)
    assert line.roughness == pytest.approx(EPS, rel=1e-15)

    nozzle = NozzleConfig(
        count=8, diameter_mm=2.25, discharge_coefficient=0.7, back_pressure_MPa=0.1
    ).coefficients(RHO)
    area = nozzle.A0
    assert area == pytest.approx(8 * math.pi * 2.25e-3**2 / 4.0, rel=1e-14)
    assert (nozzle.rho, nozzle.Cd) == (RHO, 0.7)
    assert nozzle.p_back == pytest.approx(1e5, rel=1e-15)

    meter = FlowmeterConfig(time_constant_s=0.3, delay_s=0.2, span_Lpm=100.0).coefficients()
    assert (meter.T_f, meter.delay) == (0.3, 0.2)
