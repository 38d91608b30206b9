"""The service's link to the central store: send the outbox, carry out central requests.

With a ``[central]`` table the service runs :meth:`CentralLink.run` as one more supervised task:
every ``send_every_s`` of wall time one cycle in a thread (``asyncio.to_thread``: the recorder
shares the event loop and never waits on the network):

1. :meth:`Sender.sync <fuelid.central._sender.Sender.sync>`: the outbox in batches of
   ``batch_rows`` (at most :data:`MAX_BATCHES_PER_CYCLE` a cycle, so a long backlog after an
   outage drains over a few cycles without holding the thread), the liveness row;
2. :meth:`CentralLink.requests_cycle`: the central requests for the store
   (:mod:`fuelid.central._requests`) are claimed centrally, then filed locally with
   :func:`~fuelid.online._requests.file_request` (origin ``central:<id>``, who and why kept)
   after checking that the proposal is still as its requester saw it (a revert and the test
   signal's start and stop refer to none); the service's beat applies them like the CLI's and
   the dashboard's; their outcomes are reported back at the next cycle.

A failure (the network, the database, a refused identity) is recorded as an event of the store
once when it starts (``central_error``, with the reason) and once when it ends (``central_ok``),
so the central store learns of its own outages when they end; it is kept in the store's sync
state for ``fuelid online status``, and never stops the task: the next cycle retries. Without
a service, ``fuelid central sync`` runs one cycle with ``apply_now``.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fuelid.central import Sender, SyncResult
from fuelid.online._requests import EXCITE_KINDS, apply_request, file_request
from fuelid.store import OnlineHistory, StoreError

__all__ = [
    "MAX_BATCHES_PER_CYCLE",
    "CentralLink",
    "CycleResult",
    "changed_reason",
    "origin_of",
]

MAX_BATCHES_PER_CYCLE = 20
"""Batches one cycle sends at most (the rest waits for the next cycle)."""


def origin_of(central_id: int) -> str:
    """The origin of the local request filed for central request ``central_id``.

    Examples
    --------
    >>> origin_of(17)
    'central:17'
    """
    return f"central:{int(central_id)}"


def changed_reason(history: OnlineHistory, request: dict[str, Any]) -> str | None:
    """Why the proposal is no longer what the requester saw; None when unchanged.

    Compares the proposal's status and the entries of its history now with the request's
    ``seen_status`` and ``seen_history_len``. None for a request that refers to no proposal: a
    revert and the test signal's start and stop (their site applies them as they come).

    >>> changed_reason(None, {"kind": "excite_start", "proposal_id": None}) is None
    True
    """
    pid = request.get("proposal_id")
    if request.get("kind") in ("revert", *EXCITE_KINDS) or pid is None:
        return None
    proposal = history.proposal(int(pid))
    if proposal is None:
        return f"the site has no proposal {pid}"
    status = str(proposal["status"])
    seen = request.get("seen_status")
    if seen is not None and status != seen:
        return f"proposal {pid} is now {status} (was {seen})"
    entries = len(proposal.get("history") or [])
    seen_len = request.get("seen_history_len")
    if seen_len is not None and entries != int(seen_len):
        return (
            f"proposal {pid} changed since it was seen ({entries} history entries, {seen_len} seen)"
        )
    return None


@dataclass
class CycleResult:
    """One cycle: the send's result and what became of the central requests."""

    sync: SyncResult
    filed: list[dict[str, Any]] = field(default_factory=list)
    reported: list[dict[str, Any]] = field(default_factory=list)
    error: str | None = None


