"""``fuelid tune --u-span/--flow-span``: the percent-of-span gain is Kc·(flow span)/(drive span).

A PLC's PI block in %/% sees the error as a share of the meter span and gives the output as a
share of the drive span, so Kc[%/%] = Kc[V per L/min] · y_span / u_span exactly; the spans the
user gives replace the reference plant's (1–5 V, 100 L/min) and are echoed in the JSON.
"""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from fuelid.cli import app

MODEL = ["--K", "13", "--T", "1.2", "--delay", "0.3"]


def test_the_given_spans_make_the_percent_gain() -> None:
    result = CliRunner().invoke(
        app, ["tune", *MODEL, "--u-span", "4", "--flow-span", "80", "--json"]
    )
    assert result.exit_code == 0, result.output
    plc = json.loads(result.stdout)["plc"]
    assert plc["percent_of_span"]["u_span"] == 4.0
    assert plc["percent_of_span"]["y_span"] == 80.0
    assert plc["percent_of_span"]["Kc"] == pytest.approx(plc["Kc"] * 80.0 / 4.0, rel=1e-12)


def test_a_span_that_is_not_positive_is_refused_in_one_line() -> None:
    result = CliRunner().invoke(app, ["tune", *MODEL, "--u-span", "0"])
    assert result.exit_code == 2
    assert result.stderr.strip().count("\n") == 0
    assert "--u-span must be positive" in result.stderr
