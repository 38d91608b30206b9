"""Progress of the long calls: the workflow names each stage as it starts and prints nothing.

``analyse_log``, ``tune_model`` and ``schedule_gains`` call an optional callback with the stage's
name (fuelid.workflow._progress); ``fuelid report`` shows it as a spinner on stderr only, so the
JSON on stdout stays exactly one object even when stderr is a terminal.
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.io.logs import load_log
from fuelid.model import ProcessModel
from fuelid.plant import load_plant_config
from fuelid.plant.simulate import simulate
from fuelid.profiles import step_sequence
from fuelid.workflow import (
    AnalysisSettings,
    PlantSource,
    TuneRequest,
    analyse_log,
    schedule_gains,
    tune_model,
)
from fuelid.workflow._progress import (
    ANALYSIS_STAGES,
    DIAGNOSTICS,
    IDENTIFICATION,
    RUNS,
    SCHEDULE,
    SWEEP,
    TEMPERATURE_CHECK,
    TUNE_STAGES,
    TUNING,
)

CONFIG = load_plant_config()
MODEL = ProcessModel(K=13.5, T=1.26, T_f=0.3, delay=0.2)
H = 1.0  # the PLC period is never assumed (issue 37): given, as a user gives it
H_OPTION = ["--control-period", "1"]
REFERENCE_FILE = str(resources.files("fuelid.data").joinpath("reference_plant.toml"))


@pytest.fixture(scope="module")
def short_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = simulate(CONFIG, step_sequence([1.0, 2.0, 1.5, 3.0], dwell=20.0), seed=4)
    return run.to_log().write(tmp_path_factory.mktemp("log") / "short.csv")


def test_analyse_log_names_every_stage_in_order(
    short_log: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    seen: list[str] = []
    analysis = analyse_log(
        load_log(short_log),
        PlantSource(CONFIG, "reference_plant.toml"),
        AnalysisSettings(band_width=35.0, flow_bands=1, control_period=H),
        seen.append,
    )
    assert seen == list(ANALYSIS_STAGES)
    assert analysis.schedule is not None
    assert analysis.schedule.bands
    assert capsys.readouterr() == ("", "")  # the library itself prints nothing


def test_without_a_plant_file_there_are_no_runs_and_no_schedule_to_name(short_log: Path) -> None:
    seen: list[str] = []
    analysis = analyse_log(
        load_log(short_log),
        PlantSource(CONFIG),
        AnalysisSettings(band_width=35.0, flow_bands=1, control_period=H),
        seen.append,
    )
    assert seen == [IDENTIFICATION, TUNING, TEMPERATURE_CHECK, DIAGNOSTICS]
    assert analysis.schedule is None
    assert analysis.check is None


def test_tune_model_names_only_the_stages_asked_for() -> None:
    seen: list[str] = []
    tune_model(
        CONFIG,
        TuneRequest(model=MODEL, control_period=H, band_width=35.0, flow_bands=1),
        seen.append,
    )
    assert seen == [TUNING, TEMPERATURE_CHECK]
    seen.clear()
    tune_model(
        CONFIG,
        TuneRequest(
            model=MODEL, control_period=H, simulate=True, sweep=20, band_width=35.0, flow_bands=1
        ),
        seen.append,
    )
    assert seen == list(TUNE_STAGES) == [TUNING, TEMPERATURE_CHECK, RUNS, SWEEP]


def test_schedule_gains_names_its_stage() -> None:
    seen: list[str] = []
    schedule_gains(
        CONFIG,
        TuneRequest(model=MODEL, control_period=H, band_width=35.0, flow_bands=1),
        seen.append,
    )
    assert seen == [SCHEDULE]


def test_progress_is_optional_and_changes_no_number() -> None:
    request = TuneRequest(
        model=MODEL, control_period=H, simulate=True, band_width=35.0, flow_bands=1
    )
    quiet = tune_model(CONFIG, request).to_json()
    assert tune_model(CONFIG, request, lambda stage: None).to_json() == quiet


@pytest.mark.parametrize("terminal", ["0", "1"])
def test_report_json_stays_one_object_on_stdout(
    terminal: str, short_log: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # TTY_COMPATIBLE=1 makes rich treat stderr as a terminal: the spinner runs, on stderr only
    monkeypatch.setenv("TTY_COMPATIBLE", terminal)
    out = tmp_path / "r.html"
    args = ["report", str(short_log), "--out", str(out), "--band-width", "35", *H_OPTION]
    args.append("--json")
    result = CliRunner().invoke(app, [*args, "--flow-bands", "1"])
    assert result.exit_code == 0, result.stderr
    payload, end = json.JSONDecoder().raw_decode(result.stdout)
    assert result.stdout[end:] == "\n"
    assert payload["report"] == str(out)
    if terminal == "0":
        assert all(line.startswith("warning: ") for line in result.stderr.splitlines())


@pytest.mark.parametrize("terminal", ["0", "1"])
@pytest.mark.parametrize("extra", [[], ["--schedule"]])
def test_tune_json_stays_one_object_on_stdout(
    terminal: str, extra: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # the same spinner as report's runs around tune's stages; stdout keeps exactly one object
    monkeypatch.setenv("TTY_COMPATIBLE", terminal)
    args = ["tune", "--K", "13.5", "--T", "1.26", "--T-f", "0.3", "--delay", "0.2", "--json"]
    # a schedule rests on the user's plant file (issue 37): the packaged one, given as theirs
    plant = ["--config", REFERENCE_FILE] if "--schedule" in extra else []
    result = CliRunner().invoke(
        app, [*args, *extra, *plant, *H_OPTION, "--band-width", "35", "--flow-bands", "1"]
    )
    assert result.exit_code == 0, result.stderr
    payload, end = json.JSONDecoder().raw_decode(result.stdout)
    assert result.stdout[end:] == "\n"
    assert "units" in payload
