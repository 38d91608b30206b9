"""``fuelid report`` and the chain behind it (workflow.analyse_log, htmlreport).

One simulated step-sequence log of the reference plant is analysed once; the tests then check the
numbers against what the plant's physics and the tuning formulas fix, and the page against its
contract: every figure embedded and written beside it, nothing overwritten, user text escaped.
"""

from __future__ import annotations

import base64
import json
import re
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from markupsafe import escape
from typer.testing import CliRunner

from fuelid.cli import app, main
from fuelid.errors import DataError, FuelidError
from fuelid.htmlreport import FIGURE_KEYS, figure_paths, write_report
from fuelid.io.jsonsafe import json_ready
from fuelid.io.logs import load_log
from fuelid.plant import linearise, load_plant_config
from fuelid.plant.simulate import simulate
from fuelid.profiles import step_sequence
from fuelid.tuning import robustness
from fuelid.units import celsius_to_kelvin
from fuelid.workflow import (
    REFERENCE_PLANT_NOTICE,
    AnalysisSettings,
    LogAnalysis,
    PlantSource,
    analyse_log,
)

runner = CliRunner()
LEVELS = [1.0, 1.5, 2.5, 2.0, 3.5, 3.0, 1.5]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
COLD, WARM = celsius_to_kelvin(-20.0), celsius_to_kelvin(50.0)
# the control period is never assumed (issue 37): these numbers are for h = 1 s, given
SETTINGS = AnalysisSettings(T_range=(COLD, WARM), band_width=35.0, control_period=1.0)
H1 = ["--control-period", "1"]


@pytest.fixture(scope="module")
def log_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    config = load_plant_config()
    run = simulate(config, step_sequence(LEVELS, dwell=30.0), seed=2)
    return run.to_log().write(tmp_path_factory.mktemp("log") / "sequence.csv")


@pytest.fixture(scope="module")
def plant_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The log is simulated on the reference plant, so its plant file is the user's here."""
    text = resources.files("fuelid.data").joinpath("reference_plant.toml").read_text("utf-8")
    path = tmp_path_factory.mktemp("plant") / "plant.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def analysis(log_path: Path, plant_file: Path) -> LogAnalysis:
    plant = PlantSource(load_plant_config(plant_file), str(plant_file))
    return analyse_log(load_log(log_path), plant, SETTINGS)


def test_both_methods_find_the_plant_gain_over_the_levels_visited(analysis: LogAnalysis):
    # the plant's small-signal gain at 20 °C varies over the logged commands; an equivalent
    # linear model must land inside that range (physics, not a stored number)
    config = load_plant_config()
    gains = [linearise(config, u, 293.15).static_gain for u in np.linspace(1.0, 3.5, 11)]
    assert set(analysis.identifications) == {"step-ls", "oe"}
    for result in analysis.identifications.values():
        assert min(gains) * 0.98 <= result.model.K <= max(gains) * 1.02
        assert result.model.T_f == pytest.approx(config.flowmeter.time_constant_s)
        assert result.model.delay == pytest.approx(config.flowmeter.delay_s)


def test_gains_follow_simc_with_the_half_rule_and_half_a_period(analysis: LogAnalysis):
    m = analysis.model_result.model
    h = SETTINGS.control_period
    # the half rule: the largest lag kept, half the second to it and half to the dead time, the
    # rest to the dead time; h/2 for the sampled PI
    lags = sorted((m.T, m.T2, m.T_f), reverse=True)
    T1 = lags[0] + lags[1] / 2
    theta = m.delay + lags[1] / 2 + lags[2] + h / 2
    tau_c = theta  # SIMC's default
    assert analysis.tuning.pi.Kc == pytest.approx(T1 / (m.K * (tau_c + theta)), rel=1e-12)
    assert analysis.tuning.pi.Ti == pytest.approx(min(T1, 4 * (tau_c + theta)), rel=1e-12)


