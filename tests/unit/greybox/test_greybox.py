"""Gray-box ODE estimation checked against numbers theory fixes.

Sensitivities against finite differences of whole simulations, covariances against the
Cramér–Rao bound and a closed-form steady-state formula, identifiability against exact symmetries.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

from fuelid.errors import DataError, FuelidError
from fuelid.greybox import (
    ConvergenceError,
    GreyBoxEstimator,
    NotIdentifiableError,
    OdeModel,
    ParameterSpec,
    Record,
    describe_identifiability,
    identifiability,
    parameter_specs,
)
from fuelid.greybox._identifiability import UndeterminedCombination
from fuelid.greybox._parameters import ParameterMap
from fuelid.greybox._sensitivity import Trajectory, simulate_record
from fuelid.greybox._solvers import Solver
from support.bands import coverage_band, rmse_ratio_band

FloatArray = NDArray[np.float64]
TANK_TRUTH = {"k1": 0.05, "k2": 0.04, "k3": 0.05, "k4": 0.06}
TANK_X0 = np.array([1.0, 0.8])


# --- models ---------------------------------------------------------------------------------------
def tank_f(t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    """Two Torricelli tanks in series; the pump feeds the first."""
    x1 = np.maximum(x[0], 0.0)
    x2 = np.maximum(x[1], 0.0)
    return [-p["k1"] * np.sqrt(x1) + p["k4"] * u[0], p["k2"] * np.sqrt(x1) - p["k3"] * np.sqrt(x2)]


def tank_f_scalar(t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    """The same tanks with math.sqrt and an if on a state: scalars only."""
    x1 = x[0] if x[0] > 0.0 else 0.0
    x2 = max(x[1], 0.0)
    return [
        -p["k1"] * math.sqrt(x1) + p["k4"] * u[0],
        p["k2"] * math.sqrt(x1) - p["k3"] * math.sqrt(x2),
    ]


def second_tank(x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    return x[1]


def tank_model(
    fixed: tuple[str, ...] = ("k4",), start_factor: float = 1.3, f: Any = tank_f
) -> OdeModel:
    specs = [ParameterSpec(k, v * start_factor, 0.0) for k, v in TANK_TRUTH.items()]
    specs = list(parameter_specs(specs, fixed=fixed, values={k: TANK_TRUTH[k] for k in fixed}))
    return OdeModel(f, specs, ["x1", "x2"], h=second_tank)


def tank_record(n: int = 1000, noise: float = 0.01, seed: int = 0) -> tuple[Record, FloatArray]:
    """A 1 s-sampled tank record with 20 held random pump levels; also the noise-free output."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1.0
    u = np.repeat(rng.uniform(0.5, 1.5, n // 50 + 1), 50)[:n]
    truth = tank_model(fixed=tuple(TANK_TRUTH), start_factor=1.0)
    blank = Record.from_arrays(t, u, np.zeros(n))
    clean = simulate_record(truth.bind(TANK_TRUTH, [], blank), blank, TANK_X0).outputs[:, 0]
    return Record.from_arrays(t, u, clean + rng.normal(0.0, noise, n)), clean


def first_order_f(t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    return [(p["K"] * u[0] - x[0]) / p["T"]]


def first_order_model(x0: bool = True, start: tuple[float, float] = (1.5, 3.0)) -> OdeModel:
    """Y' = (K·u − y)/T, at rest (y = 0) at the first sample when ``x0``."""
    return OdeModel(
        first_order_f,
        [ParameterSpec("K", start[0], 0.0), ParameterSpec("T", start[1], 0.0)],
        ["y"],
        x0=(lambda p, u0, y0: [0.0]) if x0 else None,
    )


def step_response(t: FloatArray, a: float, K: float, T: float) -> FloatArray:
    return K * a * (1.0 - np.exp(-t / T))


# --- sensitivities --------------------------------------------------------------------------------
def central_difference(simulate: Any, phi: FloatArray, relative_step: float = 1e-4) -> FloatArray:
    columns = []
    for j in range(len(phi)):
        step = relative_step * max(abs(phi[j]), 1.0)
        up, down = phi.copy(), phi.copy()
        up[j] += step
        down[j] -= step
        columns.append((simulate(up) - simulate(down)) / (2.0 * step))
    return np.stack(columns, axis=-1)


def tank_sensitivity_errors(
    model: OdeModel, method: str = "lsoda", with_theta: bool = True
) -> tuple[FloatArray, Trajectory]:
    """Each sensitivity column's largest error against central differences, relative.

    The tank record at the start values, the initial state estimated; the reference: central
    differences of simulations at rtol 1e-11. Without ``with_theta`` only the initial state's
    columns are integrated (as for a validation record's initial state). Also returns the
    trajectory with sensitivities.
    """
    record, _ = tank_record(400)
    pmap = ParameterMap(model.parameters)
    p = len(pmap.free_names)
    phi = np.concatenate([pmap.start(), TANK_X0])
    solver = Solver(method)

    def simulate(phi_: FloatArray) -> FloatArray:
        system = model.bind(pmap.values(phi_[:p]), pmap.free_names, record)
        out = simulate_record(system, record, phi_[p:], rtol=1e-11, solver=solver)
        return out.outputs[:, 0]

    system = model.bind(pmap.values(phi[:p]), pmap.free_names, record)
    s0 = np.hstack([np.zeros((2, p)), np.eye(2)]) if with_theta else np.eye(2)
    scale = pmap.dtheta_dphi(phi[:p]) if with_theta else None
    trajectory = simulate_record(system, record, phi[p:], s0, scale, solver=solver)
    assert trajectory.output_sensitivity is not None
    assert system._fused_at is not None  # the fused right-hand side ran
    reference = central_difference(simulate, phi)[:, slice(0 if with_theta else p, p + 2)]
    analytic = trajectory.output_sensitivity[:, 0, :]
    return np.abs(analytic - reference).max(axis=0) / np.abs(reference).max(axis=0), trajectory


def test_tank_sensitivities_match_finite_differences() -> None:
    # band: 1e-4 of each column's largest value (the integration's and the differences' error)
    error, _ = tank_sensitivity_errors(tank_model())
    assert np.all(error < 1e-4), error


@pytest.mark.parametrize("method", ["lsoda", "bdf", "radau"])
@pytest.mark.parametrize("with_theta", [True, False])
def test_scalar_rhs_sensitivities_match_finite_differences(method: str, with_theta: bool) -> None:
    """An f of scalars takes the fused right-hand side; its sensitivities are the same.

    With and without the parameters' columns (a validation record's initial state alone), and
    under the implicit methods, whose Newton matrix reuses the fused differences. The band is
    the batched f's (above): 1e-4 of each column's largest value.
    """
    error, _ = tank_sensitivity_errors(tank_model(f=tank_f_scalar), method, with_theta)
    assert np.all(error < 1e-4), error


def tank_f_batch_below(t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    """tank_f, refusing a batch once the upper level is above 1.1 (a branch written later)."""
    if np.ndim(x) > 1 and np.any(x[0] > 1.1):
        raise TypeError("a batch above 1.1")
    return tank_f(t, x, u, p)


def test_a_batched_f_that_stops_broadcasting_keeps_its_sensitivities() -> None:
    """Where the batched call fails partway, the scalar differences stand in (same band)."""
    model = tank_model(f=tank_f_batch_below)
    error, trajectory = tank_sensitivity_errors(model)
    assert model._mode.f_vectorised is True
    assert np.any(trajectory.states[:, 0] > 1.1)  # the batch was refused somewhere
    assert np.all(error < 1e-4), error


class DelayedLag:
    """x' = (g·u − x)/T with the output read τ late: an OdeSystem written by hand."""

    def __init__(self, g: float, T: float, delay: float) -> None:
        self.g, self.T = g, T
        self.n_states = 1
        self.atol = np.array([1e-10])
        self.output_delay = delay

    def derivatives(self, t: float, x: FloatArray, u: FloatArray) -> tuple[Any, Any, Any]:
        dx = np.array([(self.g * u[0] - x[0]) / self.T])
        jac_theta = np.array([[u[0] / self.T, -dx[0] / self.T]])
        return dx, np.array([[-1.0 / self.T]]), jac_theta

    def state_jacobian(self, t: float, x: FloatArray, u: FloatArray) -> FloatArray:
        return np.array([[-1.0 / self.T]])

    def outputs(self, x: FloatArray, u: FloatArray) -> tuple[Any, Any, Any]:
        n = len(x)
        return x.copy(), np.ones((n, 1, 1)), np.zeros((n, 1, 2))

    def initial_state(self, u0: FloatArray, y0: FloatArray) -> tuple[Any, Any]:
        return np.array([self.g * u0[0]]), np.array([[u0[0], 0.0]])


def test_delayed_output_sensitivities_match_finite_differences() -> None:
    t = np.arange(300) * 0.5
    u = np.where(t < 20.0, 1.0, np.where(t < 80.0, 2.0, 0.5))
    record = Record.from_arrays(t, u, np.zeros(len(t)))
    delay = 3.3  # not a multiple of the sample time

    def trajectory(phi: FloatArray, sens: bool = False, rtol: float = 1e-6) -> Any:
        theta = np.exp(phi)
        system = DelayedLag(theta[0], theta[1], delay)
        x0, dx0 = system.initial_state(u[:1], np.zeros(1))
        return simulate_record(
            system, record, x0, dx0 * theta if sens else None, theta if sens else None, rtol=rtol
        )

    phi = np.log([2.0, 7.0])
    out = trajectory(phi, sens=True)
    # the delay is applied: the output holds still for τ after the first step at 20 s
    g, T = 2.0, 7.0
    shifted = np.clip(t - delay - 20.0, 0.0, None)
    expected = g * (1.0 + (1.0 - np.exp(-shifted / T)))
    window = t < 80.0 + delay
    assert np.allclose(out.outputs[window, 0], expected[window], atol=1e-5)
    reference = central_difference(lambda ph: trajectory(ph, rtol=1e-11).outputs[:, 0], phi)
    analytic = out.output_sensitivity[:, 0, :]
    error = np.abs(analytic - reference).max(axis=0) / np.abs(reference).max(axis=0)
    assert np.all(error < 1e-4), error


# --- covariance against theory --------------------------------------------------------------------
def test_gain_stderr_matches_the_closed_form_for_a_step() -> None:
    """K's and T's standard errors equal the closed form for one step.

    One step of size a from rest, h ≪ T ≪ L = N·h: the Fisher information of (K, T) in closed
    form gives var K̂ = σ²·h / (a²·(L − 3.75·T)) and var T̂ = 4Tσ²h(L − 1.5T)/(K²a²(L − 3.75T))
    (→ sd T̂/T = √(4h/T)·σ/(Ka) for L → ∞, theory.md §3.2).
    """
    h, n, a, gain, tau, noise = 0.1, 1000, 1.0, 2.0, 2.0, 0.05
    t = np.arange(n) * h
    rng = np.random.default_rng(1)
    y = step_response(t, a, gain, tau) + rng.normal(0.0, noise, n)
    est = GreyBoxEstimator(first_order_model()).fit(Record.from_arrays(t, np.full(n, a), y))
    length = n * h
    sigma, k_hat, t_hat = est.sigma_[0], est.params_["K"], est.params_["T"]
    sd_k = sigma / a * math.sqrt(h / (length - 3.75 * t_hat))
    sd_t = math.sqrt(
        4
        * t_hat
        * sigma**2
        * h
        * (length - 1.5 * t_hat)
        / ((k_hat * a) ** 2 * (length - 3.75 * t_hat))
    )
    assert est.stderr_["K"] == pytest.approx(sd_k, rel=0.01)
    assert est.stderr_["T"] == pytest.approx(sd_t, rel=0.01)
    assert est.sigma_[0] == pytest.approx(noise, rel=0.1)
    assert abs(k_hat - gain) < 3 * sd_k
    assert abs(t_hat - tau) < 3 * sd_t


def crb_linear(
    t: FloatArray, u: FloatArray, gain: float, tau: float, x0: float, noise: float
) -> Any:
    """σ²(JᵀJ)⁻¹ for (K, T, x0) on the noise-free response, natural units."""
    model = first_order_model(x0=False)
    record = Record.from_arrays(t, u, np.zeros(len(t)))
    pmap = ParameterMap(model.parameters)
    values = {"K": gain, "T": tau}
    system = model.bind(values, pmap.free_names, record)
    scale = np.array([gain, tau])
    s0 = np.array([[0.0, 0.0, 1.0]])
    out = simulate_record(system, record, np.array([x0]), s0, scale, rtol=1e-9)
    jac = out.output_sensitivity[:, 0, :] / noise
    cov_phi = np.linalg.inv(jac.T @ jac)
    return np.sqrt(np.diag(cov_phi)) * np.array([gain, tau, 1.0]), out.outputs[:, 0]


MC_RUNS = 150


def linear_monte_carlo(runs: int, seed: int = 7) -> dict[str, Any]:
    """Fit K, T and x0 of y' = (K·u − y)/T to ``runs`` noisy copies of one two-step record."""
    h, n, gain, tau, x0, noise = 0.1, 300, 2.0, 1.5, 0.5, 0.05
    t = np.arange(n) * h
    u = np.where(t < 10.0, 1.0, 0.2)
    bound, clean = crb_linear(t, u, gain, tau, x0, noise)
    rng = np.random.default_rng(seed)
    estimates, covered = [], []
    model = first_order_model(x0=False)
    for _ in range(runs):
        record = Record.from_arrays(t, u, clean + rng.normal(0.0, noise, n))
        est = GreyBoxEstimator(model).fit(record)
        estimates.append([est.params_["K"], est.params_["T"]])
        covered.append(
            [lo <= true <= hi for (lo, hi), true in ((est.ci95_["K"], gain), (est.ci95_["T"], tau))]
        )
    errors = np.array(estimates) - [gain, tau]
    return {
        "rmse": np.sqrt(np.mean(errors**2, axis=0)),
        "bias": np.mean(errors, axis=0),
        "crb": bound[:2],
        "coverage": np.mean(covered, axis=0),
    }


def test_monte_carlo_reaches_the_cramer_rao_bound_and_intervals_cover() -> None:
    """Output error on white noise is maximum likelihood.

    RMSE ≈ the Cramér–Rao bound (the
    Monte Carlo RMSE has a relative spread of 1/√(2M) ≈ 6 %), and 95 % intervals cover.
    """
    # bands pre-registered from the statistics (tests/bands.py, 0.1 % false alarm each): the
    # RMSE/CRB ratio of an efficient estimator over 150 runs, and the misses of correct 95 %
    # intervals over 150 runs
    low, high = rmse_ratio_band(MC_RUNS)
    result = linear_monte_carlo(MC_RUNS)
    ratio = result["rmse"] / result["crb"]
    assert np.all((low <= ratio) & (ratio <= high)), (ratio, low, high)
    lo, hi = coverage_band(MC_RUNS)
    misses = np.round((1.0 - result["coverage"]) * MC_RUNS)
    assert np.all((lo <= misses) & (misses <= hi)), (misses, lo, hi)


# --- profile likelihood ---------------------------------------------------------------------------
def test_profile_interval_matches_the_gaussian_one_when_well_determined() -> None:
    h, n, a, noise = 0.1, 1000, 1.0, 0.05
    t = np.arange(n) * h
    y = step_response(t, a, 2.0, 2.0) + np.random.default_rng(3).normal(0.0, noise, n)
    est = GreyBoxEstimator(first_order_model()).fit(Record.from_arrays(t, np.full(n, a), y))
    for name in ("K", "T"):
        low, high = est.ci95_[name]
        p_low, p_high = est.profile_interval(name)
        half = (high - low) / 2.0
        assert abs(p_low - low) < 0.03 * half
        assert abs(p_high - high) < 0.03 * half


def test_profile_interval_is_asymmetric_where_the_model_is_nonlinear() -> None:
    """A short record skews T's likelihood.

    A record far shorter than T: y ≈ K·a·t/T·(1 − t/2T), so T is seen through 1/T and its
    likelihood is skewed; estimated in linear space (no lower bound) its Gaussian interval is
    symmetric, the profile reaches further up than down.
    """
    h, n, a, noise, gain, tau = 0.1, 50, 1.0, 0.02, 2.0, 10.0
    t = np.arange(n) * h
    y = step_response(t, a, gain, tau) + np.random.default_rng(3).normal(0.0, noise, n)
    model = OdeModel(
        first_order_f,
        [ParameterSpec("K", 1.5, 0.0), ParameterSpec("T", 7.0)],
        ["y"],
        x0=lambda p, u0, y0: [0.0],
    )
    est = GreyBoxEstimator(model).fit(Record.from_arrays(t, np.full(n, a), y))
    t_hat = est.params_["T"]
    low, high = est.ci95_["T"]
    assert high - t_hat == pytest.approx(t_hat - low)
    p_low, p_high = est.profile_interval("T")
    assert (p_high - t_hat) / (t_hat - p_low) > 1.2
    assert p_high > high
    assert p_low < tau < p_high


def test_profile_interval_stops_at_a_bound_inside_it() -> None:
    h, n, a, noise, gain, tau = 0.1, 50, 1.0, 0.02, 2.0, 10.0
    t = np.arange(n) * h
    y = step_response(t, a, gain, tau) + np.random.default_rng(3).normal(0.0, noise, n)
    model = OdeModel(
        first_order_f,
        [ParameterSpec("K", 1.5, 0.0), ParameterSpec("T", 7.0, upper=11.0)],
        ["y"],
        x0=lambda p, u0, y0: [0.0],
    )
    est = GreyBoxEstimator(model).fit(Record.from_arrays(t, np.full(n, a), y))
    assert est.params_["T"] < 11.0
    p_low, p_high = est.profile_interval("T")
    assert p_high == pytest.approx(11.0)
    assert p_low < est.params_["T"]
    ci = est.ci95_["T"]
    assert ci is not None
    assert ci[1] == 11.0


# --- identifiability ------------------------------------------------------------------------------
def test_tank_with_every_k_free_is_refused_naming_the_symmetry() -> None:
    """The scale of the first tank is invisible in the second one's level.

    x1 → x1/c (and its start) with k1 → k1/√c, k2 → k2·√c, k4 → k4/c leaves the second
    tank, the output, unchanged.
    """
    record, _ = tank_record()
    with pytest.raises(NotIdentifiableError) as caught:
        GreyBoxEstimator(tank_model(fixed=())).fit(record)
    report = caught.value.report
    assert {"k1", "k2", "k4"} <= set(report.undetermined_names)
    assert "k3" not in report.undetermined_names
    (combination,) = report.undetermined
    weights = dict(zip(combination.names, combination.weights, strict=True))
    # the exact null vector in relative (log) units: (k1, k2, k4, x0[x1]) ∝ (−½, ½, −1, −1)
    expected = np.array([-0.5, 0.5, -1.0, -1.0]) / math.sqrt(2.5)
    got = np.array([weights["k1"], weights["k2"], weights["k4"], weights["x0[x1]"]])
    assert np.allclose(got * np.sign(got[2] / expected[2]), expected, atol=1e-3)
    for name in ("k1", "k2", "k4"):
        assert name in str(caught.value)


def test_the_symmetry_refusal_carries_its_simulated_evidence() -> None:
    """An exact symmetry: a step of ±10 % along it leaves the simulated outputs unchanged.

    Only the integrator's error (relative 1e-6) moves the weighted cost; a change under χ²₁'s
    3.84 is what the data cannot see, and an exact symmetry stays far under it (< 0.01).
    """
    record, _ = tank_record()
    with pytest.raises(NotIdentifiableError) as caught:
        GreyBoxEstimator(tank_model(fixed=())).fit(record)
    found = re.search(r"moves the simulated weighted cost by ([0-9.e+-]+)", str(caught.value))
    assert found is not None, str(caught.value)
    assert float(found.group(1)) < 0.01
    assert "at the start values" in str(caught.value)


def test_a_combination_the_simulation_contradicts_is_not_reported_as_undetermined() -> None:
    """k2/k1 sets the steady gain, determined to about 1 %: a 10 % step along it is plainly seen.

    Offered as if the sensitivities had called (k1, k2) undetermined, the simulated check must
    contradict it: the weighted cost rises by ~(0.1/0.01)² ≫ 3.84 (band: above 50), and the
    report then lists it as unconfirmed, not among the undetermined combinations.
    """
    record, _ = tank_record()
    est = GreyBoxEstimator(tank_model()).fit(record)
    claim = UndeterminedCombination(("k1", "k2"), (math.sqrt(0.5), -math.sqrt(0.5)), math.inf)
    rises = est._simulated_rises(est.phi_, [record], est.sigma_, _evaluation(est, record), [claim])
    assert rises[claim.names] > 50.0
    report = replace(est.identifiability_, undetermined=(claim,)).contradicted(rises)
    assert report.undetermined == ()
    assert report.unconfirmed == ((("k1", "k2"), rises[claim.names]),)
    assert "trade against each other" not in report.message()
    assert "k1, k2" in report.unconfirmed_message()


def _evaluation(est: GreyBoxEstimator, record: Record) -> Any:
    """The fitted estimator's evaluation at its estimate (residuals weighted by its σ)."""
    return est._evaluate(est.phi_, [record], est.sigma_, jacobian=False)


def test_tank_with_k4_fixed_is_recovered() -> None:
    record, _ = tank_record()
    est = GreyBoxEstimator(tank_model()).fit(record)
    assert est.identifiability_.identifiable
    for name in ("k1", "k2", "k3"):
        error = abs(est.params_[name] - TANK_TRUTH[name])
        stderr = est.stderr_[name]
        assert stderr is not None
        assert error < 3 * stderr
        assert error < 0.05 * TANK_TRUTH[name]
    assert est.stderr_["k4"] is None
    assert est.ci95_["k4"] is None
    assert np.allclose(est.x0_[0], TANK_X0, atol=0.05)
    assert est.sigma_[0] == pytest.approx(0.01, rel=0.1)


def test_a_parameter_the_output_ignores_has_zero_sensitivity() -> None:
    model = OdeModel(
        lambda t, x, u, p: [(p["K"] * u[0] - x[0]) / p["T"]],
        [ParameterSpec("K", 1.0, 0.0), ParameterSpec("T", 2.0, 0.0), ParameterSpec("c", 3.0, 0.0)],
        ["y"],
        x0=lambda p, u0, y0: [0.0],
    )
    t = np.arange(200) * 0.1
    y = step_response(t, 1.0, 2.0, 2.0) + np.random.default_rng(0).normal(0.0, 0.01, 200)
    with pytest.raises(NotIdentifiableError) as caught:
        GreyBoxEstimator(model).fit(Record.from_arrays(t, np.ones(200), y))
    assert caught.value.report.zero_sensitivity == ("c",)


def test_parameters_entering_as_a_product_are_one_combination() -> None:
    """Only k·g is determined when k and g enter as a product.

    y' = (k·g·u − y)/T: only k·g is determined; the null direction in log space is
    (1, −1)/√2 (k/g is free), i.e. the determined exponents are (1, 1)/√2.
    """
    model = OdeModel(
        lambda t, x, u, p: [(p["k"] * p["g"] * u[0] - x[0]) / p["T"]],
        [ParameterSpec("k", 1.0, 0.0), ParameterSpec("g", 3.0, 0.0), ParameterSpec("T", 2.0, 0.0)],
        ["y"],
        x0=lambda p, u0, y0: [0.0],
    )
    t = np.arange(200) * 0.1
    y = step_response(t, 1.0, 2.0, 2.0) + np.random.default_rng(0).normal(0.0, 0.01, 200)
    with pytest.raises(NotIdentifiableError) as caught:
        GreyBoxEstimator(model).fit(Record.from_arrays(t, np.ones(200), y))
    (combination,) = caught.value.report.undetermined
    assert set(combination.names) == {"k", "g"}
    weights = dict(zip(combination.names, combination.weights, strict=True))
    assert abs(weights["k"]) == pytest.approx(1 / math.sqrt(2), abs=1e-4)
    assert weights["g"] == pytest.approx(-weights["k"], abs=1e-4)


def test_collinearity_index_of_two_correlated_columns() -> None:
    """Two unit columns at correlation ρ have singular values √(1 ± ρ): γ = 1/√(1 − |ρ|)."""
    rng = np.random.default_rng(0)
    a = rng.normal(size=500)
    b = rng.normal(size=500)
    b -= a * (a @ b) / (a @ a)
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    for rho in (0.5, 0.9995):
        jac = np.column_stack([a * 3.0, (rho * a + math.sqrt(1 - rho**2) * b) * 0.2])
        report = identifiability(jac, ["p", "q"])
        assert report.collinearity_index == pytest.approx(1 / math.sqrt(1 - rho), rel=1e-9)
        assert bool(report.confounded_pairs) == (rho > 0.999)
        if report.confounded_pairs:
            assert report.confounded_pairs[0][2] == pytest.approx(rho)


def test_identifiability_text_names_what_the_data_do_not_determine() -> None:
    J = np.array([[1.0, 2.0], [2.0, 4.0], [3.0, 6.0]])
    lines = describe_identifiability(identifiability(J, ["a", "b"]).to_json())
    assert lines[0].startswith("identifiability: rank 1 of 2 (a, b)")
    assert lines[1].startswith("undetermined combinations: a^")
    assert lines[2].startswith("confounded pairs: a–b")


# --- model functions ------------------------------------------------------------------------------
def test_a_scalar_only_rhs_gives_the_same_estimate_as_a_vectorised_one() -> None:
    record, _ = tank_record(600)
    vectorised = GreyBoxEstimator(tank_model()).fit(record)
    scalar_model = tank_model(f=tank_f_scalar)
    scalar = GreyBoxEstimator(scalar_model).fit(record)
    assert scalar_model._mode.f_vectorised is False
    for name in ("k1", "k2", "k3"):
        assert scalar.params_[name] == pytest.approx(vectorised.params_[name], rel=1e-5)
        assert scalar.stderr_[name] == pytest.approx(vectorised.stderr_[name], rel=1e-3)


# --- records and initial states -------------------------------------------------------------------
def two_step_records(seed: int = 0, noise: float = 0.02) -> tuple[list[Record], list[float]]:
    rng = np.random.default_rng(seed)
    h, gain, tau = 0.1, 2.0, 1.5
    records, starts = [], []
    for i, (x0, level) in enumerate(((0.5, 1.0), (3.0, 0.2), (1.0, 0.9))):
        t = np.arange(150 + 50 * i) * h
        u = np.where(t < 6.0, level, 1.2 - level)
        system = first_order_model(x0=False).bind(
            {"K": gain, "T": tau}, [], Record.from_arrays(t, u, t)
        )
        clean = simulate_record(system, Record.from_arrays(t, u, t), np.array([x0])).outputs[:, 0]
        records.append(Record.from_arrays(t, u, clean + rng.normal(0.0, noise, len(t)), f"r{i}"))
        starts.append(x0)
    return records, starts


def test_several_records_with_estimated_initial_states() -> None:
    records, starts = two_step_records()
    est = GreyBoxEstimator(first_order_model(x0=False)).fit(records)
    assert est.estimate_x0_
    assert est.identifiability_.names[2:] == ("x0[y]@r0", "x0[y]@r1", "x0[y]@r2")
    for x0_hat, x0 in zip(est.x0_, starts, strict=True):
        assert abs(x0_hat[0] - x0) < 0.05
    for name, true in (("K", 2.0), ("T", 1.5)):
        stderr = est.stderr_[name]
        assert stderr is not None
        assert abs(est.params_[name] - true) < 3 * stderr
    assert len(est.fit_percent_) == 3
    # one record alone: larger standard errors (less data)
    single = GreyBoxEstimator(first_order_model(x0=False)).fit(records[0])
    assert single.stderr_["K"] > est.stderr_["K"]


def test_missing_outputs_are_skipped() -> None:
    records, _ = two_step_records()
    record = records[1]
    y = record.y.copy()
    y[::3] = np.nan
    y[0] = np.nan
    holed = Record.from_arrays(record.t, record.u, y)
    est = GreyBoxEstimator(first_order_model(x0=False)).fit(holed)
    assert est.n_residuals_ == int(np.isfinite(y).sum())
    full = GreyBoxEstimator(first_order_model(x0=False)).fit(record)
    for name in ("K", "T"):
        stderr = full.stderr_[name]
        assert stderr is not None
        assert abs(est.params_[name] - full.params_[name]) < 2 * stderr
    # a third of the samples gone: standard errors grow by about √(3/2)
    ratio = est.stderr_["K"] / full.stderr_["K"]
    assert 1.1 < ratio < 1.4


def test_the_model_initial_state_function_is_used() -> None:
    """The model's x0(p, u0, y0) sets the initial state.

    x0(p, u0, y0) = K·u0 (at rest at the first input): x0 moves with K, so it carries
    sensitivity, and y0 is the first finite output.
    """
    seen: list[Any] = []

    def at_rest(p: Mapping[str, float], u0: Any, y0: Any) -> Any:
        seen.append(np.array(y0, dtype=float))
        return [p["K"] * u0[0]]

    model = OdeModel(
        first_order_f,
        [ParameterSpec("K", 1.5, 0.0), ParameterSpec("T", 3.0, 0.0)],
        ["y"],
        x0=at_rest,
    )
    h, n = 0.1, 400
    t = np.arange(n) * h
    u = np.where(t < 10.0, 1.0, 2.0)
    clean = np.where(t < 10.0, 2.0, 4.0 - 2.0 * np.exp(-np.clip(t - 10.0, 0.0, None) / 1.5))
    y = clean + np.random.default_rng(5).normal(0.0, 0.02, n)
    y[0] = np.nan
    est = GreyBoxEstimator(model).fit(Record.from_arrays(t, u, y))
    assert not est.estimate_x0_
    assert est.x0_[0][0] == pytest.approx(est.params_["K"] * 1.0)
    assert all(value[0] == y[1] for value in seen)
    stderr = est.stderr_["K"]
    assert stderr is not None
    assert abs(est.params_["K"] - 2.0) < 3 * stderr
    # the first 10 s are at steady state: they determine K too (x0 depends on it)
    assert stderr < 0.02 / math.sqrt(100) * 1.5


def test_predict_on_a_fresh_record_fits_its_initial_state() -> None:
    records, starts = two_step_records()
    est = GreyBoxEstimator(first_order_model(x0=False)).fit(records[:2])
    x0 = est.validation_initial_state(records[2])
    assert x0 is not None
    assert abs(x0[0] - starts[2]) < 0.1
    assert est.score(records[2])[0] > 90.0


# --- failures -------------------------------------------------------------------------------------
def test_too_few_iterations_raise_convergence_error() -> None:
    record, _ = tank_record(400)
    with pytest.raises(ConvergenceError, match="did not converge"):
        GreyBoxEstimator(tank_model(start_factor=2.0), max_iterations=2).fit(record)


def test_a_model_that_is_nan_at_the_start_raises_convergence_error() -> None:
    model = OdeModel(
        lambda t, x, u, p: [np.log(p["a"] - 2.0) - x[0]],
        [ParameterSpec("a", 1.0, 0.0)],
        ["y"],
        x0=lambda p, u0, y0: [0.0],
    )
    t = np.arange(50) * 0.1
    with pytest.raises(ConvergenceError, match="start values"):
        GreyBoxEstimator(model).fit(Record.from_arrays(t, np.ones(50), np.sin(t)))


@pytest.mark.parametrize(
    ("t", "u", "y", "match"),
    [
        ([0.0, 1.0, 2.0], [1.0, 1.0], [1.0, 2.0, 3.0], "differ in length"),
        ([0.0, 1.0], [1.0, 1.0], [1.0, 2.0], "at least 3"),
        ([0.0, 2.0, 1.0], [1.0, 1.0, 1.0], [1.0, 2.0, 3.0], "increasing"),
        ([0.0, 1.0, 2.0], [1.0, np.nan, 1.0], [1.0, 2.0, 3.0], "inputs"),
        ([0.0, 1.0, 2.0], [1.0, 1.0, 1.0], [np.nan, np.nan, np.nan], "no finite output"),
    ],
)
def test_bad_records_raise_data_error(t: Any, u: Any, y: Any, match: str) -> None:
    with pytest.raises(DataError, match=match):
        Record.from_arrays(t, u, y)


def test_the_estimator_checks_records_it_is_given() -> None:
    t = np.arange(20) * 0.1
    est = GreyBoxEstimator(first_order_model())
    with pytest.raises(DataError, match="output column"):
        est.fit(Record.from_arrays(t, np.ones(20), np.column_stack([t, t])))
    with pytest.raises(DataError, match="increasing"):
        est.fit(Record(t[::-1].copy(), np.ones((20, 1)), t[:, None]))
    with pytest.raises(DataError, match="input column"):
        est.fit(
            [
                Record.from_arrays(t, np.ones(20), t),
                Record.from_arrays(t, np.ones((20, 2)), t),
            ]
        )
    with pytest.raises(DataError, match="no record"):
        est.fit([])
    y = np.full(20, np.nan)
    y[:2] = 1.0
    with pytest.raises(DataError, match="finite output samples"):
        est.fit(Record.from_arrays(t, np.ones(20), y))


# --- several outputs ------------------------------------------------------------------------------
def test_noise_levels_are_re_estimated_per_output() -> None:
    """Each output's noise level is re-estimated.

    Flow-like and pressure-like outputs with noise 100× apart: each σ is recovered, and the
    parameters are weighted by them (the noisy output hardly counts).
    """
    record_tank, _ = tank_record()
    truth = tank_model(fixed=tuple(TANK_TRUTH), start_factor=1.0)
    both = OdeModel(
        tank_f,
        tank_model().parameters,
        ["x1", "x2"],
        h=lambda x, u, p: [x[1], 50.0 * x[0]],
        n_outputs=2,
    )
    blank = Record.from_arrays(record_tank.t, record_tank.u, np.zeros(len(record_tank.t)))
    states = simulate_record(truth.bind(TANK_TRUTH, [], blank), blank, TANK_X0).states
    rng = np.random.default_rng(11)
    noise = np.array([0.01, 1.0])
    y = (
        np.column_stack([states[:, 1], 50.0 * states[:, 0]])
        + rng.normal(0.0, 1.0, (1000, 2)) * noise
    )
    est = GreyBoxEstimator(both).fit(Record.from_arrays(record_tank.t, record_tank.u, y))
    assert est.sigma_ == pytest.approx(noise, rel=0.1)
    for name in ("k1", "k2", "k3"):
        stderr = est.stderr_[name]
        assert stderr is not None
        assert abs(est.params_[name] - TANK_TRUTH[name]) < 3 * stderr


def test_a_model_raising_at_the_start_raises_convergence_error() -> None:
    model = OdeModel(
        lambda t, x, u, p: [math.sqrt(x[0] - 5.0) - p["a"] * x[0]],
        [ParameterSpec("a", 1.0, 0.0)],
        ["y"],
        x0=lambda p, u0, y0: [0.0],
    )
    t = np.arange(50) * 0.1
    with pytest.raises(ConvergenceError, match="ValueError"):
        GreyBoxEstimator(model).fit(Record.from_arrays(t, np.ones(50), np.sin(t)))


def test_predict_with_a_model_initial_state_reproduces_the_fit() -> None:
    h, n = 0.1, 300
    t = np.arange(n) * h
    y = step_response(t, 1.0, 2.0, 2.0) + np.random.default_rng(2).normal(0.0, 0.02, n)
    record = Record.from_arrays(t, np.ones(n), y)
    est = GreyBoxEstimator(first_order_model()).fit(record)
    assert est.validation_initial_state(record) is None
    assert np.allclose(est.predict(record), est.trajectories_[0].outputs, atol=1e-5)
    assert est.score(record)[0] == pytest.approx(est.fit_percent_[0][0], abs=1e-3)


def test_a_vectorised_rhs_may_return_constants_among_arrays() -> None:
    """[x[1], c] broadcasts: the batched path is kept and the sensitivities are right."""
    model = OdeModel(
        lambda t, x, u, p: [x[1], p["c"]],
        [ParameterSpec("c", 0.5, 0.0)],
        ["position", "speed"],
        x0=lambda p, u0, y0: [0.0, 0.0],
    )
    t = np.arange(100) * 0.1
    y = 0.25 * 0.8 * t**2 + np.random.default_rng(4).normal(0.0, 0.01, 100)
    est = GreyBoxEstimator(model).fit(Record.from_arrays(t, np.ones(100), y))
    assert model._mode.f_vectorised is True
    # y = c·t²/2 is linear in c: var ĉ = σ² / Σ (t²/2)²
    stderr = est.sigma_[0] / math.sqrt(np.sum((t**2 / 2) ** 2))
    assert est.stderr_["c"] == pytest.approx(stderr, rel=1e-3)
    assert abs(est.params_["c"] - 0.4) < 3 * stderr


# --- robust start for long records ----------------------------------------------------------------
def oscillator_f(t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    """A lightly damped mass on a spring: x'' + 2ζω x' + ω² x = ω² u."""
    return [x[1], p["w"] ** 2 * (u[0] - x[0]) - 2.0 * p["z"] * p["w"] * x[1]]


def oscillator_model(w_start: float, z_start: float) -> OdeModel:
    specs = [ParameterSpec("w", w_start, 0.0), ParameterSpec("z", z_start, 0.0)]
    return OdeModel(oscillator_f, specs, ["x", "v"], h=lambda x, u, p: x[0])


@pytest.fixture(scope="module")
def ringing_record() -> Record:
    """150 s of a step response ringing at ω = 1 rad/s, ζ = 0.01 (~24 periods), noise 0.05."""
    rng = np.random.default_rng(1)
    t = np.arange(1500) * 0.1
    u = np.where(t >= 1.0, 1.0, 0.0)
    blank = Record.from_arrays(t, u, np.zeros(len(t)))
    truth = oscillator_model(1.0, 0.01).bind({"w": 1.0, "z": 0.01}, [], blank)
    clean = simulate_record(truth, blank, np.zeros(2)).outputs[:, 0]
    return Record.from_arrays(t, u, clean + rng.normal(0.0, 0.05, len(t)))


def test_single_shooting_from_a_wrong_frequency_does_not_converge(ringing_record: Record) -> None:
    """The reason for the segmented start: 60 % off in ω, the phase is lost over 24 periods."""
    with pytest.raises(ConvergenceError, match="did not converge"):
        GreyBoxEstimator(oscillator_model(1.6, 0.01), "estimate", segments=None).fit(ringing_record)


def test_a_segmented_start_recovers_the_ringing_oscillator(ringing_record: Record) -> None:
    """The default falls back to a segmented start and lands on the truth.

    Segments of 50 samples, each with its own initial state, then the whole record: the estimate
    lies within three of its (Cramér–Rao) standard errors of the truth.
    """
    est = GreyBoxEstimator(oscillator_model(1.6, 0.01), "estimate").fit(ringing_record)
    assert est.start_.startswith("segmented start (30, 7 segments")
    for name, truth in {"w": 1.0, "z": 0.01}.items():
        stderr = est.stderr_[name]
        assert stderr is not None
        assert abs(est.params_[name] - truth) < 3.0 * stderr
    assert est.sigma_[0] == pytest.approx(0.05, rel=0.1)


def test_a_good_start_is_fitted_by_single_shooting_alone(ringing_record: Record) -> None:
    """No segmented start when the single-shooting fit leaves only the noise."""
    est = GreyBoxEstimator(oscillator_model(0.98, 0.012), "estimate").fit(ringing_record)
    assert est.start_ == "single shooting"
    assert est.params_["w"] == pytest.approx(1.0, abs=1e-3)


@pytest.mark.parametrize("segments", [1, 0, True, "many", 2.5])
def test_the_segment_count_is_checked(segments: Any, ringing_record: Record) -> None:
    with pytest.raises(FuelidError, match="segments must be"):
        GreyBoxEstimator(oscillator_model(1.0, 0.01), segments=segments).fit(ringing_record)


def test_a_segmented_start_ends_in_the_same_estimate_as_single_shooting() -> None:
    """The start only changes where the whole-record fit begins, not what it converges to."""
    record, _ = tank_record()
    plain = GreyBoxEstimator(tank_model(), "estimate", segments=None).fit(record)
    segmented = GreyBoxEstimator(tank_model(), "estimate", segments=8).fit(record)
    assert plain.start_ == "single shooting"
    assert segmented.start_ == "segmented start (8, 2 segments per record)"
    for name in ("k1", "k2", "k3"):
        stderr = plain.stderr_[name]
        assert stderr is not None
        assert abs(segmented.params_[name] - plain.params_[name]) < 0.01 * stderr
    np.testing.assert_allclose(segmented.x0_[0], plain.x0_[0], rtol=1e-3)


def test_a_free_decay_with_estimated_initial_state_is_not_refused() -> None:
    """From the steady-state guess (rest at u = 0) nothing depends on ω or ζ; from x0 it does.

    The structural check is made after the initial state has been fitted with the parameters
    held, so the ringing of a released spring is fitted rather than refused.
    """
    rng = np.random.default_rng(5)
    t = np.arange(1000) * 0.1
    w, z = 1.0, 0.02
    wd = w * math.sqrt(1.0 - z * z)
    clean = np.exp(-z * w * t) * (np.cos(wd * t) + z / math.sqrt(1.0 - z * z) * np.sin(wd * t))
    record = Record.from_arrays(t, np.zeros_like(t), clean + rng.normal(0.0, 0.02, len(t)))
    est = GreyBoxEstimator(oscillator_model(1.1, 0.03), "estimate").fit(record)
    for name, truth in {"w": w, "z": z}.items():
        stderr = est.stderr_[name]
        assert stderr is not None
        assert abs(est.params_[name] - truth) < 3.0 * stderr
    np.testing.assert_allclose(est.x0_[0], [1.0, 0.0], atol=0.02)


def test_a_free_decay_whose_scale_is_free_is_refused_as_a_trade() -> None:
    """C·dT/dt = −hA·T, released from 20 K: only hA/C is seen.

    From the rest guess nothing is seen at all; the refusal describes the settled view, where C
    and hA trade against each other.
    """

    def cooling(t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
        return [-p["hA"] * x[0] / p["C"]]

    t = np.arange(300) * 1.0
    clean = 20.0 * np.exp(-0.02 * t)
    rng = np.random.default_rng(3)
    record = Record.from_arrays(t, np.zeros_like(t), clean + rng.normal(0.0, 0.05, len(t)))
    specs = [ParameterSpec("C", 8.0, 0.0), ParameterSpec("hA", 0.2, 0.0)]
    with pytest.raises(NotIdentifiableError) as caught:
        GreyBoxEstimator(OdeModel(cooling, specs, ["T"]), "estimate").fit(record)
    report = caught.value.report
    assert report.zero_sensitivity == ()
    assert {"C", "hA"} <= set(report.undetermined_names)
    assert "trade against each other" in str(caught.value)
