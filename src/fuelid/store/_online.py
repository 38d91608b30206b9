"""The durable history of the online service, in the store's SQLite file.

The online service re-identifies the loop on a rolling window (every ``identify_every_s``, 300 s
by default) and keeps what it did next to the samples the recorder writes: every window with its
verdict, the models of the accepted ones, the proposed gains and their approval, every write of
gains to the PLC and a little state that must survive a restart. :class:`OnlineHistory` keeps
them, on a connection of its own to the store's file (the recorder's :class:`SampleWriter`
writes samples through the store's connection, from its thread; SQLite's WAL lets both commit
without corrupting or losing each other's work, the busy timeout makes one wait for the other).

Tables: ``windows``, ``models``, ``proposals``, ``writes`` and ``online_state``, described with
their versions in :mod:`fuelid.store._schema` (every store has them since schema 2). Everything
rich (a model, the gates of a window, the history of a proposal)
is JSON text; NaN and ±inf are stored as ``null`` (JSON has neither), numpy scalars and arrays
as plain numbers and lists.

Writes of gains record the intent *before* the PLC is written (:meth:`OnlineHistory.begin_write`,
committed with ``synchronous=FULL``) and the outcome after (:meth:`OnlineHistory.finish_write`),
so that after a crash mid-write :meth:`OnlineHistory.unfinished_writes` tells what to reconcile
against the PLC's echo.

Times are UTC seconds since the Unix epoch [s] on two clocks: every row's ``time`` is plant time
(the samples' time base; a caller that gives none gets the newest committed sample's time,
:meth:`OnlineHistory.plant_now`, or the wall clock in an empty store) and its ``wall_time`` the
wall clock when it was written. ``T_fuel`` in °C (as the samples'
``fuel_temperature`` and the K(T) tracker have it; stored as given), ``u_mean`` in V; the gains
``Kc`` and ``Ti`` in the controller's units (as its registers hold them).
"""

from __future__ import annotations

import time as _time
from collections.abc import Mapping, Sequence
from typing import Any

from fuelid.io.jsonsafe import json_ready
from fuelid.store._online_requests import PersonRequests
from fuelid.store._online_rows import (
    _MODEL,
    PROPOSAL_COLUMNS,
    PROPOSAL_STATUSES,
    PROPOSAL_TRANSITIONS,
    REQUEST_KINDS,
    REQUEST_STATUSES,
    SERVICE_KEY,
    WINDOW_COLUMNS,
    WRITE_KINDS,
    WRITE_STATUSES,
    _check_status,
    _dumps,
    _exists,
    _finite,
    _finite_or_none,
    _gains,
    _loads,
    _model,
    _newest,
    _proposal_by_id,
    history_counts,
    proposal_row,
    window_row,
)
from fuelid.store._online_writes import GainWrites
from fuelid.store._records import StoreError

__all__ = [
    "PROPOSAL_STATUSES",
    "PROPOSAL_TRANSITIONS",
    "REQUEST_KINDS",
    "REQUEST_STATUSES",
    "WRITE_KINDS",
    "WRITE_STATUSES",
    "OnlineHistory",
    "json_ready",
]


