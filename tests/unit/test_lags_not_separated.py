"""Two lags the data do not separate: the order rule, the intervals and the table agree.

A new user's historian export (gaps, no plant file) gave T ≈ T2 correlated at +0.9999999: the
intervals of both were withheld, yet the order rule's reason said the second lag's "95 %
interval excludes zero", ``split_undetermined`` was false, and the table read "fixed" for two
estimated parameters.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fuelid.cli._identify import _print_table
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


def _data(stderr_T: float | None) -> dict[str, object]:
    model = {"K": 8.8, "T": 0.80, "T2": 0.80, "T_f": 0.0, "delay": 0.5}
    stderr = {"K": 0.01, "T": stderr_T, "T2": stderr_T, "T_f": None, "delay": 0.01}
    ci = {k: None if v is None else [model[k] - 2 * v, model[k] + 2 * v] for k, v in stderr.items()}
    return {
        "method": "oe",
        "n_samples": 100,
        "sample_time": 0.1,
        "model": model,
        "stderr": stderr,
        "ci95": ci,
        "fixed": ["T_f"],
        "fit_percent": 96.0,
        "validation_fit_percent": None,
        "operating_point": {"u": 41.1, "y": 24.26, "fuel_temperature": None},
        "priors": {
            "flowmeter_T": {"value": None, "source": "not given"},
            "delay": {"value": 0.5, "source": "estimated"},
            "order": {"value": 2, "source": "information criterion"},
            "plant": None,
        },
        "covariance": "white",
    }


def _rows(out: str) -> dict[str, str]:
    rows = {}
    for line in out.splitlines():
        cells = [c.strip() for c in line.strip("│ ").split("│")]
        if len(cells) == 5:
            rows[cells[0]] = cells[2]
    return rows


def _print(capsys: pytest.CaptureFixture[str], data: dict[str, object]) -> str:
    _print_table(data, Path("hist.csv"), "x", ("input unit", "unit of FT201.PV"), "fitted")
    return capsys.readouterr().out


def test_estimated_without_interval_reads_not_determined(
    capsys: pytest.CaptureFixture[str],
) -> None:
    rows = _rows(_print(capsys, _data(None)))
    assert rows["T"] == rows["T2"] == "not determined"
    assert rows["T_f"] == "fixed"


def test_operating_point_names_unknown_units(capsys: pytest.CaptureFixture[str]) -> None:
    out = " ".join(_print(capsys, _data(0.01)).split())
    assert "u = 41.1 (input unit), flow 24.26 (unit of FT201.PV);" in out
