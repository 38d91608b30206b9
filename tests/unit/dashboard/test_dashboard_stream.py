"""The loop page's event stream: typed change events follow the store, for every subscriber.

A fake loop stands in for the store (the stream reads only ``cursor``, ``samples_after`` and
the status function); the real store and a real browser are in the integration tests.
"""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

from fuelid.dashboard import _stream as stream
from fuelid.store import SampleArrays


class FakeLoop:
    loop_id = "fake"

    def __init__(self) -> None:
        self.counts = {"windows": 1, "accepted": 1, "proposals": 0, "proposals_pending": 0}
        self.state = "up"

    def cursor(self) -> int:
        return 0

    def samples_after(self, cursor: int, limit: int) -> tuple[int, SampleArrays]:
        return cursor, SampleArrays.from_rows([])

    def status(self) -> dict[str, Any]:
        return {"counts": dict(self.counts), "link": {"state": self.state, "service": "running"}}


async def _events_after(loop: FakeLoop, change: Any, wanted: int) -> list[str]:
    """The event types one subscriber gets: a status, then ``change`` applied, then more."""
    feeds = stream.Feeds()
    kinds: list[str] = []
    events = feeds.events(loop, loop.status)  # type: ignore[arg-type]
    async for kind, _ in events:
        kinds.append(kind)
        if kinds.count("status") == 2:
            change(loop)
        if len(kinds) >= wanted:
            break
    await events.aclose()
    return kinds


def _run(loop: FakeLoop, change: Any, wanted: int, monkeypatch: pytest.MonkeyPatch) -> list[str]:
    monkeypatch.setattr(stream, "STATUS_EVERY_S", 0.02)
    monkeypatch.setattr(stream, "POLL_S", 0.005)
    return asyncio.run(asyncio.wait_for(_events_after(loop, change, wanted), timeout=10))


def test_a_filed_proposal_is_a_proposals_event_and_nothing_else(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def file_one(loop: FakeLoop) -> None:
        loop.counts.update(proposals=1, proposals_pending=1)

    kinds = _run(FakeLoop(), file_one, 8, monkeypatch)
    changes = [k for k in kinds if k != "status"]
    assert changes == ["proposals", "history"]  # once, typed, then the catch-all


def test_a_stopped_service_is_an_events_event_and_a_window_a_windows_event(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def stop_after_a_window(loop: FakeLoop) -> None:
        loop.counts.update(windows=2, accepted=2)
        loop.state = "stopped"

    kinds = _run(FakeLoop(), stop_after_a_window, 8, monkeypatch)
    assert [k for k in kinds if k != "status"] == ["windows", "events", "history"]


def test_nothing_changed_is_status_events_only(monkeypatch: pytest.MonkeyPatch) -> None:
    kinds = _run(FakeLoop(), lambda loop: None, 6, monkeypatch)
    assert kinds == ["status"] * 6


def test_a_blip_between_two_status_events_is_an_events_event(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # a link blip shorter than the status interval leaves the state "up" at both ends: the
    # newest stored event tells the page its events table has a new row
    class WithEvents(FakeLoop):
        newest: list[Any] | None = None

        def status(self) -> dict[str, Any]:
            return {**super().status(), "newest_event": self.newest}

    def blip(loop: WithEvents) -> None:
        loop.newest = [100.0, "link_up"]

    kinds = _run(WithEvents(), blip, 8, monkeypatch)
    assert [k for k in kinds if k != "status"] == ["events", "history"]


def test_a_read_that_fails_is_said_and_the_feed_goes_on(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """A failing read must not end the feed: every page would read "disconnected" for good."""

    class Failing(FakeLoop):
        failures = 2

        def samples_after(self, cursor: int, limit: int) -> tuple[int, SampleArrays]:
            if self.failures:
                self.failures -= 1
                raise IndexError("a row shorter than the arrays expect")
            return super().samples_after(cursor, limit)

    kinds = _run(Failing(), lambda loop: None, 4, monkeypatch)
    assert kinds == ["status"] * 4
    failed = [r for r in caplog.records if "live feed of loop fake failed" in r.getMessage()]
    assert len(failed) == 2
