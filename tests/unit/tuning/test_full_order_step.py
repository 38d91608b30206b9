"""The closed loop on a state-space plant (a full linearisation) equals the model family's.

A plant of the model family written as a transfer function, num/den with its delay, is the same
plant: the sampled PI's setpoint step on it (``full_order_closed_loop``, through the modified
z-transform) must equal ``linear_closed_loop``'s on the ProcessModel to rounding (1e-8 of the unit
step: both are exact ZOH discretisations, evaluated by different algebra).
"""

from __future__ import annotations

import numpy as np
import pytest

from fuelid.model import ProcessModel
from fuelid.tuning import (
    TransferFunctionPlant,
    full_order_closed_loop,
    linear_closed_loop,
    simc,
    step_duration,
)

MODEL = ProcessModel(K=2.0, T=1.3, T2=0.4, T_f=0.3, delay=0.27)
PLANT = TransferFunctionPlant.from_coefficients(
    [2.0], np.polymul(np.polymul([1.3, 1.0], [0.4, 1.0]), [0.3, 1.0]), 0.27
)


@pytest.mark.parametrize("h", [0.1, 1.0, 0.0])
def test_a_model_of_the_family_in_state_space_has_the_same_step(h: float):
    pi = simc(MODEL, h)
    reduced = linear_closed_loop(MODEL, pi)
    full = full_order_closed_loop(PLANT, pi, step_duration(MODEL, pi))
    n = min(reduced.time.size, full.time.size)
    np.testing.assert_allclose(full.time[:n], reduced.time[:n], rtol=0, atol=1e-12)
    np.testing.assert_allclose(full.setpoint_response[:n], reduced.setpoint_response[:n], atol=1e-8)
    np.testing.assert_allclose(
        full.disturbance_response[:n], reduced.disturbance_response[:n], atol=1e-8
    )
    assert full.setpoint.overshoot_percent == pytest.approx(
        reduced.setpoint.overshoot_percent, abs=1e-6
    )
