"""The cascaded tanks from a start on a flat spot: the upper tank never full at the start values.

The record is examples/cascaded_tanks_data.py's (seed 42), the model the one with the overflow's
switch declared (examples/cascaded_tanks_switch.py). Started at xmax = 20 V, the upper level
(at most 18.8 V there) never reaches the rim: the outputs do not depend on kov at all and on xmax
only a step down, so the sensitivities of both are 0 and the fit would be refused. The start
search finds a start where the overflow acts. A least_squares + odeint script fitting the
undeclared model from the file's start reaches a validation RMSE of 0.438 V.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fuelid.greybox import GreyBoxEstimator
from fuelid.greybox.modelfile import read_model_file
from fuelid.workflow import greybox_model
from support.cascaded_tanks import EXAMPLES, REFERENCE_VALIDATION_RMSE, cascaded_tanks_records


@pytest.mark.slow
def test_a_rim_above_the_start_s_levels_is_searched_away_from_and_the_fit_validates(
    tmp_path: Path,
) -> None:
    estimation, validation = cascaded_tanks_records(tmp_path)
    model = greybox_model(
        read_model_file(EXAMPLES / "cascaded_tanks_switch.py"), values={"xmax": 20.0}
    )
    # bands stated before the run: the search runs (both overflow parameters without
    # sensitivity at the start) and finds a start; the fit ends with every parameter
    # determined, the overflow in use; the validation RMSE within 10 % of the reference
    # script's (the band)
    estimator = GreyBoxEstimator(model).fit([estimation])
    search = estimator.start_search_
    assert search is not None
    assert set(search.flat) == {"xmax", "kov"}
    assert search.chosen is not None
    assert estimator.not_determined_ == {}
    assert estimator.identifiability_.zero_sensitivity == ()
    upper = estimator.simulate(estimation, estimator.x0_[0]).states[:, 0]
    assert estimator.params_["xmax"] < float(np.max(upper)) + 1e-6
    assert 0.0 < estimator.params_["kov"] < 1.0
    predicted = estimator.predict(validation)
    rmse = math.sqrt(float(np.mean((predicted[:, 0] - validation.y[:, 0]) ** 2)))
    assert rmse <= 1.1 * REFERENCE_VALIDATION_RMSE
