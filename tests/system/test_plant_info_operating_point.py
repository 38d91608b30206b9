"""A ``fuelid plant info --json`` file is a model file with its operating point (issue 37).

``plant info`` wrote ``u`` and ``fuel_temperature`` at the top level only, where
``load_fitted_model`` did not look: ``tune --model`` then ignored the operating point. It now
also writes them inside ``operating_point``, and the loader reads either form, with the file's
full linearisation ``linear_model``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.io.fitted_model import load_fitted_model
from fuelid.model import MODEL_KEYS

runner = CliRunner()

#: How close the linear model's DC gain must be to the file's K. The reduction defines K as the
#: exact static gain −C·A⁻¹·B + D of the full linearisation (fuelid.plant._linear), and
#: ``linear_model`` is the same (A, B, C, D) converted by ss2tf, written and read back exactly
#: (JSON keeps a float's repr): only rounding separates num[-1]/den[-1] from K, a few ulps times
#: the conditioning of the pole spread (0.8 … 160 rad/s), 9e-15 relative measured. 1e-10 leaves
#: that four orders of margin for another LAPACK, and any modelling difference (a unit, the
#: meter gain, a dropped state) would be 1e-3 or more.
DC_GAIN_RTOL = 1e-10


@pytest.fixture(scope="module")
def plant_info_json() -> dict[str, Any]:
    result = runner.invoke(app, ["plant", "info", "--json", "--u", "2", "--fuel-temp", "35"])
    assert result.exit_code == 0, result.stderr
    data: dict[str, Any] = json.loads(result.stdout)
    return data


def _write(tmp_path: Path, data: dict[str, Any]) -> Path:
    path = tmp_path / "plant-info.json"
    path.write_text(json.dumps(data), encoding="utf-8")
    return path


def test_plant_info_writes_u_and_fuel_temperature_in_operating_point(
    plant_info_json: dict[str, Any],
) -> None:
    point = plant_info_json["operating_point"]
    assert point["u"] == plant_info_json["u"] == 2.0
    assert point["fuel_temperature"] == plant_info_json["fuel_temperature"] == 35.0
    # the other keys are unchanged, and the units map names both keys' units
    assert set(point) >= {"flow", "pump_pressure", "nozzle_pressure", "speed", "reynolds"}
    assert plant_info_json["units"]["u"] == "V"
    assert plant_info_json["units"]["fuel_temperature"] == "degC"


def test_a_plant_info_file_reads_back_with_its_operating_point_and_linear_model(
    tmp_path: Path, plant_info_json: dict[str, Any]
) -> None:
    fitted = load_fitted_model(_write(tmp_path, plant_info_json))
    assert fitted.u == 2.0
    assert fitted.fuel_temperature == 35.0
    assert plant_info_json["model"]["K"] == fitted.model.K
    spec = fitted.linear_model
    assert spec is not None
    written = plant_info_json["linear_model"]
    assert (list(spec.num), list(spec.den)) == (written["num"], written["den"])
    assert spec.delay == written["delay"] == plant_info_json["model"]["delay"]
    # the delay-free part's DC gain times e^(−delay·0) = 1 is the reduced model's K
    tf = spec.to_control()
    dc_gain = float(np.real(tf.dcgain())) * np.exp(-spec.delay * 0.0)
    assert dc_gain == pytest.approx(fitted.model.K, rel=DC_GAIN_RTOL)
    # plant info gives no control period, standard errors or intervals
    assert fitted.control_period is None
    assert fitted.stderr == dict.fromkeys(MODEL_KEYS)
    assert fitted.ci95 == {}  # a model from physics: no intervals to judge


def test_a_plant_info_file_of_before_reads_its_top_level_operating_point(
    tmp_path: Path, plant_info_json: dict[str, Any]
) -> None:
    older = json.loads(json.dumps(plant_info_json))
    del older["operating_point"]["u"], older["operating_point"]["fuel_temperature"]
    fitted = load_fitted_model(_write(tmp_path, older))
    assert (fitted.u, fitted.fuel_temperature) == (2.0, 35.0)
