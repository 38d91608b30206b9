"""The sync engine: a store's outbox to the central store, batch by batch, exactly once.

:class:`Sender` is synchronous and meant for a thread (the service runs it with
``asyncio.to_thread``; ``fuelid central sync`` calls it directly). One :meth:`Sender.sync`:

1. the outbox is on (:func:`~fuelid.central._outbox.enable_outbox`: the first time, every row
   already in the store is queued: the backfill, once);
2. batches in outbox order (:meth:`Sender.send_once`): in one central transaction holding the
   store's advisory lock (:func:`store_lock`), read at most ``batch_rows`` entries and their
   rows' current values (one per row however often it changed), COPY into staging and upsert
   (:func:`~fuelid.central._ingest.ingest_batch`), commit, and only then delete the sent
   entries locally; the monthly partitions the windows need are created before, in a short
   transaction of their own;
3. the store's liveness row (its service record, the backlog after the send, and what a central
   reader needs to judge the loop as its store would: :class:`~fuelid.central._ingest.SiteView`).

The retention (dropping old months) is the central owner's job (``fuelid central
retention``), not a sender's: a site's clock or settings never decide for the fleet. The
months a sender knows to exist are forgotten with its connection: a month the owner dropped
meanwhile fails one batch (no partition for the row), the failure drops the connection, and the
next cycle creates the month again.

**Exactly once.** An entry leaves the outbox only after the central transaction holding its row
committed; the central upsert keyed by ``(store_uuid, id)`` makes a resend of a committed batch
(a crash, a lost connection between the commit and the local delete) change nothing. Every
change of a row after it was read adds a newer entry, so the last value sent is the last value
written. During an outage the entries wait in the SQLite store (the recorder never waits on the
network); the next sync resumes at the oldest.

**Two senders of one store** (the service and a manual ``fuelid central sync``, which refuses
a store whose service is live, or two by mistake): each batch is read and committed under a
central transaction-level advisory lock keyed by the store's UUID, so their batches never
interleave, and a batch read after another's commit carries values at least as new: a row's
central copy never goes back to an older value. The lock does not order the liveness rows (the
last one sent wins) nor make a second sender useful: it only waits.

**Errors** (network, database, refused identity) are never raised into the caller by
:meth:`Sender.sync`: they are returned in :class:`SyncResult` and kept in the store's sync
state (``online_state`` ``central``: ``last_error``, ``last_error_wall``, ``failing_since``,
``last_ok``), the connection is dropped and the next call reconnects.
"""

from __future__ import annotations

import contextlib
import json
import sqlite3
import time as _time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fuelid.central._connect import CentralError, connect, one_line
from fuelid.central._ingest import (
    SITE_STATE_KEYS,
    SiteView,
    ingest_batch,
    months_of,
    upsert_liveness,
)
from fuelid.central._outbox import (
    Batch,
    Identity,
    backlog,
    delete_sent,
    enable_outbox,
    identity,
    open_store_file,
    read_batch,
    write_state,
)
from fuelid.central._schema import (
    PARTITIONED,
    SITE_TABLES,
    check_schema,
    ensure_partitions,
)
from fuelid.errors import FuelidError

if TYPE_CHECKING:
    import psycopg

__all__ = ["Sender", "SyncResult", "send_once", "store_lock"]

_COLUMNS = {name: [c for c, _ in t.columns] for name, t in SITE_TABLES.items()}


@dataclass
class SyncResult:
    """What one :meth:`Sender.sync` did.

    Attributes
    ----------
    sent_rows : int
        Rows sent (one per changed row, however often it changed).
    batches : int
        Batches committed centrally.
    backfilled : int
        Rows queued by the one-time backfill in this call (0 after the first).
    backlog_rows : int
        Outbox entries still waiting after the call.
    backlog_oldest_wall : float or None
        The oldest waiting entry's wall time [s UTC].
    error : str or None
        Why the call stopped early (one line), None when the outbox was sent.
    """

    sent_rows: int = 0
    batches: int = 0
    backfilled: int = 0
    backlog_rows: int = 0
    backlog_oldest_wall: float | None = None
    error: str | None = None

    def to_json(self) -> dict[str, Any]:
        """The fields as a dictionary."""
        return asdict(self)


