"""The assembled reference plant: steady states, ODE, Jacobian, linearisation and reduction.

The operating point is checked against balances written out here from the component laws (the
pipe friction factor from ``fluids``), not against the solver's own residual fields alone. The
reference plant must reproduce the facts of docs/explanation/physics.md §8: about 1 MPa at full
flow, a steady flow at 1 V, over-damped slow dynamics, 98 % settling in 5–6 s, and a gain K that
drifts with fuel temperature by at least 5 % over −20…+50 °C while the settling time hardly moves.
"""

from __future__ import annotations

import functools
import math
import subprocess
import sys

import fluids.friction
import numpy as np
import pytest

from fuelid.fuel import fuel_properties
from fuelid.plant import (
    EquivalentModel,
    LinearPlant,
    PlantCoefficients,
    PlantConfig,
    input_jacobian,
    linearise,
    load_plant_config,
    operating_point,
    plant_coefficients,
    plant_jacobian,
    plant_rhs,
)

T0 = 273.15
TEMPS_K = [253.15, 293.15, 323.15]  # −20, 20, 50 °C
COMMANDS_V = [1.0, 1.25, 2.0, 3.0, 4.0, 5.0]
LPM = 60_000.0
TWO_PI = 2.0 * math.pi

# reference plant numbers (reference_plant.toml), SI
D_P = 50e-6  # m³/rev
C_P_REF, MU_REF = 7.0 / LPM / 1e6, 1e-3  # 7 (L/min)/MPa at 1 mPa·s
ETA_M = 0.9
K_T = (7500.0 / (TWO_PI * 1450.0 / 60.0)) / (TWO_PI * 25.0 - TWO_PI * 1450.0 / 60.0)  # 9.4333
B_T, J_T = 0.02, 0.06
LENGTH, D, EPS = 80.0, 0.032, 0.045e-3
CD_A0 = 0.7 * 8 * math.pi * (2.25e-3) ** 2 / 4.0  # 2.2266e-5 m²
T_VFD, T_F, DELAY = 1.2, 0.3, 0.2
C_LINE = math.pi * D**2 * LENGTH / (4.0 * 1.2e9)  # 5.36e-11 m³/Pa


def _finite_difference_jacobian(x0: np.ndarray, u: float, c: PlantCoefficients) -> np.ndarray:
    """Central differences of plant_rhs, relative step 1e-6 per state (independent of the code)."""
    fd = np.zeros((x0.size, x0.size))
    for j in range(x0.size):
        h = 1e-6 * abs(x0[j])
        xp, xm = x0.copy(), x0.copy()
        xp[j] += h
        xm[j] -= h
        fd[:, j] = (np.array(plant_rhs(0.0, xp, u, c)) - np.array(plant_rhs(0.0, xm, u, c))) / (
            2 * h
        )
    return fd


@functools.cache
def _linear(u: float, T: float) -> LinearPlant:
    return linearise(load_plant_config(), u, T)


@functools.cache
def _equivalent(u: float, T: float) -> EquivalentModel:
    return _linear(u, T).equivalent_model()


def _frequency(u: float) -> float:
    """Drive frequency by hand: 10 Hz + 10 Hz/V·(u − 1 V)."""
    return 10.0 + 10.0 * (u - 1.0)


# --------------------------------------------------------------------------------------------
# operating point