def test_closed_loop_at_the_coldest_and_warmest_fuel(analysis: LogAnalysis):
    assert [run.T_fuel for run in analysis.runs] == [COLD, WARM]
    assert [run.to_json()["fuel_temperature"] for run in analysis.runs] == [-20.0, 50.0]
    for run in analysis.runs:
        summary = run.summary()
        assert summary["overshoot_percent"] < 25.0
        assert summary["settling_time"] < 15.0
        assert summary["disturbance_settling_time"] < 15.0
        assert np.all((run.command >= 1.0 - 1e-12) & (run.command <= 5.0 + 1e-12))


def test_schedule_meets_its_target_and_the_fixed_gains_are_stable(analysis: LogAnalysis):
    assert analysis.check.all_stable
    assert analysis.schedule.worst_Ms <= SETTINGS.ms_target + 1e-9
    # the Bode data shown are the loop whose margins are reported
    rob = robustness(analysis.model_result.model, analysis.tuning.pi)
    at_crossover = np.interp(
        rob.crossover_frequency, analysis.bode_frequency, np.abs(analysis.bode_loop)
    )
    assert at_crossover == pytest.approx(1.0, abs=0.02)


def test_report_embeds_every_figure_and_writes_them_beside(analysis: LogAnalysis, tmp_path: Path):
    out = tmp_path / "report.html"
    written = write_report(analysis, out)
    assert written[0] == out
    html = out.read_text(encoding="utf-8")
    embedded = re.findall(
        r'<figure id="fig-([a-z_]+)">\s*<img src="data:image/png;base64,([^"]+)"', html
    )
    assert [key for key, _ in embedded] == list(FIGURE_KEYS)
    beside = figure_paths(out)
    for key, payload in embedded:
        png = base64.b64decode(payload)
        assert png.startswith(PNG_MAGIC)
        assert beside[key].read_bytes() == png  # the PNG beside is the figure in the page
    # self-contained: nothing fetched from anywhere
    assert "http://" not in html
    assert "https://" not in html
    assert f"Kc = {analysis.tuning.pi.Kc:.5g}" in html


def test_report_refuses_to_overwrite_and_keeps_the_old_one(analysis: LogAnalysis, tmp_path: Path):
    out = tmp_path / "report.html"
    out.write_text("an earlier report", encoding="utf-8")
    with pytest.raises(DataError, match="exists"):
        write_report(analysis, out)
    assert out.read_text(encoding="utf-8") == "an earlier report"
    figure_paths(out)["bode"].write_bytes(b"earlier figure")
    out.unlink()
    with pytest.raises(DataError, match="bode"):
        write_report(analysis, out)  # a figure beside it is protected too
    write_report(analysis, out, overwrite=True)
    assert figure_paths(out)["bode"].read_bytes().startswith(PNG_MAGIC)


def test_text_from_the_log_is_escaped(analysis: LogAnalysis, tmp_path: Path):
    hostile = type(analysis.data)(
        u=analysis.data.u,
        y=analysis.data.y,
        sample_time=analysis.data.sample_time,
        source="<script>alert(1)</script>.csv",
        notes=("<b>note</b>",),
    )
    analysis_copy = LogAnalysis(**{**analysis.__dict__, "data": hostile})
    out = tmp_path / "escaped.html"
    write_report(analysis_copy, out)
    html = out.read_text(encoding="utf-8")
    assert "<script>" not in html
    assert "&lt;script&gt;alert(1)&lt;/script&gt;.csv" in html
    assert "&lt;b&gt;note&lt;/b&gt;" in html


def test_settings_are_validated():
    with pytest.raises(FuelidError, match="low < high"):
        AnalysisSettings(T_range=(WARM, COLD))
    with pytest.raises(FuelidError, match="tune from"):
        AnalysisSettings(tune_from="arx")  # type: ignore[arg-type]


