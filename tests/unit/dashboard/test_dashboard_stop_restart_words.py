"""What the pages say once the service stopped or restarted, and a write's two times (issue 39).

A held-out trial found the page saying what only a running service does: after a kill -9,
"Write-back: approve" and, on an out-of-date proposal, "new windows will propose afresh"; after
the restart, the health chips green within 3 s from the window judged before the crash; and the
command and the page giving a revert's times 4 s apart (its issue, its echo) unlabelled. The
expected sentences follow from the rules in the modules' docstrings (``fuelid.dashboard._fleet``:
a restarted service's chips; ``fuelid.dashboard._views``: the write-back line).
"""

from __future__ import annotations

from typing import Any

import pytest

pytest.importorskip("fastapi")

from fuelid.cli.online import status_lines
from fuelid.dashboard._fleet import LIVE_CHIPS, loop_chips
from fuelid.dashboard._views import gains_in_force, now_rows, proposal_state, write_back_text
from fuelid.online import RECENT_WINDOWS_SPAN, write_times_text

NEWEST = 1_795_767_303.4  # the newest sample [plant s]: 2026-11-27 09:15:03 CET
TZ = "Europe/Zurich"
WINDOW_S = 600.0
SPAN = RECENT_WINDOWS_SPAN * WINDOW_S
RECENT_IAE = [2.0, 2.2, 1.8, 2.1, 1.9]
HEALTH = {
    "time_in_auto": 1.0,
    "time_at_limits": 0.0,
    "oscillation": {"oscillating": False},
    "iae_per_unit_step_s": 2.0,
}


def running(**changes: Any) -> dict[str, Any]:
    """A running loop in write_back "approve", healthy, its newest sample at NEWEST."""
    out: dict[str, Any] = {
        "site": {"name": "test site", "store": "loop.db"},
        "link": {"state": "up", "service": "running", "text": "up (newest sample 0.4 s ago)",
                 "sample_age_s": 0.4, "newest_sample": NEWEST, "beat_age_s": 1.0},
        "timezone": TZ,
        "service": {"started": 1000.0, "settings": {"window_s": WINDOW_S}},
        "write_back": {"setting": "approve", "write_held": None, "revert_requested": None},
        "last_window": {"id": 9, "mode": "AUTO", "end": NEWEST - 100.0, "time": NEWEST - 90.0,
                        "wall_time": 2000.0, "accepted": True, "reason": "passed every gate"},
        "loop_health": dict(HEALTH),
        "k_trend": {"available": True, "drift": {"ratio": 1.01, "se": 0.01}},
        "pending_proposals": [],
        "last_write": None,
        "counts": {},
        "gain_units": {"Kc": "V per L/min", "Ti": "s"},
    }  # fmt: skip
    out.update(changes)
    return out


def stopped(**changes: Any) -> dict[str, Any]:
    """The same loop 12 s of wall time after a kill -9 of its service."""
    out = running(**changes)
    out["link"] = {"state": "stopped", "service": "stopped", "sample_age_s": 14.0,
                   "text": "service stopped (no beat for 12 s of wall time)",
                   "newest_sample": NEWEST, "beat_age_s": 12.0}  # fmt: skip
    return out


def chips(status: dict[str, Any]) -> dict[str, Any]:
    return {c.name: c for c in loop_chips(status, RECENT_IAE)}


# --- 1. a stopped service: what it would do is said as of its last run ------------------------


def test_write_back_is_said_as_of_the_last_run_while_the_service_is_stopped() -> None:
    assert write_back_text(running()) == "Write-back: approve."
    assert write_back_text(stopped()) == (
        "Write-back: approve when the service last ran (stopped at 09:15:03 CET); nothing is "
        "written while it is stopped."
    )
    never = running(link={"state": "stopped", "service": "never started"}, service=None)
    assert write_back_text(never) == "Write-back: approve; no service ran: nothing is written."
    # the "Now" table says the same
    assert dict(now_rows(running(), TZ))["write-back"].startswith("approve; gains in force Kc ")
    assert dict(now_rows(stopped(), TZ))["write-back"].startswith(
        "approve when the service last ran (stopped at 09:15:03 CET); nothing is written while "
        "it is stopped; gains in force Kc "
    )


def test_an_out_of_date_proposal_promises_new_windows_only_from_a_running_service() -> None:
    old_windows = [{"id": 70, "model_id": 7, "t_to": NEWEST - SPAN - 1.0}]
    pending = {"id": 4, "status": "pending", "model_id": 7, "time": NEWEST - SPAN}
    live = proposal_state(pending, running(), old_windows)
    assert live.state == "out_of_date"
    assert live.text.endswith("; new windows will propose afresh")
    down = proposal_state(pending, stopped(), old_windows)
    assert down.state == "out_of_date"
    assert down.text.endswith("; new windows will propose afresh when the service runs again")
    # the status' own reason (online status --json) is said the same way on the page
    told = {**pending, "stale": live.text.removeprefix("out of date, not written: ")}
    assert proposal_state(told, stopped(), old_windows).text == down.text


