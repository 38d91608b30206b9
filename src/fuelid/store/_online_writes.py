"""The writes of gains to the PLC in the online history: intent first, outcome after.

:meth:`GainWrites.begin_write` commits the intent (with ``synchronous=FULL``) *before* the PLC
is written and :meth:`GainWrites.finish_write` the outcome after, so that after a crash
mid-write :meth:`GainWrites.unfinished_writes` tells what to reconcile against the PLC's echo.
The gains ``kc`` and ``ti`` are in the controller's units; times in UTC seconds [s]: ``time``
and ``finished`` plant time (the newest committed sample's by default), ``wall_time`` and
``finished_wall`` the wall clock.
"""

from __future__ import annotations

import operator
import time as _time
from collections.abc import Mapping
from typing import Any

from fuelid.store._online_rows import (
    WRITE_COLUMNS,
    WRITE_KINDS,
    WRITE_STATUSES,
    HistoryConnection,
    _dumps,
    _exists,
    _finite,
    _newest,
    _write_by_id,
    write_row,
)
from fuelid.store._records import StoreError

__all__ = ["GainWrites"]


class GainWrites(HistoryConnection):
    """The ``writes`` table: every write of gains, its intent and its outcome."""

    def begin_write(
        self,
        *,
        kind: str,
        kc: float,
        ti: float,
        apply_seq: int,
        who: str,
        why: str,
        proposal_id: int | None = None,
        time: float | None = None,
    ) -> int:
        """Record the intent to write gains, durably, before the PLC is written.

        One write at a time: while a write is still an ``intent`` another is refused (finish or
        reconcile it first, :meth:`unfinished_writes`).

        Parameters
        ----------
        kind : str
            One of :data:`WRITE_KINDS`; ``proposal`` needs ``proposal_id``.
        kc, ti : float
            The gains to write, in the controller's units (finite).
        apply_seq : int
            The apply sequence number written with them; never used before (see
            :meth:`last_apply_seq`).
        who, why : str
            Who asked for the write and why.
        proposal_id : int, optional
            The proposal written (or reverted).
        time : float, optional
            Plant time [s UTC]; the newest committed sample's by default.

        Returns
        -------
        int
            The write's id, committed to disk when this returns.

        Raises
        ------
        StoreError
            Unknown kind or proposal, non-finite gains, an ``apply_seq`` already used, another
            write still an intent.
        """
        if kind not in WRITE_KINDS:
            raise StoreError(f"unknown write kind {kind!r}; known: {', '.join(WRITE_KINDS)}")
        if kind == "proposal" and proposal_id is None:
            raise StoreError("a write of kind 'proposal' needs its proposal_id")
        try:
            seq = operator.index(apply_seq)  # an integer (numpy's too), not a float
        except TypeError:
            seq = None
        if seq is None or isinstance(apply_seq, bool):
            raise StoreError(f"apply_seq must be an integer, got {apply_seq!r}")
        values = (_finite("kc", kc), _finite("ti", ti), seq)
        wall = _time.time()
        with self._transaction() as con:
            now = self._plant_time(con, time)
            if proposal_id is not None and not _exists(con, "proposals", proposal_id):
                raise StoreError(f"no proposal {proposal_id} to write")
            row = con.execute(
                "SELECT id, apply_seq FROM writes WHERE status = 'intent' ORDER BY id LIMIT 1"
            ).fetchone()
            if row is not None:
                raise StoreError(
                    f"write {row[0]} (apply_seq {row[1]}) is still an intent: "
                    "finish or reconcile it first"
                )
            row = con.execute("SELECT id FROM writes WHERE apply_seq = ?", (values[2],)).fetchone()
            if row is not None:
                raise StoreError(f"apply_seq {apply_seq} was already used by write {row[0]}")
            cursor = con.execute(
                f"INSERT INTO writes({WRITE_COLUMNS.removeprefix('id, ')}) "
                "VALUES (?, ?, ?, ?, ?, ?, 'intent', ?, ?, '{}', NULL, ?, NULL)",
                (
                    now,
                    None if proposal_id is None else int(proposal_id),
                    kind,
                    *values,
                    str(who),
                    str(why),
                    wall,
                ),
            )
            return int(cursor.lastrowid or 0)

    def finish_write(
        self,
        write_id: int,
        status: str,
        detail: Mapping[str, Any] | None = None,
        time: float | None = None,
    ) -> dict[str, Any]:
        """Record the outcome of a write that is still an intent.

        Parameters
        ----------
        write_id : int
            The write (:meth:`begin_write`).
        status : str
            ``verified``, ``failed`` or ``not_applied``.
        detail : dict, optional
            The echo read back, the error: JSON.
        time : float, optional
            When it finished, plant time [s UTC] (the ``finished`` field); the newest committed
            sample's by default. ``finished_wall`` is the wall clock.

        Returns
        -------
        dict
            The updated write (as :meth:`write` gives it).

        Raises
        ------
        StoreError
            Unknown write or status, or a write already finished.
        """
        if status not in WRITE_STATUSES[1:]:
            raise StoreError(f"a write finishes as {', '.join(WRITE_STATUSES[1:])}, not {status!r}")
        text = _dumps({} if detail is None else detail)
        wall = _time.time()
        with self._transaction() as con:
            now = self._plant_time(con, time)
            current = _write_by_id(con, write_id)
            if current is None:
                raise StoreError(f"no write {write_id}")
            if current["status"] != "intent":
                raise StoreError(
                    f"write {write_id} is {current['status']}: only an intent can be finished"
                )
            con.execute(
                "UPDATE writes SET status = ?, detail = ?, finished = ?, finished_wall = ? "
                "WHERE id = ?",
                (status, text, now, wall, int(write_id)),
            )
            updated = _write_by_id(con, write_id)
        assert updated is not None
        return updated

    def write(self, write_id: int) -> dict[str, Any] | None:
        """One write; None when there is no such id.

        Returns
        -------
        dict or None
            ``id``, ``time`` [s UTC], ``proposal_id``, ``kind``, ``kc``, ``ti``, ``apply_seq``,
            ``status``, ``who``, ``why``, ``detail`` (decoded), ``finished`` [plant s UTC] or
            None, ``wall_time`` and ``finished_wall`` [wall s UTC] or None.
        """
        with self._transaction(write=False) as con:
            return _write_by_id(con, write_id)

    def writes(self, limit: int | None = None) -> list[dict[str, Any]]:
        """Writes, oldest first; ``limit`` keeps the newest ``limit``."""
        sql, args = _newest(f"SELECT {WRITE_COLUMNS} FROM writes", "id", limit)
        with self._transaction(write=False) as con:
            rows = con.execute(sql, args).fetchall()
        return [write_row(row) for row in rows]

    def unfinished_writes(self) -> list[dict[str, Any]]:
        """Writes still an ``intent`` (a crash between the intent and its outcome), oldest first."""
        with self._transaction(write=False) as con:
            rows = con.execute(
                f"SELECT {WRITE_COLUMNS} FROM writes WHERE status = 'intent' ORDER BY id"
            ).fetchall()
        return [write_row(row) for row in rows]

    def last_apply_seq(self) -> int | None:
        """The largest ``apply_seq`` ever recorded (intents included); None before any write."""
        with self._transaction(write=False) as con:
            value = con.execute("SELECT max(apply_seq) FROM writes").fetchone()[0]
        return None if value is None else int(value)
