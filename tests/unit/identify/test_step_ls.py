"""The article's method (truncated step-response least squares + Newton), on data of known models.

Data are exact for piecewise-constant inputs: by superposition y(k) = Σ_j s((k − k_j)·T_s)·Δu_j
with the model's exact step response s (a discrete convolution of Δu with s sampled at T_s).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from fuelid.errors import FuelidError, NotExcitingError
from fuelid.identify import StepResponseLS, step_shape
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel

FloatArray = NDArray[np.float64]
T_S = 1.0
#: the article's kind of plant: settles (98 %) within N = 5 control periods
ARTICLE = ProcessModel(K=2.0, T=0.8, T_f=0.3, delay=0.2)
SLOW = ProcessModel(K=2.0, T=3.0, T_f=0.3, delay=0.2)


def multilevel(seed: int, n: int = 400, amplitude: float = 25.0) -> FloatArray:
    """Random −a/0/+a input held 2…6 periods, at rest (0) for the first 8 samples."""
    rng = np.random.default_rng(seed)
    dwell = rng.integers(2, 7, size=n)
    levels = amplitude * rng.choice([-1.0, 0.0, 1.0], size=n)
    u = np.repeat(levels, dwell)[:n]
    u[:8] = 0.0
    return u


def respond(model: ProcessModel, u: FloatArray, n_fir: int | None = None) -> FloatArray:
    """Exact sampled response from rest at u[0]; ``n_fir``: the step response held after N."""
    k = np.arange(u.size, dtype=float)
    if n_fir is not None:
        k = np.minimum(k, n_fir)
    s = model.step_response(T_S * k)
    return np.asarray(np.convolve(np.diff(u, prepend=u[0]), s)[: u.size], dtype=float)


def estimator(N: int | None = 5, **kwargs: float) -> StepResponseLS:
    return StepResponseLS(N=N, T_f=ARTICLE.T_f, delay=ARTICLE.delay, **kwargs)


def rel(value: float, true: float) -> float:
    return abs(value / true - 1.0)


def test_article_plant_settles_within_five_periods() -> None:
    assert ARTICLE.settling_time() < 5 * T_S
    assert SLOW.settling_time() > 5 * T_S


def test_exact_on_truncated_step_response_data() -> None:
    # data from the N = 5 FIR form itself: stage 1 and stage 2 are both exact
    u = multilevel(0)
    y = respond(ARTICLE, u, n_fir=5)
    est = estimator().fit(IOData(u=u, y=y, sample_time=T_S))
    np.testing.assert_allclose(est.a_, ARTICLE.step_response(T_S * np.arange(1, 6)), atol=1e-10)
    assert rel(est.K_, ARTICLE.K) < 1e-6
    assert rel(est.T_, ARTICLE.T) < 1e-6
    assert est.warnings_ == []
    assert est.N_ == 5
    assert est.newton_iterations_ < 20
    # the FIR prediction reproduces the record exactly
    np.testing.assert_allclose(est.predict(IOData(u=u, y=y, sample_time=T_S)), y, atol=1e-8)


def test_noise_free_continuous_plant_with_long_horizon() -> None:
    # N = 15: the true response has settled to 1e-8, the truncation is invisible
    u = multilevel(1)
    est = estimator(N=15).fit(IOData(u=u, y=respond(ARTICLE, u), sample_time=T_S))
    assert rel(est.K_, ARTICLE.K) < 1e-6
    assert rel(est.T_, ARTICLE.T) < 1e-6


def test_article_simulation_step_strength_25_noise_005() -> None:
    u = multilevel(2)
    rng = np.random.default_rng(3)
    y = respond(ARTICLE, u) + 0.05 * rng.standard_normal(u.size)
    est = estimator().fit(IOData(u=u, y=y, sample_time=T_S))
    assert rel(est.K_, ARTICLE.K) < 0.01
    assert rel(est.T_, ARTICLE.T) < 0.01
    assert est.warnings_ == []
    # residuals: the noise plus the truncation error (s(6 s) − s(5 s) ≈ 0.004 K per unit step)
    assert 0.05 < est.residual_std_ < 0.15
    assert est.a_stderr_.shape == (5,)
    assert np.all(est.a_stderr_ < 1e-3)
    assert est.n_exciting_rows_ <= est.n_rows_used_ <= u.size - 5


def test_noise_free_truncation_bias_of_settled_plant_is_small() -> None:
    # the 98 % criterion still leaves s(5 s) = 0.996 K: a small but non-zero bias
    u = multilevel(1)
    est = estimator().fit(IOData(u=u, y=respond(ARTICLE, u), sample_time=T_S))
    assert 1e-5 < rel(est.K_, ARTICLE.K) < 0.005
    assert 1e-5 < rel(est.T_, ARTICLE.T) < 0.005


def test_slow_plant_is_biased_and_warned() -> None:
    u = multilevel(4)
    data = IOData(u=u, y=respond(SLOW, u), sample_time=T_S)
    est = estimator().fit(data)
    assert rel(est.K_, SLOW.K) > 0.05
    assert rel(est.T_, SLOW.T) > 0.05
    assert len(est.warnings_) == 1
    warning = est.warnings_[0]
    assert f"settling time {est.model_.settling_time():.3g} s" in warning
    assert "N·T_s = 5 s" in warning
    assert "N ≥" in warning
    # it is the truncation: N from the true settling time removes the bias
    long = estimator(N=None, settling_time=SLOW.settling_time()).fit(data)
    assert long.N_ == 13
    assert rel(long.K_, SLOW.K) < 0.01
    assert rel(long.T_, SLOW.T) < 0.01


def test_refuses_constant_input() -> None:
    u = np.full(100, 3.0)
    with pytest.raises(NotExcitingError, match="constant") as info:
        estimator().fit(IOData(u=u, y=np.full(100, 7.0), sample_time=T_S))
    assert "\n" not in str(info.value)


def test_refuses_single_early_step() -> None:
    # a step at sample 1: rows start at k = N = 5, so lags 1 … 3 never see an input change
    u = np.where(np.arange(60) >= 1, 1.0, 0.0)
    with pytest.raises(NotExcitingError, match=r"rank 2 < N=5") as info:
        estimator().fit(IOData(u=u, y=respond(ARTICLE, u), sample_time=T_S))
    message = str(info.value)
    assert "a_1, a_2, a_3 not excited" in message
    assert "1 input change)" in message
    assert "\n" not in message


def test_refuses_step_too_late_and_short_record() -> None:
    u = np.where(np.arange(60) >= 57, 1.0, 0.0)  # rows k = 58, 59 see the step
    with pytest.raises(NotExcitingError, match=r"only 2 regression rows carry"):
        estimator().fit(IOData(u=u, y=respond(ARTICLE, u), sample_time=T_S))
    u = np.array([0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0])
    with pytest.raises(NotExcitingError, match=r"record too short: 7 samples give 2"):
        estimator().fit(IOData(u=u, y=u.copy(), sample_time=T_S))


def test_refuses_ill_conditioned_regressor() -> None:
    u = multilevel(5)
    with pytest.raises(NotExcitingError, match=r"condition number .* exceeds 1\.5"):
        estimator(max_condition=1.5).fit(IOData(u=u, y=respond(ARTICLE, u), sample_time=T_S))


def test_single_late_step_is_enough() -> None:
    # one step at sample N − 1 or later with N samples after it: a_i = y(k1 + i)/Δu exactly
    u = np.where(np.arange(40) >= 10, 0.5, 0.0)
    y = respond(ARTICLE, u, n_fir=5)
    est = estimator().fit(IOData(u=u, y=y, sample_time=T_S))
    np.testing.assert_allclose(est.a_, y[11:16] / 0.5, atol=1e-12)
    assert est.n_exciting_rows_ == 4
    assert est.n_rows_used_ == 40 - 10 - 1  # rows k = 11 … 39


def test_offsets_do_not_change_the_estimate() -> None:
    u = multilevel(6)
    rng = np.random.default_rng(7)
    y = respond(ARTICLE, u) + 0.05 * rng.standard_normal(u.size)
    plain = estimator().fit(IOData(u=u, y=y, sample_time=T_S))
    shifted = estimator().fit(IOData(u=u + 1.0, y=y + 100.0, sample_time=T_S))
    assert rel(shifted.K_, plain.K_) < 1e-9
    assert rel(shifted.T_, plain.T_) < 1e-9
    assert shifted.u0_ == 1.0
    assert shifted.offset_ == pytest.approx(plain.offset_ + 100.0, abs=1e-9)
    assert abs(plain.offset_) < 0.05  # mean of the 9 noisy samples before the first change
    np.testing.assert_allclose(
        shifted.predict(IOData(u=u + 1.0, y=y, sample_time=T_S)),
        plain.predict(IOData(u=u, y=y, sample_time=T_S)) + 100.0,
        atol=1e-9,
    )


@pytest.mark.parametrize(
    ("settling_time", "sample_time", "expected"), [(4.6, 1.0, 5), (5.0, 1.0, 5), (4.6, 0.5, 10)]
)
def test_N_from_settling_time(settling_time: float, sample_time: float, expected: int) -> None:
    u = multilevel(8)
    est = StepResponseLS(settling_time=settling_time, T_f=0.3, delay=0.2)
    est.fit(IOData(u=u, y=respond(ARTICLE, u), sample_time=sample_time))
    n_coefficients = est.N_
    assert n_coefficients == expected


def test_needs_N_or_settling_time() -> None:
    u = multilevel(8)
    with pytest.raises(FuelidError, match="pass N or the prior model's 98 % settling time"):
        StepResponseLS().fit(IOData(u=u, y=u, sample_time=T_S))
    with pytest.raises(FuelidError, match="not fitted"):
        StepResponseLS(N=5).predict(IOData(u=u, y=u, sample_time=T_S))


def test_time_constant_equal_to_meter_lag() -> None:
    # T = T_f: the repeated-root limit of the step response, reached by the Newton iteration
    true = ProcessModel(K=1.5, T=0.3, T_f=0.3, delay=0.2)
    u = multilevel(9)
    est = estimator().fit(IOData(u=u, y=respond(true, u, n_fir=5), sample_time=T_S))
    assert rel(est.T_, 0.3) < 1e-6
    assert rel(est.K_, 1.5) < 1e-9
    t = np.array([0.7, 1.5, 3.0])
    np.testing.assert_allclose(step_shape(t, 0.3, 0.3, 0.2), true.step_response(t) / 1.5)


def test_to_control() -> None:
    u = multilevel(0)
    est = estimator().fit(IOData(u=u, y=respond(ARTICLE, u, n_fir=5), sample_time=T_S))
    tf = est.to_control()
    assert float(tf.num[0][0][-1]) == pytest.approx(2.0, rel=1e-6)
    np.testing.assert_allclose(tf.den[0][0], [0.8 * 0.3, 1.1, 1.0], rtol=1e-6)
    assert est.model_.delay == 0.2
    assert math.isclose(est.model_.T_f, 0.3)
