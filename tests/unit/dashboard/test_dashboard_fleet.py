"""The fleet page's chips and its severity order (fuelid.dashboard._fleet's documented table).

Each loop below differs from a healthy one in exactly one way (or two, for the worst), so the
expected order follows from the documented rule alone: alarms first, more alarms before fewer,
then by the first chip in CHIP_ORDER; warnings next; unknown; info; healthy last, by loop id.
A stopped service greys the chips about the running loop (LIVE_CHIPS) and keeps the last write
and the proposals coloured; a link "up" whose newest sample is past FRESH_SAMPLE_S is grey.
"""

from __future__ import annotations

import copy
from typing import Any

import pytest

pytest.importorskip("fastapi")

from fuelid.dashboard._fleet import (
    AUTO_WARN,
    CHIP_ORDER,
    DRIFT_WARN,
    IAE_WARN,
    LIMITS_WARN,
    LIVE_CHIPS,
    fleet_row,
    loop_chips,
)
from fuelid.dashboard._views import FRESH_SAMPLE_S
from fuelid.online import RECENT_WINDOWS_SPAN

RECENT_IAE = [2.0, 2.2, 1.8, 2.1, 1.9]  # median 2.0 s
NEWEST = 1_795_767_303.4  # plant time of the newest sample: 2026-11-27 08:15:03 UTC
WINDOW_S = 600.0
SPAN = RECENT_WINDOWS_SPAN * WINDOW_S  # a proposal's window ending longer ago is out of date


def healthy() -> dict[str, Any]:
    """A status every chip of which is ok."""
    return {
        "link": {
            "state": "up",
            "text": "up (newest sample 0.4 s ago)",
            "sample_age_s": 0.4,
            "newest_sample": NEWEST,
            "beat_age_s": 1.0,
        },
        "timezone": "UTC",
        "service": {"settings": {"window_s": WINDOW_S}},
        "last_window": {"mode": "AUTO"},
        "loop_health": {
            "time_in_auto": 1.0,
            "time_at_limits": 0.0,
            "oscillation": {"oscillating": False},
            "iae_per_unit_step_s": 2.0,
        },
        "k_trend": {"available": True, "drift": {"ratio": 1.01, "se": 0.01}},
        "pending_proposals": [],
        "write_back": {"write_held": None, "revert_requested": None},
        "last_write": {"id": 3, "kind": "proposal", "status": "verified"},
    }


def with_changes(**paths: Any) -> dict[str, Any]:
    """A healthy status with ``a__b=value`` set at status[a][b]."""
    status = copy.deepcopy(healthy())
    for path, value in paths.items():
        keys = path.split("__")
        node = status
        for key in keys[:-1]:
            node = node[key]
        node[keys[-1]] = value
    return status


def levels(status: dict[str, Any], windows: list[dict[str, Any]] | None = None) -> dict[str, str]:
    return {c.name: c.level for c in loop_chips(status, RECENT_IAE, windows or [])}


def chip(status: dict[str, Any], name: str, windows: list[dict[str, Any]] | None = None) -> Any:
    return next(c for c in loop_chips(status, RECENT_IAE, windows or []) if c.name == name)


def test_a_healthy_loop_has_every_chip_ok_in_the_documented_order() -> None:
    chips = loop_chips(healthy(), RECENT_IAE)
    assert [c.name for c in chips] == list(CHIP_ORDER)
    assert {c.level for c in chips} == {"ok"}


