"""The closed-form settling time of distinct lags equals the 24,001-point grid it replaces.

The grid's linear interpolation between samples is good to ~1e-7 s: the two agree within 1e-6 s
(issue 26, second pass; the band from the grid's own error, not from what the code printed).
"""

from __future__ import annotations

import pytest

from fuelid.model import _settling_time


@pytest.mark.parametrize(
    ("K", "lags", "delay"),
    [
        (1.5, (2.0, 0.7, 0.3), 0.1),
        (1.5, (2.0, 0.3), 0.1),
        (-0.8, (5.0,), 0.0),
        (1.0, (2.0, 1.99, 0.3), 0.1),  # two lags 0.5 % apart: still distinct
        (1.0, (30.0, 0.05), 1.3),
    ],
)
def test_closed_form_settling_time_equals_the_grid(K, lags, delay):
    grid = _settling_time.__wrapped__(K, lags, delay, 0.02, False)
    exact = _settling_time.__wrapped__(K, lags, delay, 0.02, True)
    assert abs(exact - grid) <= 1e-6


def test_nearly_equal_lags_keep_the_grid():
    lags = (2.0, 2.0005)  # the closed form's coefficients T_i/(T_i − T_j) would lose digits
    grid = _settling_time.__wrapped__(1.0, lags, 0.0, 0.02, False)
    assert _settling_time.__wrapped__(1.0, lags, 0.0, 0.02, True) == grid
