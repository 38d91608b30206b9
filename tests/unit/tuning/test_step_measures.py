"""fuelid's one set of step-response measures (fuelid.lti.step_measures) and its callers.

python-control's ``step_info`` is the cross-check: on a fine grid, where sample instants and
interpolated crossings agree to a sample, the two give the same numbers.
"""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from fuelid import lti
from fuelid.online.health import step_response_measures
from fuelid.tuning._metrics import setpoint_step_metrics


def _second_order(zeta: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit-step response of ω²/(s² + 2ζωs + ω²), ω = 2 rad/s, on a 1 ms grid."""
    system = control.tf([4.0], [1.0, 4.0 * zeta, 4.0])
    t = np.arange(0.0, 30.0, 0.001)
    response = control.step_response(system, t)
    return t, np.asarray(response.outputs, dtype=float)


@pytest.mark.parametrize("zeta", [0.3, 0.7, 1.0, 2.0])
def test_agrees_with_python_control_on_a_fine_grid(zeta: float) -> None:
    t, y = _second_order(zeta)
    info = control.step_info(y, t, yfinal=1.0)
    ours = lti.step_measures(t, y, 0.0, 1.0)
    sample = t[1] - t[0]
    assert ours.overshoot_percent == pytest.approx(info["Overshoot"], abs=1e-6)
    assert ours.settling_time == pytest.approx(info["SettlingTime"], abs=sample)
    assert ours.rise_time == pytest.approx(info["RiseTime"], abs=2 * sample)


def test_a_step_down_and_an_offset_start_scale_like_a_unit_step() -> None:
    t, y = _second_order(0.5)
    unit = lti.step_measures(t, y, 0.0, 1.0)
    down = lti.step_measures(t, 50.0 - 8.0 * y, 50.0, 42.0)
    assert down.overshoot_percent == pytest.approx(unit.overshoot_percent)
    assert down.settling_time == pytest.approx(unit.settling_time)
    assert down.rise_time == pytest.approx(unit.rise_time)
    assert down.iae == pytest.approx(8.0 * unit.iae)


def test_an_unfinished_response_has_no_rise_or_settling_time() -> None:
    t = np.linspace(0.0, 1.0, 101)
    measures = lti.step_measures(t, 0.5 * t, 0.0, 1.0)  # reaches half the step
    assert math.isnan(measures.rise_time)
    assert math.isnan(measures.settling_time)
    assert measures.overshoot_percent == 0.0


def test_the_tuning_and_the_online_measures_are_the_same_numbers() -> None:
    t, y = _second_order(0.4)
    tuning = setpoint_step_metrics(t, 20.0 + 5.0 * y, 20.0, 25.0)
    online = step_response_measures(t, 20.0 + 5.0 * y, 20.0, 25.0, band_fraction=lti.SETTLING_BAND)
    assert online.overshoot_percent == tuning.overshoot_percent
    assert online.settling_time == tuning.settling_time
    assert online.iae == tuning.iae


def test_a_step_of_no_size_is_refused() -> None:
    with pytest.raises(ValueError, match="non-zero"):
        lti.step_measures([0.0, 1.0], [1.0, 1.0], 1.0, 1.0)
