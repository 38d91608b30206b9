"""Issue 38 item 5: a model file's edited ``units`` map is converted or refused, never ignored.

The conversions are exact by definition: 1 L/s = 60 L/min, 1 m³/h = 1000/60 L/min, 1 mV = 1e-3 V,
1 ms = 1e-3 s, T [K] = t [°C] + 273.15; a variance scales with the square of its factor.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest

from fuelid.cli import main
from fuelid.errors import DataError
from fuelid.io.fitted_model import load_fitted_model

AS_WRITTEN: dict[str, Any] = {
    "model": {"K": 15.0, "T": 1.5, "T2": 0.0, "T_f": 0.0, "delay": 0.25},
    "stderr": {"K": 0.03, "T": 0.006, "T2": None, "T_f": None, "delay": 0.002},
    "ci95": {"K": [14.94, 15.06], "T": [1.488, 1.512], "T2": None, "T_f": None, "delay": None},
    "cov": {"names": ["K", "T"], "matrix": [[9e-4, 1e-5], [1e-5, 3.6e-5]]},
    "operating_point": {"u": 1.5, "fuel_temperature": 20.0},
    "units": {"K": "(L/min)/V", "T": "s", "T2": "s", "T_f": "s", "delay": "s", "u": "V"},
}


def _write(tmp_path: Path, data: dict[str, Any]) -> Path:
    path = tmp_path / "model.json"
    path.write_text(json.dumps(data))
    return path


def test_a_model_file_in_other_known_units_is_converted(tmp_path: Path) -> None:
    edited = {
        "model": {"K": 0.25, "T": 1500.0, "T2": 0.0, "T_f": 0.0, "delay": 250.0},
        "stderr": {"K": 0.0005, "T": 6.0, "T2": None, "T_f": None, "delay": 2.0},
        "ci95": {
            "K": [0.249, 0.251],
            "T": [1488.0, 1512.0],
            "T2": None,
            "T_f": None,
            "delay": None,
        },
        "cov": {
            "names": ["K", "T"],
            "matrix": [[2.5e-7, 1e-5 / 60 * 1000], [1e-5 / 60 * 1000, 36.0]],
        },
        "operating_point": {"u": 1500.0, "fuel_temperature": 293.15},
        "units": {
            "K": "(L/s)/V",
            "T": "ms",
            "T2": "ms",
            "T_f": "ms",
            "delay": "ms",
            "u": "mV",
            "fuel_temperature": "K",
        },
    }
    read = load_fitted_model(_write(tmp_path, edited))
    reference = load_fitted_model(_write(tmp_path, AS_WRITTEN))
    gain, lag = read.model.K, read.model.T
    assert gain == pytest.approx(reference.model.K, rel=1e-12)
    assert lag == pytest.approx(1.5, rel=1e-12)
    assert read.model.delay == pytest.approx(0.25, rel=1e-12)
    assert read.stderr["K"] == pytest.approx(0.03, rel=1e-12)
    assert read.ci95["T"] == pytest.approx((1.488, 1.512), rel=1e-12)
    assert read.u == pytest.approx(1.5, rel=1e-12)
    assert read.fuel_temperature == pytest.approx(20.0, abs=1e-9)
    assert read.cov_names == ("K", "T")
    assert read.cov is not None
    assert read.cov[0][0] == pytest.approx(9e-4, rel=1e-12)  # 2.5e-7 (L/s)²/V² · 60²
    assert read.cov[1][1] == pytest.approx(3.6e-5, rel=1e-12)  # 36 ms² · 1e-6
    assert read.cov[0][1] == pytest.approx(1e-5, rel=1e-12)  # · 60 · 1e-3


def test_m3_per_hour_per_millivolt_is_converted(tmp_path: Path) -> None:
    data = {"model": {**AS_WRITTEN["model"], "K": 0.0009}, "units": {"K": "(m³/h)/mV"}}
    read = load_fitted_model(_write(tmp_path, data))
    gain = read.model.K
    assert gain == pytest.approx(0.0009 * (1000 / 60) / 1e-3, rel=1e-12)  # 15 (L/min)/V


@pytest.mark.parametrize(
    ("key", "unit"), [("K", "(gal/min)/V"), ("T", "h"), ("delay", "samples"), ("u", "mA")]
)
def test_an_unknown_unit_is_refused_with_the_key_and_the_unit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], key: str, unit: str
) -> None:
    path = _write(tmp_path, AS_WRITTEN | {"units": {**AS_WRITTEN["units"], key: unit}})
    with pytest.raises(DataError, match=re.escape(f"units.{key} is '{unit}'")):
        load_fitted_model(path)
    assert main(["tune", "--model", str(path), "--control-period", "1", "--json"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert f"units.{key} is '{unit}'" in err


def test_the_units_fuelid_writes_are_read_as_they_are(tmp_path: Path) -> None:
    identify_style = AS_WRITTEN | {
        "units": {"K": "output unit per input unit ((L/min)/V for the fuel loop)", "T": "s"}
    }
    read = load_fitted_model(_write(tmp_path, identify_style))
    assert read.model.K == 15.0
    assert read.model.T == 1.5
