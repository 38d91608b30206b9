"""What the loop page says of its proposals and of the gains in force (fuelid.dashboard._views).

The expected states, levels, actions and sentences follow from the rules in the module's
docstring, not from what the code prints: a proposal the service would not write (the service's
own age rule, RECENT_WINDOWS_SPAN window lengths) is "out of date", not waiting, and cannot be
approved; a verified write says "written and verified at" its plant time in the site's zone; the
gains a card moves from are those in force now: the PLC's own kc and ti tags as read first
(an older reading, or one that is not the last write's gains, says so), else the last verified
write (after a revert, the revert's).
"""

from __future__ import annotations

from typing import Any

import pytest

pytest.importorskip("fastapi")

from fuelid.dashboard._fleet import loop_chips
from fuelid.dashboard._views import (
    FRESH_SAMPLE_S,
    PROPOSAL_STATES,
    gains_in_force,
    last_written_view,
    link_line_state,
    link_text,
    proposal_stale,
    proposal_state,
    proposal_views,
)
from fuelid.online import RECENT_WINDOWS_SPAN

NEWEST = 1_795_767_303.4  # the newest sample [plant s]: 2026-11-27 09:15:03 CET
NEWEST_TEXT = "2026-11-27 09:15:03 CET"
WINDOW_S = 600.0
SPAN = RECENT_WINDOWS_SPAN * WINDOW_S
TZ = "Europe/Zurich"


def status(**changes: Any) -> dict[str, Any]:
    """A running loop in write_back "approve" with its newest sample at NEWEST."""
    out: dict[str, Any] = {
        "link": {"state": "up", "text": "up (newest sample 0.4 s ago)", "sample_age_s": 0.4,
                 "newest_sample": NEWEST},
        "timezone": TZ,
        "service": {"settings": {"window_s": WINDOW_S, "controller": {"kc": 0.1, "ti": 2.0}}},
        "write_back": {"setting": "approve", "write_held": None},
        "pending_proposals": [],
        "last_write": None,
        "gain_units": {"Kc": "V per L/min", "Ti": "s"},
    }  # fmt: skip
    out.update(changes)
    return out


def entry(state: str, t: float, who: str = "service", why: str = "") -> dict[str, Any]:
    return {"time": t, "wall_time": t, "status": state, "who": who, "why": why}


def proposal(pid: int, state: str, model_id: int | None = 7, **keys: Any) -> dict[str, Any]:
    """A proposal filed 60 s of data before NEWEST, from Kc 0.1, Ti 2 to Kc 0.12, Ti 2.2."""
    history = [entry("pending", NEWEST - 60.0, "online")]
    if state != "pending":
        history.append(entry(state, NEWEST - 30.0, "ana", "looks right"))
    return {"id": pid, "status": state, "model_id": model_id, "time": NEWEST - 60.0,
            "old": {"Kc": 0.1, "Ti": 2.0}, "new": {"Kc": 0.12, "Ti": 2.2},
            "history": history, **keys}  # fmt: skip


FRESH_WINDOWS = [{"id": 70, "model_id": 7, "t_to": NEWEST - 61.0}]
OLD_WINDOWS = [{"id": 70, "model_id": 7, "t_to": NEWEST - SPAN - 1.0}]


# --- the states --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("stored", "windows", "write_back", "state", "level", "actions"),
    [
        ("pending", FRESH_WINDOWS, "approve", "waiting", "warn", ("approve", "reject")),
        ("pending", FRESH_WINDOWS, "off", "waiting", "info", ("approve", "reject")),
        ("approved", FRESH_WINDOWS, "approve", "approved", "warn", ("reject",)),
        ("approved", FRESH_WINDOWS, "off", "approved", "info", ("reject",)),
        # the service would not write these: not waiting, no warning, no approval
        ("pending", OLD_WINDOWS, "approve", "out_of_date", "info", ("reject",)),
        ("approved", OLD_WINDOWS, "approve", "out_of_date", "info", ("reject",)),
        # closed: nothing a person can do
        ("writing", FRESH_WINDOWS, "approve", "writing", "info", ()),
        ("applied", FRESH_WINDOWS, "approve", "written", "ok", ()),
        ("reverted", FRESH_WINDOWS, "approve", "reverted", "info", ()),
        ("failed", FRESH_WINDOWS, "approve", "failed", "info", ()),
        ("rejected", FRESH_WINDOWS, "approve", "rejected", "ok", ()),
        ("superseded", OLD_WINDOWS, "approve", "superseded", "ok", ()),
    ],
)
def test_each_stored_status_has_its_state_level_and_actions(
    stored: str,
    windows: list[dict[str, Any]],
    write_back: str,
    state: str,
    level: str,
    actions: tuple[str, ...],
) -> None:
    loop = status(write_back={"setting": write_back, "write_held": None})
    got = proposal_state(proposal(4, stored), loop, windows)
    assert (got.state, got.level, got.actions) == (state, level, actions)
    assert got.state in PROPOSAL_STATES