@pytest.mark.parametrize(
    ("changes", "chip", "level"),
    [
        ({"link__state": "link_down"}, "service", "alarm"),
        ({"link__state": "no_data"}, "service", "unknown"),
        (
            {"loop_health__oscillation": {"oscillating": True, "period_s": 8.0}},
            "oscillation",
            "alarm",
        ),
        ({"last_write__status": "failed"}, "last write", "alarm"),
        ({"write_back__revert_requested": {"who": "op"}}, "last write", "alarm"),
        ({"pending_proposals": [{"id": 4, "status": "pending"}]}, "proposals", "warn"),
        ({"pending_proposals": [{"id": 4, "status": "approved"}]}, "proposals", "warn"),
        # drift: 15 % off with se 1 %: warn; 15 % off with se 10 %: inside 2 se, ok
        ({"k_trend__drift": {"ratio": 1.0 + 1.5 * DRIFT_WARN, "se": 0.01}}, "drift", "warn"),
        ({"k_trend__drift": {"ratio": 1.0 + 1.5 * DRIFT_WARN, "se": 0.1}}, "drift", "ok"),
        ({"k_trend__drift": {"ratio": 1.0 + 0.5 * DRIFT_WARN, "se": 0.001}}, "drift", "ok"),
        ({"loop_health__time_at_limits": 2 * LIMITS_WARN}, "limits", "warn"),
        ({"loop_health__time_at_limits": 0.5 * LIMITS_WARN}, "limits", "ok"),
        ({"loop_health__iae_per_unit_step_s": 2.0 * (IAE_WARN + 0.1)}, "IAE", "warn"),
        ({"loop_health__iae_per_unit_step_s": 2.0 * (IAE_WARN - 0.1)}, "IAE", "ok"),
        ({"loop_health__time_in_auto": AUTO_WARN - 0.05}, "mode", "warn"),
        ({"last_window__mode": "MAN"}, "mode", "warn"),
    ],
)
def test_each_threshold_sets_its_chip(changes: dict[str, Any], chip: str, level: str) -> None:
    got = levels(with_changes(**changes))
    assert got[chip] == level
    assert all(v == "ok" for k, v in got.items() if k != chip), got


def test_the_fleet_is_sorted_by_the_documented_severity_order() -> None:
    loops = {
        "g-healthy": healthy(),
        "f-drift-within-noise": with_changes(k_trend__drift={"ratio": 1.15, "se": 0.1}),
        "a-stopped": with_changes(link__state="stopped"),
        "b-oscillating": with_changes(loop_health__oscillation={"oscillating": True}),
        "c-write-failed": with_changes(last_write__status="failed"),
        "d-proposal": with_changes(pending_proposals=[{"id": 1, "status": "pending"}]),
        "e-drift": with_changes(k_trend__drift={"ratio": 1.15, "se": 0.01}),
        "h-new": {"link": {"state": "no_data"}},
        # a stopped service greys the oscillation chip, a failed write stays an alarm
        "z-two-alarms": with_changes(link__state="stopped", last_write__status="failed"),
        "y-proposal-and-limits": with_changes(
            pending_proposals=[{"id": 2, "status": "pending"}], loop_health__time_at_limits=0.3
        ),
    }
    rows = [fleet_row(loop_id, "site", status, RECENT_IAE) for loop_id, status in loops.items()]
    order = [r["loop_id"] for r in sorted(rows, key=lambda r: r["sort_key"])]
    assert order == [
        "z-two-alarms",  # two alarms before one
        "a-stopped",  # then by the first alarm chip: service, oscillation, last write
        "b-oscillating",
        "c-write-failed",
        "y-proposal-and-limits",  # two warnings before one
        "d-proposal",  # proposals before drift
        "e-drift",
        "h-new",  # nothing measured: after every warning
        "f-drift-within-noise",  # healthy ones by loop id
        "g-healthy",
    ]
    assert [r["level"] for r in rows if r["loop_id"] in ("a-stopped", "d-proposal", "h-new")] == [
        "alarm",
        "warn",
        "unknown",
    ]