@pytest.mark.parametrize("T", TEMPS_K)
@pytest.mark.parametrize("u", COMMANDS_V)
def test_operating_point_balances_by_hand(cfg: PlantConfig, u: float, T: float) -> None:
    op = operating_point(cfg, u, T)
    props = fuel_properties(T)
    rho, mu = props.rho, props.mu
    q, omega, p = op.q, op.omega_m, op.p_pump
    assert op.f == pytest.approx(_frequency(u), rel=1e-14)

    # pump: geometric flow − laminar leakage (∝ 1/μ) = delivered flow
    c_p = C_P_REF * MU_REF / mu
    mass = D_P * omega / TWO_PI - c_p * p - q
    assert abs(mass) <= 1e-12 * q
    assert abs(op.mass_balance) <= 1e-12 * q

    # shaft: K_T(ω_sync − ω) = B ω + D p/(2π η)
    torque_e = K_T * (TWO_PI * op.f / 2 - omega)
    torque_balance = torque_e - B_T * omega - D_P * p / (TWO_PI * ETA_M)
    assert abs(torque_balance) <= 1e-9 * torque_e
    assert abs(op.torque_balance) <= 1e-9 * torque_e
    assert op.torque == pytest.approx(torque_e, rel=1e-9)

    # line: p = Darcy–Weisbach (Churchill f from fluids) + nozzle ρq²/(2(C_d A_0)²)
    v = 4.0 * q / (math.pi * D**2)
    Re = rho * v * D / mu
    f_d = fluids.friction.Churchill_1977(Re, EPS / D)
    dp_nozzle = rho * q**2 / (2.0 * CD_A0**2)
    assert p == pytest.approx(f_d * LENGTH / D * rho * v**2 / 2.0 + dp_nozzle, rel=1e-12)
    assert op.p_nozzle == pytest.approx(dp_nozzle, rel=1e-12)
    assert op.reynolds == pytest.approx(Re, rel=1e-12)
    assert op.q_leak == pytest.approx(c_p * p, rel=1e-12)


@pytest.mark.parametrize("T", TEMPS_K)
@pytest.mark.parametrize("u", COMMANDS_V)
def test_flow_below_geometric_flow_at_synchronous_speed(
    cfg: PlantConfig, u: float, T: float
) -> None:
    # slip and leakage only take flow away: 0 < q < D_p·n_sync = 50 cm³ · 30·f rpm
    op = operating_point(cfg, u, T)
    q_sync = D_P * _frequency(u) / 2  # [m³/s], n_sync = f/m_p rev/s
    assert 0.0 < op.q < q_sync
    # and the shaft turns between zero and synchronous speed (motoring)
    assert 0.0 < op.omega_m < TWO_PI * _frequency(u) / 2


@pytest.mark.parametrize("T", TEMPS_K)
def test_minimum_frequency_gives_steady_flow_at_1V(cfg: PlantConfig, T: float) -> None:
    # 1 V → 10 Hz → 300 rpm synchronous → at most 15 L/min; slip and leakage take < 10 %
    q_lpm = operating_point(cfg, 1.0, T).q * LPM
    assert 13.5 < q_lpm < 15.0


def test_full_flow_pressure_about_1_MPa(cfg: PlantConfig) -> None:
    op = operating_point(cfg, 5.0, T0 + 20.0)
    assert 0.8e6 < op.p_pump < 1.2e6
    # turbulent line, as docs/explanation/physics.md §3.5 says (Re ~ 1e4–1e5)
    assert 1e4 < op.reynolds < 1e5


@pytest.mark.parametrize("T", TEMPS_K)
@pytest.mark.parametrize("u", [1.0, 2.0, 5.0])
def test_rhs_vanishes_at_operating_point(cfg: PlantConfig, u: float, T: float) -> None:
    op = operating_point(cfg, u, T)
    c = plant_coefficients(cfg, T)
    rhs = np.array(plant_rhs(0.0, op.state, u, c))
    # scale of each derivative: the size of the terms that cancel in it
    inductance = 4.0 * c.rho * LENGTH / (math.pi * D**2)
    scale = np.array(
        [
            op.f / T_VFD,  # Hz/s
            K_T * TWO_PI * op.f / 2 / J_T,  # rad/s²
            op.q / C_LINE,  # Pa/s
            op.p_pump / inductance,  # m³/s²
            op.q / T_F,  # m³/s²
        ]
    )
    assert np.all(np.abs(rhs) <= 1e-9 * scale)


@pytest.mark.parametrize("T", TEMPS_K)
@pytest.mark.parametrize("u", [1.0, 3.0, 5.0])
def test_jacobian_matches_central_difference(cfg: PlantConfig, u: float, T: float) -> None:
    c = plant_coefficients(cfg, T)
    x0 = operating_point(cfg, u, T).state
    jac = plant_jacobian(0.0, x0, u, c)
    fd = _finite_difference_jacobian(x0, u, c)
    # compare contributions J_ij·x_j (same unit along a row) relative to the row's largest one
    contrib, contrib_fd = jac * np.abs(x0), fd * np.abs(x0)
    row_scale = np.max(np.abs(contrib), axis=1, keepdims=True)
    assert np.all(np.abs(contrib_fd - contrib) <= 1e-5 * row_scale)
    # the structural zeros are zeros of the finite difference too
    assert np.all(fd[jac == 0.0] == 0.0)


