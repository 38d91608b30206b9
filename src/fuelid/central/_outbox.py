"""The site's side of the sync: the outbox of a SQLite store, read, collapsed and emptied.

The store's triggers (:mod:`fuelid.store._schema`, version 4) add an ``outbox(id, tbl, row_id,
wall_time)`` row for every insert and update of the tables of :data:`OUTBOX_TABLES` while
``meta`` ``outbox`` is ``on``. :func:`enable_outbox` switches it on and, once in the store's
life, queues every row already there (the backfill of a site that joins later), in the same
SQLite transaction: a row written before that commit is in the backfill, a row written after
it fires a trigger, so none is missed and none is queued twice. ``meta`` ``outbox_backfilled``
(wall clock [s UTC]) marks it done for ever.

:func:`read_batch` reads the oldest entries (outbox id order) and the rows' current values in
one read transaction (a consistent snapshot: each row at least as new as its entries), one per
row however often it changed; :func:`delete_sent` deletes the entries sent, by id, after the
central store committed them. The sync state (last send, last error) is kept in the
``online_state`` key :data:`STATE_KEY`, which is not in the outbox.

Only the sqlite3 module here: ``fuelid online status`` reads the backlog without psycopg.
"""

from __future__ import annotations

import json
import sqlite3
import time as _time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fuelid.store import OUTBOX_TABLES, StoreError

__all__ = [
    "STATE_KEY",
    "Batch",
    "Identity",
    "backlog",
    "delete_sent",
    "enable_outbox",
    "identity",
    "open_store_file",
    "read_batch",
    "read_state",
    "sync_status",
    "write_state",
]

STATE_KEY = "central"
"""The ``online_state`` key of the sync's state: ``last_ok``, ``last_error``, ``error_since``,
``sent_rows`` (wall clock [s UTC] and counts)."""

_CHUNK = 500  # ids per IN (...) list: under SQLite's 999 host parameters of older builds


@dataclass(frozen=True)
class Identity:
    """A store's identity as the central store keys it (``meta``)."""

    store_uuid: str
    loop_id: str
    site_name: str
    tag_map_hash: str


@dataclass
class Batch:
    """Outbox entries and the current rows they name.

    Attributes
    ----------
    ids : list of int
        The outbox ids read (deleted once sent).
    rows : dict
        By site table: the rows' current values (tuples in the order of the central
        :data:`~fuelid.central._schema.SITE_TABLES` columns), one per row.
    missing : int
        Entries whose row is gone (deleted locally since): nothing to send for them.
    """

    ids: list[int] = field(default_factory=list)
    rows: dict[str, list[tuple[Any, ...]]] = field(default_factory=dict)
    missing: int = 0

    @property
    def row_count(self) -> int:
        """Rows to send."""
        return sum(len(r) for r in self.rows.values())


def open_store_file(path: str | Path) -> sqlite3.Connection:
    """A connection of the sync's own to a fuelid store's file (autocommit, busy timeout 5 s).

    Raises
    ------
    StoreError
        No such file, or not a store of schema 4 or newer (no outbox).
    """
    file = Path(path)
    if not file.is_file():
        raise StoreError(f"{file}: no such store")
    con = sqlite3.connect(file, isolation_level=None, check_same_thread=False, timeout=5.0)
    con.execute("PRAGMA busy_timeout=5000")
    try:
        has = con.execute(
            "SELECT count(*) FROM sqlite_schema WHERE type = 'table' AND name = 'outbox'"
        ).fetchone()[0]
    except sqlite3.DatabaseError as error:
        con.close()
        raise StoreError(f"{file}: not a fuelid store ({error})") from None
    if not has:
        con.close()
        raise StoreError(f"{file}: no outbox (store schema older than 4: open it with fuelid once)")
    return con


def identity(con: sqlite3.Connection) -> Identity:
    """The store's identity from its ``meta`` table."""
    meta = dict(con.execute("SELECT key, value FROM meta").fetchall())
    missing = [k for k in ("store_uuid", "loop_id", "site_name", "tag_map_hash") if k not in meta]
    if missing:
        raise StoreError(f"the store's meta lacks {', '.join(missing)}")
    return Identity(meta["store_uuid"], meta["loop_id"], meta["site_name"], meta["tag_map_hash"])


def enable_outbox(con: sqlite3.Connection) -> int:
    """Switch the outbox on; the first time, queue every existing row (backfill). Rows queued.

    One ``BEGIN IMMEDIATE`` transaction: the switch, the backfill and its mark commit together.
    Calling it again queues nothing (``meta`` ``outbox_backfilled`` is set).
    """
    now = _time.time()
    con.execute("BEGIN IMMEDIATE")
    try:
        meta = dict(con.execute("SELECT key, value FROM meta").fetchall())
        queued = 0
        if "outbox_backfilled" not in meta:
            for table in OUTBOX_TABLES:
                cursor = con.execute(
                    "INSERT INTO outbox(tbl, row_id, wall_time) "
                    f"SELECT ?, rowid, ? FROM {table} ORDER BY rowid",
                    (table, now),
                )
                queued += max(cursor.rowcount, 0)
            con.execute("INSERT INTO meta VALUES ('outbox_backfilled', ?)", (repr(now),))
        if meta.get("outbox") != "on":
            con.execute(
                "INSERT INTO meta VALUES ('outbox', 'on') "
                "ON CONFLICT(key) DO UPDATE SET value = excluded.value"
            )
        con.execute("COMMIT")
    except BaseException:
        con.execute("ROLLBACK")
        raise
    return queued


