"""The proposals people decided stay on the loop page, with who and why (fuelid.dashboard._views).

A rejected proposal's card no longer vanishes at once, nor a superseded one; a written then
reverted card says who approved it and why, and who reverted it and why. The newest
:data:`DECIDED_CARDS` closed proposals are shown newest first (the last one sent to the PLC
too, when older), each once; the people's steps are rows of the events table. Times are plant
time in the site's zone (Europe/Zurich: CET in November).
"""

from __future__ import annotations

from typing import Any

import pytest

pytest.importorskip("fastapi")

from fuelid.dashboard._views import DECIDED_CARDS, decided_views, decision_events

NEWEST = 1_795_767_303.4  # the newest sample [plant s]: 2026-11-27 09:15:03 CET
TZ = "Europe/Zurich"
STATUS = {"link": {"state": "up", "newest_sample": NEWEST}, "timezone": TZ}


def entry(state: str, t: float, who: str = "service", why: str = "") -> dict[str, Any]:
    return {"time": NEWEST + t, "wall_time": NEWEST + t, "status": state, "who": who, "why": why}


def proposal(pid: int, *steps: dict[str, Any]) -> dict[str, Any]:
    """Proposal ``pid`` filed by the service 100 s before NEWEST, then ``steps``."""
    history = [entry("pending", -100.0, "online"), *steps]
    return {"id": pid, "status": history[-1]["status"], "model_id": 7, "time": NEWEST - 100.0,
            "old": {"Kc": 0.1, "Ti": 2.0}, "new": {"Kc": 0.12, "Ti": 2.2},
            "history": history}  # fmt: skip


def reverted(pid: int = 3) -> dict[str, Any]:
    return proposal(
        pid,
        entry("approved", -90.0, "ana", "the windows agree"),
        entry("writing", -89.0),
        entry("applied", -88.0, why="echo"),
        entry("reverted", -60.0, "bob", "the loop hunts"),
    )


def rejected(pid: int = 4, t: float = -50.0) -> dict[str, Any]:
    return proposal(pid, entry("rejected", t, "ana", "not before the run"))


def superseded(pid: int = 5, t: float = -40.0) -> dict[str, Any]:
    why = "the newest evidence points at the gains of #3 (reverted)"
    return proposal(pid, entry("superseded", t, "service", why))


def test_decided_cards_are_the_newest_closed_ones_newest_first_with_who_and_why() -> None:
    pending = proposal(6)
    cards = decided_views(STATUS, {"proposals": [reverted(), rejected(), superseded(), pending]})
    assert [(c["id"], c["state"], c["actions"]) for c in cards] == [
        (5, "superseded", []),
        (4, "rejected", []),
        (3, "reverted", []),
    ]
    texts = [c["state_text"] for c in cards]
    assert texts == [
        "superseded at 2026-11-27 09:14:23 CET by service: the newest evidence points at the "
        "gains of #3 (reverted)",
        "rejected at 2026-11-27 09:14:13 CET by ana: not before the run",
        "approved at 2026-11-27 09:13:33 CET by ana: the windows agree; written and verified at "
        "2026-11-27 09:13:35 CET, reverted at 2026-11-27 09:14:03 CET by bob: the loop hunts",
    ]
    assert cards[0]["from"] == {"Kc": 0.1, "Ti": 2.0}  # the gains it was filed against


def test_an_approval_is_said_on_a_rejected_a_superseded_and_a_failed_card() -> None:
    approved = entry("approved", -90.0, "ana", "try it")
    cards = decided_views(
        STATUS,
        {
            "proposals": [
                proposal(4, approved, entry("rejected", -50.0, "bob", "wrong shift")),
                proposal(5, approved, entry("superseded", -40.0, "service", "a newer proposal")),
                proposal(
                    6, approved, entry("writing", -30.0), entry("failed", -20.0, why="no echo")
                ),
            ]
        },
    )
    said = "approved at 2026-11-27 09:13:33 CET by ana: try it; "
    assert [c["state_text"] for c in cards] == [
        said + "not written: the write failed at 2026-11-27 09:14:43 CET: no echo",
        said + "superseded at 2026-11-27 09:14:23 CET by service: a newer proposal",
        said + "rejected at 2026-11-27 09:14:13 CET by bob: wrong shift",
    ]


def test_the_last_write_stays_when_newer_decisions_fill_the_cards_and_no_card_twice() -> None:
    newer = [superseded(pid, -40.0 + pid) for pid in range(5, 5 + DECIDED_CARDS)]
    cards = decided_views(STATUS, {"proposals": [reverted(), *newer]})
    ids = [c["id"] for c in cards]
    assert ids == [7, 6, 5, 3]  # the newest three, then the last proposal sent to the PLC
    # the last one sent among the newest: once
    cards = decided_views(STATUS, {"proposals": [reverted(), rejected()]})
    assert [c["id"] for c in cards] == [4, 3]
    # a proposal shown among the open cards (the status read a moment before the history) is
    # not shown again
    cards = decided_views(STATUS, {"proposals": [reverted(), rejected()]}, shown=[4])
    assert [c["id"] for c in cards] == [3]
    assert decided_views(STATUS, {"proposals": [proposal(6)]}) == []


def test_the_events_table_gets_the_peoples_decisions_not_the_services_steps() -> None:
    auto = proposal(7, entry("approved", -10.0, "service (write_back = auto)", "passed every rule"))
    rows = decision_events({"proposals": [reverted(), rejected(), superseded(), auto]})
    assert [(row["time"] - NEWEST, row["kind"], row["detail"]) for row in rows] == [
        (-90.0, "proposal", "#3 approved by ana: the windows agree"),
        (-60.0, "proposal", "#3 reverted by bob: the loop hunts"),
        (-50.0, "proposal", "#4 rejected by ana: not before the run"),
    ]
