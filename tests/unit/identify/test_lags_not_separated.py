"""Two lags the data do not separate: the order rule, the intervals and the table agree.

A new user's historian export (gaps, no plant file) gave T ≈ T2 correlated at +0.9999999: the
intervals of both were withheld, yet the order rule's reason said the second lag's "95 %
interval excludes zero", ``split_undetermined`` was false, and the table read "fixed" for two
estimated parameters.
"""

from __future__ import annotations

import numpy as np
import pytest

from fuelid.identify._order import Candidate, choose_order, lags_told_apart
from fuelid.model import ProcessModel


def _candidates() -> list[Candidate]:
    # T and T2 differ by far more than the standard error of their difference, but are
    # correlated beyond 0.999: not separately determined
    se, r = 0.0065, 0.9999999
    cov2 = np.diag([1e-4, se**2, se**2, 1e-4])
    cov2[1, 2] = cov2[2, 1] = r * se**2
    names2 = ("K", "T", "T2", "delay")
    two = Candidate(
        2, -5000.0, 6, ProcessModel(K=8.8, T=0.8042, T2=0.8044, delay=0.52),
        {"K": 0.01, "T": se, "T2": se, "delay": 0.01}, names2, cov2,
    )  # fmt: skip
    one = Candidate(
        1, -4500.0, 4, ProcessModel(K=8.8, T=1.36, delay=0.85),
        {"K": 0.03, "T": 0.02, "delay": 0.02}, ("K", "T", "delay"), np.diag([1e-3, 4e-4, 2e-4]),
    )  # fmt: skip
    return [one, two]


def test_lags_correlated_beyond_the_threshold_are_not_told_apart() -> None:
    two = _candidates()[1]
    assert not lags_told_apart(two)


@pytest.mark.parametrize("meter_lag_given", [False, True])
def test_order_reason_does_not_cite_a_withheld_interval(meter_lag_given: bool) -> None:
    choice = choose_order(_candidates(), 0.1, meter_lag_given=meter_lag_given)
    assert choice.chosen == 2
    assert choice.split_undetermined
    assert choice.to_json()["split_undetermined"] is True
    assert "excludes zero" not in choice.reason
    assert "not told apart" in choice.reason
