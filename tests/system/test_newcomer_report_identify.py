"""Issue 24 item 4.2 and 4.3: what identify and report fitted, and the spans of the %/% gains.

A new user ran ``identify`` and ``report`` on one log and got two models without being told why
(report holds out the last 30 % for validation, identify fits it all); and ``report`` without a
plant file printed percent-of-span gains computed on the reference plant's spans, unsaid.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.plant import load_plant_config
from fuelid.plant.simulate import simulate
from fuelid.profiles import step_sequence

runner = CliRunner()


@pytest.fixture(scope="module")
def log_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = simulate(load_plant_config(), step_sequence([1.0, 2.0, 1.5, 3.0], dwell=20.0), seed=2)
    return run.to_log().write(tmp_path_factory.mktemp("log") / "sequence.csv")


@pytest.fixture(scope="module")
def report_text(log_path: Path) -> str:
    out = log_path.parent / "report.html"
    result = runner.invoke(app, ["report", str(log_path), "--out", str(out), "--force"])
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


def test_report_says_the_spans_its_percent_gains_assume(report_text: str):
    text = " ".join(report_text.split())
    assert re.search(
        r"Kc = [0-9.]+ %/% \(assuming a 100 L/min meter span and a 4 V drive span: give "
        r"--flow-span/--u-span\)",
        text,
    ), text


def test_report_takes_the_spans_as_tune_does(log_path: Path):
    out = log_path.parent / "spans.html"
    spans = ["--flow-span", "50", "--u-span", "10"]
    result = runner.invoke(app, ["report", str(log_path), "--out", str(out), *spans, "--json"])
    assert result.exit_code == 0, result.stderr
    span = json.loads(result.stdout)["tuning"]["plc"]["percent_of_span"]
    assert (span["y_span"], span["u_span"]) == (50.0, 10.0)
    for command in ("report", "tune"):
        help_text = runner.invoke(app, [command, "--help"], terminal_width=200).stdout
        assert "--flow-span" in help_text, command
    assert "--u-span" in runner.invoke(app, ["report", "--help"]).stdout