# --------------------------------------------------------------------------------------------
# linear model


@pytest.mark.parametrize("T", TEMPS_K)
@pytest.mark.parametrize("u", [1.25, 3.0, 4.5])
def test_static_gain_matches_operating_point_difference(
    cfg: PlantConfig, u: float, T: float
) -> None:
    delta = 1e-3
    q_hi = operating_point(cfg, u + delta, T).q
    q_lo = operating_point(cfg, u - delta, T).q
    fd = (q_hi - q_lo) / (2 * delta) * LPM  # (L/min)/V
    assert _linear(u, T).static_gain == pytest.approx(fd, rel=1e-5)


@pytest.mark.parametrize("T", TEMPS_K)
@pytest.mark.parametrize("u", [1.25, 3.0, 5.0])
def test_gain_below_ideal_pump_gain(u: float, T: float) -> None:
    # ideal: 10 Hz/V · 30 rpm/Hz (2 pole pairs) · 50 cm³ = 15 (L/min)/V; pressure grows with
    # flow, so slip and leakage grow too and the incremental gain is smaller
    K = _linear(u, T).static_gain
    assert 0.7 * 15.0 < K < 15.0


def test_static_curve_second_order_term(cfg: PlantConfig) -> None:
    # secant gain of a finite step = K + ½K'Δu + O(Δu²): the static curve bends down (K falls
    # with u because pressure ∝ q² raises slip and leakage)
    T, u0, du = T0 + 20.0, 3.0, 0.2
    K0 = _linear(u0, T).static_gain
    dK = (_linear(u0 + 0.25, T).static_gain - _linear(u0 - 0.25, T).static_gain) / 0.5
    assert dK < 0.0
    secant = (operating_point(cfg, u0 + du, T).q - operating_point(cfg, u0, T).q) / du * LPM
    assert secant - K0 == pytest.approx(0.5 * dK * du, rel=0.05)


@pytest.mark.parametrize("T", TEMPS_K)
@pytest.mark.parametrize("u", [1.0, 1.25, 3.0, 5.0])
def test_linear_model_stable_and_slow_modes_real(u: float, T: float) -> None:
    lin = _linear(u, T)
    eig = np.linalg.eigvals(lin.A)
    assert np.all(eig.real < 0.0)
    # the slow dynamics (the two modes of lowest natural frequency |λ|, well below the 1–3 Hz
    # hydraulic band) are real: over-damped. (At 1 V and −20 °C the hydraulic pair decays about
    # as slowly as the meter lag, but it oscillates at ~2.4 Hz, far above the slow band.)
    slowest = eig[np.argsort(np.abs(eig))[:2]]
    assert np.all(np.abs(slowest.imag) <= 1e-9 * np.abs(slowest))
    # the drive lag and the meter lag are decoupled rows/columns of A: exact eigenvalues
    assert np.min(np.abs(eig + 1.0 / T_VFD)) <= 1e-9 / T_VFD
    assert np.min(np.abs(eig + 1.0 / T_F)) <= 1e-9 / T_F
    # the line's hydraulic mode (the complex pair) lies at 1–3 Hz (docs/explanation/physics.md §3.5)
    pair = eig[np.abs(eig.imag) > 0.0]
    assert pair.size == 2
    assert np.all((np.abs(pair.imag) / TWO_PI > 1.0) & (np.abs(pair.imag) / TWO_PI < 3.0))


@pytest.mark.parametrize("T", TEMPS_K)
@pytest.mark.parametrize("u", [1.0, 1.25, 3.0, 5.0])
def test_step_response_overdamped_no_overshoot(u: float, T: float) -> None:
    lin = _linear(u, T)
    K = lin.static_gain
    t = np.arange(0.0, 30.0, 0.01)
    y = lin.step_response(t)
    assert np.all(y[t < DELAY] == 0.0)
    assert np.max(y) <= K * (1.0 + 1e-9)  # no overshoot
    assert np.all(np.diff(y) >= -1e-9 * K)  # monotone
    assert y[-1] == pytest.approx(K, rel=1e-9)  # 30 s ≫ 5 settling times


