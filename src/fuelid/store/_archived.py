"""The store's side of the raw archive: its UTC days, their raw rows, the days archived.

The archive (:mod:`fuelid.archive`) reads a store one UTC day at a time, straight from SQL so
that a NULL stays a NULL (:class:`~fuelid.store._records.SampleArrays` turns it into NaN), and
records each day it wrote and read back in ``archived_days`` (:mod:`fuelid.store._schema`).
Retention with an archive (:meth:`SQLiteStore.prune <fuelid.store._sqlite.SQLiteStore.prune>`
with ``archived_only``) deletes or thins only the samples of :func:`prunable_spans`: days
archived with at least as many rows as the store now holds for them and no sample written
since (a row that arrived after the day was archived is kept until it is archived too).

Every function takes a connection of the caller's and runs short statements on it: reads use
the time index, one day at a time; a write is one small transaction. :class:`StoreDays` is the
archive's connection of its own to a store's file, with the reads it needs (a day's counts in
one snapshot, its raw rows and events, the store's identity and service record).
"""

from __future__ import annotations

import json
import math
import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = [
    "ARCHIVE_COLUMNS",
    "DAY_S",
    "StoreDays",
    "archived_days",
    "day_start",
    "days_with",
    "prunable_spans",
    "record_day",
    "sample_batches",
]

DAY_S = 86400.0
"""A UTC day [s]: day ``d`` is ``d * DAY_S <= time < (d + 1) * DAY_S`` (the epoch is midnight)."""

ARCHIVE_COLUMNS = (
    "time",
    "wall_time",
    "seq",
    "u",
    "y",
    "setpoint",
    "fuel_temperature",
    "mode",
    "quality",
    "excitation",
    "run",
)
"""The ``samples`` columns in the order of the archive's files (``fuelid.archive._layout``)."""


def day_start(day: int) -> float:
    """The plant time [s UTC] at which UTC day number ``day`` (days since the epoch) begins."""
    return day * DAY_S


def days_with(con: sqlite3.Connection, table: str) -> list[int]:
    """The UTC day numbers on which ``table`` ("samples" or "events") has rows, ascending.

    One index lookup per day (the next row at or after the next midnight), so a month of 50 Hz
    samples costs some thirty lookups, not a scan.
    """
    if table not in ("samples", "events"):
        raise ValueError(f"table must be samples or events, not {table!r}")
    days: list[int] = []
    row = con.execute(f"SELECT min(time) FROM {table}").fetchone()
    while row is not None and row[0] is not None:
        day = math.floor(float(row[0]) / DAY_S)
        days.append(day)
        row = con.execute(
            f"SELECT min(time) FROM {table} WHERE time >= ?", (day_start(day + 1),)
        ).fetchone()
    return days


def sample_batches(
    con: sqlite3.Connection, t_from: float, t_to: float, size: int = 200_000
) -> Iterator[list[tuple[object, ...]]]:
    """The raw samples rows of ``t_from <= time < t_to`` [plant s], by time then seq.

    Columns :data:`ARCHIVE_COLUMNS`, NULL as None; yielded ``size`` rows at a time so that a
    day at 50 Hz (4.32 M rows) is never held as Python tuples at once. The caller holds the
    read transaction (one snapshot for the day).
    """
    cursor = con.execute(
        f"SELECT {', '.join(ARCHIVE_COLUMNS)} FROM samples WHERE time >= ? AND time < ? "
        "ORDER BY time, seq",
        (t_from, t_to),
    )
    while rows := cursor.fetchmany(size):
        yield rows


def archived_days(con: sqlite3.Connection, loop_id: str) -> dict[str, tuple[int, float, str]]:
    """The days recorded as archived: date → (samples, wall_time [s UTC], path)."""
    rows = con.execute(
        "SELECT date, samples, wall_time, path FROM archived_days WHERE loop_id = ?", (loop_id,)
    ).fetchall()
    return {str(d): (int(n), float(w), str(p)) for d, n, w, p in rows}


def record_day(
    con: sqlite3.Connection,
    loop_id: str,
    date: str,
    samples: int,
    t_first: float | None,
    t_last: float | None,
    path: str,
    wall_time: float,
) -> None:
    """Record (or update) one archived day in its own committed transaction.

    ``wall_time`` [s UTC] is the wall clock when the day's rows were read: a sample written at
    or after it may be missing from the file, so retention keeps it (:func:`prunable_spans`).
    """
    con.execute("BEGIN IMMEDIATE")
    try:
        con.execute(
            "INSERT INTO archived_days(loop_id, date, samples, t_first, t_last, path, wall_time) "
            "VALUES (?, ?, ?, ?, ?, ?, ?) ON CONFLICT(loop_id, date) DO UPDATE SET "
            "samples = excluded.samples, t_first = excluded.t_first, t_last = excluded.t_last, "
            "path = excluded.path, wall_time = excluded.wall_time",
            (loop_id, date, samples, t_first, t_last, path, wall_time),
        )
        con.execute("COMMIT")
    except BaseException:
        con.execute("ROLLBACK")
        raise


