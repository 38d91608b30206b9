"""``fuelid simulate`` and the library behind it (:mod:`fuelid.workflow._simulation`).

The command only parses, calls :func:`simulate_log`, writes the log and prints; the profile
table is read by :func:`read_profile`. The numbers checked are fixed by the inputs: the times and
temperatures of a profile file, the levels and dwell of a sequence, the ends of a ramp.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner, Result

from fuelid.cli import app
from fuelid.errors import DataError, FuelidError
from fuelid.plant import load_plant_config
from fuelid.profiles import held_profile
from fuelid.units import T0
from fuelid.workflow import (
    SimulationRequest,
    read_profile,
    simulate_log,
    simulation_inputs,
)

runner = CliRunner()
QUIET = ("--noise-std", "0", "--resolution", "0", "--quiet")


def invoke(*args: str) -> Result:
    return runner.invoke(app, ["simulate", *args])


def write_profile(path: Path, temperature_header: str | None = "T_fuel_degC") -> Path:
    """A profile: 1 V from 0 s, 2 V from 10 s; the fuel from -10 °C at 0 s to 30 °C at 20 s."""
    columns = {"t_s": [0.0, 10.0, 20.0], "u_V": [1.0, 2.0, 2.0]}
    if temperature_header is not None:
        columns[temperature_header] = [-10.0, 10.0, 30.0]
    pd.DataFrame(columns).to_csv(path, index=False)
    return path


@pytest.mark.parametrize("header", ["T_fuel_degC", "t_fuel_degc", "T_FUEL_DEGC", " T_fuel_degC"])
def test_fuel_temperature_column_drives_the_run_whatever_its_case(
    tmp_path: Path, header: str
) -> None:
    profile = write_profile(tmp_path / "p.csv", header)
    out = tmp_path / "log.csv"
    args = ("--profile", "file", "--input-file", str(profile), "--duration", "30")
    result = invoke(str(out), *args, *QUIET)
    assert result.exit_code == 0, result.stderr
    log = pd.read_csv(out)
    temperature = log.set_index("t_s")["T_fuel_degC"]
    # the file's trajectory, interpolated between rows and held after the last: not 20 °C
    assert temperature.loc[0.0] == pytest.approx(-10.0)
    assert temperature.loc[5.0] == pytest.approx(0.0)
    assert temperature.loc[20.0] == pytest.approx(30.0)
    assert temperature.iloc[-1] == pytest.approx(30.0)
    assert log["t_s"].iloc[-1] == pytest.approx(30.0)


def test_profile_file_temperature_overrides_the_options(tmp_path: Path) -> None:
    profile = write_profile(tmp_path / "p.csv")
    out = tmp_path / "log.csv"
    args = ("--profile", "file", "--input-file", str(profile), "--fuel-temp", "45")
    result = invoke(str(out), *args, "--fuel-temp-end", "50", *QUIET)
    assert result.exit_code == 0, result.stderr
    assert pd.read_csv(out)["T_fuel_degC"].iloc[0] == pytest.approx(-10.0)


def test_profile_without_temperature_column_follows_the_options(tmp_path: Path) -> None:
    profile = write_profile(tmp_path / "p.csv", temperature_header=None)
    out = tmp_path / "log.csv"
    args = ("--profile", "file", "--input-file", str(profile), "--duration", "40")
    result = invoke(str(out), *args, "--fuel-temp", "0", "--fuel-temp-end", "40", *QUIET)
    assert result.exit_code == 0, result.stderr
    temperature = pd.read_csv(out).set_index("t_s")["T_fuel_degC"]
    assert temperature.loc[0.0] == pytest.approx(0.0)  # a ramp over the run's 40 s
    assert temperature.loc[10.0] == pytest.approx(10.0)
    assert temperature.loc[40.0] == pytest.approx(40.0)


@pytest.mark.parametrize("header", ["T_fuel [degC]", "T_fuel_K", "T fuel degC"])
def test_temperature_column_that_would_be_ignored_is_refused(tmp_path: Path, header: str) -> None:
    profile = write_profile(tmp_path / "p.csv", header)
    out = tmp_path / "log.csv"
    result = invoke(str(out), "--profile", "file", "--input-file", str(profile), "--quiet")
    assert result.exit_code == 2
    assert repr(header) in result.stderr
    assert "T_fuel_degC" in result.stderr
    assert result.stderr.count("\n") == 1
    assert not out.exists()


def test_json_summary_is_the_outcome_plus_provenance(tmp_path: Path) -> None:
    out = tmp_path / "s.csv"
    args = ("--profile", "steps", "--levels", "1,2,1.5", "--dwell", "10", "--json")
    result = invoke(str(out), *args, "--sample-time", "0.05", "--fuel-temp", "-5")
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert list(data) == [
        "output",
        "n_samples",
        "sample_time",
        "duration",
        "profile",
        "u_range",
        "q_range",
        "units",
        "fuelid_version",
        "input_sha256",
        "options",
    ]
    assert data["output"] == str(out)
    assert data["n_samples"] == 601  # 30 s every 0.05 s, both ends
    assert data["duration"] == 30.0
    assert data["profile"] == "steps"
    assert data["u_range"] == [1.0, 2.0]
    units = {"sample_time": "s", "duration": "s", "u_range": "V", "q_range": "L/min"}
    assert data["units"] == units
    assert data["options"]["fuel_temp"] == -5.0
    log = pd.read_csv(out)
    assert data["q_range"] == [log["q_Lpm"].min(), log["q_Lpm"].max()]
    assert np.allclose(log["T_fuel_degC"], -5.0)
    # the library gives the same summary for the same request, with the fuel in kelvin
    request = SimulationRequest(
        profile="steps", levels=(1.0, 2.0, 1.5), dwell=10.0, sample_time=0.05, T_fuel=T0 - 5.0
    )
    summary = simulate_log(load_plant_config(), request).to_json(out)
    provenance = {"fuelid_version", "input_sha256", "options"}
    assert summary == {key: value for key, value in data.items() if key not in provenance}


def test_text_summary_names_the_file_and_the_samples(tmp_path: Path) -> None:
    out = tmp_path / "s.csv"
    result = invoke(str(out), "--duration", "20", "--t-step", "5")
    assert result.exit_code == 0, result.stderr
    assert result.stdout.startswith(f"wrote {out}: 1001 samples every 0.02 s over 20 s, u 1…1.5 V")


def test_steps_cut_by_duration(tmp_path: Path) -> None:
    out = tmp_path / "s.csv"
    args = ("--profile", "steps", "--levels", "1,2,3", "--dwell", "10", "--duration", "15")
    result = invoke(str(out), *args, "--json", "--control-period", "0")
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert data["duration"] == 15.0
    assert data["u_range"] == [1.0, 2.0]  # the third level starts after the run ends
    assert set(pd.read_csv(out)["u_V"]) == {1.0, 2.0}


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (("--duration", "-5"), "duration must be positive"),
        (("--profile", "steps", "--duration", "0"), "duration must be positive"),
        (("--fuel-temp", "nan"), "--fuel-temp must be a finite"),
        (("--fuel-temp-end", "inf"), "--fuel-temp-end must be a finite"),
        (("--profile", "file"), "--profile file needs --input-file"),
        (("--profile", "random", "--levels", "1"), "at least two levels"),
    ],
)
def test_bad_options_are_refused_in_one_line(
    tmp_path: Path, args: tuple[str, ...], expected: str
) -> None:
    out = tmp_path / "log.csv"
    result = invoke(str(out), *args)
    assert result.exit_code == 2
    assert expected in result.stderr
    assert result.stderr.count("\n") == 1
    assert not out.exists()


def test_profile_duration_before_last_row_is_refused(tmp_path: Path) -> None:
    profile = write_profile(tmp_path / "p.csv")
    out = tmp_path / "log.csv"
    args = ("--profile", "file", "--input-file", str(profile), "--duration", "20")
    result = invoke(str(out), *args)
    assert result.exit_code == 2
    assert "duration 20 s must exceed the profile's last time 20 s" in result.stderr
    assert not out.exists()


# the library


def test_read_profile_holds_commands_and_converts_the_fuel_to_kelvin(tmp_path: Path) -> None:
    table = read_profile(write_profile(tmp_path / "p.csv", "t_fuel_degc"))
    assert table.profile.t.tolist() == [0.0, 10.0]  # the repeated 2 V row merges
    assert table.profile.u.tolist() == [1.0, 2.0]
    assert table.profile.duration == 30.0  # the last row held for the previous interval
    assert table.T_fuel is not None
    assert table.T_fuel.at(0.0) == pytest.approx(T0 - 10.0)
    assert table.T_fuel.at(15.0) == pytest.approx(T0 + 20.0)
    assert read_profile(write_profile(tmp_path / "q.csv", None), duration=25.0).T_fuel is None


def test_read_profile_refuses_bad_times(tmp_path: Path) -> None:
    path = tmp_path / "p.csv"
    pd.DataFrame({"t_s": [0.0, 5.0, 5.0], "u_V": [1.0, 2.0, 1.0]}).to_csv(path, index=False)
    with pytest.raises(DataError, match="t_s must start at 0 and increase strictly"):
        read_profile(path)
    pd.DataFrame({"t_s": [1.0, 5.0], "u_V": [1.0, 2.0]}).to_csv(path, index=False)
    with pytest.raises(DataError, match="t_s must start at 0"):
        read_profile(path)


def test_held_profile_single_row_lasts_one_second() -> None:
    profile = held_profile([0.0], [1.5])
    assert (profile.t.tolist(), profile.u.tolist(), profile.duration) == ([0.0], [1.5], 1.0)


@pytest.mark.parametrize(
    ("settings", "expected"),
    [
        ({"profile": "ramp"}, "unknown profile"),
        ({"profile": "file"}, "needs an input file"),
        ({"duration": 0.0}, "duration must be positive"),
        ({"duration": float("nan")}, "duration must be positive"),
        ({"T_fuel": float("nan")}, "at the start"),
        ({"T_fuel_end": -1.0}, "at the end"),
    ],
)
def test_request_refuses_settings_that_cannot_be_right(
    settings: dict[str, Any], expected: str
) -> None:
    with pytest.raises(FuelidError, match=expected):
        SimulationRequest(**settings)


def test_inputs_of_each_profile() -> None:
    step = simulation_inputs(SimulationRequest(T_fuel=250.0, T_fuel_end=300.0))
    assert step.duration == 60.0
    assert (step.profile.t.tolist(), step.profile.u.tolist()) == ([0.0, 10.0], [1.0, 1.5])
    assert (step.T_fuel.at(0.0), step.T_fuel.at(30.0), step.T_fuel.at(60.0)) == pytest.approx(
        (250.0, 275.0, 300.0)
    )
    random = simulation_inputs(
        SimulationRequest(profile="random", levels=(1.0, 2.0), hold=4.0, seed=1)
    )
    assert random.duration == 600.0
    assert random.profile.u[0] == 1.0  # the first hold at the first level
    assert np.all(np.diff(random.profile.t) >= 4.0)
    assert random.T_fuel.is_constant
    assert random.T_fuel.at(0.0) == pytest.approx(293.15)


def test_simulate_log_writes_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    request = SimulationRequest(t_step=1.0, duration=3.0, truth=True)
    outcome = simulate_log(load_plant_config(), request)
    assert list(tmp_path.iterdir()) == []
    assert outcome.to_json()["output"] is None
    assert "q_true_Lpm" in outcome.to_log().signals
