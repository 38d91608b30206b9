"""The durable history of the online service, in the store's SQLite file.

The online service re-identifies the loop on a rolling window (every ``identify_every_s``, 300 s
by default) and keeps what it did next to the samples the recorder writes: every window with its
verdict, the models of the accepted ones, the proposed gains and their approval, every write of
gains to the PLC and a little state that must survive a restart. :class:`OnlineHistory` keeps
them, on a connection of its own to the store's file (the recorder's :class:`SampleWriter`
writes samples through the store's connection, from its thread; SQLite's WAL lets both commit
without corrupting or losing each other's work, the busy timeout makes one wait for the other).

Tables (see the schema in :mod:`fuelid.store.sqlite`): ``windows``, ``writes`` and
``online_state`` are created on first use (``CREATE TABLE IF NOT EXISTS``, STRICT, the schema
version stays 1: older fuelid ignores them); ``models`` and ``proposals``, reserved in schema 1,
are used as they are. Everything rich (a model, the gates of a window, the history of a proposal)
is JSON text; NaN and ±inf are stored as ``null`` (JSON has neither), numpy scalars and arrays
as plain numbers and lists.

Writes of gains record the intent *before* the PLC is written (:meth:`OnlineHistory.begin_write`,
committed with ``synchronous=FULL``) and the outcome after (:meth:`OnlineHistory.finish_write`),
so that after a crash mid-write :meth:`OnlineHistory.unfinished_writes` tells what to reconcile
against the PLC's echo.

Times are UTC seconds since the Unix epoch [s]; ``T_fuel`` in °C (as the samples'
``fuel_temperature`` and the K(T) tracker have it; stored as given), ``u_mean`` in V; the gains
``Kc`` and ``Ti`` in the controller's units (as its registers hold them).
"""

from __future__ import annotations

import json
import math
import operator
import sqlite3
import threading
import time as _time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from types import MappingProxyType, TracebackType
from typing import Any, Self

from fuelid.io.jsonsafe import json_ready
from fuelid.store.base import StoreError
from fuelid.store.sqlite import SQLiteStore

__all__ = [
    "PROPOSAL_STATUSES",
    "PROPOSAL_TRANSITIONS",
    "WRITE_KINDS",
    "WRITE_STATUSES",
    "OnlineHistory",
    "json_ready",
]

PROPOSAL_TRANSITIONS: Mapping[str, frozenset[str]] = MappingProxyType(
    {
        "pending": frozenset({"approved", "rejected", "superseded", "writing"}),
        "approved": frozenset({"writing", "rejected", "superseded"}),
        "writing": frozenset({"applied", "failed"}),
        "applied": frozenset({"reverted"}),
        "failed": frozenset(),
        "rejected": frozenset(),
        "superseded": frozenset(),
        "reverted": frozenset(),
    }
)
"""The status a proposal may take next, by its status (an empty set: the status is final)."""

PROPOSAL_STATUSES = tuple(PROPOSAL_TRANSITIONS)
"""Every status of a proposal."""

WRITE_KINDS = ("proposal", "revert", "restore")
"""What a write of gains is: a proposal's gains, a revert to the gains before, or a restore of
the last-known-good gains."""

WRITE_STATUSES = ("intent", "verified", "failed", "not_applied")
"""``intent`` until :meth:`OnlineHistory.finish_write` records the outcome: ``verified`` (the PLC
echoes the gains), ``failed`` (the write failed or the echo disagrees), ``not_applied`` (the PLC
never saw it, found when reconciling after a crash)."""

_TABLES = """
CREATE TABLE IF NOT EXISTS models(
    id INTEGER PRIMARY KEY, time REAL NOT NULL, t_from REAL, t_to REAL, T_fuel REAL,
    model TEXT NOT NULL
) STRICT;
CREATE TABLE IF NOT EXISTS proposals(
    id INTEGER PRIMARY KEY, time REAL NOT NULL, model_id INTEGER REFERENCES models(id),
    kc REAL, ti REAL, status TEXT NOT NULL, detail TEXT NOT NULL
) STRICT;
CREATE TABLE IF NOT EXISTS windows(
    id INTEGER PRIMARY KEY, time REAL NOT NULL, t_from REAL NOT NULL, t_to REAL NOT NULL,
    accepted INTEGER NOT NULL CHECK (accepted IN (0, 1)), reason TEXT NOT NULL,
    T_fuel REAL, u_mean REAL, model_id INTEGER REFERENCES models(id), detail TEXT NOT NULL
) STRICT;
CREATE INDEX IF NOT EXISTS windows_t_to ON windows(t_to);
CREATE INDEX IF NOT EXISTS windows_model ON windows(model_id) WHERE model_id IS NOT NULL;
CREATE TABLE IF NOT EXISTS writes(
    id INTEGER PRIMARY KEY, time REAL NOT NULL, proposal_id INTEGER REFERENCES proposals(id),
    kind TEXT NOT NULL, kc REAL NOT NULL, ti REAL NOT NULL, apply_seq INTEGER NOT NULL UNIQUE,
    status TEXT NOT NULL, who TEXT NOT NULL, why TEXT NOT NULL, detail TEXT NOT NULL,
    finished REAL
) STRICT;
CREATE TABLE IF NOT EXISTS online_state(
    key TEXT PRIMARY KEY, value TEXT NOT NULL, time REAL NOT NULL
) STRICT;
"""

