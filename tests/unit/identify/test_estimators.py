"""The estimator convention of ``fuelid.identify``, checked on every estimator.

Settings only in ``__init__``; ``fit`` returns the estimator; fitted attributes exist only after
``fit`` (NotFittedError before); ``simulate`` from the three initial conditions; ``predict``
equals ``simulate`` for the output-error noise model H = 1; ``score``; the method registry; a
light package import. The data are noise-free responses of known models, so the expected
outputs are exact.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable

import numpy as np
import pytest
from numpy.typing import NDArray

import fuelid.identify
from fuelid.errors import FuelidError, NotExcitingError, NotFittedError
from fuelid.identify import (
    METHODS,
    IdentifyOptions,
    OutputError,
    StepResponseLS,
    identify,
)
from fuelid.identify._base import Estimator
from fuelid.io.timeseries import IOData
from fuelid.lti import discretise
from fuelid.model import ProcessModel, nrmse_fit, simulate_model
from fuelid.numerics_mode import DEFAULT_NUMERICS

FloatArray = NDArray[np.float64]
H = 0.05
OE_TRUTH = ProcessModel(K=3.0, T=2.0, T_f=0.3, delay=0.35)  # delay 7 samples
LS_TRUTH = ProcessModel(K=2.0, T=0.8, T_f=0.3, delay=0.2)  # settles within N = 5 periods
LS_N = 5


def _oe() -> OutputError:
    return OutputError(T_f=OE_TRUTH.T_f, delay=OE_TRUTH.delay)


def _ls() -> StepResponseLS:
    return StepResponseLS(N=LS_N, T_f=LS_TRUTH.T_f, delay=LS_TRUTH.delay)


def _oe_record(seed: int, n_steps: int = 8, offset: float = 10.0) -> IOData:
    rng = np.random.default_rng(seed)
    u = np.repeat(np.r_[1.0, rng.uniform(0.5, 1.5, n_steps - 1)], 200)
    return IOData(u=u, y=offset + simulate_model(OE_TRUTH, u, H), sample_time=H)


def _fir(model: ProcessModel, u: FloatArray, N: int) -> FloatArray:
    """Response from rest at u[0] of the model's step response truncated (held) after N samples."""
    s = model.step_response(np.minimum(np.arange(u.size), N).astype(float))
    return np.asarray(np.convolve(np.diff(u, prepend=u[0]), s)[: u.size], dtype=float)


def _ls_record(seed: int, offset: float = 5.0) -> IOData:
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.choice([-1.0, 0.0, 1.0], 120), rng.integers(2, 7, 120))[:400]
    u[:8] = 0.0
    return IOData(u=u, y=offset + _fir(LS_TRUTH, u, LS_N), sample_time=1.0)


ESTIMATORS: list[tuple[Callable[[], Estimator], Callable[[int], IOData]]] = [
    (_oe, _oe_record),
    (_ls, _ls_record),
]
IDS = ["oe", "step-ls"]


# ---------------------------------------------------------------------- fitted state


@pytest.mark.parametrize(("make", "record"), ESTIMATORS, ids=IDS)
def test_fitted_attributes_do_not_exist_before_fit(make, record):
    est = make()
    data = record(0)
    for name in ("K_", "T_", "delay_", "stderr_", "model_", "warnings_", "fit_percent_"):
        with pytest.raises(NotFittedError, match="not fitted"):
            getattr(est, name)
        assert not hasattr(est, name)  # NotFittedError is an AttributeError, as in scikit-learn
    for call in (est.simulate, est.predict, est.score):
        with pytest.raises(NotFittedError, match=r"not fitted: call fit\(data\) first"):
            call(data)
    assert isinstance(NotFittedError("x"), FuelidError)
    # a typo is still an ordinary AttributeError, not a fitting problem
    with pytest.raises(AttributeError) as info:
        est.no_such_setting  # noqa: B018
    assert not isinstance(info.value, NotFittedError)


@pytest.mark.parametrize(("make", "record"), ESTIMATORS, ids=IDS)
def test_fit_returns_the_estimator_and_a_failed_refit_leaves_it_unfitted(make, record):
    est = make()
    data = record(1)
    assert est.fit(data) is est
    assert est.fit_percent_ == pytest.approx(100.0, abs=1e-6)
    constant = IOData(u=np.full(data.n_samples, 1.0), y=data.y, sample_time=data.sample_time)
    with pytest.raises(NotExcitingError):
        est.fit(constant)
    with pytest.raises(NotFittedError):
        est.K_  # noqa: B018  (no estimate of the earlier record survives a failed refit)
    with pytest.raises(NotFittedError):
        est.simulate(data)


