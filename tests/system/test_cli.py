"""The command line through typer's CliRunner: JSON contracts, logs, and bad-input refusals."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from fuelid.cli import app, main
from fuelid.plant import linearise, load_plant_config, operating_point

runner = CliRunner()
REFERENCE_TOML = resources.files("fuelid.data").joinpath("reference_plant.toml").read_text()


def invoke(*args: str):
    return runner.invoke(app, list(args))


def test_help_lists_every_command():
    result = invoke("--help")
    assert result.exit_code == 0
    for command in ("plant", "simulate"):
        assert command in result.stdout


def test_plant_info_json_schema_and_values():
    result = invoke("plant", "info", "--json", "--u", "1.25", "--fuel-temp", "-20")
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)  # exactly one JSON object on stdout
    assert set(data["operating_point"]) >= {"flow", "pump_pressure", "speed", "torque"}
    assert set(data["model"]) >= {"K", "T", "T2", "T_f", "delay", "settling_time"}
    for key in ("flow", "pump_pressure", "K", "T", "delay", "settling_time"):
        assert key in data["units"]
    assert data["units"]["K"] == "(L/min)/V"
    assert data["units"]["pump_pressure"] == "MPa"
    # the numbers are the library's, converted to engineering units at the edge
    config = load_plant_config()
    op = operating_point(config, 1.25, 253.15)
    assert data["operating_point"]["flow"] == pytest.approx(op.q * 60_000, rel=1e-12)
    assert data["operating_point"]["pump_pressure"] == pytest.approx(op.p_pump / 1e6, rel=1e-12)
    assert data["model"]["K"] == pytest.approx(linearise(config, 1.25, 253.15).static_gain)
    assert data["model"]["T_f"] == config.flowmeter.time_constant_s
    assert data["model"]["delay"] == config.flowmeter.delay_s
    assert data["model"]["T2"] == 0.0
    assert 5.0 <= data["model"]["settling_time"] <= 6.0
    assert data["fuelid_version"]
    assert data["options"]["u"] == 1.25


def test_plant_info_table_shows_gain_with_unit():
    result = invoke("plant", "info")
    assert result.exit_code == 0
    assert "(L/min)/V" in result.stdout
    assert "settling" in result.stdout


def test_plant_init_writes_the_reference_plant_to_edit(tmp_path: Path):
    path = tmp_path / "mine.toml"
    result = invoke("plant", "init", str(path))
    assert result.exit_code == 0
    assert path.read_text(encoding="utf-8") == REFERENCE_TOML  # comments and all
    assert load_plant_config(path) == load_plant_config()
    again = invoke("plant", "init", str(path))
    assert again.exit_code == 2
    assert "--force" in again.stderr
    assert invoke("plant", "init", str(path), "--force").exit_code == 0


def test_plant_info_reads_a_config_file(tmp_path: Path):
    # a longer, thinner line raises the pump pressure at the same command
    path = tmp_path / "plant.toml"
    path.write_text(REFERENCE_TOML.replace("inner_diameter_mm = 32.0", "inner_diameter_mm = 16.0"))
    base = json.loads(invoke("plant", "info", "--json").stdout)
    thin = json.loads(invoke("plant", "info", "--json", "--config", str(path)).stdout)
    assert thin["operating_point"]["pump_pressure"] > base["operating_point"]["pump_pressure"]
    assert thin["input_sha256"] is not None


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (("length_m = 80.0", "length_m = -80.0"), "pipeline.length_m"),
        (("length_m = 80.0", "lenght_m = 80.0"), "unknown key"),
        (("[vfd]", "[vfd"), "not valid TOML"),
    ],
)
def test_bad_config_is_refused_in_one_line(tmp_path: Path, edit, expected):
    path = tmp_path / "bad.toml"
    path.write_text(REFERENCE_TOML.replace(*edit))
    result = invoke("plant", "info", "--config", str(path))
    assert result.exit_code == 2
    assert expected in result.stderr
    assert result.stderr.count("\n") == 1
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (("plant", "info", "--fuel-temp", "90"), "outside the valid range"),
        (("plant", "info", "--u", "7"), "signal range"),
        (("plant", "info", "--config", "/no/such/plant.toml"), "does not exist"),
    ],
)
def test_plant_info_bad_input(args, expected):
    result = invoke(*args)
    assert result.exit_code == 2
    assert expected in result.stderr
    assert result.stderr.count("\n") == 1


def test_simulate_writes_the_article_step_log(tmp_path: Path):
    out = tmp_path / "log.csv"
    result = invoke("simulate", str(out), "--seed", "3", "--quiet")
    assert result.exit_code == 0, result.stderr
    log = pd.read_csv(out)
    assert list(log.columns) == ["t_s", "u_V", "q_Lpm", "T_fuel_degC"]
    assert np.allclose(np.diff(log["t_s"]), 0.02)
    assert log["t_s"].iloc[-1] == pytest.approx(60.0)
    assert set(log["u_V"]) == {1.0, 1.5}
    assert log.loc[log["u_V"] == 1.5, "t_s"].min() == pytest.approx(10.0)
    # starts at rest at 1 V and settles at the 1.5 V operating point (noise std 0.1 L/min)
    config = load_plant_config()
    q_start = operating_point(config, 1.0, 293.15).q * 60_000
    q_end = operating_point(config, 1.5, 293.15).q * 60_000
    assert log["q_Lpm"].iloc[:400].mean() == pytest.approx(q_start, abs=0.03)
    assert log["q_Lpm"].iloc[-1000:].mean() == pytest.approx(q_end, abs=0.03)
    # quantised to the meter's 0.01 L/min
    assert np.allclose(log["q_Lpm"] * 100, np.round(log["q_Lpm"] * 100), atol=1e-6)


def test_simulate_is_reproducible_and_parquet(tmp_path: Path):
    a, b = tmp_path / "a.parquet", tmp_path / "b.parquet"
    for out in (a, b):
        assert (
            invoke(
                "simulate",
                str(out),
                "--profile",
                "random",
                "--duration",
                "120",
                "--seed",
                "5",
                "--quiet",
            ).exit_code
            == 0
        )
    assert pd.read_parquet(a).equals(pd.read_parquet(b))


def test_simulate_json_summary(tmp_path: Path):
    out = tmp_path / "s.csv"
    result = invoke(
        "simulate", str(out), "--profile", "steps", "--levels", "1,2,1.5", "--dwell", "20", "--json"
    )
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert data["n_samples"] == 3001
    assert data["u_range"] == [1.0, 2.0]
    assert data["units"]["q_range"] == "L/min"


def test_simulate_profile_file_with_temperature(tmp_path: Path):
    profile = tmp_path / "profile.csv"
    pd.DataFrame({"t_s": [0.0, 20.0], "u_V": [3.0, 3.0], "T_fuel_degC": [-10.0, 50.0]}).to_csv(
        profile, index=False
    )
    out = tmp_path / "log.csv"
    result = invoke(
        "simulate",
        str(out),
        "--profile",
        "file",
        "--input-file",
        str(profile),
        "--duration",
        "40",
        "--noise-std",
        "0",
        "--resolution",
        "0",
    )
    assert result.exit_code == 0, result.stderr
    log = pd.read_csv(out)
    assert log["T_fuel_degC"].iloc[0] == pytest.approx(-10.0)
    assert log["T_fuel_degC"].iloc[-1] == pytest.approx(50.0)
    # warmer fuel leaks more at the same command: the flow falls as the fuel warms
    assert log["q_Lpm"].iloc[-1] < log["q_Lpm"].iloc[0] - 0.5


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (("{missing}/log.csv",), "does not exist"),
        (("{tmp}/log.txt",), "extension"),
        (("{tmp}/log.csv", "--u1", "7"), "signal range"),
        (("{tmp}/log.csv", "--fuel-temp", "-60"), "outside the valid range"),
        (("{tmp}/log.csv", "--sample-time", "0"), "sample time"),
        (("{tmp}/log.csv", "--profile", "file"), "--input-file"),
        (("{tmp}/log.csv", "--profile", "steps", "--levels", "1,x"), "--levels"),
        (("{tmp}/log.csv", "--profile", "file", "--input-file", "{tmp}/none.csv"), "not exist"),
    ],
)
def test_simulate_bad_input(tmp_path: Path, args, expected):
    filled = [a.format(tmp=tmp_path, missing=tmp_path / "nope") for a in args]
    result = invoke("simulate", *filled)
    assert result.exit_code == 2
    assert expected in result.stderr
    assert result.stderr.count("\n") == 1
    assert not (tmp_path / "log.csv").exists()


def test_simulate_refuses_to_overwrite_without_force(tmp_path: Path):
    out = tmp_path / "log.csv"
    out.write_text("precious PLC data\n")
    result = invoke("simulate", str(out))
    assert result.exit_code == 2
    assert "--force" in result.stderr
    assert out.read_text() == "precious PLC data\n"
    assert invoke("simulate", str(out), "--force").exit_code == 0
    assert out.read_text().startswith("t_s,u_V,q_Lpm,T_fuel_degC")


def test_profile_file_as_a_plc_exports_it(tmp_path: Path):
    # semicolons, decimal commas and a byte-order mark, as the log reader accepts them
    profile = tmp_path / "p.csv"
    profile.write_bytes("\ufeffT_s;U_V\n0;1,0\n10;1,5\n".encode("utf-8-sig"))
    out = tmp_path / "o.csv"
    args = ("simulate", str(out), "--profile", "file", "--input-file", str(profile))
    result = invoke(*args, "--duration", "20", "--noise-std", "0", "--resolution", "0")
    assert result.exit_code == 0, result.stderr
    log = pd.read_csv(out)
    assert log["u_V"].iloc[0] == 1.0
    assert log["u_V"].iloc[-1] == 1.5
    profile.write_text("t_s;u_V\n0;1,0\n10;high\n", encoding="utf-8")
    result = invoke(*args, "--force")
    assert result.exit_code == 2
    assert "first at data row 2 ('high')" in result.stderr


def test_profile_file_missing_column_names_the_columns(tmp_path: Path):
    profile = tmp_path / "p.csv"
    pd.DataFrame({"time": [0.0, 1.0], "volts": [1.0, 2.0]}).to_csv(profile, index=False)
    result = invoke(
        "simulate", str(tmp_path / "o.csv"), "--profile", "file", "--input-file", str(profile)
    )
    assert result.exit_code == 2
    assert "columns present: time, volts" in result.stderr


def test_main_turns_usage_errors_into_one_line(capsys):
    assert main(["plant", "info", "--fuel-temp", "warm"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:")
    assert err.count("\n") == 1
    assert main(["plant", "info", "--no-such-option"]) == 2
    assert main(["--version"]) == 0