def store_lock(pg: psycopg.Connection, store_uuid: str) -> None:
    """Take the store's central advisory lock until the transaction ends (waits for it)."""
    pg.execute("SELECT pg_advisory_xact_lock(hashtext('fuelid store ' || %s))", (store_uuid,))


def send_once(
    lite: sqlite3.Connection,
    pg: psycopg.Connection,
    ident: Identity,
    batch_rows: int,
    known_months: set[tuple[str, float]] | None = None,
) -> tuple[int, int]:
    """Send the oldest batch of the outbox; ``(entries consumed, rows sent)``, (0, 0) when empty.

    Raises whatever fails (psycopg, sqlite3, :class:`CentralError`): nothing was deleted
    locally unless the central transaction committed. The batch is read under the store's lock
    (:func:`store_lock`, the module docstring); a batch with windows of a month whose
    partitions are not known is read again after creating them.

    Parameters
    ----------
    lite : sqlite3.Connection
        :func:`~fuelid.central._outbox.open_store_file`.
    pg : psycopg.Connection
        The central store (schema checked).
    ident : Identity
        The store's identity.
    batch_rows : int
        Outbox entries per batch at most.
    known_months : set, optional
        ``(table, month)`` partitions known to exist (filled here; saves a round trip).
    """
    known = known_months if known_months is not None else set()
    while True:
        with pg.transaction():
            store_lock(pg, ident.store_uuid)
            batch: Batch = read_batch(lite, batch_rows, _COLUMNS)
            if not batch.ids:
                return 0, 0
            months = sorted(months_of(batch.rows.get("windows") or []))
            missing = any((t, m) not in known for t in PARTITIONED for m in months)
            if not missing:
                sent = ingest_batch(pg, ident, batch)  # a savepoint of this transaction
        if not missing:
            break
        with pg.transaction():  # DDL in a transaction of its own: short parent locks
            for table in PARTITIONED:
                ensure_partitions(pg, table, months[0], months[-1])
        known.update((t, m) for t in PARTITIONED for m in months)
    delete_sent(lite, batch.ids)
    return len(batch.ids), sent


