"""``fuelid tune --u-span/--flow-span``: the percent-of-span gain is Kc·(flow span)/(drive span).

A PLC's PI block in %/% sees the error as a share of the meter span and gives the output as a
share of the drive span, so Kc[%/%] = Kc[V per L/min] · y_span / u_span exactly. The spans are
the user's (the options, a site file's [controller], the user's plant file) and are echoed in
the JSON with where they came from; without them no %/% gain is printed (issue 37: the reference
plant's 1–5 V and 100 L/min are not the user's loop).
"""

from __future__ import annotations

import json
from importlib import resources

import pytest
from typer.testing import CliRunner

from fuelid.cli import app

# the control period is never assumed (issue 37): h = 1 s, given
MODEL = ["--K", "13", "--T", "1.2", "--delay", "0.3", "--control-period", "1"]
REFERENCE_FILE = str(resources.files("fuelid.data").joinpath("reference_plant.toml"))


def _tune(*args: str) -> dict:
    result = CliRunner().invoke(app, ["tune", *MODEL, *args, "--json"])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def test_the_given_spans_make_the_percent_gain() -> None:
    data = _tune("--u-span", "4", "--flow-span", "80")
    plc = data["plc"]
    assert plc["percent_of_span"]["u_span"] == 4.0
    assert plc["percent_of_span"]["y_span"] == 80.0
    assert plc["percent_of_span"]["Kc"] == pytest.approx(plc["Kc"] * 80.0 / 4.0, rel=1e-12)
    assert data["spans"]["u_span"] == {"value": 4.0, "basis": "option"}
    assert data["spans"]["reason"] is None


def test_without_spans_no_percent_gain_is_printed() -> None:
    data = _tune()
    assert data["plc"]["percent_of_span"] is None
    assert data["spans"]["u_span"] is None
    assert data["spans"]["y_span"] is None
    assert "--u-span" in data["spans"]["reason"]
    assert "--flow-span" in data["spans"]["reason"]
    assert data["provenance"]["percent_of_span"] is None


def test_the_plant_files_spans_and_an_option_over_one_of_them() -> None:
    data = _tune("--config", REFERENCE_FILE, "--flow-span", "80")
    span = data["plc"]["percent_of_span"]
    assert (span["u_span"], span["y_span"]) == (4.0, 80.0)
    assert span["Kc"] == pytest.approx(data["Kc"] * 80.0 / 4.0, rel=1e-12)
    assert data["provenance"]["percent_of_span"] == ["plant file", "option"]


def test_a_span_that_is_not_positive_is_refused_in_one_line() -> None:
    result = CliRunner().invoke(app, ["tune", *MODEL, "--u-span", "0"])
    assert result.exit_code == 2
    assert result.stderr.strip().count("\n") == 0
    assert "--u-span must be positive" in result.stderr