def test_a_propose_only_loop_shows_its_waiting_proposal_as_info() -> None:
    # write_back "off": nothing is written, so a waiting proposal is advice, not a hold-up
    status = with_changes(
        pending_proposals=[{"id": 5, "status": "pending"}], write_back__setting="off"
    )
    chips = {c.name: c for c in loop_chips(status, RECENT_IAE)}
    assert chips["proposals"].level == "info"
    assert chips["proposals"].text == "1 (propose only: nothing is written)"
    row = fleet_row("p-only", "site", status, RECENT_IAE)
    assert row["level"] == "info"
    # sorts after a loop with something unknown and before a healthy one
    rows = [
        row,
        fleet_row("a-healthy", "site", healthy(), RECENT_IAE),
        fleet_row("z-new", "site", {"link": {"state": "no_data"}}, RECENT_IAE),
    ]
    assert [r["loop_id"] for r in sorted(rows, key=lambda r: r["sort_key"])] == [
        "z-new",
        "p-only",
        "a-healthy",
    ]
    # with "approve" the same proposal still warns
    approve = with_changes(
        pending_proposals=[{"id": 5, "status": "pending"}], write_back__setting="approve"
    )
    assert levels(approve)["proposals"] == "warn"


def test_held_back_gains_are_said_on_the_chip_until_a_proposal_waits() -> None:
    # the newest evidence points at gains that were reverted: no proposal comes, and the chip
    # says why instead of "none waiting" (a trial saw six hours of silence explained nowhere)
    held = {"id": 1, "status": "reverted", "Kc": 0.03, "Ti": 3.0}
    got = chip(with_changes(held_proposal=held), "proposals")
    assert (got.level, got.text) == ("info", "none filed: the gains of #1 are held back")
    waiting = with_changes(held_proposal=held, pending_proposals=[{"id": 2, "status": "pending"}])
    assert chip(waiting, "proposals").text == "1 waits for approval"
    assert chip(healthy(), "proposals").text == "none waiting"


# --- a stopped service ---------------------------------------------------------------------


def test_a_stopped_service_greys_the_chips_about_the_running_loop() -> None:
    # stopped, with a failed last write and a proposal waiting: what the store proves stays
    status = with_changes(
        link__state="stopped",
        link__text="service stopped (no beat for 12 s of wall time)",
        last_write__status="failed",
        pending_proposals=[{"id": 4, "status": "pending", "time": NEWEST - 60.0}],
        timezone="Europe/Zurich",  # the newest sample's plant time in the site's zone: 09:15:03
    )
    chips = {c.name: c for c in loop_chips(status, RECENT_IAE)}
    assert chips["service"].level == "alarm"
    assert chips["service"].text == "service stopped (no beat for 12 s of wall time)"
    for name in LIVE_CHIPS:
        assert chips[name].level == "unknown", name
        assert chips[name].text.startswith("unknown since the stop at 09:15:03 CET (last: ")
    assert chips["oscillation"].text == "unknown since the stop at 09:15:03 CET (last: none)"
    assert chips["last write"].level == "alarm"
    assert chips["proposals"].level == "warn"


def test_a_stop_a_day_old_names_its_date() -> None:
    status = with_changes(link__state="stopped", link__beat_age_s=2 * 86_400.0)
    text = chip(status, "mode").text
    assert text.startswith("unknown since the stop at 2026-11-27 08:15:03 UTC (last: AUTO")


def test_a_running_loop_is_not_greyed() -> None:
    for state in ("up", "link_down", "no_data"):
        got = levels(with_changes(link__state=state))
        assert all(got[name] == "ok" for name in LIVE_CHIPS), (state, got)


# --- the freshness of "link up" -------------------------------------------------------------


def test_link_up_with_an_old_sample_is_grey_not_green() -> None:
    # 9.3 s after a kill -9: the service is not yet judged stopped (10 s), its link still "up"
    stale = with_changes(link__sample_age_s=9.3, link__text="up (newest sample 9.3 s ago)")
    service = chip(stale, "service")
    assert (service.level, service.text) == ("unknown", "no new sample for 9.3 s")
    fresh = with_changes(
        link__sample_age_s=FRESH_SAMPLE_S - 0.1, link__text="up (newest sample 4.9 s ago)"
    )
    service = chip(fresh, "service")
    assert (service.level, service.text) == ("ok", "link up (newest sample 4.9 s ago)")


def test_a_slow_sampling_period_stretches_the_freshness_bound() -> None:
    # 4 s between samples: three periods (12 s) before a sample counts as old
    status = with_changes(link__sample_age_s=9.3)
    status["service"]["settings"]["sampling"] = {"period_s": 4.0}
    assert chip(status, "service").level == "ok"
    status["link"]["sample_age_s"] = 12.5
    assert chip(status, "service").level == "unknown"


