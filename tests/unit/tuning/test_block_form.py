"""The PLC's PI block (fuelid.tuning._block): one home of the gains' form and units (issue 37).

Worked numbers: with a 4 V drive span and a 100 L/min meter span, 1.25 %/% is
1.25·4/100 = 0.05 V per L/min; a parallel block's Ki = 2.5 %/% per minute is Ti = Kp/Ki =
1.25/2.5 min = 30 s. Every form and unit converts to the block and back within 1e-12 relative,
and PISettings.plc_form's %/% gain is the block conversion's, not a second formula.
"""

from __future__ import annotations

import itertools
import math
from types import SimpleNamespace
from typing import Any

import pytest

from fuelid.errors import FuelidError
from fuelid.online import Gains
from fuelid.plc.site import Controller
from fuelid.tuning import BlockForm, PISettings, block_units, from_block, to_block
from fuelid.tuning._block import SECONDS_PER_MINUTE, percent_of_span

SPANS = {"u_span": 4.0, "y_span": 100.0}
BLOCKS = [
    BlockForm(form, units, integral, **(SPANS if units == "percent" else {}))
    for form, units, integral in itertools.product(
        ("ideal", "parallel"), ("engineering", "percent"), ("s", "min")
    )
]


def _name(value: Any) -> str | None:
    if not isinstance(value, BlockForm):
        return None  # pytest's own id
    return f"{value.form}-{value.gain_units}-{value.integral_unit}"


def test_the_worked_numbers() -> None:
    percent = BlockForm("ideal", "percent", "s", **SPANS)
    assert from_block(1.25, 2.0, percent) == pytest.approx((0.05, 2.0), rel=1e-12)
    parallel = BlockForm("parallel", "percent", "min", **SPANS)
    assert from_block(1.25, 2.5, parallel) == pytest.approx((0.05, 30.0), rel=1e-12)
    assert to_block(0.05, 30.0, parallel) == pytest.approx((1.25, 2.5), rel=1e-12)
    assert percent_of_span(0.05, 4.0, 100.0) == 1.25
    assert SECONDS_PER_MINUTE == 60.0


@pytest.mark.parametrize(
    ("block", "kc", "ti", "Kc", "Ti"),
    [
        (BlockForm("ideal", "engineering", "s"), 0.05, 2.0, 0.05, 2.0),
        (BlockForm("ideal", "engineering", "min"), 0.05, 0.5, 0.05, 30.0),
        (BlockForm("ideal", "percent", "s", **SPANS), 1.25, 2.0, 0.05, 2.0),
        (BlockForm("ideal", "percent", "min", **SPANS), 1.25, 0.5, 0.05, 30.0),
        (BlockForm("parallel", "engineering", "s"), 0.05, 0.025, 0.05, 2.0),  # Ti = Kp/Ki
        (BlockForm("parallel", "engineering", "min"), 0.05, 0.1, 0.05, 30.0),  # Ki per min
        (BlockForm("parallel", "percent", "s", **SPANS), 1.25, 0.625, 0.05, 2.0),
        (BlockForm("parallel", "percent", "min", **SPANS), 1.25, 2.5, 0.05, 30.0),
    ],
    ids=_name,
)
def test_each_form_and_unit_against_hand_numbers(
    block: BlockForm, kc: float, ti: float, Kc: float, Ti: float
) -> None:
    assert from_block(kc, ti, block) == pytest.approx((Kc, Ti), rel=1e-12)
    assert to_block(Kc, Ti, block) == pytest.approx((kc, ti), rel=1e-12)


@pytest.mark.parametrize("block", BLOCKS, ids=_name)
@pytest.mark.parametrize(("Kc", "Ti"), [(0.05, 2.0), (3.7e-3, 0.41), (12.5, 1800.0)])
def test_round_trips_within_1e_12(block: BlockForm, Kc: float, Ti: float) -> None:
    kc, ti = to_block(Kc, Ti, block)
    back = from_block(kc, ti, block)
    assert back == pytest.approx((Kc, Ti), rel=1e-12)
    assert to_block(*back, block) == pytest.approx((kc, ti), rel=1e-12)
    # the methods of PISettings are the same conversion
    pi = PISettings(rule="simc", Kc=Kc, Ti=Ti, control_period=1.0)
    assert pi.to_block(block) == (kc, ti)
    again = PISettings.from_block(kc, ti, block, rule="simc", control_period=1.0)
    assert (again.Kc, again.Ti) == back
    assert (again.rule, again.control_period) == ("simc", 1.0)