def test_the_age_rule_is_the_services_own() -> None:
    # its window ended just more than the span before the newest sample: out of date; just
    # less: waiting
    just_out = [{"id": 70, "model_id": 7, "t_to": NEWEST - SPAN - 1.0}]
    just_in = [{"id": 70, "model_id": 7, "t_to": NEWEST - SPAN + 1.0}]
    got = proposal_state(proposal(4, "pending"), status(), just_out)
    assert got.text == (
        f"out of date, not written: stale: its newest window ended {SPAN + 1.0:.0f} s of data "
        f"before the newest sample (> {SPAN:.0f} s); new windows will propose afresh"
    )
    assert proposal_state(proposal(4, "pending"), status(), just_in).state == "waiting"
    # no model: the service has no window to judge and writes it
    assert proposal_stale(proposal(4, "pending", model_id=None), status(), just_out) is None


def test_without_its_window_the_filing_time_bounds_the_age() -> None:
    # filed 8,000 s of data ago: its window ended at least that long ago
    old = proposal(4, "approved", time=NEWEST - 8000.0)
    reason = proposal_stale(old, status(), [])
    assert reason is not None
    assert reason.startswith("stale: its newest window ended at least 8000 s of data before")
    assert proposal_stale(proposal(4, "approved"), status(), []) is None  # filed 60 s ago


def test_closed_proposals_say_what_happened_at_plant_time_in_the_site_zone() -> None:
    applied_at = NEWEST - 30.0  # 2026-11-27 09:14:33 CET
    written = proposal(4, "applied")
    assert proposal_state(written, status()).text == (
        "written and verified at 2026-11-27 09:14:33 CET"
    )
    reverted = proposal(4, "applied")
    reverted["status"] = "reverted"
    reverted["history"].append(entry("reverted", applied_at + 20.0, "service", "it oscillates"))
    assert proposal_state(reverted, status()).text == (
        "written and verified at 2026-11-27 09:14:33 CET, reverted at 2026-11-27 09:14:53 CET "
        "by service: it oscillates"
    )
    rejected = proposal(5, "rejected")
    assert proposal_state(rejected, status()).text == (
        "rejected at 2026-11-27 09:14:33 CET by ana: looks right"
    )


def test_a_waiting_proposal_says_who_must_act() -> None:
    got = proposal_state(proposal(4, "pending"), status(), FRESH_WINDOWS)
    assert got.text == "waits for an engineer to approve or reject it"
    stopped = status(link={"state": "stopped", "newest_sample": NEWEST})
    got = proposal_state(proposal(4, "approved"), stopped, FRESH_WINDOWS)
    assert got.text.startswith("approved; the service is stopped: written when it runs again")


def test_the_chip_and_the_cards_classify_alike() -> None:
    pending = [
        proposal(4, "pending", model_id=7),
        proposal(5, "approved", model_id=8),
        proposal(6, "pending", model_id=9),
    ]
    windows = [
        {"id": 70, "model_id": 7, "t_to": NEWEST - SPAN - 1.0},  # out of date
        {"id": 80, "model_id": 8, "t_to": NEWEST - 100.0},
        {"id": 90, "model_id": 9, "t_to": NEWEST - 61.0},
    ]
    loop = status(pending_proposals=pending)
    cards = proposal_views(loop, windows)
    assert [c["state"] for c in cards] == ["out_of_date", "approved", "waiting"]
    assert [c["actions"] for c in cards] == [["reject"], ["reject"], ["approve", "reject"]]
    (chip,) = [c for c in loop_chips(loop, [], windows) if c.name == "proposals"]
    assert chip.level == "warn"
    assert chip.text == (
        "1 waits for approval; 1 approved, waiting for the write; 1 out of date, not written"
    )


