"""One command line: the same names, figure rule, help, units and BLAS setting in every command."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from fuelid.cli import app, main
from fuelid.model import ProcessModel, simulate_model

runner = CliRunner()
# the PLC period is never assumed (issue 37): given, as a user gives it
TUNE = ["tune", "--K", "13.5", "--T", "1.26", "--delay", "0.2", "--control-period", "1"]


@pytest.fixture(scope="module")
def log_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Steps through a first-order loop with a meter lag, 0.02 s samples, little noise."""
    rng = np.random.default_rng(0)
    u = np.repeat(np.r_[3.0, rng.uniform(2.5, 3.5, 5)], 400)
    truth = ProcessModel(K=13.12, T=1.268, T_f=0.3, delay=0.2)
    y = 40.0 + simulate_model(truth, u, 0.02) + rng.normal(0.0, 0.05, u.size)
    path = tmp_path_factory.mktemp("consistency") / "log.csv"
    pd.DataFrame({"t_s": np.arange(u.size) * 0.02, "u_V": u, "q_Lpm": y}).to_csv(path, index=False)
    return path


def _json(*args: str) -> dict:
    result = runner.invoke(app, [*args, "--json"])
    assert result.exit_code == 0, result.stderr
    return json.loads(result.stdout)


# a. one name for the meter's lag in both commands, the other kept as an alias


@pytest.mark.parametrize("name", ["--flowmeter-T", "--T-f"])
def test_identify_and_tune_take_both_names_of_the_meter_lag(name: str, log_csv: Path):
    ident = _json("identify", str(log_csv), name, "0.3", "--flowmeter-delay", "0.2")
    assert ident["model"]["T_f"] == 0.3
    assert "T_f" in ident["fixed"]
    tuned = _json(*TUNE, name, "0.3")
    assert tuned["model"]["T_f"] == 0.3


@pytest.mark.parametrize("command", ["identify", "tune"])
def test_help_names_the_meter_lag_and_its_alias(command: str):
    result = runner.invoke(app, [command, "--help"])
    assert result.exit_code == 0
    assert "--flowmeter-T, --T-f" in result.stdout


# b. no figure is overwritten without --force, and the refusal comes before any work


def _refuse_work(*args: object, **kwargs: object) -> None:
    raise AssertionError("the command started working before refusing its figure")


@pytest.mark.parametrize("command", ["identify", "tune"])
def test_an_existing_figure_is_refused_without_force_before_any_work(
    command: str,
    log_csv: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
):
    import fuelid.workflow

    monkeypatch.setattr(fuelid.workflow, "identify_log", _refuse_work)
    monkeypatch.setattr(fuelid.workflow, "tune_model", _refuse_work)
    fig = tmp_path / "fig.png"
    fig.write_bytes(b"an earlier figure")
    args = [str(log_csv)] if command == "identify" else TUNE[1:]
    assert main([command, *args, "--plot", str(fig)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "exists" in err
    assert "--force" in err
    assert fig.read_bytes() == b"an earlier figure"


@pytest.mark.parametrize("command", ["identify", "tune"])
def test_force_replaces_an_existing_figure(command: str, log_csv: Path, tmp_path: Path):
    fig = tmp_path / "fig.png"
    fig.write_bytes(b"an earlier figure")
    args = [str(log_csv), "--flowmeter-T", "0.3"] if command == "identify" else TUNE[1:]
    result = runner.invoke(app, [command, *args, "--plot", str(fig), "--force"])
    assert result.exit_code == 0, result.stderr
    assert fig.read_bytes().startswith(b"\x89PNG")


# c. help says what an option takes, and the usage line names the argument


def test_identify_help_shows_the_choices_and_the_argument():
    result = runner.invoke(app, ["identify", "--help"])
    assert result.exit_code == 0
    text = result.stdout
    usage = text.splitlines()[0]
    assert "LOG" in usage
    assert "file" not in usage
    assert "--order 1|2|auto" in text
    assert "--delay SECONDS|auto" in text
    for line in text.splitlines():
        if line.strip().startswith(("--order", "--delay")):
            assert "<str>" not in line
            assert "TEXT" not in line


def test_tune_help_names_the_model_file():
    result = runner.invoke(app, ["tune", "--help"])
    assert result.exit_code == 0
    assert "--model MODEL.json" in result.stdout
    assert "--plot FIG.png" in result.stdout


# d. units


def test_tune_prints_the_unit_of_ki():
    result = runner.invoke(app, TUNE)
    assert result.exit_code == 0, result.stderr
    assert "V/((L/min)·s)" in result.stdout
    assert "1/s" not in result.stdout
    units = _json(*TUNE)["units"]
    assert units["Ki"] == "V/((L/min)*s)"
    assert units["Kp"] == "V/(L/min)"


def test_identify_prints_the_gain_unit_the_columns_name(log_csv: Path, tmp_path: Path):
    result = runner.invoke(app, ["identify", str(log_csv), "--flowmeter-T", "0.3"])
    assert result.exit_code == 0, result.stderr
    assert "(L/min)/V" in result.stdout
    assert "(out)/(in)" not in result.stdout
    # an input scaled to the drive's volts is in V, the contract of --input-scale; a flow column
    # that names no unit and is not scaled is named as such (issue 24), never a guessed unit
    frame = pd.read_csv(log_csv)
    raw = tmp_path / "raw.csv"
    pd.DataFrame(
        {"t_s": frame["t_s"], "ao": 4.0 + (frame["u_V"] - 1.0) * 4.0, "ft": frame["q_Lpm"]}
    ).to_csv(raw, index=False)
    args = ["--input-col", "ao", "--output-col", "ft", "--input-scale", "4:20:1:5"]
    scaled = runner.invoke(app, ["identify", str(raw), *args, "--flowmeter-T", "0.3"])
    assert scaled.exit_code == 0, scaled.stderr
    assert "(unit of ft)/V" in scaled.stdout
    assert "flow column 'ft' has no unit: give --flow-unit" in " ".join(scaled.stderr.split())
    both = [*args, "--output-scale", "0:100:0:100"]
    scaled = runner.invoke(app, ["identify", str(raw), *both, "--flowmeter-T", "0.3"])
    assert scaled.exit_code == 0, scaled.stderr
    assert "(L/min)/V" in scaled.stdout


# f. BLAS on one thread for the whole of every command


@pytest.mark.parametrize("command", ["report", "simulate"])
def test_report_and_simulate_usage_name_the_log(command: str) -> None:
    result = runner.invoke(app, [command, "--help"])
    assert result.exit_code == 0
    usage = result.stdout.splitlines()[0]
    assert "LOG" in usage
    assert "{file}" not in usage
    assert "{output}" not in usage