def read_batch(con: sqlite3.Connection, limit: int, columns: Mapping[str, Sequence[str]]) -> Batch:
    """The oldest ``limit`` outbox entries and their rows' current values, in one snapshot.

    Parameters
    ----------
    con : sqlite3.Connection
        :func:`open_store_file`.
    limit : int
        Entries at most (``[central] batch_rows``).
    columns : dict
        By site table, the columns to read (the site's names, ``id`` first).
    """
    batch = Batch()
    con.execute("BEGIN")  # a read transaction: entries and rows from one snapshot
    try:
        entries = con.execute(
            "SELECT id, tbl, row_id FROM outbox ORDER BY id LIMIT ?", (int(limit),)
        ).fetchall()
        wanted: dict[str, set[int]] = {}
        for entry_id, table, row_id in entries:
            batch.ids.append(int(entry_id))
            wanted.setdefault(str(table), set()).add(int(row_id))
        for table, ids in wanted.items():
            if table not in columns:
                raise StoreError(f"outbox entry of an unknown table {table!r}")
            cols = ", ".join(columns[table])
            ordered = sorted(ids)
            found: list[tuple[Any, ...]] = []
            for k in range(0, len(ordered), _CHUNK):
                part = ordered[k : k + _CHUNK]
                found += con.execute(
                    f"SELECT {cols} FROM {table} WHERE rowid IN ({', '.join('?' * len(part))}) "
                    "ORDER BY rowid",
                    part,
                ).fetchall()
            batch.rows[table] = found
            batch.missing += len(ordered) - len(found)
    finally:
        con.execute("COMMIT")
    return batch


def delete_sent(con: sqlite3.Connection, ids: Sequence[int]) -> None:
    """Delete the outbox entries sent (one transaction)."""
    con.execute("BEGIN IMMEDIATE")
    try:
        for k in range(0, len(ids), _CHUNK):
            part = list(ids[k : k + _CHUNK])
            con.execute(f"DELETE FROM outbox WHERE id IN ({', '.join('?' * len(part))})", part)
        con.execute("COMMIT")
    except BaseException:
        con.execute("ROLLBACK")
        raise


def backlog(con: sqlite3.Connection) -> tuple[int, float | None]:
    """Entries waiting in the outbox and the oldest one's wall time [s UTC] (None when empty)."""
    row = con.execute("SELECT count(*), min(wall_time) FROM outbox").fetchone()
    return int(row[0]), (None if row[1] is None else float(row[1]))


def read_state(con: sqlite3.Connection) -> dict[str, Any]:
    """The sync's state (:data:`STATE_KEY`); empty before the first sync."""
    row = con.execute("SELECT value FROM online_state WHERE key = ?", (STATE_KEY,)).fetchone()
    if row is None:
        return {}
    try:
        value = json.loads(row[0])
    except ValueError:
        return {}
    return value if isinstance(value, dict) else {}


def write_state(con: sqlite3.Connection, **changes: Any) -> dict[str, Any]:
    """Merge ``changes`` into the sync's state; the state after."""
    state = {**read_state(con), **changes}
    con.execute(
        "INSERT INTO online_state(key, value, time) VALUES (?, ?, ?) "
        "ON CONFLICT(key) DO UPDATE SET value = excluded.value, time = excluded.time",
        (STATE_KEY, json.dumps(state, allow_nan=False), _time.time()),
    )
    return state


def sync_status(con: sqlite3.Connection, now: float | None = None) -> dict[str, Any]:
    """The sync as ``fuelid online status`` shows it (wall clock [s UTC], ages [s]).

    Keys: ``outbox`` ("on" or "off"), ``backlog_rows``, ``backlog_oldest_wall``,
    ``backlog_age_s``, ``last_ok`` (the last sync that sent everything), ``last_error`` (one
    line, None when none), ``last_error_wall``, ``failing_since`` (None while syncs succeed).
    """
    when = _time.time() if now is None else float(now)
    row = con.execute("SELECT value FROM meta WHERE key = 'outbox'").fetchone()
    rows, oldest = backlog(con)
    state = read_state(con)
    return {
        "outbox": "on" if row is not None and row[0] == "on" else "off",
        "backlog_rows": rows,
        "backlog_oldest_wall": oldest,
        "backlog_age_s": None if oldest is None else max(0.0, when - oldest),
        "last_ok": state.get("last_ok"),
        "last_error": state.get("last_error"),
        "last_error_wall": state.get("last_error_wall"),
        "failing_since": state.get("failing_since"),
    }