_WINDOW = "id, t_from, t_to, time, accepted, reason, T_fuel, u_mean, model_id, detail"
_MODEL = (
    "m.id, (SELECT w.id FROM windows w WHERE w.model_id = m.id ORDER BY w.id LIMIT 1) "
    "AS window_id, m.time, m.t_from, m.t_to, m.T_fuel, m.model"
)
_WRITE = "id, time, proposal_id, kind, kc, ti, apply_seq, status, who, why, detail, finished"


def _dumps(value: Any) -> str:
    try:
        plain = json_ready(value)
    except TypeError as exc:
        raise StoreError(f"cannot be stored as JSON: {exc}") from None
    return json.dumps(plain, allow_nan=False, separators=(",", ":"))


def _loads(text: str | None) -> Any:
    return None if text is None else json.loads(text)


def _finite_or_none(value: float | None) -> float | None:
    if value is None:
        return None
    x = float(value)
    return x if math.isfinite(x) else None


def _finite(name: str, value: Any) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise StoreError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(x):
        raise StoreError(f"{name} must be finite, got {value!r}")
    return x


def _gains(name: str, gains: Mapping[str, Any]) -> dict[str, Any]:
    if not isinstance(gains, Mapping) or "Kc" not in gains or "Ti" not in gains:
        raise StoreError(f"{name} gains must be a mapping with 'Kc' and 'Ti', got {gains!r}")
    return dict(gains)


def _now(time: float | None) -> float:
    return _time.time() if time is None else _finite("time", time)


def _newest(query: str, order: str, limit: int | None) -> tuple[str, list[Any]]:
    """``query`` ordered oldest first by ``order``, keeping the newest ``limit`` rows."""
    if limit is None:
        return f"{query} ORDER BY {order}", []
    if isinstance(limit, bool) or not isinstance(limit, int) or limit < 0:
        raise StoreError(f"limit must be a non-negative integer, got {limit!r}")
    desc = ", ".join(f"{column} DESC" for column in order.split(", "))
    plain = ", ".join(column.split(".")[-1] for column in order.split(", "))
    return f"SELECT * FROM ({query} ORDER BY {desc} LIMIT ?) ORDER BY {plain}", [limit]