# --- the gains in force ------------------------------------------------------------------


def write(wid: int, kind: str, state: str, kc: float, ti: float, t: float) -> dict[str, Any]:
    return {"id": wid, "kind": kind, "status": state, "Kc": kc, "Ti": ti, "time": t,
            "finished": t + 1.0, "proposal_id": 3 if kind == "proposal" else None}  # fmt: skip


def test_after_a_revert_the_reverts_gains_are_in_force() -> None:
    writes = [
        write(3, "proposal", "verified", 0.12, 2.2, NEWEST - 200.0),
        write(4, "revert", "verified", 0.1, 2.0, NEWEST - 100.0),
    ]
    got = gains_in_force(status(last_write=writes[-1]), writes)
    assert (got["Kc"], got["Ti"], got["source"], got["write_id"]) == (0.1, 2.0, "write", 4)
    assert got["text"] == (  # its two instants, as fuelid online status says them
        "last verified write #4 (a revert): issued at 2026-11-27 09:13:23 CET, verified at "
        "09:13:24 CET"
    )
    assert got["units"] == {"Kc": "V per L/min", "Ti": "s"}
    # the status alone says the same (its last write is the revert)
    assert gains_in_force(status(last_write=writes[-1]))["Kc"] == 0.1


def test_a_failed_write_is_never_the_gains_in_force() -> None:
    writes = [
        write(3, "proposal", "verified", 0.12, 2.2, NEWEST - 200.0),
        write(5, "proposal", "failed", 0.15, 2.5, NEWEST - 50.0),
    ]
    got = gains_in_force(status(last_write=writes[-1]), writes)
    assert (got["Kc"], got["Ti"], got["write_id"]) == (0.12, 2.2, 3)
    assert got["text"].endswith("; write #5 after it is failed: the PLC may differ")
    # from the status alone: the verified gains the service keeps, in the block's units
    only = status(
        last_write=writes[-1],
        write_back={"setting": "approve", "current_gains_block": {"Kc": 0.12, "Ti": 2.2}},
    )
    got = gains_in_force(only)
    assert (got["Kc"], got["Ti"], got["source"], got["write_id"]) == (0.12, 2.2, "write", None)


def test_before_any_write_the_gains_come_from_a_proposal_then_the_site_file() -> None:
    with_proposal = status(pending_proposals=[proposal(4, "pending", old={"Kc": 0.11, "Ti": 2})])
    got = gains_in_force(with_proposal)
    assert (got["Kc"], got["Ti"], got["source"]) == (0.11, 2, "proposal")
    assert got["text"] == (
        "as the service found them when it filed proposal #4 at 2026-11-27 09:14:03 CET"
    )
    got = gains_in_force(status())
    assert (got["Kc"], got["Ti"], got["source"]) == (0.1, 2.0, "commissioning")
    bare = status(service=None)
    got = gains_in_force(bare)
    assert (got["Kc"], got["Ti"], got["source"]) == (None, None, "unknown")


def reading(kc: float, ti: float, t: float) -> dict[str, Any]:
    """The status' ``plc_gains``: the PLC's kc and ti tags as read at plant time ``t``."""
    return {"Kc": kc, "Ti": ti, "units": {"Kc": "V per L/min", "Ti": "s"},
            "ideal": {"Kc": kc, "Ti": ti}, "tag_units": {"kc": "V per L/min", "ti": "s"},
            "time": t, "wall_time": t}  # fmt: skip


def test_the_plcs_own_reading_comes_first_and_agrees_with_the_write() -> None:
    writes = [write(3, "proposal", "verified", 0.12, 2.2, NEWEST - 200.0)]
    # read after the write (at NEWEST - 190 s: 09:11:53 CET), the gains it wrote
    loop = status(last_write=writes[-1], plc_gains=reading(0.12, 2.2, NEWEST - 190.0))
    got = gains_in_force(loop, writes)
    assert (got["Kc"], got["Ti"], got["source"], got["write_id"]) == (0.12, 2.2, "plc", None)
    assert got["text"] == "the PLC's kc and ti tags as read at 2026-11-27 09:11:53 CET"
    assert got["units"] == {"Kc": "V per L/min", "Ti": "s"}
    # a float32 tag reads a written gain back to about 1e-7: still the same gains
    close = status(last_write=writes[-1], plc_gains=reading(0.12000001, 2.2, NEWEST - 190.0))
    assert gains_in_force(close, writes)["text"] == got["text"]


