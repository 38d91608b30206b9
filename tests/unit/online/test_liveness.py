"""One clock (issue "one clock"): the loop's state, the gains' units, times as text.

The loop's state from the service record and the wall clock alone; the units of the PLC
block's gains by its form; the one formatter of times.
"""

from __future__ import annotations

import math

import pytest

from fuelid.io import format_age, format_time
from fuelid.online import SERVICE_BEAT_S, SERVICE_STALE_S
from fuelid.online._liveness import LINK_FRESH_S, loop_state
from fuelid.plc.site import Controller
from fuelid.tuning import BlockForm, block_units

NOW = 1_795_767_303.0
LIVE = {"started": NOW - 600.0, "beat": NOW - 1.0, "stopped": None}


@pytest.mark.parametrize(
    ("service", "sample_wall", "link_event", "state", "running"),
    [
        (None, NOW - 0.5, None, "stopped", "never started"),  # no record at all
        ({**LIVE, "stopped": NOW - 5.0}, NOW - 0.5, None, "stopped", "stopped"),  # clean stop
        ({**LIVE, "beat": NOW - 11.0}, NOW - 0.5, None, "stopped", "stopped"),  # kill -9
        ({**LIVE, "beat": NOW - 9.0}, NOW - 0.5, None, "up", "running"),  # within 5 beats
        (LIVE, NOW - 0.6, ("link_up", NOW - 100.0), "up", "running"),
        (LIVE, NOW - 0.6, ("link_down", NOW - 3.0), "link_down", "running"),
        (LIVE, NOW - 31.0, ("link_up", NOW - 100.0), "link_down", "running"),  # recorder silent
        (LIVE, math.nan, None, "link_down", "running"),  # samples of before schema 3: unknown
        (LIVE, None, None, "no_data", "running"),
    ],
)
def test_loop_state_table(
    service: dict | None,
    sample_wall: float | None,
    link_event: tuple[str, float] | None,
    state: str,
    running: str,
) -> None:
    out = loop_state(service, sample_wall, link_event, NOW)
    assert (out["state"], out["service"]) == (state, running)
    assert isinstance(out["text"], str)
    assert "\n" not in out["text"]


def test_a_killed_service_reads_stopped_with_its_last_beat() -> None:
    out = loop_state({**LIVE, "beat": NOW - 11.0}, NOW - 12.0, None, NOW, "UTC")
    assert out["state"] == "stopped"
    assert out["beat_age_s"] == pytest.approx(11.0)
    assert out["since"] == NOW - 11.0
    assert out["text"] == "service stopped (no beat for 11 s of wall time)"


def test_a_stop_says_its_wall_age_and_the_newest_samples_plant_time_each_labelled() -> None:
    # issue 39: "no beat for 12 s" stood beside plant times, unlabelled; an accelerated PLC's
    # plant time runs ahead of the wall clock, so each figure says its clock
    plant = NOW + 7000.0  # 2026-11-27 10:11:43 UTC
    killed = loop_state({**LIVE, "beat": NOW - 12.0}, NOW - 13.0, None, NOW, "UTC", plant)
    assert killed["text"] == (
        "service stopped (no beat for 12 s of wall time; newest sample at 10:11:43 UTC plant time)"
    )
    clean = loop_state({**LIVE, "stopped": NOW - 5.0}, NOW - 6.0, None, NOW, "Europe/Zurich", plant)
    assert clean["text"] == (
        "service stopped (5.0 s ago in wall time; newest sample at 11:11:43 CET plant time)"
    )
    # a stop a day old or more: the sample's date too
    old = loop_state({**LIVE, "beat": NOW - 2e5}, NOW - 2e5, None, NOW, "UTC", plant)
    assert old["text"].endswith("; newest sample at 2026-11-27 10:11:43 UTC plant time)")


def test_plant_time_running_ahead_is_never_used() -> None:
    # an accelerated virtual PLC: the newest sample's plant time 7000 s ahead of the wall clock;
    # the state is read from its wall_time (written 0.4 s ago), so the loop is up
    plant_time = NOW + 7000.0
    out = loop_state(LIVE, NOW - 0.4, None, NOW)
    assert out["state"] == "up"
    assert out["sample_age_s"] == pytest.approx(0.4)
    assert "ahead" not in out["text"]
    assert str(int(plant_time)) not in out["text"]


def test_the_constants_hold_together() -> None:
    assert SERVICE_STALE_S == 5 * SERVICE_BEAT_S
    assert LINK_FRESH_S > SERVICE_STALE_S


@pytest.mark.parametrize(
    ("controller", "units"),
    [
        (Controller(), {"Kc": "V per L/min", "Ti": "s"}),
        (Controller(integral_unit="min"), {"Kc": "V per L/min", "Ti": "min"}),
        (
            Controller(gain_units="percent", u_span_V=4.0, y_span_Lpm=100.0),
            {"Kc": "%/%", "Ti": "s"},
        ),
        (Controller(form="parallel"), {"Kc": "V per L/min", "Ti": "V per L/min per s"}),
        (
            Controller(form="parallel", integral_unit="min"),
            {"Kc": "V per L/min", "Ti": "V per L/min per min"},
        ),
        (
            Controller(form="parallel", gain_units="percent", u_span_V=4.0, y_span_Lpm=100.0),
            {"Kc": "%/%", "Ti": "%/% per s"},
        ),
    ],
)
def test_gain_units_name_what_the_registers_hold(controller: Controller, units: dict) -> None:
    assert block_units(BlockForm.of(controller)) == units


def test_times_and_ages_as_text() -> None:
    assert format_time(NOW) == "2026-11-27 08:15:03 UTC"
    assert format_time(NOW, "Europe/Zurich") == "2026-11-27 09:15:03 CET"
    assert format_time(NOW, "America/New_York").endswith(" EST")
    assert format_time(None) == "never"
    assert format_age(250.0) == "4 min"
    assert format_age(0.62) == "0.6 s"
