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


def test_a_result_with_its_lags_withheld_says_they_are_merged():
    # what _separate_lags leaves: T's and T2's rows unknown, the gain's known; the report then
    # judges T by the response, not alone (its interval is withheld, not infinite)
    from fuelid.identify import IdentificationResult
    from fuelid.identify._procedure import _separate_lags
    from fuelid.model import ProcessModel

    names = ("K", "T", "T2", "delay")
    cov = np.diag([1e-4, 4e-4, 4e-4, 1e-5])
    cov[1, 2] = cov[2, 1] = 3.9999e-4  # corr +0.99998
    stderr: dict[str, float | None] = {"K": 0.01, "T": 0.02, "T2": 0.02, "delay": 0.003}
    withheld = _separate_lags(names, cov, stderr, [])
    empty = np.zeros(3)

    def result(model: ProcessModel, c: np.ndarray) -> IdentificationResult:
        return IdentificationResult(
            "oe", model, (), stderr, names, c, 97.0, None, 3, 0.02, [], empty, empty, empty, None
        )

    two = ProcessModel(K=13.3, T=1.09, T2=1.09, delay=0.66)
    assert stderr["T"] is None
    assert stderr["T2"] is None
    assert result(two, withheld).lags_merged
    assert not result(two, cov).lags_merged  # intervals kept: judged as they are
    assert not result(ProcessModel(K=13.3, T=1.09, delay=0.66), withheld).lags_merged
