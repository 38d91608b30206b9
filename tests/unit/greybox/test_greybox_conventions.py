"""The gray-box estimator follows fuelid's estimator conventions; its fit percent is nrmse_fit."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

from fuelid.errors import FuelidError, NotFittedError
from fuelid.greybox import GreyBoxEstimator, OdeModel, ParameterSpec, Record
from fuelid.model import nrmse_fit, nrmse_fit_columns

FloatArray = NDArray[np.float64]


def _first_order(t: float, x: Any, u: Any, p: Any) -> Any:
    return [(p["K"] * u[0] - x[0]) / p["T"]]


def _model() -> OdeModel:
    return OdeModel(
        _first_order,
        [ParameterSpec("K", 1.5, 0.0), ParameterSpec("T", 8.0, 0.0)],
        ["x"],
        x0=lambda p, u0, y0: [y0[0]],
    )


def _record(seed: int = 0) -> Record:
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 199.5, 400)  # 0.5 s sampling
    u = np.repeat(rng.uniform(0.0, 1.0, 9), 50)[:400]
    x = np.zeros(400)
    for k in range(1, 400):  # K = 2, T = 5 s, forward Euler on a 0.5 s grid: close enough
        x[k] = x[k - 1] + 0.5 * (2.0 * u[k - 1] - x[k - 1]) / 5.0
    y: FloatArray = x + rng.normal(0.0, 0.01, 400)
    return Record.from_arrays(t, u, y)


def test_fitted_attributes_do_not_exist_before_fit() -> None:
    estimator = GreyBoxEstimator(_model())
    with pytest.raises(NotFittedError, match="params_ exists only after fit"):
        _ = estimator.params_
    assert not hasattr(estimator, "cov_")
    with pytest.raises(NotFittedError):
        estimator.correlated_pairs()


def test_fit_returns_the_estimator_and_sets_the_fitted_attributes() -> None:
    estimator = GreyBoxEstimator(_model(), segments=None)
    assert estimator.fit(_record()) is estimator
    assert set(estimator.params_) == {"K", "T"}
    assert estimator.params_["K"] == pytest.approx(2.0, rel=0.05)


def test_a_failed_fit_leaves_no_half_set_attributes() -> None:
    estimator = GreyBoxEstimator(_model(), segments=None).fit(_record())
    estimator.initial_state = "nonsense"
    with pytest.raises(FuelidError, match="initial_state"):
        estimator.fit(_record())
    assert not hasattr(estimator, "params_")
    assert estimator.initial_state == "nonsense"  # the settings stay as given


def test_fit_percent_is_model_nrmse_fit_per_output() -> None:
    estimator = GreyBoxEstimator(_model(), segments=None).fit(_record())
    record = _record(seed=1)
    score = estimator.score(record)
    assert score.shape == (1,)
    assert score[0] == nrmse_fit(record.y[:, 0], estimator.predict(record)[:, 0])
    fitted = estimator.trajectories_[0].outputs
    assert np.array_equal(estimator.fit_percent_[0], nrmse_fit_columns(_record().y, fitted))


def test_nrmse_fit_columns_skips_each_columns_gaps() -> None:
    y = np.array([[0.0, 1.0], [np.nan, 2.0], [2.0, 4.0], [3.0, np.nan]])
    y_hat = np.array([[0.5, 1.0], [9.0, 2.5], [2.0, 4.0], [3.0, 9.0]])
    expected = [nrmse_fit(y[[0, 2, 3], 0], y_hat[[0, 2, 3], 0]), nrmse_fit(y[:3, 1], y_hat[:3, 1])]
    assert np.array_equal(nrmse_fit_columns(y, y_hat), expected)
    assert np.isnan(nrmse_fit_columns(np.full((3, 1), np.nan), np.zeros((3, 1)))[0])


def test_settings_are_parameters_as_for_the_other_estimators() -> None:
    model = _model()
    estimator = GreyBoxEstimator(model, segments=None)
    assert estimator.get_params() == {
        "model": model,
        "initial_state": "auto",
        "max_iterations": 60,
        "segments": None,
        "solver": "auto",
        "max_step": None,
        "substeps": None,
        "hold_undetermined": False,
        "start_search": True,
    }
    assert estimator.set_params(max_iterations=5) is estimator
    assert estimator.max_iterations == 5
    assert repr(estimator).startswith("GreyBoxEstimator(model=")
    with pytest.raises(FuelidError, match="no setting tol"):
        estimator.set_params(tol=1.0)