class OnlineHistory:
    """The online service's history in a store's SQLite file, on a connection of its own.

    Every method is one transaction (committed with ``synchronous=FULL`` before it returns) and
    thread-safe (one lock around the connection). The ``models``/``proposals`` tables of schema 1
    are used as they are, ``windows``, ``writes`` and ``online_state`` are created when absent.

    Parameters
    ----------
    store : SQLiteStore
        An open store (its identity is checked by :class:`SQLiteStore`); only its ``path`` is
        used, the store's own connections are left alone.

    Raises
    ------
    StoreError
        The file cannot be opened or its tables created (the reason in one line).

    Examples
    --------
    >>> import tempfile, pathlib
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

    def __init__(self, store: SQLiteStore) -> None:
        self.path = store.path
        self._lock = threading.Lock()
        self._con: sqlite3.Connection | None = None
        try:
            con = sqlite3.connect(
                self.path, isolation_level=None, check_same_thread=False, timeout=5.0
            )
        except sqlite3.Error as error:
            raise StoreError(f"{self.path}: cannot open the online history ({error})") from None
        try:
            con.execute("PRAGMA busy_timeout=5000")
            con.execute("PRAGMA synchronous=FULL")
            con.execute("BEGIN IMMEDIATE")
            try:
                for statement in _TABLES.split(";"):
                    if statement.strip():
                        con.execute(statement)
                con.execute("COMMIT")
            except BaseException:
                con.execute("ROLLBACK")
                raise
        except sqlite3.Error as error:
            con.close()
            raise StoreError(f"{self.path}: cannot create the online history ({error})") from None
        self._con = con

    # -- plumbing -------------------------------------------------------------------------

    def close(self) -> None:
        """Close the connection (every change is already committed); closing twice is fine."""
        with self._lock:
            if self._con is not None:
                self._con.close()
                self._con = None

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    @contextmanager
    def _transaction(self, write: bool = True) -> Iterator[sqlite3.Connection]:
        """The connection, locked, in one transaction (``BEGIN IMMEDIATE`` to write)."""
        with self._lock:
            con = self._con
            if con is None:
                raise StoreError(f"{self.path}: the online history is closed")
            try:
                con.execute("BEGIN IMMEDIATE" if write else "BEGIN")
                try:
                    yield con
                    con.execute("COMMIT")
                except BaseException:
                    con.execute("ROLLBACK")
                    raise
            except sqlite3.Error as error:
                raise StoreError(f"{self.path}: online history: {error}") from None

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
            When the window was analysed, UTC [s]; now by default.

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
        now = _now(time)
        temperature = _finite_or_none(T_fuel)
        detail_text = _dumps(detail)
        model_text = _dumps(model) if accepted and model is not None else None
        with self._transaction() as con:
            model_id: int | None = None
            if model_text is not None:
                cursor = con.execute(
                    "INSERT INTO models(time, t_from, t_to, T_fuel, model) VALUES (?, ?, ?, ?, ?)",
                    (now, t0, t1, temperature, model_text),
                )
                model_id = int(cursor.lastrowid or 0)
            cursor = con.execute(
                f"INSERT INTO windows({_WINDOW.removeprefix('id, ')}) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
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
            ``id``, ``t_from``, ``t_to``, ``time`` [s UTC], ``accepted`` (bool), ``reason``,
            ``T_fuel`` [°C] or None, ``u_mean`` [V] or None, ``model_id`` or None, ``detail``
            (decoded).
        """
        where, args = [], []
        if t_from is not None:
            where.append("t_to >= ?")
            args.append(float(t_from))
        if t_to is not None:
            where.append("t_to < ?")
            args.append(float(t_to))
        query = f"SELECT {_WINDOW} FROM windows" + (
            " WHERE " + " AND ".join(where) if where else ""
        )
        sql, more = _newest(query, "t_to, id", limit)
        with self._transaction(write=False) as con:
            rows = con.execute(sql, [*args, *more]).fetchall()
        return [_window(row) for row in rows]

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
            ``t_from``, ``t_to`` [s UTC], ``T_fuel`` [°C] or None, ``model`` (decoded).
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
            UTC [s]; now by default.
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
        now = _now(time)
        history = [{"time": now, "status": status, "who": str(who), "why": str(why)}]
        text = _dumps({"old": old_gains, "new": new_gains, "detail": detail, "history": history})
        with self._transaction() as con:
            if model_id is not None and not _exists(con, "models", model_id):
                raise StoreError(f"no model {model_id} to propose gains for")
            cursor = con.execute(
                "INSERT INTO proposals(time, model_id, kc, ti, status, detail) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                (now, None if model_id is None else int(model_id), kc, ti, status, text),
            )
            return int(cursor.lastrowid or 0)

    def proposal(self, proposal_id: int) -> dict[str, Any] | None:
        """One proposal; None when there is no such id.

        Returns
        -------
        dict or None
            ``id``, ``time`` [s UTC], ``model_id``, ``status``, ``old``, ``new`` (gains),
            ``detail`` and ``history`` (a list of ``{"time", "status", "who", "why"}``).
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
        query = "SELECT id, time, model_id, status, detail FROM proposals"
        args: list[str] = []
        if status is not None:
            args = [status] if isinstance(status, str) else [str(s) for s in status]
            if not args:
                return []
            query += f" WHERE status IN ({', '.join('?' * len(args))})"
        with self._transaction(write=False) as con:
            rows = con.execute(query + " ORDER BY time, id", args).fetchall()
        return [_proposal(row) for row in rows]

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
            UTC [s]; now by default.

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
        now = _now(time)
        with self._transaction() as con:
            current = _proposal_by_id(con, proposal_id)
            if current is None:
                raise StoreError(f"no proposal {proposal_id}")
            if status not in PROPOSAL_TRANSITIONS.get(current["status"], frozenset()):
                raise StoreError(
                    f"proposal {proposal_id} is {current['status']}: it cannot be {status}"
                )
            history = [
                *current["history"],
                {"time": now, "status": status, "who": str(who), "why": str(why)},
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

    # -- writes of gains ------------------------------------------------------------------

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
            UTC [s]; now by default.

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
        now = _now(time)
        with self._transaction() as con:
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
                f"INSERT INTO writes({_WRITE.removeprefix('id, ')}) "
                "VALUES (?, ?, ?, ?, ?, ?, 'intent', ?, ?, '{}', NULL)",
                (
                    now,
                    None if proposal_id is None else int(proposal_id),
                    kind,
                    *values,
                    str(who),
                    str(why),
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
            When it finished, UTC [s] (the ``finished`` field); now by default.

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
        now = _now(time)
        text = _dumps({} if detail is None else detail)
        with self._transaction() as con:
            current = _write_by_id(con, write_id)
            if current is None:
                raise StoreError(f"no write {write_id}")
            if current["status"] != "intent":
                raise StoreError(
                    f"write {write_id} is {current['status']}: only an intent can be finished"
                )
            con.execute(
                "UPDATE writes SET status = ?, detail = ?, finished = ? WHERE id = ?",
                (status, text, now, int(write_id)),
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
            ``status``, ``who``, ``why``, ``detail`` (decoded) and ``finished`` [s UTC] or None.
        """
        with self._transaction(write=False) as con:
            return _write_by_id(con, write_id)

    def writes(self, limit: int | None = None) -> list[dict[str, Any]]:
        """Writes, oldest first; ``limit`` keeps the newest ``limit``."""
        sql, args = _newest(f"SELECT {_WRITE} FROM writes", "id", limit)
        with self._transaction(write=False) as con:
            rows = con.execute(sql, args).fetchall()
        return [_write(row) for row in rows]

    def unfinished_writes(self) -> list[dict[str, Any]]:
        """Writes still an ``intent`` (a crash between the intent and its outcome), oldest first."""
        with self._transaction(write=False) as con:
            rows = con.execute(
                f"SELECT {_WRITE} FROM writes WHERE status = 'intent' ORDER BY id"
            ).fetchall()
        return [_write(row) for row in rows]

    def last_apply_seq(self) -> int | None:
        """The largest ``apply_seq`` ever recorded (intents included); None before any write."""
        with self._transaction(write=False) as con:
            value = con.execute("SELECT max(apply_seq) FROM writes").fetchone()[0]
        return None if value is None else int(value)

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
        out = {"windows": int(windows), "accepted": int(accepted), "models": int(models)}
        out["proposals"] = int(sum(proposals.values()))
        for status in (*PROPOSAL_STATUSES, *(s for s in proposals if s not in PROPOSAL_STATUSES)):
            out[f"proposals_{status}"] = int(proposals.get(status, 0))
        out["writes"] = int(sum(writes.values()))
        for status in (*WRITE_STATUSES, *(s for s in writes if s not in WRITE_STATUSES)):
            out[f"writes_{status}"] = int(writes.get(status, 0))
        return out


