"""Retention of a SQLite store: raw samples kept so long, older ones thinned or deleted.

:class:`PruneMixin` gives :class:`~fuelid.store._sqlite.SQLiteStore` its ``prune``: windows of
about an hour of data per transaction (the writer never waits long), a sample's age by the older
of its two clocks (:data:`AGE`), and with an archive only the samples of days archived and read
back (:func:`fuelid.store._archived.prunable_spans`), written before the day's archiving.
"""

from __future__ import annotations

import math
import sqlite3
import threading
import time as _time

from fuelid.store._archived import prunable_spans
from fuelid.store._records import PruneResult, StoreError

__all__ = ["AGE", "DAY", "PRUNE_WINDOW_S", "PruneMixin"]

DAY = 86400.0
PRUNE_WINDOW_S = 3600.0
"""Samples pruned per transaction [s of data]."""
AGE = "min(time, coalesce(wall_time, time))"
"""What retention compares with its cutoff: the older of a sample's two clocks [s UTC]."""
_AGE = AGE
_COUNT = "SELECT count(*) FROM samples WHERE time >= ? AND time < ?"
_DELETE_LOD = "DELETE FROM samples_lod WHERE bucket >= ? AND bucket + level <= ?"


class PruneMixin:
    """``prune`` for a store with a writer and a reader connection (see the module docstring)."""

    path: str
    loop_id: str
    _writable: bool
    _lock: threading.Lock
    _read_lock: threading.Lock
    _con: sqlite3.Connection
    _read_con: sqlite3.Connection

    def prune(
        self,
        older_than_days: float,
        thin_to_period_s: float | None = 1.0,
        now: float | None = None,
        archived_only: bool = False,
    ) -> PruneResult:
        """Keep raw samples ``older_than_days`` [d]; of older ones the first per period [s].

        With ``archived_only`` (an archive is configured) only the samples of days archived and
        read back are thinned or deleted (:func:`fuelid.store._archived.prunable_spans`); the
        old samples kept because they are not archived are counted in the result. A ``prune``
        event records what was done. The file does not shrink (SQLite reuses the freed pages
        for new samples).
        """
        if not (math.isfinite(older_than_days) and older_than_days >= 0.0):
            raise StoreError(f"retention must be a non-negative number of days: {older_than_days}")
        if thin_to_period_s is not None and not thin_to_period_s > 0.0:
            raise StoreError(f"thinning period must be positive, got {thin_to_period_s} s")
        if not self._writable:
            raise StoreError(f"{self.path}: opened without the site's identity, cannot prune")
        cutoff = (_time.time() if now is None else float(now)) - older_than_days * DAY
        # a sample's age is by the wall clock where known (coalesce(wall_time, time)), and by
        # its plant time when that is older still (a replayed log's samples are written today
        # with their own old times: counted back from the log's newest, as before). An
        # accelerated virtual PLC's plant time runs ahead of the wall clock: then the wall
        # clock rules. The windows below walk plant time, up to the plant time of the cutoff.
        plant_cut = self._plant_at_wall(cutoff)
        with self._read_lock:
            first = self._read_con.execute("SELECT min(time) FROM samples").fetchone()[0]
        # one transaction per window of about an hour (whole thinning periods), so that the
        # writer never waits long for the lock
        step = 1.0 if thin_to_period_s is None else thin_to_period_s
        window = step * math.ceil(PRUNE_WINDOW_S / step)
        spans = [(-math.inf, math.inf, math.inf)]
        if archived_only:
            with self._read_lock:
                spans = prunable_spans(self._read_con, self.loop_id, plant_cut)
        deleted = 0
        t = plant_cut if first is None else math.floor(first / step) * step
        while t < plant_cut:
            t_end = min(t + window, plant_cut)
            for a, b, written_before in spans:  # the window's parts that may be pruned
                if max(a, t) < min(b, t_end):
                    deleted += self._prune_window(
                        max(a, t), min(b, t_end), thin_to_period_s, cutoff, written_before
                    )
            t = t_end
        with self._lock:
            con = self._con
            for a, b, _ in spans:  # thinning keeps the LOD rows: they summarise
                if thin_to_period_s is None and a < plant_cut:
                    con.execute(_DELETE_LOD, (a, min(b, plant_cut)))
            kept = int(con.execute(_COUNT, (-math.inf, plant_cut)).fetchone()[0])
            how = "none" if thin_to_period_s is None else f"one per {thin_to_period_s} s"
            # the retention as an age, as the other events say a time (a blip's length, a time
            # without a link): the event's row is dated in plant time in the site's zone, and a
            # wall-clock date in UTC beside it would give the events table a second clock
            detail = (
                f"samples older than {older_than_days:g} d: {deleted} deleted, {kept} kept ({how})"
            )
            unarchived = 0
            if archived_only:
                unarchived = kept - sum(
                    int(con.execute(_COUNT, (a, min(b, plant_cut))).fetchone()[0])
                    for a, b, _ in spans
                    if a < plant_cut
                )
                detail += f"; {unarchived} of them not archived"
            con.execute(
                "INSERT INTO events(time, kind, detail, wall_time) "
                "VALUES ((SELECT coalesce(max(time), ?1) FROM samples), 'prune', ?2, ?1)",
                (_time.time(), detail),
            )
        return PruneResult(cutoff, deleted, kept - unarchived, unarchived)

    def _plant_at_wall(self, cutoff: float) -> float:
        """The plant time before which samples were written before ``cutoff`` [wall s].

        A bisection over the time index (the wall clock grows with plant time within a
        recording): the age (:data:`_AGE`) of the first sample at or after a plant time.
        """
        with self._read_lock:
            con = self._read_con
            first, last = con.execute("SELECT min(time), max(time) FROM samples").fetchone()
            if first is None:
                return cutoff

            def wall_at(t: float) -> float:
                row = con.execute(
                    f"SELECT {_AGE} FROM samples WHERE time >= ? ORDER BY time LIMIT 1",
                    (t,),
                ).fetchone()
                return math.inf if row is None else float(row[0])

            if wall_at(last) < cutoff:
                return math.nextafter(float(last), math.inf)
            if wall_at(first) >= cutoff:
                return float(first)
            lo, hi = float(first), float(last)
            for _ in range(64):
                if hi - lo <= 1e-4:
                    break
                mid = 0.5 * (lo + hi)
                if wall_at(mid) < cutoff:
                    lo = mid
                else:
                    hi = mid
            # the first young sample's own time: every sample before it is old
            row = con.execute(
                "SELECT time FROM samples WHERE time >= ? ORDER BY time LIMIT 1", (hi,)
            ).fetchone()
            return hi if row is None else float(row[0])

    def _prune_window(
        self,
        t_from: float,
        t_to: float,
        thin_to_period_s: float | None,
        cutoff: float,
        written_before: float = math.inf,
    ) -> int:
        """Delete (or thin) the samples in ``[t_from, t_to)`` [plant s] older than ``cutoff``.

        Thinning keeps one per period [s]; ``cutoff`` is compared with :data:`_AGE`; only rows
        written before ``written_before`` [wall s] (the day's archiving) go; committed.
        """
        with self._lock:
            con = self._con
            con.execute("BEGIN IMMEDIATE")
            try:
                before = con.total_changes
                if thin_to_period_s is None:
                    con.execute(
                        "DELETE FROM samples WHERE time >= ?1 AND time < ?2 "
                        f"AND {_AGE} < ?3 AND coalesce(wall_time, 0) < ?4",
                        (t_from, t_to, cutoff, written_before),
                    )
                else:
                    con.execute(
                        "DELETE FROM samples WHERE time >= ?1 AND time < ?2 "
                        f"AND {_AGE} < ?4 AND coalesce(wall_time, 0) < ?5 AND rowid NOT IN ("
                        "SELECT rowid FROM (SELECT rowid, row_number() OVER (PARTITION BY "
                        "CAST(floor(time / ?3) AS INTEGER) ORDER BY time) AS k "
                        "FROM samples WHERE time >= ?1 AND time < ?2) WHERE k = 1)",
                        (t_from, t_to, float(thin_to_period_s), cutoff, written_before),
                    )
                deleted = con.total_changes - before
                con.execute("COMMIT")
            except BaseException:
                con.execute("ROLLBACK")
                raise
        return int(deleted)
