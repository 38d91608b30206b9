"""The %/% gain's spans are named without "output": fuelid calls the flow the output.

The report said "%/% gain is Kc·(meter span)/(output span)", which a new user read as the flow.
"""

from __future__ import annotations

from importlib.resources import files

from fuelid.plc.site import Controller


def test_report_names_the_drive_span() -> None:
    template = files("fuelid").joinpath("templates/report.html.j2").read_text(encoding="utf-8")
    assert "Kc·(meter span)/(drive span)" in template
    assert "output span" not in template


def test_site_fields_name_the_drive_and_meter_spans() -> None:
    fields = Controller.model_fields
    assert fields["u_span_V"].description == "drive span [V] of percent gains"
    assert fields["y_span_Lpm"].description == "meter span [L/min] of percent gains"