def _check_status(status: str) -> None:
    if status not in PROPOSAL_TRANSITIONS:
        known = ", ".join(PROPOSAL_STATUSES)
        raise StoreError(f"unknown proposal status {status!r}; known: {known}")


def _exists(con: sqlite3.Connection, table: str, row_id: int) -> bool:
    return con.execute(f"SELECT 1 FROM {table} WHERE id = ?", (int(row_id),)).fetchone() is not None


def _window(row: Sequence[Any]) -> dict[str, Any]:
    keys = ("id", "t_from", "t_to", "time", "accepted", "reason", "T_fuel", "u_mean", "model_id")
    out = dict(zip(keys, row, strict=False))
    out["accepted"] = bool(out["accepted"])
    out["detail"] = _loads(row[9])
    return out


def _model(row: Sequence[Any]) -> dict[str, Any]:
    keys = ("id", "window_id", "time", "t_from", "t_to", "T_fuel")
    out = dict(zip(keys, row, strict=False))
    out["model"] = _loads(row[6])
    return out


def _proposal(row: Sequence[Any]) -> dict[str, Any]:
    stored = _loads(row[4]) or {}
    return {
        "id": row[0],
        "time": row[1],
        "model_id": row[2],
        "status": row[3],
        "old": stored.get("old"),
        "new": stored.get("new"),
        "detail": stored.get("detail"),
        "history": list(stored.get("history") or []),
    }


def _proposal_by_id(con: sqlite3.Connection, proposal_id: int) -> dict[str, Any] | None:
    row = con.execute(
        "SELECT id, time, model_id, status, detail FROM proposals WHERE id = ?",
        (int(proposal_id),),
    ).fetchone()
    return None if row is None else _proposal(row)


def _write(row: Sequence[Any]) -> dict[str, Any]:
    keys = _WRITE.split(", ")
    out = dict(zip(keys, row, strict=True))
    out["detail"] = _loads(out["detail"])
    return out


def _write_by_id(con: sqlite3.Connection, write_id: int) -> dict[str, Any] | None:
    row = con.execute(f"SELECT {_WRITE} FROM writes WHERE id = ?", (int(write_id),)).fetchone()
    return None if row is None else _write(row)
