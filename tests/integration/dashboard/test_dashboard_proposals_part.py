"""The loop page's proposals and events parts keep a trace of what people decided (issue 39).

A store made here (no service, no run): windows with their models, a proposal rejected by ana,
one approved by eve, written, then reverted by bob, one pending whose window is older than the
newest ``PART_WINDOWS`` (30) windows, and a restart event among the decisions. The page as
served (``/loops/{id}/parts``, the part the live refresh renders):

- a rejected card says "rejected at … by ana: why", the reverted one who approved it and why,
  then who reverted it and why, newest first, each card once;
- the events table shows those decisions (kind "proposal") among the store's events, in time
  order, without storing anything;
- the pending card keeps its "evidence: window 5" row however many windows came since.
"""

from __future__ import annotations

import re
import sqlite3
from collections.abc import Iterator
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("fastapi")

from fastapi.testclient import TestClient

from fuelid.dashboard import Loops, Security, create_app
from fuelid.dashboard._loop_page import PART_WINDOWS
from fuelid.io import format_time
from fuelid.store import Event, OnlineHistory, SQLiteStore, tag_map_hash

pytestmark = pytest.mark.xdist_group("dashboard")

T0 = 1_795_760_000.0  # plant time [s UTC]: 2026-11-27
SITE = {"site_name": "tunnel 2 fuel loop", "tag_map_hash": tag_map_hash({"flow": "ir:20"})}
MODEL = {"K": 12.5, "T": 0.42, "delay": 0.08}
WINDOWS_AFTER = PART_WINDOWS + 10
"""Windows stored after the pending proposal's: its window is not among the page's newest."""


def _window(history: OnlineHistory, k: int) -> int:
    """Window ``k`` (ending at T0 + 300 k), accepted with a model; the model's id."""
    end = T0 + 300.0 * k
    _, model_id = history.add_window(
        t_from=end - 600.0, t_to=end, accepted=True, reason="all gates passed", T_fuel=20.0,
        u_mean=2.5, detail={}, model={**MODEL, "K": 12.0 + 0.01 * k}, time=end + 1.0,
    )  # fmt: skip
    assert model_id is not None
    return model_id


def _proposal(history: OnlineHistory, model_id: int, t: float) -> int:
    return history.add_proposal(
        model_id=model_id, old={"Kc": 0.10, "Ti": 2.0}, new={"Kc": 0.12, "Ti": 2.2},
        detail={"reason": "2 independent windows agree"}, time=T0 + t, who="online",
    )  # fmt: skip


def _step(history: OnlineHistory, pid: int, status: str, who: str, why: str, t: float) -> None:
    history.set_proposal_status(pid, status, who=who, why=why, time=T0 + t)


@pytest.fixture
def store(tmp_path: Path) -> Path:
    folder = tmp_path / "stores"
    folder.mkdir()
    path = folder / "loop.db"
    with SQLiteStore(path, period_s=0.02, **SITE) as writer, OnlineHistory(writer) as history:
        models = {k: _window(history, k) for k in range(1, 6)}
        rejected = _proposal(history, models[3], 1000.0)
        _step(history, rejected, "rejected", "ana", "not before the run", 1100.0)
        reverted = _proposal(history, models[4], 1110.0)
        _step(history, reverted, "approved", "eve", "the windows agree", 1200.0)
        _step(history, reverted, "writing", "service", "", 1201.0)
        _step(history, reverted, "applied", "service", "echo", 1210.0)
        _step(history, reverted, "reverted", "bob", "the loop hunts", 1300.0)
        _proposal(history, models[5], 1400.0)
        for k in range(6, 6 + WINDOWS_AFTER):
            _window(history, k)
        writer.append(events=[Event(T0 + 1150.0, "restart", "service started")])
    return folder


@pytest.fixture
def client(store: Path) -> Iterator[TestClient]:
    loops = Loops([store])
    try:
        yield TestClient(create_app(loops, Security(None, require_login=False)))
    finally:
        loops.close()


class _Cards(HTMLParser):
    """Each ``div.proposal``'s id, state and text; the events table's rows."""

    def __init__(self) -> None:
        super().__init__()
        self.cards: list[dict[str, Any]] = []
        self.events: list[list[str]] = []
        self._depth = 0  # inside a card: the div nesting
        self._in_events = False
        self._cell: list[str] | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "div" and "proposal" in (a.get("class") or "").split():
            self.cards.append({"id": int(a["data-proposal"] or 0), "state": a["data-state"]})
            self.cards[-1]["text"] = ""
            self._depth = 1
        elif tag == "div" and self._depth:
            self._depth += 1
        if tag == "table" and a.get("id") == "events":
            self._in_events = True
        if self._in_events and tag == "tr":
            self.events.append([])
        if self._in_events and tag == "td":
            self._cell = []

    def handle_endtag(self, tag: str) -> None:
        if tag == "div" and self._depth:
            self._depth -= 1
        if tag == "table":
            self._in_events = False
        if tag == "td" and self._cell is not None:
            self.events[-1].append("".join(self._cell).strip())
            self._cell = None

    def handle_data(self, data: str) -> None:
        if self._depth:
            self.cards[-1]["text"] += data
        if self._cell is not None:
            self._cell.append(data)


def _parts(client: TestClient) -> _Cards:
    """The proposals and events parts as the live refresh gets them, parsed."""
    (row,) = client.get("/api/loops").json()["loops"]
    answer = client.get(f"/loops/{row['loop_id']}/parts")
    assert answer.status_code == 200, answer.text
    parsed = _Cards()
    parsed.feed(answer.json()["html"]["proposals"] + answer.json()["html"]["events"])
    return parsed


def _at(t: float) -> str:
    return format_time(T0 + t, "UTC")


def test_decided_cards_say_who_decided_and_why_newest_first(client: TestClient) -> None:
    cards = _parts(client).cards
    assert [(c["id"], c["state"]) for c in cards] == [
        (3, "waiting"),  # open
        (2, "reverted"),  # decided, newest first
        (1, "rejected"),
    ]
    text = {c["id"]: " ".join(c["text"].split()) for c in cards}
    assert f"rejected at {_at(1100.0)} by ana: not before the run" in text[1]
    assert (
        f"approved at {_at(1200.0)} by eve: the windows agree; written and verified at "
        f"{_at(1210.0)}, reverted at {_at(1300.0)} by bob: the loop hunts"
    ) in text[2]


def test_the_events_table_shows_peoples_decisions_among_the_stores_events(
    client: TestClient, store: Path
) -> None:
    events = [row for row in _parts(client).events if len(row) == 3]
    assert events == [
        [_at(1300.0), "proposal", "#2 reverted by bob: the loop hunts"],
        [_at(1200.0), "proposal", "#2 approved by eve: the windows agree"],
        [_at(1150.0), "restart", "service started"],
        [_at(1100.0), "proposal", "#1 rejected by ana: not before the run"],
    ]
    with sqlite3.connect(store / "loop.db") as con:  # shown, not stored
        assert con.execute("SELECT count(*) FROM events").fetchone() == (1,)


def test_a_cards_evidence_is_found_however_many_windows_came_since(client: TestClient) -> None:
    (row,) = client.get("/api/loops").json()["loops"]
    html = client.get(f"/loops/{row['loop_id']}/parts").json()["html"]["proposals"]
    card = html[html.index('data-proposal="3"') :]
    card = card[: card.index("</div>")]
    assert re.search(r"<th>evidence</th><td><a href=\"[^\"]+/windows/5\">window 5</a>", card)