@pytest.mark.parametrize("T", TEMPS_K)
@pytest.mark.parametrize("u", [1.25, 3.0])
def test_settling_time_5_to_6_s(u: float, T: float) -> None:
    lin, eq = _linear(u, T), _equivalent(u, T)
    assert 5.0 <= lin.settling_time() <= 6.0
    assert 5.0 <= eq.settling_time <= 6.0
    assert 5.0 <= eq.model_settling_time <= 6.0
    # the 98 % settling time is where the step response enters the ±2 % band for good
    ts, K = lin.settling_time(), lin.static_gain
    t_after = np.linspace(ts + 1e-3, ts + 20.0, 2000)
    assert np.all(np.abs(lin.step_response(t_after) - K) <= 0.02 * K)
    assert abs(float(lin.step_response(np.array([ts]))[0]) - K) == pytest.approx(0.02 * K, rel=1e-3)


@pytest.mark.parametrize("u", [1.25, 3.0])
def test_gain_drifts_with_temperature_settling_time_does_not(u: float) -> None:
    K = [_linear(u, T).static_gain for T in TEMPS_K]
    ts = [_linear(u, T).settling_time() for T in TEMPS_K]
    # warmer fuel leaks more: K falls monotonically, by at least 5 % from −20 to +50 °C
    assert K[0] > K[1] > K[2]
    assert (K[0] - K[2]) / K[0] >= 0.05
    rel_K = abs(K[2] - K[0]) / K[1]
    rel_ts = abs(ts[2] - ts[0]) / ts[1]
    assert rel_ts < rel_K / 3.0


def test_leakage_is_what_makes_gain_drift(cfg: PlantConfig) -> None:
    # docs/explanation/physics.md §6: without pump leakage only slip (through the line pressure)
    # depends on viscosity
    tight = cfg.model_copy(
        update={"pump": cfg.pump.model_copy(update={"leakage_Lpm_per_MPa": 0.0})}
    )
    cold, warm = TEMPS_K[0], TEMPS_K[2]
    drift = abs(1.0 - _linear(3.0, warm).static_gain / _linear(3.0, cold).static_gain)
    drift_tight = abs(
        1.0 - linearise(tight, 3.0, warm).static_gain / linearise(tight, 3.0, cold).static_gain
    )
    assert drift_tight < drift / 10.0


def test_flow_drop_with_warming_equals_extra_leakage(cfg: PlantConfig) -> None:
    # at a fixed command, warming −20 → 50 °C: q falls by about the growth of C_p(μ)·p (the
    # slip changes little); leakage by hand from the TS-1 viscosity: μ(−20) = 808.4·2.8696e-6,
    # μ(50) = 758·0.8305e-6 Pa·s
    cold = operating_point(cfg, 3.0, TEMPS_K[0])
    warm = operating_point(cfg, 3.0, TEMPS_K[2])
    mu_cold = (794.0 + 0.72 * 20.0) * 2.8696e-6
    mu_warm = (794.0 - 0.72 * 50.0) * 0.8305e-6
    leak_cold = C_P_REF * MU_REF / mu_cold * cold.p_pump
    leak_warm = C_P_REF * MU_REF / mu_warm * warm.p_pump
    assert leak_warm > leak_cold
    assert cold.q - warm.q == pytest.approx(leak_warm - leak_cold, rel=0.05)


# --------------------------------------------------------------------------------------------
# equivalent (reduced) model


@pytest.mark.parametrize("T", TEMPS_K)
@pytest.mark.parametrize("u", [1.25, 3.0])
def test_equivalent_model(cfg: PlantConfig, u: float, T: float) -> None:
    lin, eq = _linear(u, T), _equivalent(u, T)
    m = eq.model
    gain = m.K
    assert gain == lin.static_gain
    assert m.T_f == pytest.approx(cfg.flowmeter.time_constant_s, rel=1e-14)
    assert m.delay == cfg.flowmeter.delay_s
    assert m.T2 == 0.0
    assert eq.fit_rms < 0.02
    # the fitted T matches the moment-matched value: the mean residence time of the full model
    # −G'(0)/G(0) = C A⁻² B/(−C A⁻¹ B) equals T + T_f for the reduced model
    a_inv_b = np.linalg.solve(lin.A, lin.B)
    t_ar = float((lin.C @ np.linalg.solve(lin.A, a_inv_b))[0, 0] / -(lin.C @ a_inv_b)[0, 0])
    lag = m.T
    assert lag == pytest.approx(t_ar - m.T_f, rel=0.02)
    # and is about the drive lag plus the fast motor and hydraulic lags
    assert T_VFD < lag < T_VFD + 0.2
    # the reduced model reaches 98 % exactly at its settling time and stays there
    ts = eq.model_settling_time
    assert float(m.step_response(np.array([ts]))[0]) == pytest.approx(0.98 * m.K, rel=1e-6)
    t_after = np.linspace(ts + 1e-3, ts + 20.0, 500)
    assert np.all(np.abs(m.step_response(t_after) - m.K) < 0.02 * m.K)