# --- 2. a restarted service: unknown until it judged a window ---------------------------------


def restarted(
    started_plant: Any, window_time: float, opened: float | None = None, **changes: Any
) -> dict[str, Any]:
    """Running again since plant time ``started_plant``, its newest window judged at another.

    The window opened at ``opened``, a window length before ``window_time`` unless given.
    """
    status = running(**changes)
    status["service"] = {"started": 5000.0, "started_plant": started_plant,
                         "settings": {"window_s": WINDOW_S}}  # fmt: skip
    start = window_time - WINDOW_S if opened is None else opened
    status["last_window"] = {**status["last_window"], "start": start, "time": window_time,
                             "wall_time": 4990.0}  # fmt: skip
    return status


def test_a_restarted_service_greys_the_live_chips_until_it_judged_a_window() -> None:
    # restarted at 09:14:33 CET (its first sample); the newest window was judged before the kill
    before = chips(restarted(NEWEST - 30.0, NEWEST - 90.0))
    for name in LIVE_CHIPS:
        assert before[name].level == "unknown", name
        assert before[name].text.startswith(
            "unknown since the restart at 09:14:33 CET: no window of its own yet (last before: "
        ), before[name].text
    assert before["oscillation"].text.endswith("(last before: none)")
    assert before["service"].level == "ok"  # the service chip is about now: running, link up
    # judged after the restart but opened before it (the held-out trial's window #102, 78 %
    # the previous run's samples, the outage within): still not the restarted service's health
    mixed = chips(restarted(NEWEST - 30.0, NEWEST - 20.0))
    assert {mixed[name].level for name in LIVE_CHIPS} == {"unknown"}
    # the first window of its own (opened at the restart): its health, coloured again
    after = chips(restarted(NEWEST - 630.0, NEWEST - 20.0, opened=NEWEST - 630.0))
    assert {after[name].level for name in LIVE_CHIPS} == {"ok"}
    # running again, but no sample of its own yet: nothing judged since either
    waiting = chips(restarted(None, NEWEST - 90.0))
    assert waiting["mode"].level == "unknown"
    assert waiting["mode"].text.startswith("unknown since the restart: no window of its own yet")


def test_a_record_without_its_plant_start_compares_the_two_wall_stamps_of_the_site() -> None:
    # a service from before the plant start was recorded: its start and the window's commit are
    # both the service host's wall clock (never a wall time against a plant time)
    status = restarted(None, NEWEST - 90.0)
    del status["service"]["started_plant"]
    assert chips(status)["limits"].level == "unknown"
    status["last_window"]["wall_time"] = 5001.0  # written after the start
    assert chips(status)["limits"].level == "ok"


def test_the_restart_rule_leaves_a_first_start_and_a_stop_alone() -> None:
    # a stop keeps its own words; a loop without a window has nothing to grey
    assert chips(stopped())["mode"].text.startswith("unknown since the stop at")
    first = restarted(NEWEST - 30.0, NEWEST - 90.0, loop_health=None)
    first["last_window"] = None
    assert chips(first)["mode"].text == "mode not measured yet"
    # a window written after the service's start (running() has no restart): coloured
    assert {chips(running())[name].level for name in LIVE_CHIPS} == {"ok"}


# --- 3. a write's two times: the same instants on the command and the page ---------------------


def test_a_revert_is_said_with_its_issue_and_its_echo_by_the_command_and_the_page() -> None:
    revert = {"id": 4, "kind": "revert", "status": "verified", "Kc": 0.1, "Ti": 2.0,
              "time": NEWEST - 100.0, "finished": NEWEST - 96.0, "proposal_id": None,
              "who": "eve", "why": "too lively"}  # fmt: skip
    both = "issued at 2026-11-27 09:13:23 CET, verified at 09:13:27 CET"
    assert write_times_text(revert, TZ) == both
    status = running(last_write=revert)
    (writes,) = [line for line in status_lines(status) if line.startswith("writes")]
    assert writes.endswith(f"last write #4 revert verified (Kc 0.1, Ti 2): {both}")
    assert dict(now_rows(status, TZ))["last write"] == f"#4 revert verified: {both}"
    assert gains_in_force(status, [revert])["text"] == f"last verified write #4 (a revert): {both}"


def test_a_write_without_its_outcome_and_a_failed_one_say_so() -> None:
    intent = {"id": 5, "kind": "proposal", "status": "intent", "time": NEWEST, "finished": None}
    assert write_times_text(intent, TZ) == "issued at 2026-11-27 09:15:03 CET, no echo yet"
    failed = {**intent, "status": "failed", "finished": NEWEST + 86_400.0}
    assert write_times_text(failed, TZ) == (
        "issued at 2026-11-27 09:15:03 CET, failed at 2026-11-28 09:15:03 CET"
    )
