"""Issue 24 item 4.2 and 4.3: what identify and report fitted, and the spans of the %/% gains.

A new user ran ``identify`` and ``report`` on one log and got two models without being told why
(report holds out the last 30 % for validation, identify fits it all); and ``report`` without a
plant file printed percent-of-span gains computed on the reference plant's spans, unsaid. Since
issue 37 no %/% gain is printed on spans nobody gave: the report says which spans are missing and
where to give them.
"""

from __future__ import annotations

import json
import re
from importlib import resources
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.plant import load_plant_config
from fuelid.plant.simulate import simulate
from fuelid.profiles import step_sequence

runner = CliRunner()
PERIOD = ["--control-period", "1"]  # never assumed (issue 37)
REFERENCE_FILE = str(resources.files("fuelid.data").joinpath("reference_plant.toml"))


@pytest.fixture(scope="module")
def log_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = simulate(load_plant_config(), step_sequence([1.0, 2.0, 1.5, 3.0], dwell=20.0), seed=2)
    return run.to_log().write(tmp_path_factory.mktemp("log") / "sequence.csv")


@pytest.fixture(scope="module")
def report_text(log_path: Path) -> str:
    out = log_path.parent / "report.html"
    result = runner.invoke(app, ["report", str(log_path), "--out", str(out), "--force", *PERIOD])
    assert result.exit_code == 0, result.stderr
    return result.stdout


def _first_line(text: str) -> str:
    return " ".join(text.splitlines()[0].split())


def _range(line: str) -> tuple[float, float]:
    found = re.search(r"\((\d+(?:\.\d+)?)–(\d+(?:\.\d+)?) s\)", line)
    assert found is not None, line
    return float(found.group(1)), float(found.group(2))


def test_identify_and_report_say_first_which_part_they_fitted(log_path: Path, report_text: str):
    result = runner.invoke(app, ["identify", str(log_path)])
    assert result.exit_code == 0, result.stderr
    identify_line = _first_line(result.stdout)
    report_line = _first_line(report_text)
    assert identify_line.startswith("fitted on all of the log"), identify_line
    assert "--validate-split" in identify_line
    assert report_line.startswith("fitted on 0–70 % of the log"), report_line
    assert "validated on the rest" in report_line
    whole, fitted = _range(identify_line), _range(report_line)
    assert fitted[0] == whole[0] == 0.0
    assert fitted[1] == pytest.approx(0.7 * whole[1], abs=0.1)


def test_report_without_spans_prints_no_percent_gain_and_says_which_are_missing(
    report_text: str,
):
    text = " ".join(report_text.split())
    assert "%/% (" not in text  # no %/% gain on the reference plant's spans
    assert (
        "no %/% gains: spans not given: the drive span (--u-span [V]) and the meter span "
        "(--flow-span [L/min]), or a plant file (--config) or a site file with [controller] "
        "u_span_V and y_span_Lpm (--site)"
    ) in text, text


def test_report_with_one_span_given_assumes_not_the_other(log_path: Path):
    out = log_path.parent / "one_span.html"
    args = ["report", str(log_path), "--out", str(out), "--flow-span", "80", *PERIOD]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.stderr
    text = " ".join(result.stdout.split())
    assert "no %/% gains: spans not given: the drive span (--u-span [V])," in text, text
    assert "the meter span (--flow-span" not in text


def test_report_says_the_spans_come_from_the_plant_file(log_path: Path):
    out = log_path.parent / "plant_spans.html"
    args = ["report", str(log_path), "--out", str(out), "--config", REFERENCE_FILE, *PERIOD]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.stderr
    text = " ".join(result.stdout.split())
    assert re.search(
        r"Kc = [0-9.]+ %/% \(100 L/min meter span, 4 V drive span, from "
        + re.escape(REFERENCE_FILE)
        + r"\)",
        text,
    ), text


def test_report_takes_the_spans_as_tune_does(log_path: Path):
    out = log_path.parent / "spans.html"
    spans = ["--flow-span", "50", "--u-span", "10", *PERIOD]
    result = runner.invoke(app, ["report", str(log_path), "--out", str(out), *spans, "--json"])
    assert result.exit_code == 0, result.stderr
    tuning = json.loads(result.stdout)["tuning"]
    span = tuning["plc"]["percent_of_span"]
    assert (span["y_span"], span["u_span"]) == (50.0, 10.0)
    assert span["Kc"] == pytest.approx(tuning["Kc"] * 50.0 / 10.0, rel=1e-12)
    assert tuning["spans"]["y_span"] == {"value": 50.0, "basis": "option"}
    for command in ("report", "tune"):
        help_text = runner.invoke(app, [command, "--help"], terminal_width=200).stdout
        assert "--flow-span" in help_text, command
    assert "--u-span" in runner.invoke(app, ["report", "--help"]).stdout
