"""The live stream of a loop page: one server-sent-event stream per page, typed events.

Browsers allow six HTTP/1.1 connections per site across all tabs, so a page opens one stream
(``/api/loops/{id}/stream``) and every chart listens to the event types it needs:

- ``samples``: the samples committed since the last event (``t`` [plant s], ``y``,
  ``setpoint`` [L/min], ``u`` [V], ``fuel_temperature`` [°C], ``quality``; NaN as null),
  every ``POLL_S``;
- ``status``: the loop's state (``link`` as ``online status`` gives it, the fleet chips), every
  ``STATUS_EVERY_S`` and at once on connecting;
- ``windows``, ``proposals``, ``writes``: that part of the store changed (a window judged, a
  proposal filed, approved, written or superseded, a write made or verified); ``events``: a new
  event was stored (a link blip too short to change the link's state between two status events)
  or the link's or the service's state changed (a start, a stop). The data is the store's
  counts; the page re-reads the parts it shows (:func:`changed_topics`);
- ``excitation``: the test signal's state changed (a burst started or ended, what holds one
  off, the windows it reached, its measured cost): the fleet row's ``excitation`` note, which
  the status event carries, differs from the previous one. The state lives in the service's
  ``online_state`` record, not in the counts, so it has a topic of its own; the data is the
  counts, as for the others, and the page re-reads its parts. How long a burst has run is not
  a change: the page advances it from each status event's newest sample;
- ``history``: any of the above (kept for pages and tools written before the typed events).

One ``Feed`` per loop reads the store for all its subscribers (three browsers cost the
store what one does), in a worker thread so that the event loop never waits on SQLite, and only
while someone listens.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator, Callable
from typing import Any

from fuelid.dashboard._source import LoopReader
from fuelid.io.jsonsafe import json_ready

_LOGGER = logging.getLogger(__name__)

__all__ = ["MAX_BATCH", "POLL_S", "STATUS_EVERY_S", "TOPICS", "Feed", "Feeds", "changed_topics"]

POLL_S = 0.2
"""Interval between reads of new samples [s] (the latency a sample adds beyond its commit)."""
STATUS_EVERY_S = 2.0
"""Interval between status events [s]."""
MAX_BATCH = 5000
"""Samples per read at most (a page that connects late gets the backlog in pieces)."""
QUEUE_EVENTS = 256
"""Events kept for a slow subscriber; beyond, the oldest are dropped (a tab in the background)."""
TOPICS = ("windows", "proposals", "writes", "events", "excitation")
"""The typed change events, in the order they are sent."""


def _state_of(status: dict[str, Any]) -> tuple[Any, Any, Any]:
    link = status.get("link") or {}
    return link.get("state"), link.get("service"), status.get("newest_event")


def changed_topics(before: dict[str, Any] | None, after: dict[str, Any]) -> list[str]:
    """The :data:`TOPICS` whose part of the store differs between two status events' data.

    ``before`` None (the first status): nothing changed.

    >>> a = {"counts": {"windows": 1, "proposals_pending": 0}, "link": {"state": "up"}}
    >>> b = {"counts": {"windows": 2, "proposals_pending": 1}, "link": {"state": "stopped"}}
    >>> changed_topics(a, b)
    ['windows', 'proposals', 'events']
    >>> changed_topics(a, a), changed_topics(None, b)
    ([], [])
    >>> changed_topics(a, {**a, "excitation": {"state": "running"}})
    ['excitation']
    """
    if before is None:
        return []
    old, new = before.get("counts") or {}, after.get("counts") or {}

    def moved(prefix: str) -> bool:
        keys = {k for k in (*old, *new) if k.startswith(prefix)}
        return any(old.get(k) != new.get(k) for k in keys)

    out = [
        t
        for t, p in (("windows", "windows"), ("proposals", "proposals"), ("writes", "writes"))
        if moved(p) or (t == "windows" and moved("accepted"))
    ]
    if _state_of(before) != _state_of(after):
        out.append("events")
    if before.get("excitation") != after.get("excitation"):
        out.append("excitation")  # the exciter's record, not counted: compared as the note
    return out


class Feed:
    """Reads one loop's new samples and state for every subscriber of its stream.

    Parameters
    ----------
    loop : LoopReader
        The loop.
    status : callable
        Returns the ``status`` event's data (run in a worker thread).
    """

    def __init__(self, loop: LoopReader, status: Callable[[], dict[str, Any]]) -> None:
        self.loop = loop
        self._status = status
        self._queues: set[asyncio.Queue[tuple[str, Any]]] = set()
        self._task: asyncio.Task[None] | None = None
        self.last_status: dict[str, Any] | None = None
        self.reads = 0
        self._previous: dict[str, Any] | None = None  # the last status, for its changes
        self._next_status = 0.0  # the event loop's time of the next status event [s]

    def subscribe(self) -> asyncio.Queue[tuple[str, Any]]:
        """A queue of (event type, data) for a new subscriber; starts reading when needed."""
        queue: asyncio.Queue[tuple[str, Any]] = asyncio.Queue(QUEUE_EVENTS)
        self._queues.add(queue)
        if self._task is None or self._task.done():
            self._task = asyncio.get_running_loop().create_task(self._run())
        return queue

    def unsubscribe(self, queue: asyncio.Queue[tuple[str, Any]]) -> None:
        """Forget a subscriber; the reading stops with the last one."""
        self._queues.discard(queue)
        if not self._queues and self._task is not None:
            self._task.cancel()
            self._task = None

    def _publish(self, kind: str, data: Any) -> None:
        for queue in list(self._queues):
            if queue.full():
                with contextlib.suppress(asyncio.QueueEmpty):
                    queue.get_nowait()
            queue.put_nowait((kind, data))

    async def _run(self) -> None:
        cursor = await asyncio.to_thread(self.loop.cursor)
        while self._queues:
            try:
                cursor = await self._step(cursor)
            except Exception:  # any failure: said, then tried again; never a silent stop
                # a feed that dies leaves every page "disconnected" with nothing in the log
                _LOGGER.exception("the live feed of loop %s failed; retrying", self.loop.loop_id)
                await asyncio.sleep(STATUS_EVERY_S)

    async def _step(self, cursor: int) -> int:
        """One read of the new samples, and the status when it is due; the new cursor."""
        clock = asyncio.get_running_loop().time
        cursor, batch = await asyncio.to_thread(self.loop.samples_after, cursor, MAX_BATCH)
        self.reads += 1
        if len(batch):
            self._publish(
                "samples",
                {
                    "t": json_ready(batch.time),
                    "y": json_ready(batch.y),
                    "setpoint": json_ready(batch.setpoint),
                    "u": json_ready(batch.u),
                    "fuel_temperature": json_ready(batch.fuel_temperature),
                    "quality": batch.quality.tolist(),
                },
            )
        if clock() >= self._next_status:
            self._next_status = clock() + STATUS_EVERY_S
            status = await asyncio.to_thread(self._status)
            self.last_status = status
            self._publish("status", status)
            topics = changed_topics(self._previous, status)
            for topic in topics:
                self._publish(topic, status.get("counts"))
            if topics:
                self._publish("history", status.get("counts"))
            self._previous = status
        if len(batch) < MAX_BATCH:
            await asyncio.sleep(POLL_S)
        return cursor


class Feeds:
    """One :class:`Feed` per loop id."""

    def __init__(self) -> None:
        self._feeds: dict[str, Feed] = {}

    def get(self, loop: LoopReader, status: Callable[[], dict[str, Any]]) -> Feed:
        """The loop's feed (made on first use)."""
        feed = self._feeds.get(loop.loop_id)
        if feed is None or feed.loop is not loop:
            feed = self._feeds[loop.loop_id] = Feed(loop, status)
        return feed

    async def events(
        self, loop: LoopReader, status: Callable[[], dict[str, Any]]
    ) -> AsyncIterator[tuple[str, Any]]:
        """(event type, data) for one subscriber, the current status first."""
        feed = self.get(loop, status)
        queue = feed.subscribe()
        try:
            if feed.last_status is not None:
                yield "status", feed.last_status
            while True:
                yield await queue.get()
        finally:
            feed.unsubscribe(queue)
