"""The default sample store: one SQLite file in WAL mode.

Durability: ``journal_mode=WAL`` with ``synchronous=FULL``: a commit is on disk when
:meth:`SQLiteStore.append` returns, a crash of the recorder (kill -9) at any moment loses at most
the batch not yet committed and never corrupts the file (SQLite's WAL guarantees, checked by the
kill test). One writer connection, readers on a connection of their own.

The tables, their versions and the migrations that upgrade an older file are in
:mod:`fuelid.store._schema`: opening a store applies the migrations it lacks, and a store written
by a newer fuelid is refused.

Re-flagging (:meth:`SQLiteStore.requalify`, the writer's ``set_quality``): ``UPDATE samples SET
quality = ? WHERE time BETWEEN ? AND ? AND quality = 0`` on the ``samples_time`` index, in the
transaction of the batch it was queued after, so it never races the inserts; the buckets of
``samples_lod`` it touches recount their bad samples in the same transaction.

Every append writes ``wall_time`` (the wall clock at the commit) beside the samples' plant
``time``, and keeps ``samples_lod`` (min/max per bucket, :mod:`fuelid.store._schema`) for the
samples actually inserted.

Opening an existing file: its identity (``application_id`` and the ``meta`` table) is read
before anything is written to it, ``journal_mode=WAL`` included, so that another application's
SQLite file is refused untouched (WAL is a persistent property of the file).
"""

from __future__ import annotations

import math
import re
import sqlite3
import threading
import time as _time
import uuid
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from fuelid.store._base import SampleStore
from fuelid.store._lod import RECOUNT_BAD, UPSERT_LOD, lod_rows, read_lod
from fuelid.store._prune import PruneMixin
from fuelid.store._records import (
    SAMPLE_COLUMNS_SQL,
    Event,
    Quality,
    Requalify,
    Sample,
    SampleArrays,
    StateValue,
    StoreError,
    StoreInfo,
)
from fuelid.store._schema import (
    APPLICATION_ID,
    LOD_LEVELS,
    SCHEMA_VERSION,
    check_not_newer,
    create,
    default_loop_id,
    stored_version,
    upgrade,
)

__all__ = ["APPLICATION_ID", "SCHEMA_VERSION", "SQLiteStore"]

# DO NOTHING only on a duplicate key: a NULL time or a bad quality code still fails the batch
_COLUMNS = SAMPLE_COLUMNS_SQL  # time, seq, u, y, …, quality, excitation, run
_INSERT_SAMPLE = (
    f"INSERT INTO samples({_COLUMNS}, wall_time) "
    f"VALUES ({', '.join('?' * (len(Sample._fields) + 1))}) ON CONFLICT DO NOTHING"
)
_INSERT_EVENT = "INSERT INTO events(time, kind, detail, wall_time) VALUES (?, ?, ?, ?)"
# only samples still OK: a stale or link-down flag says more than "bad value"
_REQUALIFY = "UPDATE samples SET quality = ?3 WHERE time >= ?1 AND time <= ?2 AND quality = 0"
# the same statement as OnlineHistory.set_state: the row's time is the wall clock of the commit
_UPSERT_STATE = (
    "INSERT INTO online_state(key, value, time) VALUES (?, ?, ?) "
    "ON CONFLICT(key) DO UPDATE SET value = excluded.value, time = excluded.time"
)


_LOOP_ID = re.compile(r"[a-z0-9-]{1,40}")


def _connect(path: Path) -> sqlite3.Connection:
    con = sqlite3.connect(path, isolation_level=None, check_same_thread=False, timeout=5.0)
    con.execute("PRAGMA busy_timeout=5000")
    return con


def _range(t_from: float | None, t_to: float | None) -> tuple[str, list[float]]:
    where, args = [], []
    if t_from is not None:
        where.append("time >= ?")
        args.append(float(t_from))
    if t_to is not None:
        where.append("time < ?")
        args.append(float(t_to))
    return (" WHERE " + " AND ".join(where)) if where else "", args