# --------------------------------------------------------------------------------------------
# the ODE is the documented model, composed of the component laws


def _rhs_by_hand(
    x: np.ndarray,
    u: float,
    T: float,
    *,
    lag: float = T_VFD,
    f_max: float = 50.0,
    max_rate: float | None = None,
    J: float = J_T,
    B: float = B_T,
    eta: float = ETA_M,
    leak_lpm_per_mpa: float = 7.0,
    beta: float = 1.2e9,
    eps: float = EPS,
    cd: float = 0.7,
    p_back: float = 0.0,
    T_f: float = T_F,
) -> np.ndarray:
    """docs/explanation/physics.md §4 with the reference plant's numbers (one may be changed)."""
    props = fuel_properties(T)
    rho, mu = props.rho, props.mu
    f, omega, p, q, q_m = x
    # drive: f* = f_min + K_f (u − u_min), clipped; first-order ramp, optionally rate-limited
    f_star = min(max(10.0 + (f_max - 10.0) / 4.0 * (u - 1.0), 10.0), f_max)
    df = (f_star - f) / lag
    if max_rate is not None:
        df = min(max(df, -max_rate), max_rate)
    # shaft: J ω̇ = K_T (2πf/m_p − ω) − B ω − D_p p/(2π η_m)
    domega = (K_T * (TWO_PI * f / 2 - omega) - B * omega - D_P * p / (TWO_PI * eta)) / J
    # line capacitance: C ṗ = D_p ω/(2π) − C_p(μ) p − q
    c_p = leak_lpm_per_mpa / LPM / 1e6 * MU_REF / mu
    capacitance = math.pi * D**2 * LENGTH / (4.0 * beta)
    dp = (D_P * omega / TWO_PI - c_p * p - q) / capacitance
    # fuel column: L q̇ = p − Δp_f − Δp_N − p_back (Churchill friction factor from fluids)
    v = 4.0 * q / (math.pi * D**2)
    f_d = fluids.friction.Churchill_1977(rho * abs(v) * D / mu, eps / D)
    dp_friction = f_d * LENGTH / D * rho * v * abs(v) / 2.0
    dp_nozzle = rho * q * abs(q) / (2.0 * (cd * CD_A0 / 0.7) ** 2)
    inductance = 4.0 * rho * LENGTH / (math.pi * D**2)
    dq = (p - dp_friction - dp_nozzle - p_back) / inductance
    # meter: T_f q̇_m = q − q_m
    dq_m = (q - q_m) / T_f
    return np.array([df, domega, dp, dq, dq_m])


def _off_balance_state(cfg: PlantConfig, u: float, T: float, scale: float) -> np.ndarray:
    """A state away from rest: every derivative is far from zero (no cancellation)."""
    x = operating_point(cfg, u, T).state
    return x * np.array([1.0 - 0.1 * scale, 1.0 + 0.01 * scale, 1.0 + 0.2 * scale, 1.0, 0.9])


OFF_BALANCE = [(1.25, 253.15, 1.0), (3.0, 293.15, -1.0), (5.0, 323.15, 0.5)]


@pytest.mark.parametrize(("u", "T", "scale"), OFF_BALANCE)
def test_rhs_is_the_documented_model(cfg: PlantConfig, u: float, T: float, scale: float) -> None:
    x = _off_balance_state(cfg, u, T, scale)
    got = np.array(plant_rhs(0.0, x, u, plant_coefficients(cfg, T)))
    expected = _rhs_by_hand(x, u, T)
    assert np.all(np.abs(expected) > 0.0)
    np.testing.assert_allclose(got, expected, rtol=1e-11, atol=0.0)


