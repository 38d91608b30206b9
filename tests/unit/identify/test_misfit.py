"""The model error a log shows, and the worst Ms over it (issue 37: what the model misses).

The loop is K·e^(−0.2s)/((s+1)(0.3s+1)); the model leaves out the 0.3 s lag, so the true error
is Δ(jω) = 1/(1 + 0.3jω) − 1, known exactly, and so is the true Ms of any PI on the loop.
Bands, from the estimator's theory (Bendat & Piersol's H1 estimate, six averages):

- where the command has power (below the first null of its 1 s hold, 2π rad/s) the bound
  |Δ̂| + ρ covers the true |Δ| at every frequency up to the stated 95 % (some bins may miss);
- the worst Ms over the misfit is at least the true Ms less the estimate's leakage bias (2 %)
  and at most the true Ms plus what the 95 % disk adds (15 %); the model's own Ms is far below;
- a model that is the loop: the worst Ms over the misfit is the model's within 5 %.
"""

from __future__ import annotations

import numpy as np
import pytest

from fuelid.identify._misfit import misfit_bound
from fuelid.model import ProcessModel, simulate_model
from fuelid.tuning import robust_peak, robustness, tune

H = 0.02
TRUTH = ProcessModel(K=2.0, T=1.0, T2=0.3, delay=0.2)
NOMINAL = ProcessModel(K=2.0, T=1.0, delay=0.2)


def _log(seed: int = 11) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.choice([-0.5, 0.5], 600), 50)  # 600 s, a random switch every 1 s
    y = simulate_model(TRUTH, u, H) + rng.normal(0.0, 0.02, u.size)
    return u, y


def test_the_bound_covers_the_true_model_error():
    u, y = _log()
    bound = misfit_bound(u, y - simulate_model(NOMINAL, u, H), H, NOMINAL)
    assert bound is not None
    excited = bound.omega < 2.0 * np.pi
    true_error = np.abs(1.0 / (1.0 + 0.3j * bound.omega) - 1.0)
    assert np.mean(bound.bound[excited] >= true_error[excited]) >= 0.95
    assert bound.excited_up_to > 2.0  # beyond the loop's crossover (about 1 rad/s)


@pytest.mark.parametrize("h", [0.1, 0.0])
def test_the_worst_ms_over_the_misfit_is_the_loops(h: float):
    u, y = _log()
    bound = misfit_bound(u, y - simulate_model(NOMINAL, u, H), H, NOMINAL)
    assert bound is not None
    pi = tune(NOMINAL, "simc", h)
    nominal, true = robustness(NOMINAL, pi).Ms, robustness(TRUTH, pi).Ms
    worst = robust_peak(NOMINAL, pi, bound.at, bound.excited_up_to).Ms
    assert 0.98 * true <= worst <= 1.15 * true
    assert nominal < 0.75 * true  # the model alone misses it: 1.57 against 2.27 at h = 0.1


def test_a_model_that_is_the_loop_keeps_its_ms():
    u, y = _log(seed=5)
    bound = misfit_bound(u, y - simulate_model(TRUTH, u, H), H, TRUTH)
    assert bound is not None
    pi = tune(TRUTH, "simc", 0.1)
    nominal = robustness(TRUTH, pi).Ms
    worst = robust_peak(TRUTH, pi, bound.at, bound.excited_up_to).Ms
    assert nominal <= worst <= 1.05 * nominal


def test_a_log_that_does_not_reach_the_crossover_bounds_nothing():
    # one step and a long hold: the command's power is all far below the loop's crossover
    rng = np.random.default_rng(2)
    u = np.r_[np.zeros(2000), np.full(28000, 0.5)]
    y = simulate_model(TRUTH, u, H) + rng.normal(0.0, 0.2, u.size)
    bound = misfit_bound(u, y - simulate_model(NOMINAL, u, H), H, NOMINAL)
    assert bound is not None
    pi = tune(NOMINAL, "simc", 0.1)
    peak = robust_peak(NOMINAL, pi, bound.at, bound.excited_up_to)
    assert peak.up_to < robustness(NOMINAL, pi).crossover_frequency
    assert peak.Ms == np.inf


def test_the_overshoot_with_the_misfit_is_the_loops():
    # the step on the model with the estimated error: the loop's own step at the instants,
    # within 10 % or 1 point (the estimate's bias, a few % of Δ); the model alone is far off
    from fuelid.tuning import linear_closed_loop, misfit_overshoot

    u, y = _log()
    bound = misfit_bound(u, y - simulate_model(NOMINAL, u, H), H, NOMINAL)
    assert bound is not None
    pi = tune(NOMINAL, "simc", 0.1)
    true = linear_closed_loop(TRUTH, pi, oversample=1).setpoint.overshoot_percent
    nominal = linear_closed_loop(NOMINAL, pi, oversample=1).setpoint.overshoot_percent
    with_misfit = misfit_overshoot(NOMINAL, pi, bound.at, bound.excited_up_to)
    assert with_misfit is not None
    assert abs(with_misfit - true) <= max(0.1 * true, 1.0)
    assert abs(nominal - true) > 5.0
