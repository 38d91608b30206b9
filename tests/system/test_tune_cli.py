"""``fuelid tune`` through the CLI: JSON contract, worked numbers, model file, refusals."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from fuelid.cli import app, main
from fuelid.plant import load_plant_config
from fuelid.tuning.closedloop import flow_at
from fuelid.units import celsius_to_kelvin
from fuelid.workflow import REFERENCE_PLANT_NOTICE

runner = CliRunner()
CONFIG = load_plant_config()
# the nonlinear runs need a plant file: the packaged reference plant's, as a user would give theirs
REFERENCE_FILE = str(resources.files("fuelid.data").joinpath("reference_plant.toml"))
WORKED = ["--K", "1", "--T", "2", "--delay", "1", "--control-period", "0"]
# no control period is assumed (issue 37): the numbers below were computed for h = 1 s
H1 = ("--control-period", "1")
JSON_KEYS = {
    "rule",
    "Kc",
    "Ti",
    "Ki",
    "control_period",
    "tuning_parameter",
    "model",
    "reduced_model",
    "plc",
    "gain_margin",
    "phase_margin_deg",
    "Ms",
    "robustness",
    "closed_loop",
    "temperature_check",
    "command_band_check",
    "spans",
    "control_period_basis",
    "provenance",
    "units",
    "fuelid_version",
    "input_sha256",
    "options",
}


def _json(*args: str) -> dict:
    result = runner.invoke(app, ["tune", *args, "--json"])
    assert result.exit_code == 0, result.stderr
    return json.loads(result.stdout)


def test_worked_example_json():
    simc = _json(*WORKED, "--rule", "simc", "--tau-c", "1")
    assert set(simc) >= JSON_KEYS
    assert (simc["rule"], simc["Kc"], simc["Ti"]) == (
        "simc",
        pytest.approx(1.0),
        pytest.approx(2.0),
    )
    assert simc["control_period"] == 0.0
    assert round(simc["Ms"], 2) == 1.59
    assert simc["plc"]["discrete"] is None  # continuous
    assert simc["units"]["Kc"] == "V/(L/min)"
    assert simc["units"]["Ti"] == "s"
    assert simc["units"]["gain_margin"] == "ratio"
    amigo = _json(*WORKED, "--rule", "amigo")
    assert (round(amigo["Kc"], 2), round(amigo["Ti"], 2), round(amigo["Ms"], 2)) == (
        0.41,
        1.84,
        1.21,
    )


def test_percent_of_span_uses_the_meter_span():
    model = ("--K", "13.5", "--T", "1.26", "--T-f", "0.3", "--delay", "0.2", *H1)
    data = _json(*model, "--flow-span", "80", "--u-span", "4")
    span = data["plc"]["percent_of_span"]
    assert span["Kc"] == pytest.approx(data["Kc"] * 80.0 / 4.0, rel=1e-12)
    assert span["Ti_min"] == pytest.approx(data["Ti"] / 60.0, rel=1e-12)
    assert data["spans"]["y_span"] == {"value": 80.0, "basis": "option"}
    assert data["provenance"]["percent_of_span"] == "option"
    # the meter span alone, without a plant file: no drive span is assumed, so no %/% gains
    half = _json(*model, "--flow-span", "80")
    assert half["plc"]["percent_of_span"] is None
    assert half["spans"]["u_span"] is None
    assert "the drive span (--u-span [V])" in half["spans"]["reason"]
    assert half["Kc"] == data["Kc"]
    d = data["plc"]["discrete"]
    assert d["h"] == 1.0
    assert d["q1"] == pytest.approx(-data["Kc"] * (1.0 - 1.0 / data["Ti"]), rel=1e-12)


def test_flowmeter_lag_enters_the_half_rule():
    without = _json("--K", "13.5", "--T", "1.26", "--delay", "0.2", *H1)
    with_meter = _json("--K", "13.5", "--T", "1.26", "--T-f", "0.3", "--delay", "0.2", *H1)
    # half of T_f goes to T1 and half to θ (plus h/2 = 0.5 s): SIMC's Kc = T1/(2Kθ)
    assert without["Kc"] == pytest.approx(1.26 / (2 * 13.5 * 0.7), rel=1e-12)
    assert with_meter["Kc"] == pytest.approx(1.41 / (2 * 13.5 * 0.85), rel=1e-12)
    assert with_meter["Kc"] < without["Kc"]


def _ident_file(tmp_path: Path, model: dict, **extra: object) -> Path:
    path = tmp_path / "ident.json"
    path.write_text(json.dumps({"method": "oe", "model": model, **extra}), encoding="utf-8")
    return path


def test_model_file_equals_the_same_model_from_flags(tmp_path: Path):
    model = {"K": 13.5, "T": 1.26, "T2": 0.0, "delay": 0.2, "T_f": 0.3}
    cov = {"names": ["K", "T"], "matrix": [[0.01, 0.0], [0.0, 1e-4]]}
    path = _ident_file(tmp_path, model, cov=cov)
    from_file = _json("--model", str(path), *H1)
    from_flags = _json("--K", "13.5", "--T", "1.26", "--T-f", "0.3", "--delay", "0.2", *H1)
    for key in ("Kc", "Ti", "Ms", "gain_margin", "phase_margin_deg"):
        assert from_file[key] == pytest.approx(from_flags[key], rel=1e-12)
    assert len(from_file["input_sha256"]) == 64
    swept = _json("--model", str(path), "--sweep", "20", *H1)
    assert swept["sweep"]["n"] == 20
    assert isinstance(swept["sweep"]["n"], int)
    assert swept["sweep"]["worst_Ms"] >= swept["Ms"] - 0.2


def test_identification_covariance_with_nuisance_parameters_and_nulls(tmp_path: Path):
    # `fuelid identify --json` writes the offset and initial-state amplitudes into the
    # covariance (oe), and null for the unknown K–T correlation (step-ls): the sweep must use
    # the model parameters' variances, not drop them or crash on the nulls
    model = {"K": 13.5, "T": 1.26, "T2": 0.0, "delay": 0.2, "T_f": 0.3}
    var_k, var_t = (0.15 * 13.5) ** 2, (0.15 * 1.26) ** 2
    cov = {
        "names": ["K", "T", "offset", "c0"],
        "matrix": [
            [var_k, None, 0.0, 0.0],
            [None, var_t, 0.0, 0.0],
            [0, 0, 1.0, 0],
            [0, 0, 0, 1.0],
        ],
    }
    wide = _json("--model", str(_ident_file(tmp_path, model, cov=cov)), "--sweep", "40", *H1)
    (tmp_path / "bare").mkdir()
    bare = _json("--model", str(_ident_file(tmp_path / "bare", model)), "--sweep", "40", *H1)
    assert wide["sweep"]["worst_Ms"] > bare["sweep"]["worst_Ms"] + 0.05


def test_schedule_json_and_table():
    data = _json(
        "--schedule", "--band-width", "35", "--ms-target", "1.65", "--config", REFERENCE_FILE, *H1
    )
    assert set(data) >= {"rule", "control_period", "ms_target", "worst_Ms", "bands", "units"}
    assert data["bands"]
    assert all(b["Ms"] <= 1.65 + 1e-6 for b in data["bands"])
    assert {b["t_low"] for b in data["bands"]} == {-20.0, 15.0}
    assert (data["u_span"], data["y_span"]) == (4.0, 100.0)  # the plant file's, as given
    for band in data["bands"]:
        assert band["Kc_percent_of_span"] == pytest.approx(band["Kc"] * 100.0 / 4.0, rel=1e-12)
    assert data["single_set_suffices"] is False
    assert data["single_set"] is None
    table = runner.invoke(
        app, ["tune", "--schedule", "--band-width", "35", "-c", REFERENCE_FILE, *H1]
    )
    assert table.exit_code == 0
    assert "h = 1 s (option)" in table.stdout
    assert "Kc V/(L/min)" in table.stdout
    assert "Kc %/%" in table.stdout
    first = data["bands"][0]
    assert f"{first['Kc_percent_of_span']:.4g}" in table.stdout
    assert "one set of gains suffices" not in table.stdout


def test_schedule_says_when_one_set_of_gains_suffices():
    args = [
        "--schedule",
        "--t-min",
        "10",
        "--t-max",
        "30",
        "--flow-bands",
        "1",
        "-c",
        REFERENCE_FILE,
        *H1,
    ]
    data = _json(*args, "--flow-span", "80")
    assert data["y_span"] == 80.0
    assert data["u_span"] == 4.0  # the plant file's drive range
    assert data["options"]["flow_span"] == 80.0
    assert data["single_set_suffices"] is True
    single = data["single_set"]
    assert single["Kc"] == min(b["Kc"] for b in data["bands"])
    assert single["Kc_percent_of_span"] == pytest.approx(single["Kc"] * 80.0 / 4.0, rel=1e-12)
    assert single["Ms"] <= data["ms_target"]
    table = runner.invoke(app, ["tune", *args])
    assert table.exit_code == 0
    text = " ".join(table.stdout.split())
    assert f"one set of gains suffices: Kc = {single['Kc']:.4g} V/(L/min)" in text
    assert f"Ti = {single['Ti']:.3g} s" in text


def test_schedule_plot(tmp_path: Path):
    fig = tmp_path / "schedule.png"
    result = runner.invoke(
        app,
        ["tune", "--schedule", "--band-width", "35", "--plot", str(fig), "-c", REFERENCE_FILE, *H1],
    )
    assert result.exit_code == 0
    assert fig.read_bytes().startswith(b"\x89PNG")


def test_simulate_adds_the_nonlinear_runs(tmp_path: Path):
    fig = tmp_path / "cl.png"
    data = _json(
        "--K", "13.5", "--T", "1.26", "--T-f", "0.3", "--delay", "0.2", "--simulate",
        "--config", REFERENCE_FILE, "--plot", str(fig), *H1,
    )  # fmt: skip
    runs = data["closed_loop_plant"]
    assert [r["fuel_temperature"] for r in runs] == [-20.0, 50.0]
    for run in runs:
        assert 0.0 <= run["summary"]["overshoot_percent"] < 25.0
        assert run["summary"]["settling_time"] < 15.0
    assert fig.read_bytes().startswith(b"\x89PNG")


def test_simulate_near_the_top_of_the_drive_steps_down():
    """At 4.8 V the 20 °C flow is more than warm fuel can reach: the runs start lower, step down."""
    data = _json(
        "--K", "13.5", "--T", "1.26", "--T-f", "0.3", "--delay", "0.2", "--u", "4.8",
        "--simulate", "--config", REFERENCE_FILE, *H1,
    )  # fmt: skip
    warm_top = flow_at(CONFIG, 5.0, celsius_to_kelvin(50.0))
    for run in data["closed_loop_plant"]:
        assert run["start_flow"] < warm_top
        (step,) = [e for e in run["events"] if e["kind"] == "setpoint"]
        assert step["size"] == pytest.approx(-10.0)  # 10 % of the 100 L/min span, downward
        assert run["summary"]["settling_time"] < 15.0
        assert run["summary"]["time_at_limits"] == 0.0


def test_simulate_without_a_plant_file_is_refused():
    # the runs on a nonlinear plant are only evidence on the user's own plant
    result = runner.invoke(app, ["tune", "--K", "13.5", "--T", "1.26", "--simulate", *H1])
    assert result.exit_code == 2
    assert "--config" in result.stderr
    assert "needs your plant file" in result.stderr


def test_without_a_plant_file_the_reference_plant_is_said_out_loud():
    data = _json("--K", "13.5", "--T", "1.26", *H1)
    assert data["plant"]["source"] == "built-in reference"
    assert data["plant"]["notice"] == REFERENCE_PLANT_NOTICE
    assert data["notices"][0] == REFERENCE_PLANT_NOTICE
    assert "built-in reference plant" in data["notices"][0]
    assert data["fuel_temperature_source"] == "assumed"
    # no figure rests on the reference plant: no temperature check, no %/% gains on its spans
    assert data["temperature_check"] is None
    assert data["provenance"]["temperature_check"] is None
    assert data["plc"]["percent_of_span"] is None
    assert data["spans"]["reason"].startswith("spans not given")
    assert data["command_band_check"] is None  # a model from flags has no command bands
    with_file = _json(
        "--K", "13.5", "--T", "1.26", "--config", REFERENCE_FILE, "--fuel-temp", "8", *H1
    )
    assert with_file["plant"] == {
        "source": "file",
        "path": REFERENCE_FILE,
        "name": "reference",
        "notice": None,
    }
    assert with_file["notices"] == []
    assert with_file["fuel_temperature_source"] == "option"
    assert with_file["temperature_check"]["cases"]
    assert with_file["provenance"]["temperature_check"] == "plant file"
    span = with_file["plc"]["percent_of_span"]
    assert (span["u_span"], span["y_span"]) == (4.0, 100.0)
    assert with_file["provenance"]["percent_of_span"] == "plant file"


def test_without_a_plant_file_the_table_says_what_is_not_checked():
    result = runner.invoke(app, ["tune", "--K", "13.5", "--T", "1.26", "--delay", "0.2", *H1])
    assert result.exit_code == 0, result.stderr
    text = " ".join(result.stdout.split())
    assert "h = 1 s (option)" in text
    assert "over fuel temperature: not checked" in text
    assert "no %/% gains: spans not given" in text
    assert "worst Ms" not in text  # no worst case over temperature from the reference plant


def test_no_control_period_is_assumed(capsys: pytest.CaptureFixture[str]):
    assert main(["tune", "--K", "13.5", "--T", "1.26"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "no control period: give --control-period SECONDS" in err[0]


def test_list_rules():
    result = runner.invoke(app, ["tune", "--list-rules", "--json"])
    assert result.exit_code == 0
    names = [r["name"] for r in json.loads(result.stdout)["rules"]]
    assert names == ["simc", "isimc", "lambda", "amigo"]


BAD_COV = json.dumps(
    {
        "model": {"K": 13.5, "T": 1.3},
        "cov": {"names": ["K", "T"], "matrix": [[1e-4, 5e-5], [0, 1e-4]]},
    }
)
SHORT_COV = json.dumps(
    {"model": {"K": 13.5, "T": 1.3}, "cov": {"names": ["K", "T"], "matrix": [[1e-4]]}}
)


def test_unusable_covariance_only_matters_to_the_sweep(tmp_path: Path):
    model_file = tmp_path / "m.json"
    model_file.write_text(BAD_COV, encoding="utf-8")
    result = runner.invoke(app, ["tune", "--model", str(model_file), "--json", *H1])
    assert result.exit_code == 0, result.stderr
    assert json.loads(result.stdout)["Kc"] > 0.0


@pytest.mark.parametrize(
    ("args", "reason"),
    [
        (["--model", 'FILE:{"fit": 1}'], "no 'model'"),
        (["--model", "FILE:not json"], "not JSON"),
        (["--model", 'FILE:{"model": {"K": 1.0}}'], "lacks T"),
        (["--model", 'FILE:{"model": {"K": 1.0, "T": null}}'], "lacks T"),
        (["--model", 'FILE:{"model": {"K": 1.0, "T": -2}}'], "T"),
        (["--model", 'FILE:{"model": {"K": 1.0, "T": 2, "delay": "x"}}'], "not a number"),
        (["--model", "missing.json"], "does not exist"),
        (["--K", "1", "--T", "-2"], "--T must be a positive"),
        (["--K", "1", "--T", "0"], "--T must be a positive"),
        (["--K", "1", "--T", "2", "--delay", "-0.1"], "--delay must not be negative"),
        (["--K", "1", "--T", "2", "--T-f", "-1"], "--T-f"),
        (["--K", "1", "--T", "2", "--rule", "ziegler"], "ziegler"),
        (["--K", "1", "--T", "2", "--delay", "1", "--tau-c", "0", *H1], "tau_c"),
        (["--K", "1", "--T", "2", "--control-period", "-1"], "control period"),
        (["--K", "1", "--T", "2", "--lambda", "3"], "--lambda belongs"),
        (["--K", "1"], "at least --K and --T"),
        ([], "give a model"),
        (["--K", "1", "--T", "2", "--t-min", "50", "--t-max", "0", *H1], "--t-min"),
        (["--K", "1", "--T", "2", "--plot", "no/such/dir/f.png"], "does not exist"),
        (["--K", "1", "--T", "2", "--plot", "DIR"], "is a folder"),
        (["--K", "1", "--T", "2", "--plot", "FIG:f.xyz"], "name it .png"),
        # far outside any flow loop: refused at once, not minutes of work or an overflow
        (["--model", 'FILE:{"model": {"K": 13.5, "T": 1e300}}', *H1], "exceeds 100000 s"),
        (["--model", 'FILE:{"model": {"K": 13.5, "T": 1e-300}}', *H1], "below 1e-06 s"),
        (["--K", "1e300", "--T", "2", *H1], "process gain K"),
        (["--K", "13.5", "--T", "1.26", "--delay", "1e6", *H1], "exceeds 100000 s"),
        (["--K", "13.5", "--T", "1.26", "--delay", "5000", *H1], "more than 1000 control periods"),
        (["--K", "13.5", "--T", "1.26", "--control-period", "1e6", "--simulate"], "up to 10 s"),
        (["--K", "13.5", "--T", "1.26", "--sweep", "10000000"], "1 to 20,000"),
        (["--schedule", "--band-width", "0.001", "-c", REFERENCE_FILE, *H1], "at most 50"),
        (["--schedule", "--flow-bands", "1000", "-c", REFERENCE_FILE, *H1], "1 to 10"),
        # gains from the physics of a plant that is not the user's: refused, not printed
        (["--schedule", *H1], "rests on your plant's physics: give your plant file"),
        # gains for a period nobody gave would be wrong gains: none is assumed
        (["--K", "13.5", "--T", "1.26"], "no control period"),
        (["--schedule", "-c", REFERENCE_FILE], "no control period"),
        # a covariance the sweep cannot draw from
        (["--model", f"FILE:{BAD_COV}", "--sweep", "5"], "not symmetric"),
        (["--model", f"FILE:{SHORT_COV}", "--sweep", "5"], "not 2×2 like its names"),
        # a gain within 1.96 standard errors of zero: the log showed no response
        (["--model", 'FILE:{"model": {"K": 0.1, "T": 2}, "stderr": {"K": 0.2}}'], "from zero"),
    ],
)
def test_bad_input_one_line_exit_2(
    args: list[str], reason: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    resolved = []
    for arg in args:
        if arg.startswith("FILE:"):
            path = tmp_path / "other.json"
            path.write_text(arg[5:], encoding="utf-8")
            arg = str(path)
        resolved.append(arg)
    for i, arg in enumerate(args):
        if arg == "DIR":
            resolved[i] = str(tmp_path)
        elif arg.startswith("FIG:"):
            resolved[i] = str(tmp_path / arg[4:])
    if "--model" in args and resolved[resolved.index("--model") + 1] == "missing.json":
        resolved[resolved.index("--model") + 1] = str(tmp_path / "missing.json")
    assert main(["tune", *resolved]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1
    assert reason in lines[0]


def test_model_and_flags_together_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    path = _ident_file(tmp_path, {"K": 1.0, "T": 2.0})
    assert main(["tune", "--model", str(path), "--K", "2"]) == 2
    assert "not both" in capsys.readouterr().err


def test_a_log_without_response_is_not_tuned(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    """Flow that is pure noise around a constant: identify warns, tune refuses its model."""
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 200.0, 0.1)
    u = np.where((t // 20) % 2 == 0, 2.0, 3.0)  # steps every 20 s
    q = 30.0 + rng.normal(0.0, 1.0, t.size)  # does not follow u
    log = tmp_path / "flat.csv"
    np.savetxt(log, np.column_stack([t, u, q]), delimiter=",", header="t_s,u_V,q_Lpm", comments="")
    ident = runner.invoke(app, ["identify", str(log), "--method", "oe", "--json"])
    assert ident.exit_code == 0
    result = json.loads(ident.stdout)
    assert any("does not differ from zero" in w for w in result["warnings"])
    model_file = tmp_path / "ident.json"
    model_file.write_text(ident.stdout, encoding="utf-8")
    capsys.readouterr()
    assert main(["tune", "--model", str(model_file)]) == 2
    assert "does not differ from zero" in capsys.readouterr().err


def test_without_a_plant_file_the_range_check_is_the_logs_command_bands(tmp_path: Path):
    """The model file's K per command band stands in for the reference plant's physics."""
    model = {"K": 13.5, "T": 1.26, "T2": 0.0, "delay": 0.2, "T_f": 0.3}
    bands = [
        {"u": 1.75, "u_low": 1.5, "u_high": 2.0, "y": 25.0, "K": 12.0, "stderr": 0.2},
        {"u": 2.25, "u_low": 2.0, "u_high": 2.5, "y": 32.0, "K": 15.0, "stderr": 0.3},
    ]
    path = _ident_file(tmp_path, model, diagnostics={"nonlinearity": {"bands": bands}})
    data = _json("--model", str(path), *H1)
    assert data["temperature_check"] is None
    check = data["command_band_check"]
    assert check["basis"] == "log"
    assert check["u_range"] == [1.5, 2.5]
    # K at each band's 95 % interval ends: the largest gain is the least robust
    gains = [case["K"] for case in check["cases"]]
    assert gains == pytest.approx([12.0 - 1.96 * 0.2, 12.0 + 1.96 * 0.2,
                                   15.0 - 1.96 * 0.3, 15.0 + 1.96 * 0.3], rel=1e-3)  # fmt: skip
    assert check["worst_Ms"] == max(case["Ms"] for case in check["cases"])
    assert check["worst_Ms"] > data["Ms"]
    assert data["provenance"]["command_band_check"] == "log"
    table = runner.invoke(app, ["tune", "--model", str(path), *H1])
    assert table.exit_code == 0, table.stderr
    text = " ".join(table.stdout.split())
    assert "over the log's commands 1.5…2.5 V" in text
    assert f"worst Ms {check['worst_Ms']:.2f}" in text