def test_without_a_reading_the_last_verified_write_is_in_force_labelled_as_such() -> None:
    writes = [write(3, "proposal", "verified", 0.12, 2.2, NEWEST - 200.0)]
    for loop in (status(last_write=writes[-1]), status(last_write=writes[-1], plc_gains=None)):
        got = gains_in_force(loop, writes)
        assert (got["Kc"], got["Ti"], got["source"], got["write_id"]) == (0.12, 2.2, "write", 3)
        assert got["text"] == (
            "last verified write #3: issued at 2026-11-27 09:11:43 CET, verified at 09:11:44 CET"
        )


def test_a_change_at_the_panel_no_write_explains_is_shown_as_the_plcs_gains() -> None:
    writes = [write(3, "proposal", "verified", 0.12, 2.2, NEWEST - 200.0)]
    # someone typed Kc 0.2 into the panel after the write: the PLC's gains, the mismatch said
    loop = status(last_write=writes[-1], plc_gains=reading(0.2, 2.2, NEWEST - 60.0))
    got = gains_in_force(loop, writes)
    assert (got["Kc"], got["Ti"], got["source"]) == (0.2, 2.2, "plc")
    assert got["text"] == (
        "the PLC's kc and ti tags as read at 2026-11-27 09:14:03 CET; not the gains of the last "
        "verified write #3 at 2026-11-27 09:11:44 CET (Kc 0.12 V per L/min, Ti 2.2 s): changed "
        "at the PLC, not by a write"
    )
    # the card of a waiting proposal moves from them too
    (card,) = proposal_views({**loop, "pending_proposals": [proposal(6, "pending")]},
                             FRESH_WINDOWS, writes)  # fmt: skip
    assert card["from"] == {"Kc": 0.2, "Ti": 2.2}
    assert card["from_text"] == got["text"]


def test_a_reading_older_than_the_last_write_says_so() -> None:
    writes = [write(3, "proposal", "verified", 0.12, 2.2, NEWEST - 200.0)]
    # read before the write and not its gains: the tags have not been read since; the PLC's
    # echo of the write's apply number is its newer word, so the written gains are in force
    stale = status(last_write=writes[-1], plc_gains=reading(0.1, 2.0, NEWEST - 500.0))
    got = gains_in_force(stale, writes)
    assert (got["Kc"], got["Ti"], got["source"], got["write_id"]) == (0.12, 2.2, "write", 3)
    assert got["text"] == (
        "last verified write #3: issued at 2026-11-27 09:11:43 CET, verified at 09:11:44 CET; "
        "the PLC's kc and ti tags, last read at 2026-11-27 09:06:43 CET before it, do not show "
        "it yet"
    )
    # read before a write of the very gains they hold (only changes are kept): said, no alarm
    same = status(last_write=writes[-1], plc_gains=reading(0.12, 2.2, NEWEST - 500.0))
    assert gains_in_force(same, writes)["text"] == (
        "the PLC's kc and ti tags as read at 2026-11-27 09:06:43 CET, before the last verified "
        "write #3 at 2026-11-27 09:11:44 CET (the same gains)"
    )


def test_a_card_moves_from_the_gains_in_force_not_the_stored_old_gains() -> None:
    # the proposal was filed against Kc 0.1, Ti 2; a write then a revert happened since
    writes = [
        write(3, "proposal", "verified", 0.12, 2.2, NEWEST - 200.0),
        write(4, "revert", "verified", 0.09, 1.9, NEWEST - 100.0),
    ]
    loop = status(pending_proposals=[proposal(6, "pending")], last_write=writes[-1])
    (card,) = proposal_views(loop, FRESH_WINDOWS, writes)
    assert card["from"] == card["old"] == {"Kc": 0.09, "Ti": 1.9}
    assert card["filed_old"] == {"Kc": 0.1, "Ti": 2.0}
    assert card["from_changed"] is True
    assert card["from_text"].startswith("last verified write #4 (a revert)")
    # the keys the page used before stay
    assert card["new"] == {"Kc": 0.12, "Ti": 2.2}
    assert (card["window_id"], card["stale"]) == (70, None)
    assert card["next"] == card["state_text"] == "waits for an engineer to approve or reject it"
    assert (card["state"], card["state_label"], card["level"]) == (
        "waiting",
        "waits for approval",
        "warn",
    )