def prunable_spans(
    con: sqlite3.Connection, loop_id: str, before: float = math.inf
) -> list[tuple[float, float, float]]:
    """The plant-time spans [s UTC] whose samples retention may delete with an archive.

    A day qualifies when it is in ``archived_days`` with at least as many rows as the store
    holds for it now and no sample of the day has a ``wall_time`` at or after the day's
    archiving (so neither a late row nor a re-sent one is lost). Only days that begin before
    ``before`` [plant s UTC] (retention's cutoff) are checked: each check reads the day's rows.
    Ascending ``(start, end, archived_wall)``: retention deletes only rows written before
    ``archived_wall`` [wall s UTC], so a row that arrives between this check and the delete is
    kept (it is not in the file).
    """
    import datetime as _dt

    spans = []
    for date, (samples, wall, _path) in sorted(archived_days(con, loop_id).items()):
        start = _dt.datetime.fromisoformat(date).replace(tzinfo=_dt.UTC).timestamp()
        end = start + DAY_S
        if start >= before:
            continue
        count, newer = con.execute(
            "SELECT count(*), coalesce(sum(wall_time >= ?), 0) FROM samples "
            "WHERE time >= ? AND time < ?",
            (wall, start, end),
        ).fetchone()
        if int(count) <= samples and int(newer) == 0:
            spans.append((start, end, float(wall)))
    return spans


class StoreDays:
    """A store's file read for the archive, one UTC day at a time, on a connection of its own.

    Autocommit: each read is a statement of its own unless inside :meth:`snapshot`, so that a
    recorder writing the store meanwhile is never held up for long (WAL readers never block
    its commits). SQLite's errors pass through (:class:`sqlite3.Error`): the archive says which
    store it could not read.

    Parameters
    ----------
    path : str
        The store's file (opened by :class:`~fuelid.store._sqlite.SQLiteStore` before: its
        tables are the current schema's).
    """

    def __init__(self, path: str) -> None:
        self.path = path
        self._con = sqlite3.connect(
            path, isolation_level=None, check_same_thread=False, timeout=5.0
        )
        self._con.execute("PRAGMA busy_timeout=5000")

    def close(self) -> None:
        """Close the connection."""
        self._con.close()

    @contextmanager
    def snapshot(self) -> Iterator[None]:
        """Every read inside sees one moment of the store (one read transaction)."""
        self._con.execute("BEGIN")
        try:
            yield
        finally:
            if self._con.in_transaction:
                self._con.execute("COMMIT")

    def meta(self) -> dict[str, str]:
        """The store's ``meta`` table (``loop_id``, ``store_uuid``, ``site_name``, …)."""
        return dict(self._con.execute("SELECT key, value FROM meta").fetchall())

    def newest_time(self) -> float | None:
        """The newest sample's time [plant s UTC]; None without samples."""
        value = self._con.execute("SELECT max(time) FROM samples").fetchone()[0]
        return None if value is None else float(value)

    def sample_count(self) -> int:
        """The samples the store holds."""
        return int(self._con.execute("SELECT count(*) FROM samples").fetchone()[0])

    def days_with(self, table: str) -> list[int]:
        """The UTC day numbers with rows in ``table`` (:func:`days_with`)."""
        return days_with(self._con, table)

    def archived_days(self, loop_id: str) -> dict[str, tuple[int, float, str]]:
        """The days recorded as archived (:func:`archived_days`)."""
        return archived_days(self._con, loop_id)

    def day_counts(self, start: float, end: float, since: float) -> tuple[int, int, int]:
        """(samples, samples written since, events written since) of one day.

        The day is ``start <= time < end`` [plant s UTC]; "since" is at or after ``since``
        [wall s UTC].
        """
        count, newer = self._con.execute(
            "SELECT count(*), coalesce(sum(wall_time >= ?), 0) FROM samples "
            "WHERE time >= ? AND time < ?",
            (since, start, end),
        ).fetchone()
        new_events = self._con.execute(
            "SELECT count(*) FROM events WHERE time >= ? AND time < ? AND wall_time >= ?",
            (start, end, since),
        ).fetchone()[0]
        return int(count), int(newer), int(new_events)

    def sample_batches(self, start: float, end: float) -> Iterator[list[tuple[object, ...]]]:
        """The raw sample rows of ``start <= time < end`` in batches (:func:`sample_batches`)."""
        return sample_batches(self._con, start, end)

    def event_rows(self, start: float, end: float) -> list[tuple[Any, ...]]:
        """The events of ``start <= time < end`` [plant s UTC]: (time, kind, detail, wall_time)."""
        rows: list[tuple[Any, ...]] = self._con.execute(
            "SELECT time, kind, detail, wall_time FROM events WHERE time >= ? AND time < ? "
            "ORDER BY time, id",
            (start, end),
        ).fetchall()
        return rows

    def record_day(
        self,
        loop_id: str,
        date: str,
        samples: int,
        t_first: float | None,
        t_last: float | None,
        path: str,
        wall_time: float,
    ) -> None:
        """Record one archived day (:func:`record_day`)."""
        record_day(self._con, loop_id, date, samples, t_first, t_last, path, wall_time)

    def state_value(self, key: str) -> Any:
        """The ``online_state`` value of ``key`` decoded; None when absent or not JSON."""
        row = self._con.execute("SELECT value FROM online_state WHERE key = ?", (key,)).fetchone()
        if row is None:
            return None
        try:
            return json.loads(row[0])
        except ValueError:
            return None
