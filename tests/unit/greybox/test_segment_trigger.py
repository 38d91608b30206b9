"""The segmented start's trigger: a local minimum told from a model error.

The arithmetic against constructions whose answer is known (the residual in the parameters'
span, or orthogonal to it), and the estimator on a tank record with a model error (a pump gain
that drifts, which no parameter value follows): the segmented start is not tried there, and
the fit is the plain one.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuelid.greybox import GreyBoxEstimator, Record
from fuelid.greybox._fitting import Evaluation
from fuelid.greybox._segment_trigger import PARAMETER_SHARE, Pieces, trigger_test
from fuelid.greybox._sensitivity import simulate_record
from unit.greybox.test_greybox import TANK_TRUTH, TANK_X0, tank_model

SAMPLES = 200  # per segment
SEGMENTS = 4


def _pieces() -> Pieces:
    t = np.arange(SAMPLES, dtype=float)
    records = [Record.from_arrays(t, np.zeros(SAMPLES), np.zeros(SAMPLES))] * SEGMENTS
    spans = [(0, k * SAMPLES, (k + 1) * SAMPLES) for k in range(SEGMENTS)]
    return Pieces(records, spans, [np.zeros(1)] * SEGMENTS)


def _evaluation(residuals: np.ndarray, theta_column: np.ndarray) -> Evaluation:
    """One parameter, one state per segment (an offset: a column of ones on its rows)."""
    m = SAMPLES * SEGMENTS
    jacobian = np.zeros((m, 1 + SEGMENTS))
    jacobian[:, 0] = theta_column
    for k in range(SEGMENTS):
        jacobian[k * SAMPLES : (k + 1) * SAMPLES, 1 + k] = 1.0
    return Evaluation(residuals, jacobian, [])


def test_a_misfit_the_parameters_explain_on_the_segments_pays() -> None:
    """Residuals a·J_θ + white noise of unit variance (the floor): the parameter takes the excess.

    Theory: the excess over the floor is a²·‖P⊥J_θ‖² ± the noise's χ² fluctuation
    (√(2m) ≈ 40 on m = 800, against an excess of 2000), and the parameter removes all of it
    plus a χ²₁ share of the noise: the share is 1 within 0.1.
    """
    rng = np.random.default_rng(3)
    ramp = np.tile(np.linspace(-1.0, 1.0, SAMPLES), SEGMENTS)
    column = ramp * math.sqrt(2000.0 / np.sum(ramp**2))  # ‖J_θ‖² = 2000 (ramps have mean 0)
    residuals = column + rng.normal(0.0, 1.0, SAMPLES * SEGMENTS)
    test = trigger_test(_evaluation(residuals, column), _pieces(), 1, 1, np.ones(1))
    assert test.floor == SAMPLES * SEGMENTS
    assert test.share == pytest.approx(1.0, abs=0.1)
    assert test.pays


def test_a_misfit_no_parameter_makes_is_a_model_error() -> None:
    """Residuals g + noise, g orthogonal to J_θ and to every segment's offset: nothing to gain.

    Theory: the parameter removes only a χ²₁ share of the noise (≈ 1 against an excess of
    2000): the share is below 0.01.
    """
    rng = np.random.default_rng(4)
    x = np.linspace(-1.0, 1.0, SAMPLES)
    ramp, shape = np.tile(x, SEGMENTS), np.tile(x**2 - np.mean(x**2), SEGMENTS)
    shape -= ramp * (shape @ ramp) / (ramp @ ramp)  # (already orthogonal: x² − c is even)
    misfit = shape * math.sqrt(2000.0 / np.sum(shape**2))
    residuals = misfit + rng.normal(0.0, 1.0, SAMPLES * SEGMENTS)
    test = trigger_test(_evaluation(residuals, ramp), _pieces(), 1, 1, np.ones(1))
    assert test.share < 0.01
    assert not test.pays
    assert "model error" in test.describe()


def test_no_excess_over_the_noise_is_no_reason_to_segment() -> None:
    rng = np.random.default_rng(5)
    ramp = np.tile(np.linspace(-1.0, 1.0, SAMPLES), SEGMENTS)
    residuals = rng.normal(0.0, 1.0, SAMPLES * SEGMENTS)
    test = trigger_test(_evaluation(residuals, ramp), _pieces(), 1, 1, np.full(1, 2.0))
    assert test.share == 0.0
    assert not test.pays


def drifting_pump_record(n: int = 1000, noise: float = 0.01) -> Record:
    """The tanks of test_greybox with the pump's gain drifting ±20 % over 400 s (not recorded)."""
    rng = np.random.default_rng(6)
    t = np.arange(n) * 1.0
    u = np.repeat(rng.uniform(0.5, 1.5, n // 50 + 1), 50)[:n]
    drifted = u * (1.0 + 0.2 * np.sin(2.0 * math.pi * t / 400.0))
    truth = tank_model(fixed=tuple(TANK_TRUTH), start_factor=1.0)
    blank = Record.from_arrays(t, drifted, np.zeros(n))
    clean = simulate_record(truth.bind(TANK_TRUTH, [], blank), blank, TANK_X0).outputs[:, 0]
    return Record.from_arrays(t, u, clean + rng.normal(0.0, noise, n))


def test_a_model_error_does_not_start_the_segmented_start() -> None:
    """Residuals far above the noise from a drift no parameter follows: the plain fit stands.

    The trigger's rule (share ≥ PARAMETER_SHARE) says "model error"; the estimate is the one
    single shooting alone gives, and the start says why the segmented start was not tried.
    """
    record = drifting_pump_record()
    plain = GreyBoxEstimator(tank_model(), "estimate", segments=None).fit(record)
    assert plain.sigma_[0] > 3.0 * plain.noise_floor_[0]  # suspect by the old rule
    auto = GreyBoxEstimator(tank_model(), "estimate").fit(record)
    assert auto.start_.startswith("single shooting (a segmented start would not pay")
    assert f"({PARAMETER_SHARE:.0%} needed)" in auto.start_
    for name in ("k1", "k2", "k3"):
        assert auto.params_[name] == pytest.approx(plain.params_[name], rel=1e-9)
