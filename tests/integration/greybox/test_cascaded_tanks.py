"""The user's cascaded-tanks model (examples/cascaded_tanks.py) on the real-like record.

The record is made by examples/cascaded_tanks_data.py (seed 42) from a plant richer than the
model (power-law outflows with a leak, a steep overflow pipe, a drifting pump gain), so the fit
has a model error as on the benchmark's real record. A least_squares + odeint script fitting the
same model from the same start reaches a validation RMSE of 0.438 V on this record.

With --hold-undetermined the search holds xmax (the switch hides it from the sensitivities at
the start), and releasing it at the held fit's end once refused the fit there ("kov is not
determined") and, with that fixed, met LSODA's "Excess work" at a point no guard covered.
That point was the end of the segmented start, which ``segments="auto"`` tried because the
residuals exceed 3× the noise; the trigger test (greybox/_segment_trigger.py) now tells this
model error from a local minimum and does not try it, so the fit does not go there.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fuelid.greybox import GreyBoxEstimator
from fuelid.greybox.modelfile import load_model_file
from support.cascaded_tanks import EXAMPLES, REFERENCE_VALIDATION_RMSE, cascaded_tanks_records


@pytest.mark.slow
def test_hold_undetermined_fits_the_user_model_where_the_held_fit_ended_in_a_solver_failure(
    tmp_path: Path,
) -> None:
    estimation, validation = cascaded_tanks_records(tmp_path)
    model = load_model_file(EXAMPLES / "cascaded_tanks.py")
    estimator = GreyBoxEstimator(model, hold_undetermined=True)
    # bands stated before the run: no refusal and no solver error escapes; a model error, so no
    # segmented start (with the states reset the parameters take under half the excess misfit);
    # a solver that failed on the way is said in the solver's reason; the validation RMSE within
    # 25 % of the reference script's
    estimator.fit([estimation])
    assert estimator.start_.startswith("single shooting (a segmented start would not pay")
    assert estimator.solver_.reason == "" or "fell back" in estimator.solver_.reason
    # with k4 fixed the model has no exact symmetry (theory: k4 fixes the upper level's scale),
    # so no trade-off may be claimed at the end point: a claim the sensitivities make there
    # (the switch spikes xmax's column) must be contradicted by the simulated step, not printed
    report = estimator.identifiability_
    assert "trade against each other" not in report.message()
    assert all(rise > 3.84 for _, rise in report.unconfirmed)
    predicted = estimator.predict(validation)
    rmse = math.sqrt(float(np.mean((predicted[:, 0] - validation.y[:, 0]) ** 2)))
    assert rmse <= 1.25 * REFERENCE_VALIDATION_RMSE
