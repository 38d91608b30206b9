"""The printed table of ``fuelid identify``: what a lag without an interval reads.

A lag estimated without an interval reads "not determined"; an operating point without units
names the units it lacks.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from fuelid.cli._identify import _print_table


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