class SQLiteStore(PruneMixin, SampleStore):
    """A sample store in one SQLite file (its tables: :mod:`fuelid.store._schema`).

    Parameters
    ----------
    path : str or Path
        The database file; created (with its directory) when absent.
    site_name : str, optional
        The site's name (``[site] name`` of the site file). Needed to create or write a store.
    tag_map_hash : str, optional
        SHA-256 of the site's tag map (:func:`~fuelid.store._base.tag_map_hash`).
    period_s : float, optional
        The sampling period [s], recorded on creation and used to count gaps without a
        sequence counter.

    Raises
    ------
    StoreError
        The file is not a fuelid store, was written by a newer fuelid, or belongs to another site
        (a ``site_mismatch`` event is then recorded in it).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> db = pathlib.Path(tempfile.mkdtemp()) / "loop.db"
    >>> with SQLiteStore(db, site_name="tunnel 2", tag_map_hash="ab12") as store:
    ...     store.append_samples([Sample(1.7e9, 0, 2.0, 40.0), Sample(1.7e9 + 0.02, 1, 2.0, 40.1)])
    2
    >>> SQLiteStore(db).info().rows
    2
    """

    def __init__(
        self,
        path: str | Path,
        site_name: str | None = None,
        tag_map_hash: str | None = None,
        period_s: float | None = None,
        loop_id: str | None = None,
    ) -> None:
        if loop_id is not None and not _LOOP_ID.fullmatch(loop_id):
            raise StoreError(f"loop_id must match [a-z0-9-]{{1,40}}, got {loop_id!r}")
        self._file = Path(path)
        self.path = str(self._file)
        self._lock = threading.Lock()  # the writer connection
        self._read_lock = threading.Lock()  # the reader connection: reads never wait for a commit
        self._writable = site_name is not None and tag_map_hash is not None
        new = not self._file.exists() or self._file.stat().st_size == 0
        if new and not self._writable:
            raise StoreError(f"{self.path}: no such store (a new store needs the site's identity)")
        if new:
            self._file.parent.mkdir(parents=True, exist_ok=True)
        try:
            self._con = _connect(self._file)
            if not new:
                # identity first, with reads only: nothing (not even WAL) is written to a file
                # that is not a fuelid store. A crash while creating leaves a file without
                # tables (and without the application id): create it again.
                empty = self._con.execute("SELECT count(*) FROM sqlite_schema").fetchone()[0] == 0
                app_id = self._con.execute("PRAGMA application_id").fetchone()[0]
                if empty and app_id in (0, APPLICATION_ID) and self._writable:
                    new = True
                else:
                    self._check_store()
            self._con.execute("PRAGMA journal_mode=WAL")
            self._con.execute("PRAGMA synchronous=FULL")
            if new:
                self._create(str(site_name), str(tag_map_hash), period_s, loop_id)
            else:
                upgrade(self._con, self.path)
            meta = self._check_store()
        except sqlite3.DatabaseError as error:
            self._close_quietly()
            raise StoreError(f"{self.path}: not a fuelid store ({error})") from None
        except StoreError:
            self._close_quietly()
            raise
        self.site_name = meta["site_name"]
        self.tag_map_hash = meta["tag_map_hash"]
        self.schema_version = int(meta["schema_version"])
        self.period_s = float(meta["period_s"]) if "period_s" in meta else None
        self.store_uuid = meta.get("store_uuid")
        self.loop_id = meta.get("loop_id") or default_loop_id(self.site_name)
        if self._writable and (site_name, tag_map_hash) != (self.site_name, self.tag_map_hash):
            reason = (
                f"{self.path}: the store belongs to site {self.site_name!r} (tag map "
                f"{self.tag_map_hash[:12]}), not {site_name!r} (tag map {str(tag_map_hash)[:12]})"
            )
            self._raw_append((), [Event(_time.time(), "site_mismatch", reason)])
            self._close_quietly()
            raise StoreError(reason)
        if (
            self._writable
            and loop_id is not None
            and loop_id != default_loop_id(self.site_name)
            and loop_id != self.loop_id
        ):
            reason = (
                f"{self.path}: the store belongs to loop {self.loop_id!r}, not {loop_id!r} "
                "(the site file's [site] loop_id)"
            )
            self._raw_append((), [Event(_time.time(), "site_mismatch", reason)])
            self._close_quietly()
            raise StoreError(reason)
        self._read_con = _connect(self._file)

    def _create(
        self, site_name: str, tag_map_hash: str, period_s: float | None, loop_id: str | None
    ) -> None:
        meta = {
            "site_name": site_name,
            "tag_map_hash": tag_map_hash,
            "created": repr(_time.time()),
            "store_uuid": uuid.uuid4().hex,
            "loop_id": loop_id or default_loop_id(site_name),
        }
        if period_s is not None:
            meta["period_s"] = repr(float(period_s))
        create(self._con, meta, path=self.path)

    def _check_store(self) -> dict[str, str]:
        con = self._con
        app_id = con.execute("PRAGMA application_id").fetchone()[0]
        has_meta = con.execute(
            "SELECT count(*) FROM sqlite_schema WHERE type = 'table' AND name = 'meta'"
        ).fetchone()[0]
        if app_id != APPLICATION_ID or not has_meta:
            raise StoreError(f"{self.path}: not a fuelid store (an SQLite file of another kind)")
        meta = dict(con.execute("SELECT key, value FROM meta").fetchall())
        version = stored_version(con)
        check_not_newer(version, self.path)
        if version < 1 or "site_name" not in meta or "tag_map_hash" not in meta:
            raise StoreError(f"{self.path}: not a fuelid store (meta table incomplete)")
        return meta

    def _close_quietly(self) -> None:
        for name in ("_con", "_read_con"):
            con = getattr(self, name, None)
            if con is not None:
                con.close()

    def _raw_append(
        self,
        samples: Iterable[Sample],
        events: Iterable[Event],
        requalify: Iterable[Requalify] = (),
        state: Iterable[StateValue] = (),
    ) -> tuple[int, int]:
        """One transaction; (samples added, samples re-flagged).

        Every sample and event gets ``wall_time`` = the wall clock at the commit, and the
        samples actually inserted update ``samples_lod``. Only those: a re-sent duplicate
        (ON CONFLICT DO NOTHING) must not be counted twice, so each sample is inserted on its
        own and kept for the LOD when its ``rowcount`` is 1 (exact whatever the duplicate's
        time: a sequence number re-sent after a PLC restart may carry a newer time, so "newer
        than the newest stored" would not be).
        """
        with self._lock:
            con = self._con
            con.execute("BEGIN IMMEDIATE")
            try:
                wall = _time.time()
                inserted = []
                for sample in samples:
                    if con.execute(_INSERT_SAMPLE, (*sample, wall)).rowcount == 1:
                        inserted.append(sample)
                added = len(inserted)
                for level in LOD_LEVELS:
                    con.executemany(UPSERT_LOD, lod_rows(inserted, level))
                con.executemany(_INSERT_EVENT, ((*event, wall) for event in events))
                changed = 0
                for change in requalify:
                    before = con.total_changes
                    con.execute(_REQUALIFY, change)
                    if con.total_changes > before:
                        changed += con.total_changes - before
                        for level in LOD_LEVELS:
                            con.execute(RECOUNT_BAD, (*change[:2], level))
                con.executemany(_UPSERT_STATE, ((key, text, wall) for key, text in state))
                con.execute("COMMIT")
            except BaseException:
                con.execute("ROLLBACK")
                raise
        return added, changed

    def append(
        self,
        samples: Iterable[Sample] = (),
        events: Iterable[Event] = (),
        requalify: Iterable[Requalify] = (),
        state: Iterable[StateValue] = (),
    ) -> int:
        """Store samples and events, then re-flag and set state, in one committed transaction.

        See :class:`SampleStore`; the re-flag is an indexed ``UPDATE`` (module docstring), the
        state an upsert of ``online_state``.
        """
        return self._write(samples, events, requalify, state)[0]

    def requalify(self, changes: Iterable[Requalify]) -> int:
        """Apply re-flags in one committed transaction; the number of samples changed."""
        return self._write((), (), changes)[1]

    def _write(
        self,
        samples: Iterable[Sample],
        events: Iterable[Event],
        requalify: Iterable[Requalify],
        state: Iterable[StateValue] = (),
    ) -> tuple[int, int]:
        if not self._writable:
            raise StoreError(
                f"{self.path}: opened without the site's identity, so it cannot be written"
            )
        try:
            return self._raw_append(samples, events, requalify, state)
        except sqlite3.IntegrityError as error:
            raise StoreError(f"{self.path}: a sample was refused ({error})") from None
        except sqlite3.ProgrammingError as error:
            raise StoreError(f"{self.path}: a sample has the wrong shape ({error})") from None

    def read(self, t_from: float | None = None, t_to: float | None = None) -> SampleArrays:
        """Samples with ``t_from <= time < t_to`` [s UTC], sorted by time (then seq)."""
        where, args = _range(t_from, t_to)
        with self._read_lock:
            rows = self._read_con.execute(
                f"SELECT {_COLUMNS} FROM samples{where} ORDER BY time, seq", args
            ).fetchall()
        return SampleArrays.from_rows(rows)

    def read_events(self, t_from: float | None = None, t_to: float | None = None) -> list[Event]:
        """Events with ``t_from <= time < t_to`` [s UTC], in time order."""
        where, args = _range(t_from, t_to)
        with self._read_lock:
            rows = self._read_con.execute(
                f"SELECT time, kind, detail FROM events{where} ORDER BY time, rowid", args
            ).fetchall()
        return [Event(*row) for row in rows]

    def read_event_rows(
        self, t_from: float | None = None, t_to: float | None = None
    ) -> list[dict[str, object]]:
        """Events as :meth:`read_events` gives them, with ``wall_time`` (None before schema 3).

        Each a dict: ``time`` [plant s UTC], ``kind``, ``detail``, ``wall_time`` [wall s UTC].
        """
        where, args = _range(t_from, t_to)
        with self._read_lock:
            rows = self._read_con.execute(
                f"SELECT time, kind, detail, wall_time FROM events{where} ORDER BY time, rowid",
                args,
            ).fetchall()
        return [
            dict(zip(("time", "kind", "detail", "wall_time"), row, strict=True)) for row in rows
        ]

    def last_seq(self) -> int | None:
        """The largest stored sequence number, from the index (None when there is none)."""
        with self._read_lock:
            value = self._read_con.execute("SELECT max(seq) FROM samples").fetchone()[0]
        return None if value is None else int(value)

    def first_time(self) -> float | None:
        """The oldest sample time [s UTC], from the time index (None when empty)."""
        with self._read_lock:
            value = self._read_con.execute("SELECT min(time) FROM samples").fetchone()[0]
        return None if value is None else float(value)

    def last_time(self) -> float | None:
        """The newest sample time [s UTC], from the time index (None when empty)."""
        with self._read_lock:
            value = self._read_con.execute("SELECT max(time) FROM samples").fetchone()[0]
        return None if value is None else float(value)

    def newest_sample_clocks(self) -> tuple[float, float] | None:
        """The newest sample's plant ``time`` and ``wall_time`` [s UTC]; None when empty.

        ``wall_time`` is NaN when unknown (a sample written before schema 3).
        """
        with self._read_lock:
            row = self._read_con.execute(
                "SELECT time, wall_time FROM samples ORDER BY time DESC LIMIT 1"
            ).fetchone()
        if row is None:
            return None
        return float(row[0]), math.nan if row[1] is None else float(row[1])

    def last_event(self, kinds: Iterable[str]) -> tuple[float, str, str, float | None] | None:
        """The newest event of one of ``kinds``: (time, kind, detail, wall_time); None if none.

        Newest by plant time, then by the order written.
        """
        names = [str(k) for k in kinds]
        if not names:
            return None
        with self._read_lock:
            row = self._read_con.execute(
                "SELECT time, kind, detail, wall_time FROM events "
                f"WHERE kind IN ({', '.join('?' * len(names))}) "
                "ORDER BY time DESC, rowid DESC LIMIT 1",
                names,
            ).fetchone()
        return None if row is None else (float(row[0]), str(row[1]), str(row[2]), row[3])

    # -- what a live reader reads (the dashboard: newest events, trend, stream) -----------

    @contextmanager
    def _reading(self) -> Iterator[sqlite3.Connection]:
        """The reader connection, locked; an SQLite failure as a one-line StoreError."""
        with self._read_lock:
            try:
                yield self._read_con
            except sqlite3.Error as error:
                raise StoreError(f"{self.path}: {error}") from None

    def newest_events(self, limit: int) -> list[dict[str, object]]:
        """The newest ``limit`` events, oldest first: ``time`` [plant s UTC], ``kind``, ``detail``.

        Read newest first, by the time index (a long store's events are never all read).
        """
        with self._reading() as con:
            rows = con.execute(
                "SELECT time, kind, detail FROM events ORDER BY time DESC, rowid DESC LIMIT ?",
                (int(limit),),
            ).fetchall()
        return [{"time": t, "kind": k, "detail": d} for t, k, d in reversed(rows)]

    def read_lod(self, level: int, t_from: float, t_to: float) -> dict[str, np.ndarray[Any, Any]]:
        """``samples_lod``'s buckets of ``level`` s in ``[t_from, t_to)`` [plant s] as arrays.

        See :func:`fuelid.store._lod.read_lod` (min and max of each series per bucket).
        """
        with self._reading() as con:
            return read_lod(con, level, t_from, t_to)

    def newest_rowid(self) -> int:
        """The insertion mark (rowid) of the newest committed sample; 0 without samples."""
        with self._reading() as con:
            value = con.execute("SELECT max(rowid) FROM samples").fetchone()[0]
        return int(value or 0)

    def samples_after(self, rowid: int, limit: int) -> tuple[int, SampleArrays]:
        """Samples inserted after ``rowid`` (at most ``limit``, in insertion order), new mark.

        The mark comes back unchanged when there are none (see :meth:`newest_rowid`).
        """
        with self._reading() as con:
            rows = con.execute(
                f"SELECT rowid, {_COLUMNS} FROM samples WHERE rowid > ? ORDER BY rowid LIMIT ?",
                (int(rowid), int(limit)),
            ).fetchall()
        if not rows:
            return int(rowid), SampleArrays.from_rows([])
        return int(rows[-1][0]), SampleArrays.from_rows([r[1:] for r in rows])

    def info(self) -> StoreInfo:
        """Rows, time span, gaps, link events and size on disk."""
        with self._read_lock:
            con = self._read_con
            con.execute("BEGIN")  # one snapshot for every count
            try:
                rows, t_first, t_last = con.execute(
                    "SELECT count(*), min(time), max(time) FROM samples"
                ).fetchone()
                # a PLC restart leaves one number out on purpose, at the sample its restart
                # event is timed at: that number is a break, not a missing sample
                seq_gaps, missing = con.execute(
                    "SELECT count(*), coalesce(sum(d - 1 - EXISTS (SELECT 1 FROM events e "
                    "WHERE e.kind = 'restart' AND e.time = g.time)), 0) FROM (SELECT time, "
                    "seq - lag(seq) OVER (ORDER BY seq) AS d FROM samples "
                    "WHERE seq IS NOT NULL) AS g WHERE d > 1"
                ).fetchone()
                time_gaps = 0
                if self.period_s is not None:
                    time_gaps = con.execute(
                        "SELECT count(*) FROM (SELECT time - lag(time) OVER (ORDER BY time) AS d "
                        "FROM samples WHERE seq IS NULL) WHERE d > ?",
                        (1.5 * self.period_s,),
                    ).fetchone()[0]
                quality = dict(
                    con.execute("SELECT quality, count(*) FROM samples GROUP BY quality")
                )
                events = dict(con.execute("SELECT kind, count(*) FROM events GROUP BY kind"))
            finally:
                con.execute("COMMIT")
        size = sum(
            p.stat().st_size
            for p in (self._file, self._file.with_name(self._file.name + "-wal"))
            if p.exists()
        )
        return StoreInfo(
            path=self.path,
            site_name=self.site_name,
            tag_map_hash=self.tag_map_hash,
            schema_version=self.schema_version,
            rows=int(rows),
            t_first=t_first,
            t_last=t_last,
            span_s=0.0 if rows == 0 else float(t_last - t_first),
            gaps=int(seq_gaps) + int(time_gaps),
            missing_samples=int(missing),
            quality={Quality(int(code)).name.lower(): int(n) for code, n in quality.items()},
            events={str(kind): int(n) for kind, n in events.items()},
            size_bytes=size,
        )

    def integrity_check(self) -> str:
        """``PRAGMA integrity_check`` of the file (``"ok"`` when sound)."""
        with self._read_lock:
            return str(self._read_con.execute("PRAGMA integrity_check").fetchone()[0])

    def close(self) -> None:
        """Close both connections (every append is already committed)."""
        with self._lock, self._read_lock:
            self._close_quietly()
