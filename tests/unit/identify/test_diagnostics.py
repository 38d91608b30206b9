"""Residual tests against residuals whose whiteness and correlation are known by construction."""

from __future__ import annotations

import numpy as np
import scipy.signal

from fuelid.identify import (
    feedback_suspected,
    input_residual_correlation,
    residual_whiteness,
    sample_time_advice,
    steady_state_errors,
)

N = 4000


def test_white_noise_passes_and_coloured_noise_fails():
    rng = np.random.default_rng(1)
    white = rng.normal(size=N)
    coloured = scipy.signal.lfilter([1.0], [1.0, -0.8], white)  # AR(1): r(1) = 0.8
    ok = residual_whiteness(white)
    bad = residual_whiteness(coloured)
    assert ok.passed
    assert ok.bound == 1.96 / np.sqrt(N)
    assert not bad.passed
    assert abs(bad.values[0] - 0.8) < 0.05  # lag 1 autocorrelation of an AR(1) with a = 0.8


def test_unmodelled_dynamics_show_in_the_cross_correlation():
    rng = np.random.default_rng(2)
    u = np.repeat(rng.choice([0.0, 1.0], N // 10), 10)
    noise = rng.normal(0.0, 0.1, N)
    # a residual that still contains a delayed piece of the input (an unmodelled lag)
    leaked = noise + 0.2 * scipy.signal.lfilter([0.0, 0.3], [1.0, -0.7], u - u.mean())
    assert input_residual_correlation(u, noise).passed
    assert not input_residual_correlation(u, leaked).passed


def test_feedback_is_detected_from_correlation_with_later_inputs():
    rng = np.random.default_rng(3)
    e = rng.normal(size=N)
    u_open = np.repeat(rng.choice([0.0, 1.0], N // 10), 10)
    # a controller reacting to the measured output: u moves after the disturbance e appears
    u_closed = u_open - 0.8 * np.r_[0.0, np.cumsum(e)[:-1]] * 0.05
    assert not feedback_suspected(input_residual_correlation(u_open, e))
    assert feedback_suspected(input_residual_correlation(u_closed, e))


def test_steady_state_error_of_each_long_plateau():
    u = np.repeat([1.0, 1.5, 1.2], [300, 300, 30])  # the last plateau is too short to judge
    y = 14.0 * u
    y_hat = 14.0 * u * np.where(u == 1.5, 1.02, 1.0)
    errors = steady_state_errors(u, y, y_hat, 0.02, settle=5.3)
    assert [round(e.error_percent, 9) for e in errors] == [0.0, 2.0]


def test_sample_time_advice():
    assert "only 5.3 samples" in (sample_time_advice(5.3, 1.0) or "")
    assert sample_time_advice(5.3, 0.02) is None