def test_rhs_with_backflow_and_rate_limit(cfg: PlantConfig) -> None:
    # a reversed line flow (Δp signed with q) and a drive ramp limited to 2 Hz/s
    limited = cfg.model_copy(update={"vfd": cfg.vfd.model_copy(update={"max_rate_Hz_per_s": 2.0})})
    T, u = 293.15, 4.0
    x = np.array([20.0, 60.0, 2e5, -1e-4, 1e-4])
    got = np.array(plant_rhs(0.0, x, u, plant_coefficients(limited, T)))
    expected = _rhs_by_hand(x, u, T, max_rate=2.0)
    assert got[0] == 2.0  # (40 − 20)/1.2 = 16.7 Hz/s, limited
    np.testing.assert_allclose(got, expected, rtol=1e-11, atol=0.0)


# (section, key, new value, keyword of _rhs_by_hand, new value there, the one row it changes,
#  the change that row must show by the component's law, from the state x, ρ and μ)
PERTURBATIONS = [
    ("vfd", "lag_s", 2.4, "lag", 2.4, 0, "(f* − f)(1/2.4 − 1/1.2)"),
    ("vfd", "f_max_Hz", 60.0, "f_max", 60.0, 0, "ΔK_f (u − u_min)/T_vfd"),
    ("vfd", "max_rate_Hz_per_s", 0.5, "max_rate", 0.5, 0, "clip to ±0.5 Hz/s"),
    ("motor", "damping_N_m_s_per_rad", 0.05, "B", 0.05, 1, "−ΔB ω/J"),
    ("motor", "inertia_kg_m2", 0.09, "J", 0.09, 1, "ω̇ scales by J/J'"),
    ("pump", "mechanical_efficiency", 0.8, "eta", 0.8, 1, "−D_p p/(2πJ)·Δ(1/η)"),
    ("pump", "leakage_Lpm_per_MPa", 10.5, "leak_lpm_per_mpa", 10.5, 2, "−ΔC_p p/C"),
    ("pipeline", "bulk_modulus_MPa", 600.0, "beta", 0.6e9, 2, "ṗ scales by β'/β"),
    ("pipeline", "roughness_mm", 0.15, "eps", 0.15e-3, 3, "−Δf_D (l/d) ρ v|v|/(2L)"),
    ("nozzle", "discharge_coefficient", 0.6, "cd", 0.6, 3, "−ρq|q|/2·Δ(1/(C_d A_0)²)/L"),
    ("nozzle", "back_pressure_MPa", 0.1, "p_back", 1e5, 3, "−Δp_back/L"),
    ("flowmeter", "time_constant_s", 0.6, "T_f", 0.6, 4, "(q − q_m)·Δ(1/T_f)"),
]


def _predicted_change(key: str, x: np.ndarray, u: float, rho: float, mu: float) -> float:
    """The change of the one affected derivative, written from that component's law alone."""
    f, omega, p, q, q_m = x
    f_star = 10.0 + 10.0 * (u - 1.0)
    inductance = 4.0 * rho * LENGTH / (math.pi * D**2)
    v = 4.0 * q / (math.pi * D**2)
    Re = rho * abs(v) * D / mu
    a0 = CD_A0 / 0.7
    changes = {
        "lag_s": lambda: (f_star - f) * (1.0 / 2.4 - 1.0 / T_VFD),
        "f_max_Hz": lambda: (12.5 - 10.0) * (u - 1.0) / T_VFD,
        "max_rate_Hz_per_s": lambda: math.copysign(0.5, f_star - f) - (f_star - f) / T_VFD,
        "damping_N_m_s_per_rad": lambda: -(0.05 - B_T) * omega / J_T,
        "inertia_kg_m2": lambda: (
            (K_T * (TWO_PI * f / 2 - omega) - B_T * omega - D_P * p / (TWO_PI * ETA_M))
            * (1.0 / 0.09 - 1.0 / J_T)
        ),
        "mechanical_efficiency": lambda: -D_P * p / (TWO_PI * J_T) * (1.0 / 0.8 - 1.0 / ETA_M),
        "leakage_Lpm_per_MPa": lambda: -(3.5 / LPM / 1e6) * MU_REF / mu * p / C_LINE,
        # C = πd²l/(4β): half the bulk modulus, twice the capacitance, half the pressure rate
        "bulk_modulus_MPa": lambda: (
            (600.0 / 1200.0 - 1.0) * (D_P * omega / TWO_PI - C_P_REF * MU_REF / mu * p - q) / C_LINE
        ),
        "roughness_mm": lambda: (
            -(
                fluids.friction.Churchill_1977(Re, 0.15e-3 / D)
                - fluids.friction.Churchill_1977(Re, EPS / D)
            )
            * LENGTH
            / D
            * rho
            * v
            * abs(v)
            / 2.0
            / inductance
        ),
        "discharge_coefficient": lambda: (
            -rho * q * abs(q) / 2.0 * (1.0 / (0.6 * a0) ** 2 - 1.0 / (0.7 * a0) ** 2) / inductance
        ),
        "back_pressure_MPa": lambda: -1e5 / inductance,
        "time_constant_s": lambda: (q - q_m) * (1.0 / 0.6 - 1.0 / T_F),
    }
    return float(changes[key]())


