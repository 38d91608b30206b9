"""The assembled reference plant: steady states, ODE, Jacobian, linearisation and reduction.

The operating point is checked against balances written out here from the component laws (the
pipe friction factor from ``fluids``), not against the solver's own residual fields alone. The
reference plant must reproduce the facts of theory.md §1: about 1 MPa at full flow, a steady
flow at 1 V, over-damped slow dynamics, 98 % settling in 5–6 s, and a gain K that drifts with
fuel temperature by at least 5 % over −20…+50 °C while the settling time hardly moves.
"""

from __future__ import annotations

import functools
import math

import fluids.friction
import numpy as np
import pytest

from fuelid.fuel import fuel_properties
from fuelid.plant import (
    EquivalentModel,
    LinearPlant,
    PlantConfig,
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


@pytest.fixture(scope="module")
def cfg() -> PlantConfig:
    return load_plant_config()


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
    # turbulent line, as theory says (Re ~ 1e4–1e5)
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
    fd = np.zeros_like(jac)
    for j in range(5):
        h = 1e-6 * abs(x0[j])
        xp, xm = x0.copy(), x0.copy()
        xp[j] += h
        xm[j] -= h
        fd[:, j] = (np.array(plant_rhs(0.0, xp, u, c)) - np.array(plant_rhs(0.0, xm, u, c))) / (
            2 * h
        )
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
    # the line's hydraulic mode (the complex pair) lies at 1–3 Hz (theory §1)
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
    # theory §1: without pump leakage only slip (through the line pressure) depends on viscosity
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
