"""Equal lags get no separate intervals: corr(T, T2) beyond ±0.999 determines only the response."""

from __future__ import annotations

import numpy as np
import pytest


def test_equal_lags_get_no_separate_intervals():
    # corr(T, T2) beyond ±0.999: only the response is determined, the intervals would lie
    from fuelid.identify._procedure import _lags_not_separated

    names = ("K", "T", "T2", "offset")
    cov = np.diag([1.0, 4.0, 4.0, 1.0])
    assert _lags_not_separated(names, cov) is None
    cov[1, 2] = cov[2, 1] = -3.999
    assert _lags_not_separated(names, cov) == pytest.approx(-0.99975)
    assert _lags_not_separated(("K", "T"), np.eye(2)) is None