def test_cli_report_json(
    log_path: Path,
    plant_file: Path,
    tmp_path: Path,
    analysis: LogAnalysis,
    capsys: pytest.CaptureFixture[str],
):
    out = tmp_path / "r.html"
    result = runner.invoke(
        app,
        [
            "report",
            str(log_path),
            "--out",
            str(out),
            "--band-width",
            "35",
            "--config",
            str(plant_file),
            *H1,
            "--json",
        ],
    )
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert set(data) >= {
        "report",
        "figures",
        "identification",
        "tuned_from",
        "tuning",
        "temperature_check",
        "command_band_check",
        "closed_loop_plant",
        "schedule",
        "provenance",
        "undetermined",
        "units",
        "fuelid_version",
        "input_sha256",
        "options",
    }
    assert Path(data["report"]) == out
    assert sorted(Path(p).name for p in data["figures"]) == sorted(
        f"r_{key}.png" for key in FIGURE_KEYS
    )
    assert set(data["identification"]) == {"step-ls", "oe"}
    m = data["tuning"]["model"]
    # the half rule: the largest lag kept, half the second to it and half to the dead time, the
    # rest to the dead time; h/2 = 0.5 s for the sampled PI; SIMC's default tau_c = theta
    lags = sorted((m["T"], m["T2"], m["T_f"]), reverse=True)
    T1, theta = lags[0] + lags[1] / 2, m["delay"] + lags[1] / 2 + lags[2] + 0.5
    assert data["tuning"]["Kc"] == pytest.approx(T1 / (m["K"] * 2 * theta), rel=1e-9)
    assert data["plant"]["source"] == "file"
    assert data["priors"]["flowmeter_T"]["source"] == "plant file"
    # with the user's plant file nothing is assumed but the fit's structure: the simulated log's
    # residuals are coloured by the linear model's misfit, which the intervals do not hold
    assert all("conditional on its structure" in n for n in data["notices"]), data["notices"]
    assert data["identification"]["oe"]["structure"]["conditional"] == bool(data["notices"])
    assert data["temperature_check"]["all_stable"] is True
    assert data["schedule"]["worst_Ms"] <= 1.7 + 1e-9
    assert data["tuning"]["control_period"] == 1.0
    assert data["tuning"]["control_period_basis"] == "option"
    # the user's plant file (a copy of the reference plant's) gives the spans: 4 V, 100 L/min
    span = data["tuning"]["plc"]["percent_of_span"]
    assert (span["u_span"], span["y_span"]) == (4.0, 100.0)
    assert span["Kc"] == pytest.approx(data["tuning"]["Kc"] * 100.0 / 4.0, rel=1e-12)
    assert data["provenance"]["temperature_check"] == "plant file"
    assert data["provenance"]["schedule"] == "plant file"
    assert data["undetermined"] == []
    # the command only adds the paths and the provenance to the workflow's JSON
    library = json.loads(json.dumps(json_ready(analysis.to_json()), allow_nan=False))
    extra = {"report", "figures", "fuelid_version", "input_sha256", "options"}
    assert {k: v for k, v in data.items() if k not in extra} == library


@pytest.mark.parametrize(
    ("args", "reason"),
    [
        (["missing.csv", *H1], "does not exist"),
        (["LOG", "--out", "report.pdf"], ".html"),
        (["LOG", "--out", "no/such/folder/r.html"], "does not exist"),
        (["LOG", "--t-min", "50", "--t-max", "-20", *H1], "low < high"),
        (["LOG", "--rule", "ziegler"], "ziegler"),
        (["LOG", "--tau-c", "1", "--rule", "amigo", *H1], "tau-c"),
        # gains for a period nobody gave would be wrong gains: none is assumed (issue 37)
        (["LOG"], "no control period: give --control-period SECONDS"),
    ],
)
def test_cli_report_bad_input(
    args: list[str],
    reason: str,
    log_path: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
):
    monkeypatch.chdir(tmp_path)
    args = [str(log_path) if a == "LOG" else a for a in args]
    assert main(["report", *args]) == 2
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1
    assert reason in lines[0]
    assert not list(tmp_path.iterdir())  # refused before anything was written


