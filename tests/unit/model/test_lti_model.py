"""Exact LTI responses and the process-model family against closed forms.

Closed forms used: a first-order lag K/(Ts+1) sampled with a zero-order hold over h gives
a = e^(−h/T), b = K(1 − a); its step response is K(1 − e^(−t'/T)); two or three distinct lags
give, by partial fractions, y/K = 1 − Σ_i T_i^(n−1) e^(−t'/T_i) / Π_(j≠i)(T_i − T_j).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from fuelid import lti
from fuelid.errors import FuelidError
from fuelid.model import ProcessModel
from support.rounding import gamma, modal_gain


def _lags_step(t: np.ndarray, K: float, lags: tuple[float, ...], delay: float) -> np.ndarray:
    """Unit-step response of K·e^(−θs)/Π(T_i s + 1) by partial fractions (distinct T_i)."""
    tp = np.maximum(np.asarray(t, dtype=float) - delay, 0.0)
    n = len(lags)
    y = np.ones_like(tp)
    for i, Ti in enumerate(lags):
        denom = math.prod(Ti - Tj for j, Tj in enumerate(lags) if j != i)
        y -= Ti ** (n - 1) * np.exp(-tp / Ti) / denom
    return K * y


# --------------------------------------------------------------------------------------------
# zoh_discretise


@pytest.mark.parametrize(("K", "T", "h"), [(1.0, 2.0, 1.0), (14.1, 1.25, 0.02), (3.0, 0.3, 5.0)])
def test_zoh_first_order(K: float, T: float, h: float) -> None:
    Ad, Bd = lti.zoh_discretise([[-1.0 / T]], [[K / T]], h)
    a = math.exp(-h / T)
    assert Ad[0, 0] == pytest.approx(a, rel=1e-13)
    assert Bd[0, 0] == pytest.approx(K * (1.0 - a), rel=1e-12)


def test_zoh_double_integrator() -> None:
    # ẍ = u: A_d = [[1, h], [0, 1]], B_d = [h²/2, h] (singular A is fine)
    h = 0.7
    Ad, Bd = lti.zoh_discretise([[0.0, 1.0], [0.0, 0.0]], [[0.0], [1.0]], h)
    np.testing.assert_allclose(Ad, [[1.0, h], [0.0, 1.0]], rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(Bd, [[h**2 / 2.0], [h]], rtol=1e-14, atol=1e-15)


def test_zoh_zero_step_is_identity() -> None:
    A = np.array([[-1.0, 2.0], [0.0, -3.0]])
    Ad, Bd = lti.zoh_discretise(A, [[1.0], [1.0]], 0.0)
    np.testing.assert_array_equal(Ad, np.eye(2))
    np.testing.assert_array_equal(Bd, np.zeros((2, 1)))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_zoh_matches_the_integral_by_eigendecomposition(seed: int) -> None:
    # independent of the matrix exponential: A = VΛV⁻¹ gives e^{Ah} = V e^{Λh} V⁻¹ and
    # ∫₀^h e^{Aτ}dτ = V diag((e^{λh} − 1)/λ) V⁻¹
    rng = np.random.default_rng(seed)
    M = rng.normal(size=(3, 3))
    A = M - (np.max(np.linalg.eigvals(M).real) + 0.5) * np.eye(3)  # all eigenvalues Re ≤ −0.5
    B = rng.normal(size=(3, 2))
    h = 0.37
    lam, V = np.linalg.eig(A)
    Vi = np.linalg.inv(V)
    Ad_ref = (V @ np.diag(np.exp(lam * h)) @ Vi).real
    Bd_ref = (V @ np.diag((np.exp(lam * h) - 1.0) / lam) @ Vi @ B).real
    Ad, Bd = lti.zoh_discretise(A, B, h)
    np.testing.assert_allclose(Ad, Ad_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(Bd, Bd_ref, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("delay", [0.0, 0.05, 0.1, 0.2999999, 0.3, 0.37, 2.0])
@pytest.mark.parametrize("feedthrough", [0.0, 0.4])
def test_uniform_grid_step_response_is_the_closed_form(delay: float, feedthrough: float) -> None:
    # lightly damped second order ω0 = 3 rad/s, ζ = 0.1 (the shape of the line's hydraulic mode):
    # y(t) = D + 1 − e^{−ζω0τ}(cos ω_d τ + ζ/√(1−ζ²)·sin ω_d τ), τ = t − θ ≥ 0, on the fast
    # uniform-grid path (h = 0.1 s, fractional delays included)
    w0, zeta = 3.0, 0.1
    A = [[0.0, 1.0], [-(w0**2), -2.0 * zeta * w0]]
    B, C = [[0.0], [w0**2]], [[1.0, 0.0]]
    t = np.arange(0.0, 30.0, 0.1)
    y = lti.step_response(A, B, C, feedthrough, t, delay=delay)
    tau = t - delay
    wd = w0 * np.sqrt(1.0 - zeta**2)
    shape = 1.0 - np.exp(-zeta * w0 * tau) * (
        np.cos(wd * tau) + zeta / np.sqrt(1.0 - zeta**2) * np.sin(wd * tau)
    )
    expected = np.where(tau >= -1e-12, feedthrough + shape, 0.0)
    np.testing.assert_allclose(y, expected, rtol=0.0, atol=1e-11)


def _doubling_budget(A: np.ndarray, B: np.ndarray, C: np.ndarray, h: float, n: int) -> float:
    """How far the uniform grid's step response (powers by doubling) may be from the exact one.

    The fast path applies M^(2^j), M = [[A_d, Γ], [0, 1]] of order k + 1, to the states found so
    far. Each squaring doubles the error its factor carried and adds γ_(k+1) of its entries; an
    error in a state reaches the output at most G = max_i Σ_j |C·A_d^j·e_i| times over (the
    modes' ℓ₁ gain), so a power carries at most 2·γ_(k+1)·G·(1 + max|x|) at the output (the
    doublings' errors summed as a geometric series). A state is the product of at most ⌈log₂n⌉
    such powers, and C·x rounds γ_k more. The per-time route steps through the grid's coarser
    points (whose gain is thousands of times smaller) and is bounded by the same figure: the
    two routes lie within twice it of each other.
    """
    k = A.shape[0]
    gain = modal_gain(expm(A * h), C)
    x_max = float(np.max(np.abs(np.linalg.solve(A, B))))  # the states' final values, |x| ≤ them
    per_route = 2.0 * math.ceil(math.log2(n)) * gamma(k + 1) * gain * (1.0 + x_max)
    return 2.0 * (per_route + gamma(k) * float(np.abs(C).sum()) * x_max)


def test_uniform_and_irregular_grids_agree_on_a_stiff_plant() -> None:
    # poles 1000:1 apart, 200,000 samples on the fast path against the per-time propagation
    A = np.array([[-1000.0, 0.0], [1.0, -1.0]])
    B, C = np.array([[1000.0], [0.0]]), np.array([[0.0, 1.0]])
    t = np.arange(200_000) * 1e-4
    fast = lti.step_response(A, B, C, 0.0, t, delay=0.00123)
    on_grid = t[997::997]
    probe = np.r_[0.5 * on_grid[0], on_grid]  # an extra first time: not uniform, the exact path
    slow = lti.step_response(A, B, C, 0.0, probe, delay=0.00123)
    budget = _doubling_budget(A, B, C, 1e-4, t.size)  # 4.8e-10, far below a wrong delay's error
    np.testing.assert_allclose(fast[997::997], slow[1:], rtol=0.0, atol=budget)


# --------------------------------------------------------------------------------------------
# lti.step_response and settling_time


def test_state_space_step_first_order_with_delay() -> None:
    K, T, delay = 2.5, 1.7, 0.45
    t = np.linspace(0.0, 15.0, 1501)
    y = lti.step_response([[-1.0 / T]], [[K / T]], [[1.0]], 0.0, t, delay=delay)
    expected = np.where(t >= delay, K * (1.0 - np.exp(-(t - delay) / T)), 0.0)
    np.testing.assert_allclose(y, expected, rtol=0.0, atol=1e-12 * K)
    assert np.all(y[t < delay] == 0.0)


def test_state_space_step_irregular_grid_and_feedthrough() -> None:
    # y = D + K(1 − e^(−t/T)) on an irregular grid: the ZOH propagation is exact for any step
    K, T, Dff = 1.0, 0.8, 0.25
    t = np.sort(np.random.default_rng(3).uniform(0.0, 6.0, 60))
    y = lti.step_response([[-1.0 / T]], [[K / T]], [[1.0]], Dff, t)
    np.testing.assert_allclose(y, Dff + K * (1.0 - np.exp(-t / T)), rtol=0.0, atol=1e-12)


def test_settling_time_first_order() -> None:
    # 1 − e^(−t/T) enters the 2 % band at T·ln(50) = 3.912·T
    T = 2.0
    t = np.linspace(0.0, 20.0, 200_001)
    assert lti.settling_time(t, 1.0 - np.exp(-t / T), 1.0) == pytest.approx(
        T * math.log(50.0), rel=1e-6
    )
    # 5 % band: T·ln(20)
    assert lti.settling_time(t, 1.0 - np.exp(-t / T), 1.0, band=0.05) == pytest.approx(
        T * math.log(20.0), rel=1e-6
    )


def test_settling_time_nan_when_not_settled() -> None:
    t = np.linspace(0.0, 5.0, 501)  # 5 s < 3.9·T = 7.8 s
    assert math.isnan(lti.settling_time(t, 1.0 - np.exp(-t / 2.0), 1.0))


# --------------------------------------------------------------------------------------------
# ProcessModel


@pytest.mark.parametrize(
    ("K", "T", "T_f", "delay"),
    [(2.5, 3.0, 0.5, 0.7), (14.1, 1.24, 0.3, 0.2), (-0.8, 0.4, 2.0, 0.0)],
)
def test_process_step_with_meter_lag_closed_form(
    K: float, T: float, T_f: float, delay: float
) -> None:
    m = ProcessModel(K=K, T=T, T_f=T_f, delay=delay)
    t = np.linspace(0.0, 30.0, 3001)
    tp = t - delay
    expected = np.where(
        tp >= 0.0,
        K * (1.0 - (T * np.exp(-tp / T) - T_f * np.exp(-tp / T_f)) / (T - T_f)),
        0.0,
    )
    np.testing.assert_allclose(m.step_response(t), expected, rtol=0.0, atol=1e-11 * abs(K))


def test_process_step_three_lags_partial_fractions() -> None:
    K, lags, delay = 3.0, (4.0, 1.5, 0.3), 1.1
    m = ProcessModel(K=K, T=lags[0], T2=lags[1], T_f=lags[2], delay=delay)
    t = np.linspace(0.0, 40.0, 2001)
    np.testing.assert_allclose(m.step_response(t), _lags_step(t, K, lags, delay), atol=1e-11 * K)


@pytest.mark.parametrize(("T", "delay"), [(1.0, 0.0), (1.0, 0.5), (2.7, 1.3)])
def test_first_order_settling_time(T: float, delay: float) -> None:
    # θ + T·ln(50)
    m = ProcessModel(K=5.0, T=T, delay=delay)
    assert m.settling_time() == pytest.approx(delay + T * math.log(50.0), rel=1e-6)


@pytest.mark.parametrize(("T", "T_f", "delay"), [(1.24, 0.3, 0.2), (3.0, 0.5, 0.0)])
def test_second_order_settling_reaches_98_percent(T: float, T_f: float, delay: float) -> None:
    K = 7.0
    m = ProcessModel(K=K, T=T, T_f=T_f, delay=delay)
    ts = m.settling_time()
    # closed form at the settling time is exactly 98 % of K (monotone response)
    assert _lags_step(np.array([ts]), K, (T, T_f), delay)[0] == pytest.approx(0.98 * K, rel=1e-7)
    # slower than the slowest lag alone, faster than the sum of both lags times ln 50
    assert delay + T * math.log(50.0) < ts < delay + (T + T_f) * math.log(50.0)


@pytest.mark.parametrize(("K", "T", "T2", "T_f"), [(2.0, 4.0, 0.0, 0.0), (14.1, 1.24, 0.0, 0.3)])
def test_to_control_gain_and_poles(K: float, T: float, T2: float, T_f: float) -> None:
    tf = ProcessModel(K=K, T=T, T2=T2, T_f=T_f, delay=0.4).to_control()
    assert float(np.real(tf.dcgain())) == pytest.approx(K, rel=1e-13)
    expected_poles = sorted(-1.0 / tc for tc in (T, T2, T_f) if tc > 0.0)
    np.testing.assert_allclose(np.sort(np.real(tf.poles())), expected_poles, rtol=1e-12)


def test_state_space_static_gain() -> None:
    m = ProcessModel(K=3.3, T=2.0, T2=0.7, T_f=0.3)
    A, B, C, Dff = m.state_space()
    assert float((-C @ np.linalg.solve(A, B) + Dff)[0, 0]) == pytest.approx(3.3, rel=1e-13)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"K": 1.0, "T": 0.0},
        {"K": 1.0, "T": -1.0},
        {"K": 1.0, "T": 1.0, "delay": -0.1},
        {"K": 1.0, "T": 1.0, "T2": -0.5},
        {"K": 1.0, "T": 1.0, "T_f": -0.3},
        {"K": float("nan"), "T": 1.0},
        {"K": 1.0, "T": float("nan")},
        {"K": 1.0, "T": float("inf")},
        {"K": 1.0, "T": 1.0, "delay": float("nan")},
    ],
)
def test_invalid_parameters_refused(kwargs: dict[str, float]) -> None:
    with pytest.raises(FuelidError, match="model"):
        ProcessModel(**kwargs)