COMMON = ("K_", "T_", "T2_", "delay_", "T_f_", "stderr_", "fixed_", "fit_percent_", "n_samples_")


@pytest.mark.parametrize(("make", "record"), ESTIMATORS, ids=IDS)
def test_every_estimator_has_the_common_fitted_attributes(make, record):
    data = record(16)
    est = make().fit(data)
    for name in (*COMMON, "sample_time_", "warnings_", "model_"):
        assert hasattr(est, name), name
    model = est.model_
    assert (est.K_, est.T_, est.T2_, est.delay_, est.T_f_) == (
        model.K,
        model.T,
        model.T2,
        model.delay,
        model.T_f,
    )
    assert set(est.stderr_) == {"K", "T", "T2", "delay", "T_f"}
    assert all(est.stderr_[name] is None for name in est.fixed_)
    assert (est.n_samples_, est.sample_time_) == (data.n_samples, data.sample_time)
    assert est.fit_percent_ == pytest.approx(est.score(data), rel=1e-12)


def test_init_only_stores_settings_and_fit_checks_them():
    est = OutputError(order=3, T_f=-1.0)  # type: ignore[arg-type]  # stored, not checked
    assert est.get_params() == {
        "order": 3,
        "delay": None,
        "T_f": -1.0,
        "initial": "estimate",
        "u_before": None,
        "max_delay": None,
        "covariance": "auto",
        "full_record": False,
        "numerics": DEFAULT_NUMERICS,
    }
    with pytest.raises(FuelidError, match="order must be 1, 2 or 'auto'"):
        est.fit(_oe_record(2))
    ls = StepResponseLS(max_condition=0.5)
    assert repr(ls) == (
        "StepResponseLS(N=None, T_f=0.0, delay=0.0, settling_time=None, max_condition=0.5)"
    )
    with pytest.raises(FuelidError, match="max_condition must exceed 1"):
        ls.set_params(N=5).fit(_ls_record(2))
    with pytest.raises(FuelidError, match="no setting min_condition"):
        ls.set_params(min_condition=1e8)
    copy = type(ls)(**ls.get_params())
    assert copy.get_params() == ls.get_params()
    assert copy is not ls


# ---------------------------------------------------------------------- simulate / predict


def test_oe_simulate_from_the_fitted_state_continues_through_held_out_data():
    # fitted on the first half, simulated through the whole record: the held-out half is the
    # truth itself (noise-free data), as `fuelid identify --validate-split` scores it
    data = _oe_record(3)
    half = data.n_samples // 2
    est = _oe().fit(data.segment(0, half))
    y = est.simulate(data)  # initial="fitted" is the default
    np.testing.assert_allclose(y, data.y, atol=1e-7)
    np.testing.assert_allclose(est.simulate(data.segment(0, half), initial="fitted"), est.y_hat_)
    assert est.score(data.segment(0, half)) == pytest.approx(est.fit_percent_, rel=1e-12)


@pytest.mark.parametrize(("make", "record"), ESTIMATORS, ids=IDS)
def test_fitted_initial_state_is_refused_on_another_record(make, record):
    est = make().fit(record(4))
    other = record(5)
    with pytest.raises(FuelidError, match="use initial='estimate'") as info:
        est.simulate(other, initial="fitted")
    assert "does not start with the fitting record" in str(info.value)
    shorter = record(4).segment(0, 100)
    with pytest.raises(FuelidError, match="has only 100 samples"):
        est.simulate(shorter)
    with pytest.raises(FuelidError, match="initial must be one of 'rest', 'estimate', 'fitted'"):
        est.simulate(other, initial="steady")  # type: ignore[arg-type]


def test_oe_simulate_from_rest_is_the_model_from_rest_at_the_first_input():
    est = _oe().fit(_oe_record(6, offset=10.0))
    other = _oe_record(7, offset=0.0)  # starts at rest at u[0] = 1 (the fitting record's too)
    y_rest = est.simulate(other, initial="rest")
    np.testing.assert_allclose(y_rest, 10.0 + simulate_model(OE_TRUTH, other.u, H), atol=1e-7)
    # from rest at another input: y(0) = offset + K·(u[0] − u_ref)
    shifted = IOData(u=other.u + 0.5, y=other.y, sample_time=H)
    assert est.simulate(shifted, initial="rest")[0] == pytest.approx(10.0 + 3.0 * 0.5, abs=1e-7)


