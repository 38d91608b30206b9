"""The online window's faster numerics equal what they replace (issue 26, second pass).

Each fast piece is checked against the computation it replaces, with the band stated from its
own error budget (not from what the code printed):

- the lags' sensitivities as filters of the input against central differences of Φ·β at a
  relative step of 1e-4 (truncation ~1e-8, rounding of the differenced responses ~1e-6 of the
  column): equal within 1e-5 of the column's largest value;
- Kaufman's projected Jacobian has the gradient Jᵀr of the exact one: against a central
  difference of ½‖r‖² within 1e-4 relative;
- (JᵀJ)⁻¹ from the SVD of R (J = QR) against the SVD of J: within the two backward-stable
  factorisations' budget (γ_(mk), the condition number), and the same parameters found
  undetermined; the sandwich as a Gram matrix against the product: within the chains'
  γ_(N+2k)·|B||F|ᵀ|F||B|; autocovariances by dot products against the FFT: within γ_m·Σ|x·x| and
  the FFT's log₂L·η; the sensitivities with and without Φ: within their rounding budget (the
  recursion's ℓ₁ gain). The budgets' bounds are in tests/support/rounding.py;
- step-ls without its diagnostics: the same model, standard errors and fit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.signal

from fuelid.identify import IdentifyOptions, ResidualAR, identify
from fuelid.identify._covariance import _autocovariance, bread, sandwich_covariance
from fuelid.identify._variable_projection import (
    Structure,
    _coefficient_derivatives,
    projected_jacobian,
    regressors,
    sensitivities,
    solve_linear,
)
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel, simulate_model
from fuelid.numerics_mode import REFERENCE_NUMERICS, WINDOW_NUMERICS
from support.rounding import fft_relative_error, gamma, product_budget, recursion_gain

H = 0.02
U_REF = 3.0
BOUNDS = [(0, 4000), (4000, 12000)]  # two segments: each its own simulation and free response


def _input(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return U_REF + np.repeat(rng.normal(0.0, 0.3, 24), 500)


STRUCTURES = [
    (Structure(1, 0.3, 0.1, "estimate", None), {"T": 2.0, "T2": 0.0, "delay": 0.1}),
    (Structure(2, 0.3, 0.1, "estimate", None), {"T": 2.0, "T2": 0.7, "delay": 0.1}),
    (Structure(2, 0.0, None, "estimate", None), {"T": 2.0, "T2": 0.7, "delay": 0.13}),
    (Structure(1, 0.0, None, "rest", U_REF), {"T": 1.2, "T2": 0.0, "delay": 0.05}),
]


def _response(st: Structure, v: dict[str, float], beta: np.ndarray, u: np.ndarray) -> np.ndarray:
    Phi = regressors(st, v["T"], v["T2"], v["delay"], u, H, U_REF, BOUNDS)
    return np.asarray(Phi @ beta[: Phi.shape[1]])


def _rounding_budget(
    st: Structure, values: dict[str, float], beta: np.ndarray, u: np.ndarray, Phi: np.ndarray
) -> np.ndarray:
    """How far two roundings of the lags' sensitivity columns may differ [unit/s], per column.

    Each column is β₀·(1/a)·(∂b·v − ∂a·s): two short filters of the delayed input v and the
    response s, then the recursion 1/a of order n (the number of lags). A sample's update rounds
    about 2n + 2 times (the recursion's n products and sums, the filters' few), each by at most
    ε of the values entering, and the recursion carries an error at its input to its output by
    at most the ℓ₁ norm of its impulse response, ‖g‖₁ = 1/Π(1 − p_i) (about 55,000 for the
    poles 0.990, 0.972 and 0.936 of lags 2 s, 0.7 s and 0.3 s at 0.02 s). Each route is thus
    within (2n + 2)·ε·‖g‖₁·β₀·(‖∂b‖₁·max|v| + ‖∂a‖₁·max|s|) of the exact column, and the two
    routes within twice that of each other. On the machine this was written on the differences
    used at most 0.08 of it.
    """
    lags = [tc for tc in (values["T"], values["T2"], st.T_f) if tc > 0.0]
    index = [0 if name == "T" else 1 for name in st.nonlinear_names if name != "delay"]
    db, da = _coefficient_derivatives(lags, values["delay"], H, index)
    g_l1 = recursion_gain([math.exp(-H / tc) for tc in lags])
    v_max = float(np.max(np.abs(u - U_REF)))
    s_max = float(np.max(np.abs(Phi[:, 0]))) + v_max  # a later segment's level taken off
    per_lag = iter(
        2.0
        * (2 * len(lags) + 2)
        * np.finfo(float).eps
        * g_l1
        * abs(beta[0])
        * (np.abs(db).sum(axis=1) * v_max + np.abs(da).sum(axis=1) * s_max)
    )
    # the delay's column is a difference quotient of two responses the routes compute alike
    return np.array([0.0 if name == "delay" else next(per_lag) for name in st.nonlinear_names])


@pytest.mark.parametrize(("st", "values"), STRUCTURES)
def test_sensitivities_equal_central_differences(st: Structure, values: dict[str, float]):
    u = _input()
    Phi = regressors(st, values["T"], values["T2"], values["delay"], u, H, U_REF, BOUNDS)
    beta = np.r_[1.5, 20.0, np.random.default_rng(1).normal(size=Phi.shape[1] - 2)]
    analytic = sensitivities(
        st, values["T"], values["T2"], values["delay"], beta, u, H, U_REF, BOUNDS, Phi
    )
    # without Φ the response is recomputed (a later segment's level not added and taken off):
    # equal to rounding, whose budget is the recursion's (a wrong level would be off by ~0.1)
    again = sensitivities(st, values["T"], values["T2"], values["delay"], beta, u, H, U_REF, BOUNDS)
    budget = _rounding_budget(st, values, beta, u, Phi)
    assert np.all(np.max(np.abs(again - analytic), axis=0) <= budget)
    for c, name in enumerate(st.nonlinear_names):
        step = 1e-4 * values[name]
        up, down = dict(values), dict(values)
        up[name] += step
        down[name] -= step
        difference = (_response(st, up, beta, u) - _response(st, down, beta, u)) / (2 * step)
        scale = float(np.max(np.abs(difference)))
        assert np.max(np.abs(analytic[:, c] - difference)) <= 1e-5 * scale, name


def test_projected_jacobian_has_the_exact_gradient():
    st, values = STRUCTURES[1]
    u = _input(2)
    truth = ProcessModel(K=1.4, T=1.7, T2=0.5, T_f=0.3, delay=0.1)
    y = 20.0 + simulate_model(truth, u, H) + np.random.default_rng(3).normal(0.0, 0.05, u.size)

    def half_sse(z: np.ndarray) -> float:
        T, T2 = math.exp(z[0]), math.exp(z[1])
        fit = solve_linear(regressors(st, T, T2, 0.1, u, H, U_REF, BOUNDS), y)
        return 0.5 * fit.sse

    z = np.log([values["T"], values["T2"]])
    fit = solve_linear(regressors(st, values["T"], values["T2"], 0.1, u, H, U_REF, BOUNDS), y)
    sens = sensitivities(st, values["T"], values["T2"], 0.1, fit.beta, u, H, U_REF, BOUNDS)
    J = projected_jacobian(fit.Phi, sens * np.array([values["T"], values["T2"]]))
    gradient = J.T @ fit.residual
    for i in range(2):
        step = np.zeros(2)
        step[i] = 1e-5
        numeric = (half_sse(z + step) - half_sse(z - step)) / 2e-5
        assert gradient[i] == pytest.approx(numeric, rel=1e-4)


def _bread_budget(J: np.ndarray, rank: int) -> np.ndarray:
    """How far (JᵀJ)⁻¹ by the SVD of R (J = QR) and by the SVD of J may differ, per entry.

    Both routes factor the column-scaled J_s = J/s (unit columns, m × k) and keep its ``rank``
    largest singular directions. Householder QR and the SVD are backward stable: each route's
    result is exact for J_s + E with ‖E‖₂ ≤ 2·γ_(mk)·‖J_s‖_F (a QR or an SVD of the m × k matrix,
    then one of a k × k one; the constant of the bound taken as 1). To first order E moves
    (J_sᵀJ_s)⁻¹ = V·Σ⁻²·Vᵀ by at most 2·κ·‖E‖₂/σ_r³ through the singular values, and as much
    again through the kept directions' turn (σ_r the smallest kept singular value, κ = σ₁/σ_r,
    the dropped ones near 0). The two routes are within twice that of each other, each entry
    unscaled by s_i·s_j.
    """
    scale = np.linalg.norm(J, axis=0)
    singular = np.linalg.svd(J / scale, compute_uv=False)
    m, k = J.shape
    perturbation = 2.0 * gamma(m * k) * math.sqrt(k)  # ‖J_s‖_F = √k
    kappa = singular[0] / singular[rank - 1]
    return 2.0 * 4.0 * kappa * perturbation / singular[rank - 1] ** 3 / np.outer(scale, scale)


def _sandwich_budget(J: np.ndarray, noise: ResidualAR) -> np.ndarray:
    """How far the sandwich as a Gram matrix and as a product may differ, per entry.

    Both are σ_e²·B·(FᵀF)·B with B = (JᵀJ)⁻¹ and F = ΨᵀJ, filtered alike: one rounds (FB)ᵀ(FB)
    block by block, the other B·(FᵀF)·B; each is within γ_(N+2k)·|B||F|ᵀ|F||B| of the exact
    chain (N rows, k columns, any order of summation). Each route computes its own B, which
    differ by at most ΔB (:func:`_bread_budget`), adding |ΔB||FᵀF||B| + |B||FᵀF||ΔB|.
    """
    B, _ = bread(J)
    dB = _bread_budget(J, J.shape[1])
    F = scipy.signal.lfilter([1.0], noise.a, J[::-1], axis=0)[::-1]
    M = np.abs(F.T @ F)
    chains = 2.0 * product_budget(B, F.T, F, B)
    return noise.sigma_e**2 * (chains + dB @ M @ np.abs(B) + np.abs(B) @ M @ dB)


def _autocovariance_budget(v: np.ndarray, spans: list[tuple[int, int]], max_lag: int) -> np.ndarray:
    """How far the autocovariance by dot products and by the FFT may differ, per lag.

    In a segment x of m samples with r₀ = Σx²: a dot product per lag is off by at most
    γ_m·Σ|x_k·x_(k+τ)|. The FFT route transforms x padded to L (a power of 2, ≥ 2m) with
    relative error ρ in the 2-norm, so Σ_f ||X̂_f|² − |X_f|²| ≤ (2ρ + ρ²)‖X‖₂² = (2ρ + ρ²)·L·r₀
    (Parseval), which the inverse's 1/L makes (2ρ + ρ²)·r₀ at any lag; the product rounds once
    more (u·r₀) and the inverse adds at most ρ·‖r‖₂ ≤ ρ·√L·r₀ (|r_τ| ≤ r₀). Summing the
    segments and dividing by n round twice more.
    """
    n = sum(b - a for a, b in spans)
    budget = np.zeros(max_lag + 1)
    for a, b in spans:
        x, m = v[a:b], b - a
        size = 1 << math.ceil(math.log2(2 * m))
        rho, r0 = fft_relative_error(size), float(x @ x)
        for k in range(min(max_lag, m - 1) + 1):
            dots = gamma(m) * float(np.abs(x[k:]) @ np.abs(x[: m - k]))
            fft = (2.0 * rho + rho**2 + gamma(3) + rho * math.sqrt(size)) * r0
            budget[k] += dots + fft
    return budget / n


def test_bread_through_qr_equals_the_svd():
    rng = np.random.default_rng(4)
    J = rng.normal(size=(3000, 5)) * np.array([1.0, 1e3, 1e-2, 5.0, 1.0])
    fast, none = bread(J)
    slow, none_slow = bread(J, REFERENCE_NUMERICS)
    assert none == none_slow == []
    assert np.all(np.abs(fast - slow) <= _bread_budget(J, rank=5))
    J[:, 4] = 2.0 * J[:, 0] - J[:, 3]  # a combination: parameters 0, 3, 4 undetermined
    fast, unidentified = bread(J)
    slow, unidentified_slow = bread(J, REFERENCE_NUMERICS)
    assert unidentified == unidentified_slow == [0, 3, 4]
    assert np.array_equal(np.isnan(fast), np.isnan(slow))
    kept = ~np.isnan(slow)
    assert np.all(np.abs(fast - slow)[kept] <= _bread_budget(J, rank=4)[kept])


def test_sandwich_as_a_gram_matrix_equals_the_product_and_stays_non_negative():
    rng = np.random.default_rng(8)
    noise = ResidualAR(a=np.array([1.0, -0.9]), sigma_e=0.3, bic={})
    J = rng.normal(size=(5000, 4))
    fast, _ = sandwich_covariance(J, noise)
    slow, _ = sandwich_covariance(J, noise, numerics=REFERENCE_NUMERICS)
    assert np.all(np.abs(fast - slow) <= _sandwich_budget(J, noise))
    # two columns 1e-7 apart (two lags that nearly coincide): variances of ~1e14 relative to
    # the others, which the product form can round below zero; a Gram matrix cannot
    J[:, 2] = J[:, 1] + 1e-7 * rng.normal(size=5000)
    fast, _ = sandwich_covariance(J, noise)
    assert np.all(np.diag(fast) >= 0.0)


def test_autocovariance_by_dot_products_equals_the_fft():
    v = np.random.default_rng(5).normal(size=10_000)
    spans = [(0, 3000), (3000, 10_000)]
    fast = _autocovariance(v, spans, 20)
    slow = _autocovariance(v, spans, 20, REFERENCE_NUMERICS)
    assert np.all(np.abs(fast - slow) <= _autocovariance_budget(v, spans, 20))


def test_step_ls_without_diagnostics_is_the_same_fit():
    u = np.repeat([3.0, 3.3, 2.9, 3.2, 3.0, 2.8], 1500)
    truth = ProcessModel(K=12.0, T=1.2, T_f=0.3, delay=0.2)
    y = 30.0 + simulate_model(truth, u, H) + np.random.default_rng(6).normal(0.0, 0.1, u.size)
    data = IOData(u=u, y=y, sample_time=H)
    options = IdentifyOptions(
        method="step-ls", flowmeter_T=0.3, delay=0.2, settling_time=6.0, control_period=0.1
    )
    full = identify(data, options)
    light = identify(data, options, diagnose=False)
    assert light.diagnostics == {}
    assert full.diagnostics
    assert light.model == full.model
    assert light.stderr == full.stderr
    assert light.fit_percent == full.fit_percent


@pytest.mark.parametrize("warm", [False, True])
def test_window_search_reaches_the_reference_optimum(warm: bool):
    """The windows' search reaches the reference optimum.

    Levenberg–Marquardt with the analytic Jacobian at the windows' statistical tolerances
    against scipy's trf with finite differences at the tight default ones: the same order, and
    every estimate within 0.05 of its standard error (the tolerances leave 0.02).
    """
    from fuelid.identify import OutputError

    u = np.repeat([3.0, 3.3, 2.9, 3.25, 3.0, 2.8, 3.1, 2.95], 600)
    truth = ProcessModel(K=12.0, T=1.2, T2=0.25, T_f=0.3, delay=0.2)
    rng = np.random.default_rng(7)
    y = 30.0 + simulate_model(truth, u, H) + rng.normal(0.0, 0.05, u.size)
    data = IOData(u=u, y=y, sample_time=H)
    init = ProcessModel(K=11.0, T=1.0, T2=0.3, T_f=0.3, delay=0.2) if warm else None
    settings = {"order": "auto", "T_f": 0.3, "delay": 0.2}
    reference = OutputError(**settings).fit(data, init=init)
    fast = OutputError(**settings, numerics=WINDOW_NUMERICS).fit(data, init=init)
    assert fast.order_choice_.chosen == reference.order_choice_.chosen
    for name in ("K", "T", "T2"):
        se = reference.stderr_[name]
        if se is None:
            continue
        assert abs(getattr(fast, f"{name}_") - getattr(reference, f"{name}_")) <= 0.05 * se, name