def test_tune_from_the_reports_model_gives_the_reports_worst_case(
    log_path: Path, plant_file: Path, tmp_path: Path
):
    # the operating point travels with the model: tune --model anchors its temperature check
    # at the log's command and fuel temperature, as the report did, so the worst Ms agrees
    out = tmp_path / "r.html"
    common = ["--config", str(plant_file), "--band-width", "35", *H1, "--json"]
    report = runner.invoke(app, ["report", str(log_path), "--out", str(out), *common])
    assert report.exit_code == 0, report.stderr
    data = json.loads(report.stdout)
    point = data["operating_point"]
    assert point["u"] == pytest.approx(float(np.mean(LEVELS)), abs=0.1)
    model_file = tmp_path / "oe.json"
    model_file.write_text(
        json.dumps(data["identification"]["oe"] | {"operating_point": point}), encoding="utf-8"
    )
    tuned = runner.invoke(app, ["tune", "--model", str(model_file), *common])
    assert tuned.exit_code == 0, tuned.stderr
    check = json.loads(tuned.stdout)["temperature_check"]
    assert check["worst_Ms"] == pytest.approx(data["temperature_check"]["worst_Ms"], rel=1e-9)
    assert [c["u"] for c in check["cases"]][1] == pytest.approx(point["u"])


def test_report_without_a_plant_file_says_so_and_assumes_no_meter(log_path: Path, tmp_path: Path):
    out = tmp_path / "r.html"
    args = ["report", str(log_path), "--out", str(out), "--band-width", "35", *H1]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.stderr
    assert "built-in reference plant" in result.stdout
    assert "built-in reference plant" in result.stderr
    # no figure from the reference plant: no temperature check, schedule or %/% gains; the
    # range check is the log's command bands
    summary = " ".join(result.stdout.split())
    assert "over fuel temperature" not in summary
    assert "schedule of" not in summary
    assert "one set of gains suffices" not in summary
    assert "over the log's commands" in summary
    assert "no %/% gains: spans not given" in summary
    page = out.read_text(encoding="utf-8")
    assert 'id="notices"' in page
    assert str(escape(REFERENCE_PLANT_NOTICE)) in page
    assert "not given" in page  # the priors table: no meter lag assumed
    assert "Closed loop on the nonlinear plant" not in page
    assert "Gain schedule" not in page
    assert "Fixed gains over fuel temperature" not in page
    assert "Over the log's commands" in page
    assert 'id="fig-schedule"' not in page
    assert not figure_paths(out)["schedule"].exists()
    data = json.loads(runner.invoke(app, [*args, "--force", "--json"]).stdout)
    assert data["temperature_check"] is None
    assert data["schedule"] is None
    assert data["provenance"]["schedule"] is None
    assert data["tuning"]["plc"]["percent_of_span"] is None
    assert data["tuning"]["spans"]["reason"].startswith("spans not given")
    bands = data["command_band_check"]
    assert bands["basis"] == "log"
    assert bands["cases"]
    # the bands cover the commands the log visited (1…3.5 V)
    assert bands["u_range"][0] <= min(LEVELS) + 0.5
    assert bands["u_range"][1] >= max(LEVELS) - 0.5
    assert sorted(Path(p).name for p in data["figures"]) == sorted(
        f"r_{key}.png" for key in FIGURE_KEYS if key != "schedule"
    )


def test_a_log_with_gaps_is_reported_from_its_segments(log_path: Path, tmp_path: Path):
    # two stretches of missing rows (a PLC link that dropped out): the report identifies the
    # segments jointly and says so; nothing is bridged unless asked
    frame = pd.read_csv(log_path)
    gapped = tmp_path / "gapped.csv"
    frame.drop(index=[*range(3000, 3050), *range(7000, 7010)]).to_csv(gapped, index=False)
    out = tmp_path / "g.html"
    result = runner.invoke(
        app, ["report", str(gapped), "--out", str(out), "--band-width", "35", *H1, "--json"]
    )
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert data["identification"]["oe"]["segments"] == 3
    assert any("2 gaps split the log into 3 segments" in w for w in data["warnings"])
    # the model of the whole log is found from the pieces: K within 2 % of the gap-free fit's
    whole = runner.invoke(
        app, ["report", str(log_path), "--out", str(tmp_path / "w.html"), *H1, "--json"]
    )
    K_whole = json.loads(whole.stdout)["identification"]["oe"]["model"]["K"]
    assert data["identification"]["oe"]["model"]["K"] == pytest.approx(K_whole, rel=0.02)