# --- proposals: the cards' classification -------------------------------------------------


def proposal(pid: int, status: str, window_end: float, model_id: int) -> dict[str, Any]:
    return {"id": pid, "status": status, "model_id": model_id, "time": window_end + 1.0}


def test_an_out_of_date_proposal_is_said_as_info_not_a_warning() -> None:
    # its window ended more than RECENT_WINDOWS_SPAN window lengths before the newest sample:
    # the service would not write it, so nothing waits for anyone
    old = proposal(4, "pending", NEWEST - SPAN - 1.0, model_id=7)
    windows = [{"id": 70, "model_id": 7, "t_to": NEWEST - SPAN - 1.0}]
    status = with_changes(pending_proposals=[old])
    got = chip(status, "proposals", windows)
    assert (got.level, got.text) == ("info", "1 out of date, not written")
    assert fleet_row("l", "s", status, RECENT_IAE, windows)["level"] == "info"


def test_a_proposal_just_inside_the_span_still_waits() -> None:
    fresh = proposal(4, "pending", NEWEST - SPAN + 1.0, model_id=7)
    windows = [{"id": 70, "model_id": 7, "t_to": NEWEST - SPAN + 1.0}]
    got = chip(with_changes(pending_proposals=[fresh]), "proposals", windows)
    assert (got.level, got.text) == ("warn", "1 waits for approval")


def test_without_its_window_a_proposal_is_judged_on_its_filing_time() -> None:
    # the fleet may pass no windows: filed 8,000 s of data ago, its window ended even earlier
    old = {"id": 4, "status": "approved", "model_id": 7, "time": NEWEST - 8000.0}
    got = chip(with_changes(pending_proposals=[old]), "proposals")
    assert (got.level, got.text) == ("info", "1 out of date, not written")


def test_waiting_approved_and_out_of_date_are_counted_apart() -> None:
    pending = [
        proposal(4, "pending", NEWEST - SPAN - 500.0, model_id=7),  # out of date
        proposal(5, "approved", NEWEST - 600.0, model_id=8),
        proposal(6, "pending", NEWEST - 300.0, model_id=9),
    ]
    windows = [
        {"id": 70 + i, "model_id": 7 + i, "t_to": p["time"] - 1.0} for i, p in enumerate(pending)
    ]
    got = chip(with_changes(pending_proposals=pending), "proposals", windows)
    assert got.level == "warn"
    assert got.text == (
        "1 waits for approval; 1 approved, waiting for the write; 1 out of date, not written"
    )


def test_propose_only_approved_proposals_are_info() -> None:
    status = with_changes(
        pending_proposals=[{"id": 5, "status": "approved"}], write_back__setting="off"
    )
    got = chip(status, "proposals")
    assert (got.level, got.text) == ("info", "1 approved (propose only: not written)")


# --- drift ----------------------------------------------------------------------------------


def test_drift_without_a_model_for_the_gains_in_force_is_info() -> None:
    # K is tracked, but the gains in force were never written by the service (as commissioned)
    status = with_changes(k_trend__drift=None)
    got = chip(status, "drift")
    assert got.level == "info"
    assert got.text == (
        "K tracked; the gains in force have no model of their own (as commissioned, or "
        "reverted to): drift is measured from the next proposal written and verified"
    )
    # info sorts after unknown and before healthy
    rows = [
        fleet_row("a-healthy", "site", healthy(), RECENT_IAE),
        fleet_row("b-drift-unknown", "site", status, RECENT_IAE),
        fleet_row("c-new", "site", {"link": {"state": "no_data"}}, RECENT_IAE),
    ]
    order = [r["loop_id"] for r in sorted(rows, key=lambda r: r["sort_key"])]
    assert order == ["c-new", "b-drift-unknown", "a-healthy"]
    assert chip(with_changes(k_trend={"available": False}), "drift").level == "unknown"