class CentralLink:
    """A loop's link to the central store (see the module docstring).

    Parameters
    ----------
    store_path : str or Path
        The loop's SQLite store.
    central : Central
        The site file's ``[central]`` (url, send_every_s, batch_rows).
    history : OnlineHistory
        The store's online history (the service's own: thread-safe).
    say : callable, optional
        ``say(word, **fields)``: the service's structured log (:meth:`ServiceContext.say`).
    event : callable, optional
        ``event(kind, detail)``: records an event in the store and logs it
        (:meth:`ServiceContext.event`); the start and the end of a failure go there.
    write_back_setting : str, optional
        Given to :func:`~fuelid.online._requests.apply_request` with ``apply_now`` (where a
        revert is refused whatever it says: no service runs to write it).
    """

    def __init__(
        self,
        store_path: str | Path,
        central: Any,
        history: OnlineHistory,
        say: Callable[..., None] | None = None,
        write_back_setting: str | None = None,
        event: Callable[[str, str], None] | None = None,
    ) -> None:
        self.central = central
        self.history = history
        self.say = say
        self.event = event
        self.write_back_setting = write_back_setting
        self.sender = Sender(
            store_path,
            central.url,
            batch_rows=central.batch_rows,
            send_every_s=central.send_every_s,  # the centre tells "no contact" by it
        )
        self._failing: str | None = None

    def cycle(
        self, apply_now: bool = False, max_batches: int | None = MAX_BATCHES_PER_CYCLE
    ) -> CycleResult:
        """Send, then the requests; never raises for a network, database or store failure."""
        import psycopg

        from fuelid.errors import FuelidError

        result = CycleResult(self.sender.sync(max_batches=max_batches))
        result.error = result.sync.error
        if result.error is None:
            try:
                self.requests_cycle(result, apply_now)
            except (psycopg.Error, FuelidError, OSError) as error:
                result.error = self.sender.record_failure(error)
        if result.error is None and (result.filed or result.reported):
            # the requests changed local rows (the request, the proposal): send them now
            again = self.sender.sync(max_batches=max_batches)
            result.sync.sent_rows += again.sent_rows
            result.sync.batches += again.batches
            result.sync.backlog_rows = again.backlog_rows
            result.sync.backlog_oldest_wall = again.backlog_oldest_wall
            result.error = result.sync.error = again.error
        self._log(result)
        return result

    def requests_cycle(self, result: CycleResult, apply_now: bool) -> None:
        """File the store's waiting central requests locally; report the finished ones.

        A request is claimed centrally first (:func:`~fuelid.central._requests.claim`) and filed
        locally only when the claim succeeded: one that expired meanwhile is never applied. A
        claimed request the site has no record of (the filing failed, or the site died between
        the claim and the filing) is refused with that reason, never applied later unreported.
        """
        from fuelid.central import (
            claim,
            fetch_waiting,
            finish_central_request,
            mark_fetched,
        )

        pg = self.sender.connection()
        ident = self.sender.ident
        waiting = fetch_waiting(pg, ident.loop_id, ident.store_uuid)
        for request in waiting:
            local = self._local(request["id"])
            if local is None and request.get("fetched") is not None:
                outcome = "claimed but the site has no record of it"
                finish_central_request(pg, request["id"], "refused", outcome)
                result.reported.append({**request, "status": "refused", "outcome": outcome})
                continue
            if local is None:
                reason = changed_reason(self.history, request)
                if reason is None:
                    if not claim(pg, request["id"], ident.store_uuid):
                        continue  # expired or taken since the fetch: never filed here
                    try:
                        local = file_request(
                            self.history,
                            str(request["kind"]),
                            request.get("proposal_id"),
                            str(request["who"]),
                            str(request["why"]),
                            origin_of(request["id"]),
                        )
                    except StoreError as error:
                        reason = f"claimed but the site could not file it: {error}"
                if reason is not None or local is None:
                    finish_central_request(pg, request["id"], "refused", str(reason))
                    result.reported.append({**request, "status": "refused", "outcome": reason})
                    continue
                result.filed.append(local)
                if apply_now:
                    status, outcome = self._apply_now(local)
                    local = self.history.finish_request(local["id"], status, outcome)
            if request.get("local_id") is None:
                mark_fetched(pg, request["id"], int(local["id"]))
            if local["status"] != "waiting":
                status = "done" if local["status"] == "done" else "refused"
                finish_central_request(pg, request["id"], status, str(local["outcome"]))
                result.reported.append({**request, "status": status, "outcome": local["outcome"]})

    def _local(self, central_id: int) -> dict[str, Any] | None:
        """The local request filed for central request ``central_id`` (by its origin)."""
        return self.history.request_of_origin(origin_of(central_id))

    def _apply_now(self, local: dict[str, Any]) -> tuple[str, str]:
        """Apply a request with no service running (``fuelid central sync``).

        A revert needs a service that writes: recorded now, it would fire unseen at some later
        start; so without one it is refused, and says so. The test signal likewise: a start is
        refused (nothing carries a signal; left for the exciter, it would start unseen at a
        later start), a stop is done at once, as :func:`fuelid.online._requests.apply_request`
        answers with no service: the PLC holds the signal at 0 (its heartbeat rule). Neither
        reads the service record: a stale one (a service that died) must not count as running.
        """
        if local["kind"] == "revert":
            return "refused", "no service runs at the site to write a revert: start it first"
        if local["kind"] == "excite_start":
            return "refused", "no service runs at the site to carry a signal: start it first"
        if local["kind"] == "excite_stop":
            return "done", "no service runs: the PLC holds the signal at 0 (its heartbeat rule)"
        return apply_request(self.history, local, self.write_back_setting)

    def _log(self, result: CycleResult) -> None:
        """An event when a failure starts (or its reason changes) and when it ends."""
        change: tuple[str, str] | None = None
        if result.error is not None and result.error != self._failing:
            change = ("central_error", result.error)
        elif result.error is None and self._failing is not None:
            change = ("central_ok", f"sent again: {result.sync.sent_rows} rows")
        self._failing = result.error
        if change is not None and self.event is not None:
            self.event(*change)
        elif change is not None and self.say is not None:
            self.say("event", kind=change[0], detail=change[1])
        if self.say is None:
            return
        for row in result.reported:
            self.say(
                "request",
                id=row["id"],
                kind=row["kind"],
                status=row["status"],
                outcome=row["outcome"],
                origin="central",
            )

    async def run(self, stopping: asyncio.Event, on_stop: Callable[[], None] | None = None) -> None:
        """A cycle every ``send_every_s`` until ``stopping`` is set; a last one at the end.

        ``on_stop`` (in a thread) runs before the last cycle: the service marks its record
        stopped there, so that the centre learns of a clean stop.
        """
        try:
            while not stopping.is_set():
                await asyncio.to_thread(self.cycle)
                with contextlib.suppress(asyncio.TimeoutError):
                    await asyncio.wait_for(stopping.wait(), float(self.central.send_every_s))
            if on_stop is not None:
                await asyncio.to_thread(on_stop)
            if self._failing is None:  # what the stop wrote; not when the last cycle failed
                await asyncio.to_thread(self.cycle)  # (no wait for a connect timeout at stop)
        finally:
            await asyncio.to_thread(self.sender.close)

    def close(self) -> None:
        """Close the sender's connections."""
        self.sender.close()