def test_oe_simulate_estimate_recovers_a_record_that_does_not_start_at_rest():
    # the plant was at rest at u = 0.4, stepped to 1.0 two seconds before the record: at the
    # record's start the lags are still moving (the delay line is already constant), so the
    # record is the response from rest at u[0] plus the lags' free response c_i·e^(−kh/T_i)
    est = _oe().fit(_oe_record(8, offset=10.0))
    record = _oe_record(9)
    pre = np.r_[np.full(400, 0.4), np.full(40, 1.0)]
    y = 10.0 + simulate_model(OE_TRUTH, np.r_[pre, record.u], H)[pre.size :]
    data = IOData(u=record.u, y=y, sample_time=H)
    np.testing.assert_allclose(est.simulate(data, initial="estimate"), y, atol=1e-6)
    assert est.score(data, initial="estimate") == pytest.approx(100.0, abs=1e-5)
    assert est.score(data, initial="rest") < 99.0  # the transient is not a response to data.u


def test_step_ls_simulate_is_the_truncated_step_response_model():
    data = _ls_record(10, offset=5.0)
    est = _ls().fit(data)
    # data from the N = 5 FIR form itself: every initial condition reproduces it on the fit
    # record (it starts at rest at u[0], which is what the fit assumes)
    for initial in ("fitted", "rest", "estimate"):
        np.testing.assert_allclose(est.simulate(data, initial=initial), data.y, atol=1e-8)
    # rest at a shifted input: offset + K·(u[0] − u0)
    shifted = IOData(u=data.u + 1.0, y=data.y, sample_time=1.0)
    assert est.simulate(shifted, initial="rest")[0] == pytest.approx(5.0 + 2.0, abs=1e-6)
    # an offset and a decaying free response of the fitted lags are re-estimated
    p = discretise([LS_TRUTH.T, LS_TRUTH.T_f], LS_TRUTH.delay, 1.0).modes(data.n_samples)
    drifted = IOData(u=data.u, y=data.y + 3.0 + p @ [2.0, -1.0], sample_time=1.0)
    np.testing.assert_allclose(est.simulate(drifted, initial="estimate"), drifted.y, atol=1e-5)
    with pytest.raises(FuelidError, match="fitted sample time 1 s"):
        est.simulate(IOData(u=data.u, y=data.y, sample_time=0.5), initial="rest")


@pytest.mark.parametrize(("make", "record"), ESTIMATORS, ids=IDS)
def test_predict_is_the_simulation_for_every_horizon(make, record):
    # output error: noise model H = 1, so ŷ(t|t−k) = G(q)u(t) for every k (Ljung 1999, §3.2)
    est = make().fit(record(11))
    other = record(12)
    y_sim = est.simulate(other, initial="rest")
    for horizon in (1, 5, 1000):
        np.testing.assert_array_equal(est.predict(other, horizon=horizon), y_sim)
    np.testing.assert_array_equal(
        est.predict(other, initial="estimate"), est.simulate(other, initial="estimate")
    )
    for bad in (0, -1, 1.5, True):
        with pytest.raises(FuelidError, match="horizon must be a whole number"):
            est.predict(other, horizon=bad)


@pytest.mark.parametrize(("make", "record"), ESTIMATORS, ids=IDS)
def test_score_is_the_nrmse_fit_of_the_simulation(make, record):
    est = make().fit(record(13))
    other = record(14)
    noise = np.random.default_rng(0).normal(0.0, 0.05, other.n_samples)
    noisy = IOData(u=other.u, y=other.y + noise, sample_time=other.sample_time)
    for initial in ("rest", "estimate"):
        expected = nrmse_fit(noisy.y, est.simulate(noisy, initial=initial))
        assert est.score(noisy, initial=initial) == expected
        assert expected < 100.0


# ---------------------------------------------------------------------- procedure and package


def test_unknown_method_is_refused_naming_the_valid_ones():
    assert METHODS == ("oe", "step-ls", "pem", "auto")
    with pytest.raises(FuelidError, match=r"unknown identification method 'arx': use one of oe, "):
        IdentifyOptions(method="arx")  # type: ignore[arg-type]
    with pytest.raises(FuelidError, match="step-ls"):
        IdentifyOptions(method="step_ls")  # type: ignore[arg-type]
    result = identify(_oe_record(15), IdentifyOptions(flowmeter_T=0.3, flowmeter_delay=0.35))
    assert result.method == "oe"
    assert pytest.approx(OE_TRUTH.K, rel=1e-7) == result.model.K


def test_package_exports_its_api_and_imports_light():
    for name in fuelid.identify.__all__:
        assert getattr(fuelid.identify, name) is not None
    assert {"OutputError", "StepResponseLS", "IdentifyOptions", "identify"} <= set(
        fuelid.identify.__all__
    )
    code = (
        "import sys, fuelid.identify; "
        "print(sorted(m for m in ('control', 'matplotlib') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