class Sender:
    """One store's sync to one central store (see the module docstring).

    Parameters
    ----------
    store_path : str or Path
        The site's SQLite store (schema 4 or newer).
    url : str
        The central store's libpq URL (``[central] url``).
    batch_rows : int
        Outbox entries per batch (``[central] batch_rows``).
    application_name : str, optional
        For ``pg_stat_activity``; ``fuelid sync <loop_id>`` by default.
    send_every_s : float, optional
        The service's send interval [s] (``[central] send_every_s``), told to the centre with
        the liveness; None for a sync by hand.

    Raises
    ------
    StoreError
        The store cannot be opened or has no outbox.
    """

    def __init__(
        self,
        store_path: str | Path,
        url: str,
        *,
        batch_rows: int = 5000,
        application_name: str | None = None,
        send_every_s: float | None = None,
    ) -> None:
        self.url = url
        self.send_every_s = send_every_s
        self.batch_rows = int(batch_rows)
        self.lite = open_store_file(store_path)
        self.ident = identity(self.lite)
        self.application_name = application_name or f"fuelid sync {self.ident.loop_id}"
        self.pg: psycopg.Connection | None = None
        self.known_months: set[tuple[str, float]] = set()
        self._enabled = False

    def connection(self) -> psycopg.Connection:
        """The central connection, opened (and its schema checked) when there is none."""
        if self.pg is None or self.pg.closed:
            pg = connect(self.url, application_name=self.application_name)
            try:
                check_schema(pg)
            except BaseException:
                pg.close()
                raise
            self.pg = pg
            self.known_months.clear()
        return self.pg

    def enable(self) -> int:
        """Switch the store's outbox on; rows queued by the one-time backfill.

        Once per sender: the switch is a write transaction, not worth taking every cycle.
        """
        if self._enabled:
            return 0
        queued = enable_outbox(self.lite)
        self._enabled = True
        return queued

    def send_once(self) -> tuple[int, int]:
        """One batch (:func:`send_once`); raises on any failure."""
        return send_once(
            self.lite, self.connection(), self.ident, self.batch_rows, self.known_months
        )

    def sync(self, max_batches: int | None = None) -> SyncResult:
        """Send the outbox (up to ``max_batches`` batches), then the liveness.

        Never raises for a network, database or store failure: see :class:`SyncResult`.
        """
        import psycopg

        result = SyncResult()
        try:
            result.backfilled = self.enable()
            while max_batches is None or result.batches < max_batches:
                entries, rows = self.send_once()
                if entries == 0:
                    break
                result.batches += 1
                result.sent_rows += rows
            result.backlog_rows, result.backlog_oldest_wall = backlog(self.lite)
            wall = _time.time()
            pg = self.connection()
            upsert_liveness(
                pg,
                self.ident,
                self._service_record(),
                result.backlog_rows,
                result.backlog_oldest_wall,
                wall if result.batches else None,
                self._site_view(wall),
            )
        except (psycopg.Error, sqlite3.Error, FuelidError, OSError) as error:
            result.error = self.record_failure(error)
        else:
            self._record(last_ok=_time.time(), failing_since=None)
        if result.error is not None:
            with contextlib.suppress(sqlite3.Error):
                result.backlog_rows, result.backlog_oldest_wall = backlog(self.lite)
        return result

    def _service_record(self) -> dict[str, Any] | None:
        row = self.lite.execute("SELECT value FROM online_state WHERE key = 'service'").fetchone()
        if row is None:
            return None
        try:
            value = json.loads(row[0])
        except ValueError:
            return None
        return value if isinstance(value, dict) else None

    def _site_view(self, wall: float) -> SiteView:
        """The store's clocks, sampling and state for the liveness row (schema 2)."""
        newest = self.lite.execute(
            "SELECT time, wall_time FROM samples ORDER BY time DESC LIMIT 1"
        ).fetchone()
        first = self.lite.execute("SELECT min(time) FROM samples").fetchone()
        meta = dict(
            self.lite.execute(
                "SELECT key, value FROM meta WHERE key IN ('period_s', 'schema_version')"
            ).fetchall()
        )
        keys = ", ".join("?" * len(SITE_STATE_KEYS))
        state: dict[str, Any] = {}
        for key, value in self.lite.execute(
            f"SELECT key, value FROM online_state WHERE key IN ({keys})", SITE_STATE_KEYS
        ).fetchall():
            with contextlib.suppress(ValueError):  # an unreadable value is left out
                state[str(key)] = json.loads(value)
        return SiteView(
            site_wall=wall,
            send_every_s=self.send_every_s,
            newest_sample_time=None if newest is None else float(newest[0]),
            newest_sample_wall=None if newest is None or newest[1] is None else float(newest[1]),
            first_sample_time=None if first is None or first[0] is None else float(first[0]),
            period_s=_number(meta.get("period_s")),
            schema_version=None if "schema_version" not in meta else int(meta["schema_version"]),
            state=state,
        )

    def record_failure(self, error: BaseException) -> str:
        """Drop the connection, keep the reason (one line) in the sync state."""
        reason = str(error) if isinstance(error, CentralError) else one_line(error)
        if not isinstance(error, CentralError):
            reason = f"{type(error).__name__}: {reason}"
        if self.pg is not None:
            with contextlib.suppress(Exception):  # a broken connection may fail to close
                self.pg.close()
            self.pg = None
        now = _time.time()
        try:
            state = self._state()
            self._record(
                last_error=reason,
                last_error_wall=now,
                failing_since=state.get("failing_since") or now,
            )
        except sqlite3.Error:
            pass
        return reason

    def _state(self) -> dict[str, Any]:
        from fuelid.central._outbox import read_state

        return read_state(self.lite)

    def _record(self, **changes: Any) -> None:
        with contextlib.suppress(sqlite3.Error):  # informative; the sync itself went on
            write_state(self.lite, **changes)

    def close(self) -> None:
        """Close both connections."""
        if self.pg is not None:
            with contextlib.suppress(Exception):  # a connection the server already cut
                self.pg.close()
            self.pg = None
        self.lite.close()

    def __enter__(self) -> Sender:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _number(text: str | None) -> float | None:
    """A meta value as a number; None when absent or not a number."""
    try:
        return None if text is None else float(text)
    except ValueError:
        return None