def test_an_out_of_date_card_says_why_in_stale() -> None:
    (card,) = proposal_views(status(pending_proposals=[proposal(4, "pending")]), OLD_WINDOWS)
    assert card["state"] == "out_of_date"
    assert card["stale"] is not None
    assert card["next"] == f"out of date, not written: {card['stale']}"


# --- the last written proposal ------------------------------------------------------------


def test_the_last_verified_write_stays_on_the_page() -> None:
    older = proposal(3, "applied")
    older["history"][-1]["time"] = NEWEST - 500.0
    newest = proposal(4, "applied")
    failed_before = proposal(6, "failed")
    failed_before["history"][-1]["time"] = NEWEST - 400.0
    history = {"proposals": [older, newest, proposal(5, "pending"), failed_before]}
    card = last_written_view(status(), history, FRESH_WINDOWS)
    assert card is not None
    assert (card["id"], card["state"], card["actions"]) == (4, "written", [])
    assert card["state_text"] == "written and verified at 2026-11-27 09:14:33 CET"
    assert card["from"] == {"Kc": 0.1, "Ti": 2.0}  # the gains before its write
    assert last_written_view(status(), {"proposals": [proposal(5, "pending")]}) is None
    # a write that failed after it is the newest to reach the PLC: its card says so
    failed_after = proposal(7, "failed")
    failed_after["history"][-1]["time"] = NEWEST + 10.0
    card = last_written_view(status(), {"proposals": [newest, failed_after]}, FRESH_WINDOWS)
    assert card is not None
    assert (card["id"], card["state"]) == (7, "failed")


# --- the link line -------------------------------------------------------------------------


def test_link_up_is_said_only_with_a_fresh_sample() -> None:
    assert link_text(status(), TZ) == "link up (newest sample 0.4 s ago)"
    quiet = status(link={"state": "up", "text": "up (newest sample 9.3 s ago)",
                         "sample_age_s": 9.3, "newest_sample": NEWEST})  # fmt: skip
    assert FRESH_SAMPLE_S < 9.3
    assert link_text(quiet, TZ) == "no new sample for 9.3 s"
    central = status(link={**quiet["link"], "contact_age_s": 12.0})
    assert link_text(central, TZ) == "no new sample for 9.3 s, as of the site's last sync 12 s ago"
    stopped = status(link={"state": "stopped",
                           "text": "service stopped (no beat for 12 s of wall time)",
                           "sample_age_s": 14.0})  # fmt: skip
    assert link_text(stopped, TZ) == "service stopped (no beat for 12 s of wall time)"


def test_a_link_line_past_the_freshness_bound_is_not_in_the_colour_of_a_healthy_link() -> None:
    # the held-out trial saw "no new sample for 5.7 s" in the green of "up" (F7)
    assert link_line_state(status()) == "up"
    quiet = status(link={"state": "up", "text": "up (newest sample 9.3 s ago)",
                         "sample_age_s": 9.3, "newest_sample": NEWEST})  # fmt: skip
    assert link_line_state(quiet) == "unknown"
    assert link_line_state(status(link={"state": "stopped", "sample_age_s": 14.0})) == "stopped"


# --- the revert button ---------------------------------------------------------------------


def test_revert_is_offered_only_when_it_would_change_the_gains() -> None:
    from fuelid.dashboard._loop_page import revert_offer

    good = {"Kc": 0.028, "Ti": 3.43}
    status = {"write_back": {"last_known_good_block": good}}
    offered, gains, _ = revert_offer(status, "approve", {"Kc": 0.035, "Ti": 3.1})
    assert offered
    assert gains == good
    # after a revert the gains in force are the last-known-good ones: nothing to revert to
    offered, _, why = revert_offer(status, "approve", {"Kc": 0.02800001, "Ti": 3.43})
    assert not offered
    assert why == "No revert: the gains in force are the last-known-good ones."
    assert not revert_offer(status, "off", {"Kc": 0.035, "Ti": 3.1})[0]
    assert not revert_offer({}, "approve", {"Kc": 0.035, "Ti": 3.1})[0]
