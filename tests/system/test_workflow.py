"""The library workflow: the command line's JSON is the workflow's ``to_json()``, nothing more.

``fuelid identify``, ``fuelid tune`` and ``fuelid tune --schedule`` only parse, call the workflow
and print; so the JSON they print must equal the workflow result's ``to_json()`` (through the same
JSON writer) apart from the provenance block. Inside, temperatures are kelvin; the JSON has °C.
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.errors import FuelidError
from fuelid.identify import IdentifyOptions
from fuelid.io.jsonsafe import json_ready
from fuelid.io.logs import load_log
from fuelid.model import ProcessModel, simulate_model
from fuelid.plant import load_plant_config
from fuelid.units import celsius_to_kelvin
from fuelid.workflow import (
    T_REF,
    PlantSource,
    TuneRequest,
    check_over_temperature,
    identify_log,
    operating_command,
    plant_priors,
    schedule_gains,
    tune_model,
)

runner = CliRunner()
CONFIG = load_plant_config()
MODEL = ProcessModel(K=13.5, T=1.26, T_f=0.3, delay=0.2)
REFERENCE_FILE = str(resources.files("fuelid.data").joinpath("reference_plant.toml"))
# the control period is never assumed (issue 37): the numbers below are for h = 1 s, given
FLAGS = ["--K", "13.5", "--T", "1.26", "--T-f", "0.3", "--delay", "0.2", "--control-period", "1"]
H = 1.0
# the plant file given on the command line, as the library is given it
USERS_PLANT = PlantSource(CONFIG, REFERENCE_FILE)
PROVENANCE = {"fuelid_version", "input_sha256", "options"}
# what the command adds about its own options: the plant file (or its absence), the notices and
# the parameters of a model file the log does not determine (accepted)
ASSUMPTIONS = {"plant", "notices", "fuel_temperature_source", "undetermined"}


def _cli(*args: str) -> dict:
    result = runner.invoke(app, [*args, "--json"])
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert set(data) >= PROVENANCE
    return {key: value for key, value in data.items() if key not in PROVENANCE | ASSUMPTIONS}


def _as_printed(payload: dict, capsys: pytest.CaptureFixture[str]) -> dict:
    # what the command prints of a payload: json_ready, then one JSON object
    return json.loads(json.dumps(json_ready(payload), allow_nan=False))


def test_tune_model_is_what_fuelid_tune_prints(capsys: pytest.CaptureFixture[str]):
    request = TuneRequest(
        model=MODEL, control_period=H, T_fuel=celsius_to_kelvin(12.0), simulate=True
    )
    outcome = tune_model(USERS_PLANT, request)
    cli = _cli("tune", *FLAGS, "--fuel-temp", "12", "--simulate", "--config", REFERENCE_FILE)
    assert _as_printed(outcome.to_json(), capsys) == cli
    # a bare PlantConfig is the script's own plant, as a plant file is
    assert _as_printed(tune_model(CONFIG, request).to_json(), capsys) == cli
    # the defaults resolved from the user's plant file: the middle of 1…5 V and its 100 L/min
    assert (outcome.u, outcome.y_span) == (3.0, 100.0)
    assert outcome.spans.y_span is not None
    assert outcome.spans.y_span.basis == "plant file"
    # SIMC with the half rule and h/2 (docs/explanation/tuning.md §2–3): T1 = 1.41 s, θ = 0.85 s
    assert outcome.pi.Kc == pytest.approx(1.41 / (13.5 * 2 * 0.85), rel=1e-12)
    # kelvin inside, °C in the JSON
    assert [run.T_fuel for run in outcome.runs] == [celsius_to_kelvin(-20.0), celsius_to_kelvin(50)]
    assert [run["fuel_temperature"] for run in cli["closed_loop_plant"]] == [-20.0, 50.0]


def test_schedule_gains_is_what_fuelid_tune_schedule_prints(capsys: pytest.CaptureFixture[str]):
    request = TuneRequest(model=MODEL, control_period=H, band_width=35.0, flow_bands=1)
    outcome = schedule_gains(USERS_PLANT, request)
    cli = _cli(
        "tune", *FLAGS, "--schedule", "--band-width", "35", "--flow-bands", "1",
        "--config", REFERENCE_FILE,
    )  # fmt: skip
    assert _as_printed(outcome.to_json(), capsys) == cli
    assert [(b["t_low"], b["t_high"]) for b in cli["bands"]] == [(-20.0, 15.0), (15.0, 50.0)]
    assert cli["anchored_to_model"] == MODEL.to_json()
    assert (cli["u_span"], cli["y_span"]) == (4.0, 100.0)  # the plant file's
    # the trend over temperature would be the reference plant's, not the user's loop: refused
    with pytest.raises(FuelidError, match="rests on your plant's physics"):
        schedule_gains(PlantSource(CONFIG), request)


def test_identify_log_is_what_fuelid_identify_prints(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    rng = np.random.default_rng(3)
    u = np.repeat(np.r_[3.0, rng.uniform(2.5, 3.5, 7)], 400)
    y = 40.0 + simulate_model(MODEL, u, 0.02) + rng.normal(0.0, 0.05, u.size)
    path = tmp_path / "log.csv"
    t = np.arange(u.size) * 0.02
    np.savetxt(path, np.column_stack([t, u, y]), delimiter=",", header="t_s,u_V,q_Lpm", comments="")
    options = plant_priors(IdentifyOptions(validate_split=0.3), CONFIG)
    assert (options.flowmeter_T, options.flowmeter_delay) == (0.3, 0.2)  # the meter's priors
    plant = str(resources.files("fuelid.data").joinpath("reference_plant.toml"))
    outcome = identify_log(
        load_log(path),
        IdentifyOptions(validate_split=0.3),
        t_start=2.0,
        plant=PlantSource(CONFIG, plant),
    )
    cli = _cli(
        "identify", str(path), "--config", plant, "--validate-split", "0.3", "--t-start", "2"
    )
    assert _as_printed(outcome.to_json(), capsys) == cli
    assert cli["units"]["T"] == "s"
    # the plant file's meter, held fixed, and said so
    assert cli["priors"]["flowmeter_T"] == {"value": 0.3, "source": "plant file"}
    assert cli["priors"]["delay"] == {"value": 0.2, "source": "plant file"}
    assert set(cli["fixed"]) >= {"delay", "T_f"}


@pytest.mark.parametrize(
    ("changes", "reason"),
    [
        ({"control_period": 20.0}, "up to 10 s"),
        ({"T_range": (323.15, 253.15)}, "low < high, got 50…-20 °C"),
        ({"T_fuel": float("nan")}, "fuel temperature"),
        ({"sweep": 0}, "1 to 20,000"),
        ({"y_span": -1.0}, "flow span"),
        ({"step_percent": 80.0}, "0…50 %"),
        ({"model": ProcessModel(K=13.5, T=1.26, delay=5000.0)}, "1000 control periods"),
    ],
)
def test_a_request_is_refused_before_any_work(changes: dict, reason: str):
    with pytest.raises(FuelidError, match=reason):
        TuneRequest(**{"model": MODEL, "control_period": H, **changes})


def test_tuning_needs_a_model_and_a_command_the_drive_gives():
    with pytest.raises(FuelidError, match="needs a model"):
        tune_model(CONFIG, TuneRequest(control_period=H))
    assert operating_command(CONFIG, None) == 3.0
    with pytest.raises(FuelidError, match="signal range"):
        tune_model(CONFIG, TuneRequest(model=MODEL, control_period=H, u=7.0))


def test_tuning_needs_a_control_period():
    """Gains for another period are wrong gains: the library assumes none (issue 37)."""
    for plant in (CONFIG, PlantSource(CONFIG)):
        with pytest.raises(FuelidError, match="no control period"):
            tune_model(plant, TuneRequest(model=MODEL))
    with pytest.raises(FuelidError, match="no control period"):
        schedule_gains(USERS_PLANT, TuneRequest(model=MODEL))


def test_without_a_plant_file_no_figure_rests_on_the_reference_plant():
    outcome = tune_model(PlantSource(CONFIG), TuneRequest(model=MODEL, control_period=H))
    assert outcome.check is None
    assert outcome.tuning.plc_form()["percent_of_span"] is None
    assert outcome.y_span is None
    data = outcome.to_json()
    assert data["temperature_check"] is None
    assert data["provenance"]["temperature_check"] is None
    with pytest.raises(FuelidError, match="needs your plant file"):
        tune_model(PlantSource(CONFIG), TuneRequest(model=MODEL, control_period=H, simulate=True))


def test_the_temperature_check_covers_the_range_in_kelvin():
    pi = tune_model(CONFIG, TuneRequest(model=MODEL, control_period=H)).pi
    check = check_over_temperature(
        CONFIG, pi, None, (celsius_to_kelvin(-20.0), celsius_to_kelvin(50.0)), 35.0, 2.0
    )
    temperatures = sorted({case.case.T_fuel for case in check.cases})
    assert temperatures == pytest.approx([253.15, 288.15, 323.15])
    assert sorted({case.case.u for case in check.cases}) == [1.0, 2.0, 5.0]
    assert celsius_to_kelvin(20.0) == T_REF  # the default fuel temperature