@pytest.mark.parametrize(("u_span", "y_span"), [(4.0, 100.0), (10.0, 37.5), (16.0, 250.0)])
def test_plc_form_percent_is_the_block_conversion(u_span: float, y_span: float) -> None:
    pi = PISettings(rule="simc", Kc=0.0437, Ti=1.7, control_period=1.0)
    percent = pi.plc_form(u_span=u_span, y_span=y_span)["percent_of_span"]
    kc, ti_s = to_block(pi.Kc, pi.Ti, BlockForm("ideal", "percent", "s", u_span, y_span))
    _, ti_min = to_block(pi.Kc, pi.Ti, BlockForm("ideal", "percent", "min", u_span, y_span))
    assert percent["Kc"] == kc  # the same formula: equal, not merely close
    assert percent["Ti"] == ti_s
    assert percent["Ti_min"] == ti_min
    assert pi.plc_form()["percent_of_span"] is None  # no spans, no %/% gain


def test_the_block_of_a_controller_a_mapping_or_anything_named_alike() -> None:
    c = Controller(
        form="parallel", gain_units="percent", integral_unit="min", u_span_V=4.0, y_span_Lpm=100.0
    )
    expected = BlockForm("parallel", "percent", "min", 4.0, 100.0)
    assert BlockForm.of(c) == expected
    assert BlockForm.of(c.model_dump()) == expected
    assert BlockForm.of(SimpleNamespace(**c.model_dump())) == expected
    assert BlockForm.of({}) == BlockForm()  # the [controller] table's defaults
    assert BlockForm.of(Controller()) == BlockForm()


@pytest.mark.parametrize(
    "fields",
    [
        {"form": "series"},
        {"gain_units": "percent"},  # no spans
        {"gain_units": "percent", "u_span": 4.0},
        {"integral_unit": "h"},
        {"u_span": -4.0},
        {"y_span": math.nan},
    ],
)
def test_a_block_nobody_could_have_is_refused(fields: dict) -> None:
    with pytest.raises(FuelidError):
        BlockForm(**fields)


@pytest.mark.parametrize(("kc", "ti"), [(0.0, 1.0), (1.0, -1.0), (math.nan, 1.0), (1.0, math.inf)])
def test_gains_that_are_not_positive_and_finite_are_refused(kc: float, ti: float) -> None:
    with pytest.raises(FuelidError, match="positive and finite"):
        from_block(kc, ti, BlockForm())
    with pytest.raises(FuelidError, match="positive and finite"):
        to_block(kc, ti, BlockForm())


def test_block_units_name_what_the_registers_hold() -> None:
    assert block_units(BlockForm("parallel", "percent", "min", **SPANS)) == {
        "Kc": "%/%",
        "Ti": "%/% per min",
    }
    assert block_units(BlockForm(integral_unit="min")) == {"Kc": "V per L/min", "Ti": "min"}


def test_the_online_gains_are_the_tuning_type() -> None:
    """Gains is a PISettings with no conversion of its own; its JSON stays {"Kc", "Ti"}."""
    g = Gains(0.05, 30.0)
    assert isinstance(g, PISettings)
    assert g.to_json() == {"Kc": 0.05, "Ti": 30.0}
    block = BlockForm("parallel", "percent", "min", **SPANS)
    assert g.to_block(block) == pytest.approx((1.25, 2.5), rel=1e-12)
    back = Gains.from_block(1.25, 2.5, block, rule="plc", control_period=1.0)
    assert type(back) is Gains
    assert (back.Kc, back.Ti, back.rule) == (pytest.approx(0.05), pytest.approx(30.0), "plc")
    for name in ("to_block", "from_block", "plc_form"):
        assert name not in vars(Gains), name
