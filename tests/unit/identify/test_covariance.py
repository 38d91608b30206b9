"""Standard errors that hold under coloured noise (issue 13, part 1).

The output-error fit's white covariance σ²(JᵀJ)⁻¹ understates the spread several times when the
noise is an AR(1) process; the sandwich with the residuals' spectrum must match the spread the
estimates actually have, and its 95 % intervals must cover the truth about 95 % of the time.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from fuelid.identify import OutputError, ResidualAR, residual_ar
from fuelid.identify._covariance import sandwich_covariance
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel, simulate_model
from support.bands import coverage_band, rmse_ratio_band

H = 0.05
TRUTH = ProcessModel(K=3.0, T=1.0, delay=0.2)
POLE = 0.95
SD = 0.25  # stationary standard deviation of the noise


def _record(seed: int, pole: float = POLE) -> IOData:
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.choice([1.5, 2.0, 2.5, 3.0, 3.5], 40), 100)  # 40 steps of 5 s
    innovation = rng.normal(0.0, SD * np.sqrt(1.0 - pole**2), u.size)
    noise = scipy.signal.lfilter([1.0], [1.0, -pole], innovation)
    return IOData(u=u, y=20.0 + simulate_model(TRUTH, u, H) + noise, sample_time=H)


def test_the_sandwich_equals_the_explicit_toeplitz_formula():
    rng = np.random.default_rng(2)
    n = 300
    J = rng.normal(size=(n, 3))
    noise = ResidualAR(a=np.array([1.0, -0.8, 0.15]), sigma_e=0.7, bic={})
    # Ψ: lower-triangular Toeplitz of 1/A(q)'s impulse response; Σ_v = σ_e²ΨΨᵀ
    impulse = scipy.signal.lfilter([1.0], noise.a, np.r_[1.0, np.zeros(n - 1)])
    psi = scipy.linalg.toeplitz(impulse, np.zeros(n))
    bread = np.linalg.inv(J.T @ J)
    expected = bread @ J.T @ (noise.sigma_e**2 * psi @ psi.T) @ J @ bread
    cov, unidentified = sandwich_covariance(J, noise)
    assert unidentified == []
    np.testing.assert_allclose(cov, expected, rtol=1e-9)
    # two segments: the noise restarts after the gap, so Σ_v is block diagonal
    cut = 120
    blocks = scipy.linalg.block_diag(psi[:cut, :cut], psi[: n - cut, : n - cut])
    expected = bread @ J.T @ (noise.sigma_e**2 * blocks @ blocks.T) @ J @ bread
    cov, _ = sandwich_covariance(J, noise, [(0, cut), (cut, n)])
    np.testing.assert_allclose(cov, expected, rtol=1e-9)


def test_residual_ar_recovers_an_ar2_and_its_long_run_variance():
    rng = np.random.default_rng(4)
    a = np.array([1.0, -1.2, 0.35])  # poles 0.7 and 0.5
    v = scipy.signal.lfilter([1.0], a, rng.normal(0.0, 0.5, 50000))
    model = residual_ar(v)
    assert model.order == 2
    np.testing.assert_allclose(model.a, a, atol=0.02)
    assert model.sigma_e == pytest.approx(0.5, rel=0.02)
    # long-run over plain variance: (σ_e²/A(1)²)/σ_v²
    impulse = scipy.signal.lfilter([1.0], a, np.r_[1.0, np.zeros(999)])
    exact = 1.0 / np.sum(a) ** 2 / float(impulse @ impulse)
    assert model.variance_ratio == pytest.approx(exact, rel=0.1)


def test_white_residuals_keep_the_white_covariance():
    rng = np.random.default_rng(5)
    u = np.repeat(rng.choice([1.5, 2.5, 3.5], 40), 100)
    y = 20.0 + simulate_model(TRUTH, u, H) + rng.normal(0.0, SD, u.size)
    est = OutputError(delay=TRUTH.delay).fit(IOData(u=u, y=y, sample_time=H))
    assert est.covariance_ == "white"
    assert est.residual_ar_.order == 0
    np.testing.assert_array_equal(est.cov_, est.cov_white_)


def test_intervals_cover_the_truth_under_ar1_noise_where_white_ones_do_not():
    # 40 seeded records with AR(1) noise (pole 0.95 per 0.05 s sample): the sandwich's standard
    # error matches the spread of K and T across runs, the white one is several times too small
    runs = [OutputError(delay=TRUTH.delay).fit(_record(seed)) for seed in range(40)]
    assert all(est.covariance_ == "hac" for est in runs)
    for name, true in (("K", TRUTH.K), ("T", TRUTH.T)):
        values = np.array([getattr(est, f"{name}_") for est in runs])
        index = runs[0].param_names_.index(name)
        hac = np.array([np.sqrt(est.cov_[index, index]) for est in runs])
        white = np.array([np.sqrt(est.cov_white_[index, index]) for est in runs])
        spread = float(np.std(values, ddof=1))
        # pre-registered (tests/bands.py, 0.1 % false alarm): the sample sd of 40 runs over the
        # true sd lies in √(χ²(39)/39)'s band, so a right standard error over it in the inverse
        low, high = rmse_ratio_band(len(runs) - 1)
        assert 1.0 / high < float(np.median(hac)) / spread < 1.0 / low, name
        assert float(np.median(white)) / spread < 0.5, name
        misses = int(np.sum(np.abs(values - true) > 1.96 * hac))
        lo, hi = coverage_band(len(runs))
        assert lo <= misses <= hi, (name, misses)
        assert (np.abs(values - true) <= 1.96 * white).mean() < 0.7, name


def test_colour_from_the_model_s_misfit_keeps_the_white_covariance():
    # a second lag the first-order fit lacks: its residuals are coloured after every step (the
    # misfit, the same in every noise realisation), white where the output has settled. The
    # estimate scatters by the white noise alone around the fit of the noise-free record, so
    # the white covariance (the noise's level taken where the output settled) is the right one;
    # the sandwich with the residuals' spectrum counts the misfit's slow colour as noise
    truth = ProcessModel(K=3.0, T=1.0, T2=0.4, delay=0.2)
    rng = np.random.default_rng(9)
    u = np.repeat(rng.choice([1.5, 2.0, 2.5, 3.0, 3.5], 20), 400)  # 20 steps of 20 s
    clean = 20.0 + simulate_model(truth, u, H)
    settings = {"order": 1, "delay": truth.delay}
    target = OutputError(**settings).fit(IOData(u=u, y=clean, sample_time=H)).K_
    runs = [
        OutputError(**settings).fit(
            IOData(u=u, y=clean + rng.normal(0.0, SD, u.size), sample_time=H)
        )
        for _ in range(40)
    ]
    # the settled residuals are white noise, which the whiteness test (1 % level) rejects in
    # Binomial(40, 0.01) runs: at most 3 with probability 99.9 %
    verdicts = [est.residual_colour_ for est in runs]
    assert set(verdicts) <= {"model", "noise"}
    assert verdicts.count("noise") <= 3
    assert all(est.covariance_ == "white" for est in runs if est.residual_colour_ == "model")
    values = np.array([est.K_ for est in runs])
    se = np.array([est.stderr_["K"] for est in runs])
    spread = float(np.std(values, ddof=1))
    # 40 runs: the sample sd lies within 0.65–1.38 of the truth with probability 99.9 %
    assert 0.65 < float(np.median(se)) / spread < 1.38
    # coverage of the noise-free fit: misses within the 99.9 % binomial band of 40 runs, 0…8
    assert int(np.sum(np.abs(values - target) > 1.96 * se)) <= 8