class OnlineHistory(GainWrites, PersonRequests):
    """The online service's history in a store's SQLite file, on a connection of its own.

    Every method is one transaction (committed with ``synchronous=FULL`` before it returns) and
    thread-safe (one lock around the connection). The tables exist: opening the store created
    or upgraded them (:mod:`fuelid.store._schema`). The writes of gains are in
    :class:`~fuelid.store._online_writes.GainWrites`, the connection in
    :class:`~fuelid.store._online_rows.HistoryConnection`.

    Parameters
    ----------
    store : SQLiteStore
        An open store (its identity is checked by :class:`SQLiteStore`); only its ``path`` is
        used, the store's own connections are left alone.

    Raises
    ------
    StoreError
        The file cannot be opened (the reason in one line).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from fuelid.store import SQLiteStore
    >>> db = pathlib.Path(tempfile.mkdtemp()) / "loop.db"
    >>> with SQLiteStore(db, site_name="tunnel 2", tag_map_hash="ab12") as store:
    ...     with OnlineHistory(store) as history:
    ...         history.add_window(t_from=0.0, t_to=600.0, accepted=True, reason="ok",
    ...                            T_fuel=293.15, u_mean=2.5, detail={"fit": 91.0},
    ...                            model={"K": 12.0, "T": 0.4}, time=600.5)
    ...         history.accepted_models()[0]["model"]
    (1, 1)
    {'K': 12.0, 'T': 0.4}
    """

    # -- windows and models ---------------------------------------------------------------

    def add_window(
        self,
        *,
        t_from: float,
        t_to: float,
        accepted: bool,
        reason: str,
        T_fuel: float | None,
        u_mean: float | None,
        detail: Mapping[str, Any],
        model: Mapping[str, Any] | None = None,
        time: float | None = None,
    ) -> tuple[int, int | None]:
        """Record one identification window, accepted or not, in one transaction.

        Parameters
        ----------
        t_from, t_to : float
            The window's data span, UTC [s] (``t_from <= t_to``).
        accepted : bool
            Whether the window passed its gates.
        reason : str
            Why it was accepted or refused (one line).
        T_fuel : float or None
            Mean fuel temperature over the window [°C]; None when unknown (NaN is stored as NULL).
        u_mean : float or None
            Mean VFD command over the window [V].
        detail : dict
            Gates, fit, health metrics: stored as JSON (NaN and ±inf as null).
        model : dict, optional
            The identified model (JSON). For an accepted window it is also a row of ``models``
            (with ``t_from``, ``t_to``, ``T_fuel`` and ``time``) whose id the window keeps; for a
            refused window it is not stored (put what matters of it in ``detail``).
        time : float, optional
            When the window was analysed, plant time [s UTC]; by default the newest committed
            sample's time. Never before ``t_to`` (the larger of the two is stored).

        Returns
        -------
        tuple of (int, int or None)
            The window's id and the model's id (None when no model was stored).

        Raises
        ------
        StoreError
            A non-finite or reversed span, a value without a JSON form, a database error.
        """
        t0, t1 = _finite("t_from", t_from), _finite("t_to", t_to)
        if t1 < t0:
            raise StoreError(f"window t_to {t_to} is before t_from {t_from}")
        temperature = _finite_or_none(T_fuel)
        detail_text = _dumps(detail)
        model_text = _dumps(model) if accepted and model is not None else None
        wall = _time.time()
        with self._transaction() as con:
            now = max(t1, self._plant_time(con, time))
            model_id: int | None = None
            if model_text is not None:
                cursor = con.execute(
                    "INSERT INTO models(time, t_from, t_to, T_fuel, model, wall_time) "
                    "VALUES (?, ?, ?, ?, ?, ?)",
                    (now, t0, t1, temperature, model_text, wall),
                )
                model_id = int(cursor.lastrowid or 0)
            cursor = con.execute(
                f"INSERT INTO windows({WINDOW_COLUMNS.removeprefix('id, ')}) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (
                    t0,
                    t1,
                    now,
                    int(bool(accepted)),
                    str(reason),
                    temperature,
                    _finite_or_none(u_mean),
                    model_id,
                    detail_text,
                    wall,
                ),
            )
            window_id = int(cursor.lastrowid or 0)
        return window_id, model_id

    def windows(
        self, t_from: float | None = None, t_to: float | None = None, limit: int | None = None
    ) -> list[dict[str, Any]]:
        """Windows that end in ``[t_from, t_to)`` [s UTC], oldest first (by their ``t_to``).

        Parameters
        ----------
        t_from, t_to : float, optional
            Bounds on each window's end, UTC [s]; None leaves that side open.
        limit : int, optional
            Keep only the newest ``limit`` windows (still oldest first).

        Returns
        -------
        list of dict
            ``id``, ``t_from``, ``t_to``, ``time`` [plant s UTC], ``accepted`` (bool),
            ``reason``, ``T_fuel`` [°C] or None, ``u_mean`` [V] or None, ``model_id`` or None,
            ``detail`` (decoded), ``wall_time`` [wall s UTC] or None.
        """
        where, args = [], []
        if t_from is not None:
            where.append("t_to >= ?")
            args.append(float(t_from))
        if t_to is not None:
            where.append("t_to < ?")
            args.append(float(t_to))
        query = f"SELECT {WINDOW_COLUMNS} FROM windows" + (
            " WHERE " + " AND ".join(where) if where else ""
        )
        sql, more = _newest(query, "t_to, id", limit)
        with self._transaction(write=False) as con:
            rows = con.execute(sql, [*args, *more]).fetchall()
        return [window_row(row) for row in rows]

    def window(self, window_id: int) -> dict[str, Any] | None:
        """One window as :meth:`windows` gives it; None when there is no such id."""
        with self._transaction(write=False) as con:
            row = con.execute(
                f"SELECT {WINDOW_COLUMNS} FROM windows WHERE id = ?", (int(window_id),)
            ).fetchone()
        return None if row is None else window_row(row)

    def windows_of_models(self, model_ids: Sequence[int]) -> list[dict[str, Any]]:
        """The first window naming each of ``model_ids`` (as :meth:`windows` gives it), by id.

        One row per model at most, whatever the windows since (the index on ``model_id``): a
        proposal's evidence, however many windows came after it. Unknown ids give no row.
        """
        ids = sorted({int(i) for i in model_ids})
        if not ids:
            return []
        marks = ", ".join("?" * len(ids))
        sql = (
            f"SELECT {WINDOW_COLUMNS} FROM windows WHERE id IN (SELECT min(id) FROM windows "
            f"WHERE model_id IN ({marks}) GROUP BY model_id) ORDER BY id"
        )
        with self._transaction(write=False) as con:
            rows = con.execute(sql, ids).fetchall()
        return [window_row(row) for row in rows]

    def last_window(self) -> dict[str, Any] | None:
        """The newest window (largest ``t_to``), as :meth:`windows` gives it; None when none."""
        rows = self.windows(limit=1)
        return rows[0] if rows else None

    def accepted_models(self, limit: int | None = None) -> list[dict[str, Any]]:
        """The stored models, oldest first (by the end of their window).

        Parameters
        ----------
        limit : int, optional
            Keep only the newest ``limit`` models.

        Returns
        -------
        list of dict
            ``id``, ``window_id`` (None for a model stored without a window), ``time``,
            ``t_from``, ``t_to`` [plant s UTC], ``T_fuel`` [°C] or None, ``model`` (decoded),
            ``wall_time`` [wall s UTC] or None.
        """
        sql, args = _newest(f"SELECT {_MODEL} FROM models m", "m.t_to, m.id", limit)
        with self._transaction(write=False) as con:
            rows = con.execute(sql, args).fetchall()
        return [_model(row) for row in rows]

    def model(self, model_id: int) -> dict[str, Any] | None:
        """One model as :meth:`accepted_models` gives it; None when there is no such id."""
        with self._transaction(write=False) as con:
            row = con.execute(
                f"SELECT {_MODEL} FROM models m WHERE m.id = ?", (int(model_id),)
            ).fetchone()
        return None if row is None else _model(row)

    # -- proposals ------------------------------------------------------------------------

    def add_proposal(
        self,
        *,
        model_id: int | None,
        old: Mapping[str, Any],
        new: Mapping[str, Any],
        detail: Mapping[str, Any],
        status: str = "pending",
        time: float | None = None,
        who: str = "online",
        why: str = "",
    ) -> int:
        """Record proposed gains.

        Parameters
        ----------
        model_id : int or None
            The model the gains were tuned for (an id of :meth:`accepted_models`).
        old, new : dict
            ``{"Kc": ..., "Ti": ...}`` in the controller's units: the gains in the PLC and the
            proposed ones (``new`` must be finite; its values are also the ``kc``/``ti`` columns).
        detail : dict
            Why (the rule, margins, agreeing windows): JSON.
        status : str
            The first status, one of :data:`PROPOSAL_STATUSES` (``pending`` by default).
        time : float, optional
            Plant time [s UTC]; the newest committed sample's by default.
        who, why : str
            The first entry of the proposal's history (who proposed it and why).

        Returns
        -------
        int
            The proposal's id.

        Raises
        ------
        StoreError
            An unknown status or model, gains without ``Kc``/``Ti``, non-finite new gains.
        """
        _check_status(status)
        old_gains, new_gains = _gains("old", old), _gains("new", new)
        kc, ti = _finite("new Kc", new_gains["Kc"]), _finite("new Ti", new_gains["Ti"])
        wall = _time.time()
        _dumps(detail)  # refused before the transaction when it has no JSON form
        with self._transaction() as con:
            now = self._plant_time(con, time)
            history = [
                {"time": now, "wall_time": wall, "status": status, "who": str(who), "why": str(why)}
            ]
            text = _dumps(
                {"old": old_gains, "new": new_gains, "detail": detail, "history": history}
            )
            if model_id is not None and not _exists(con, "models", model_id):
                raise StoreError(f"no model {model_id} to propose gains for")
            cursor = con.execute(
                "INSERT INTO proposals(time, model_id, kc, ti, status, detail, wall_time) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                (now, None if model_id is None else int(model_id), kc, ti, status, text, wall),
            )
            return int(cursor.lastrowid or 0)

    def proposal(self, proposal_id: int) -> dict[str, Any] | None:
        """One proposal; None when there is no such id.

        Returns
        -------
        dict or None
            ``id``, ``time`` [plant s UTC], ``model_id``, ``status``, ``old``, ``new`` (gains),
            ``detail``, ``history`` (a list of ``{"time", "wall_time", "status", "who",
            "why"}``: plant and wall time) and ``wall_time`` [wall s UTC] or None.
        """
        with self._transaction(write=False) as con:
            return _proposal_by_id(con, proposal_id)

    def proposals(self, status: str | Sequence[str] | None = None) -> list[dict[str, Any]]:
        """Proposals, oldest first, all or those with ``status`` (one or several).

        Returns
        -------
        list of dict
            As :meth:`proposal` gives them.
        """
        query = f"SELECT {PROPOSAL_COLUMNS} FROM proposals"
        args: list[str] = []
        if status is not None:
            args = [status] if isinstance(status, str) else [str(s) for s in status]
            if not args:
                return []
            query += f" WHERE status IN ({', '.join('?' * len(args))})"
        with self._transaction(write=False) as con:
            rows = con.execute(query + " ORDER BY time, id", args).fetchall()
        return [proposal_row(row) for row in rows]

    def set_proposal_status(
        self,
        proposal_id: int,
        status: str,
        *,
        who: str,
        why: str = "",
        time: float | None = None,
    ) -> dict[str, Any]:
        """Move a proposal to ``status`` along :data:`PROPOSAL_TRANSITIONS`; the history grows.

        Parameters
        ----------
        proposal_id : int
            The proposal.
        status : str
            Its next status.
        who : str
            Who decided (an operator's name, ``online``).
        why : str
            Why, one line.
        time : float, optional
            Plant time [s UTC]; the newest committed sample's by default.

        Returns
        -------
        dict
            The updated proposal (as :meth:`proposal` gives it).

        Raises
        ------
        StoreError
            Unknown proposal or status, or a transition that is not allowed
            (``proposal 3 is applied: it cannot be approved``).
        """
        _check_status(status)
        wall = _time.time()
        with self._transaction() as con:
            now = self._plant_time(con, time)
            current = _proposal_by_id(con, proposal_id)
            if current is None:
                raise StoreError(f"no proposal {proposal_id}")
            if status not in PROPOSAL_TRANSITIONS.get(current["status"], frozenset()):
                raise StoreError(
                    f"proposal {proposal_id} is {current['status']}: it cannot be {status}"
                )
            history = [
                *current["history"],
                {
                    "time": now,
                    "wall_time": wall,
                    "status": status,
                    "who": str(who),
                    "why": str(why),
                },
            ]
            text = _dumps(
                {
                    "old": current["old"],
                    "new": current["new"],
                    "detail": current["detail"],
                    "history": history,
                }
            )
            con.execute(
                "UPDATE proposals SET status = ?, detail = ? WHERE id = ?",
                (status, text, int(proposal_id)),
            )
            updated = _proposal_by_id(con, proposal_id)
        assert updated is not None
        return updated

    # -- small durable state --------------------------------------------------------------

    def set_state(self, key: str, value: Any) -> None:
        """Store ``value`` (JSON; NaN as null) under ``key``, replacing what was there.

        For the last-known-good gains, the model the current gains were tuned for, the
        schedule: what the service needs after a restart.
        """
        if not isinstance(key, str) or not key:
            raise StoreError(f"a state key is a non-empty string, got {key!r}")
        text = _dumps(value)
        with self._transaction() as con:
            con.execute(
                "INSERT INTO online_state VALUES (?, ?, ?) ON CONFLICT(key) DO UPDATE "
                "SET value = excluded.value, time = excluded.time",
                (key, text, _time.time()),
            )

    def beat(self, now: float | None = None, key: str = SERVICE_KEY) -> None:
        """Refresh the ``beat`` [wall s UTC] of the service record, one small transaction.

        Only that field changes (``json_set`` in SQL); nothing happens when the record is
        absent (the service writes it whole at its start).
        """
        wall = _time.time() if now is None else float(now)
        with self._transaction() as con:
            con.execute(
                "UPDATE online_state SET value = json_set(value, '$.beat', ?1), time = ?1 "
                "WHERE key = ?2",
                (wall, key),
            )

    def set_record_field(self, name: str, value: Any, key: str = SERVICE_KEY) -> None:
        """Set one field of the service record (``json_set`` in SQL, as :meth:`beat`).

        Nothing happens when the record is absent.
        """
        with self._transaction() as con:
            con.execute(
                "UPDATE online_state SET value = json_set(value, '$.' || ?1, json(?2)) "
                "WHERE key = ?3",
                (name, _dumps(value), key),
            )

    def first_sample_after(self, t: float | None) -> float | None:
        """The plant time of the first sample newer than ``t`` [s UTC] (any, when None); None."""
        query = "SELECT min(time) FROM samples" + ("" if t is None else " WHERE time > ?")
        with self._transaction(write=False) as con:
            value = con.execute(query, () if t is None else (float(t),)).fetchone()[0]
        return None if value is None else float(value)

    def plant_now(self) -> float | None:
        """Plant time now: the newest committed sample's time [s UTC]; None in an empty store."""
        with self._transaction(write=False) as con:
            value = con.execute("SELECT max(time) FROM samples").fetchone()[0]
        return None if value is None else float(value)

    def state(self, key: str, default: Any = None) -> Any:
        """The value stored under ``key`` (decoded); ``default`` when the key was never set."""
        with self._transaction(write=False) as con:
            row = con.execute("SELECT value FROM online_state WHERE key = ?", (key,)).fetchone()
        return default if row is None else _loads(row[0])

    def counts(self) -> dict[str, int]:
        """Counts from one snapshot.

        Returns
        -------
        dict of str to int
            ``windows``, ``accepted``, ``models``, ``proposals`` and ``proposals_<status>`` for
            every status, ``writes`` and ``writes_<status>`` for every write status.
        """
        with self._transaction(write=False) as con:
            windows, accepted = con.execute(
                "SELECT count(*), coalesce(sum(accepted), 0) FROM windows"
            ).fetchone()
            models = con.execute("SELECT count(*) FROM models").fetchone()[0]
            proposals = dict(con.execute("SELECT status, count(*) FROM proposals GROUP BY 1"))
            writes = dict(con.execute("SELECT status, count(*) FROM writes GROUP BY 1"))
        return history_counts(windows, accepted, models, proposals, writes)