@pytest.mark.parametrize(
    ("section", "key", "value", "keyword", "si_value", "row", "law"),
    PERTURBATIONS,
    ids=[p[1] for p in PERTURBATIONS],
)
@pytest.mark.parametrize(("u", "T", "scale"), OFF_BALANCE[:2])
def test_one_parameter_changes_rhs_as_its_law_predicts(
    cfg: PlantConfig,
    section: str,
    key: str,
    value: float,
    keyword: str,
    si_value: float,
    row: int,
    law: str,
    u: float,
    T: float,
    scale: float,
) -> None:
    changed = cfg.model_copy(
        update={section: getattr(cfg, section).model_copy(update={key: value})}
    )
    x = _off_balance_state(cfg, u, T, scale)
    before = np.array(plant_rhs(0.0, x, u, plant_coefficients(cfg, T)))
    after = np.array(plant_rhs(0.0, x, u, plant_coefficients(changed, T)))
    # every other derivative is untouched, to the bit
    others = np.arange(5) != row
    assert np.array_equal(after[others], before[others]), law
    # the affected one moves by what the component's law says
    props = fuel_properties(T)
    predicted = _predicted_change(key, x, u, props.rho, props.mu)
    assert predicted != 0.0
    assert after[row] - before[row] == pytest.approx(predicted, rel=1e-9), law
    # and equals the whole documented model with the new value
    expected = _rhs_by_hand(x, u, T, **{keyword: si_value})
    assert after[row] == pytest.approx(expected[row], rel=1e-11)


@pytest.mark.parametrize(
    "update",
    [
        {"flowmeter": {"time_constant_s": 0.0}},
        {"vfd": {"max_rate_Hz_per_s": 2.0}},
        {"pipeline": {"friction_method": "Clamond"}},
    ],
    ids=["no-meter-lag", "rate-limit", "Clamond"],
)
@pytest.mark.parametrize("u", [1.25, 4.0])
def test_jacobian_matches_central_difference_for_variants(
    cfg: PlantConfig, update: dict[str, dict[str, object]], u: float
) -> None:
    section, values = next(iter(update.items()))
    variant = cfg.model_copy(update={section: getattr(cfg, section).model_copy(update=values)})
    T = 293.15
    c = plant_coefficients(variant, T)
    # off balance, with the drive 1 Hz behind its command (inside a 2 Hz/s ramp limit)
    x0 = operating_point(variant, u, T).state * np.array([1.0, 0.99, 1.1, 1.05, 0.9])
    x0[0] -= 1.0
    jac = plant_jacobian(0.0, x0, u, c)
    fd = _finite_difference_jacobian(x0, u, c)
    contrib, contrib_fd = jac * np.abs(x0), fd * np.abs(x0)
    row_scale = np.max(np.abs(contrib), axis=1, keepdims=True)
    row_scale[row_scale == 0.0] = 1.0
    assert np.all(np.abs(contrib_fd - contrib) <= 1e-5 * row_scale)
    assert np.all(fd[jac == 0.0] == 0.0)


def test_rate_limited_drive_has_zero_jacobian_row(cfg: PlantConfig) -> None:
    limited = cfg.model_copy(update={"vfd": cfg.vfd.model_copy(update={"max_rate_Hz_per_s": 2.0})})
    c = plant_coefficients(limited, 293.15)
    x = operating_point(limited, 3.0, 293.15).state
    x[0] -= 10.0  # 10 Hz behind: (10 Hz)/1.2 s = 8.3 Hz/s > 2 Hz/s, the ramp limit binds
    assert np.all(plant_jacobian(0.0, x, 3.0, c)[0] == 0.0)


def test_input_jacobian_is_drive_gain_over_lag(cfg: PlantConfig) -> None:
    c = plant_coefficients(cfg, 293.15)
    # K_f/T_vfd = 10 Hz/V / 1.2 s inside the signal range (ends included), nothing else
    for u in (1.0, 3.0, 5.0):
        b = input_jacobian(u, c)
        assert b[0, 0] == pytest.approx(10.0 / T_VFD, rel=1e-14)
        assert np.all(b[1:] == 0.0)


# --------------------------------------------------------------------------------------------
# static gain, and a plant whose meter has no lag


@pytest.mark.parametrize("T_f", [T_F, 0.0])
def test_static_gain_is_python_controls_dcgain(cfg: PlantConfig, T_f: float) -> None:
    plant = cfg.model_copy(
        update={"flowmeter": cfg.flowmeter.model_copy(update={"time_constant_s": T_f})}
    )
    import control

    lin = linearise(plant, 3.0, 293.15)
    dcgain = float(np.real(control.dcgain(lin.to_state_space())))
    assert lin.static_gain == pytest.approx(dcgain, rel=1e-12)
    assert type(lin.static_gain) is float


@pytest.fixture(scope="module")
def no_lag() -> PlantConfig:
    cfg = load_plant_config()
    return cfg.model_copy(
        update={"flowmeter": cfg.flowmeter.model_copy(update={"time_constant_s": 0.0})}
    )


@pytest.mark.parametrize("T", TEMPS_K)
@pytest.mark.parametrize("u", [1.25, 3.0, 5.0])
def test_linearise_without_meter_lag(no_lag: PlantConfig, u: float, T: float) -> None:
    lin = linearise(no_lag, u, T)
    # K is the slope of the steady-state curve q(u) (one-sided at the top of the range)
    delta = 1e-3
    lo, hi = max(u - delta, 1.0), min(u + delta, 5.0)
    fd = (operating_point(no_lag, hi, T).q - operating_point(no_lag, lo, T).q) / (hi - lo) * LPM
    assert lin.static_gain == pytest.approx(fd, rel=1e-4)
    # a meter lag changes the dynamics, never the gain
    assert lin.static_gain == pytest.approx(_linear(u, T).static_gain, rel=1e-12)
    settle = lin.settling_time()
    assert math.isfinite(settle)
    # without the 0.3 s meter lag the plant settles sooner, but still after drive lag and delay
    assert DELAY + 3.0 * T_VFD < settle < _linear(u, T).settling_time()
    # the meter state carries no dynamics without a lag: it is dropped and A is Hurwitz
    assert lin.states == ("f", "omega_m", "p", "q")
    assert lin.A.shape == (4, 4)
    assert np.all(np.linalg.eigvals(lin.A).real < 0.0)


def test_equivalent_model_without_meter_lag(no_lag: PlantConfig) -> None:
    eq = linearise(no_lag, 3.0, 293.15).equivalent_model()
    assert eq.model.T_f == 0.0
    assert type(eq.model.T_f) is float
    assert math.isfinite(eq.settling_time)
    assert eq.fit_rms < 0.02
    assert T_VFD < eq.model.T < T_VFD + 0.2


def test_equivalent_model_parameters_are_plain_floats() -> None:
    m = _equivalent(3.0, 293.15).model
    for name in ("K", "T", "T2", "T_f", "delay"):
        assert type(getattr(m, name)) is float, name
    assert m.T_f == T_F


def test_plant_import_does_not_load_python_control() -> None:
    # python-control takes about a second to import; the CLI must not pay it to load a plant
    code = (
        "import sys, fuelid.plant, fuelid.plant.simulate\n"
        "from fuelid.plant import linearise, load_plant_config\n"
        "linearise(load_plant_config(), 3.0, 293.15).step_response([0.0, 1.0])\n"
        "print('control' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
