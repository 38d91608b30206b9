"""The online history's vocabulary, its row codecs and its connection.

What :class:`~fuelid.store._online.OnlineHistory` shares between its parts: the statuses of a
proposal and of a write of gains, JSON and number checks (NaN and ±inf as ``null``), the
decoders of a row into a dictionary, and :class:`HistoryConnection`, the locked connection of
its own on which every method is one transaction. The tables are in :mod:`fuelid.store._schema`.
"""

from __future__ import annotations

import json
import math
import sqlite3
import threading
import time as _time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from types import MappingProxyType, TracebackType
from typing import TYPE_CHECKING, Any, Self

from fuelid.io.jsonsafe import json_ready
from fuelid.store._records import StoreError

if TYPE_CHECKING:
    from fuelid.store._sqlite import SQLiteStore

__all__ = [
    "PROPOSAL_COLUMNS",
    "PROPOSAL_STATUSES",
    "PROPOSAL_TRANSITIONS",
    "REQUEST_COLUMNS",
    "REQUEST_KINDS",
    "REQUEST_STATUSES",
    "SERVICE_KEY",
    "WINDOW_COLUMNS",
    "WRITE_COLUMNS",
    "WRITE_KINDS",
    "WRITE_STATUSES",
    "HistoryConnection",
    "history_counts",
    "proposal_row",
    "request_row",
    "window_row",
    "write_row",
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

WINDOW_COLUMNS = (
    "id, t_from, t_to, time, accepted, reason, T_fuel, u_mean, model_id, detail, wall_time"
)
"""The columns of a window row, in the order :func:`window_row` decodes (the site's SQLite table
and the central store's ``windows`` have them alike: an unquoted ``T_fuel`` is ``t_fuel`` in
PostgreSQL)."""
_MODEL = (
    "m.id, (SELECT w.id FROM windows w WHERE w.model_id = m.id ORDER BY w.id LIMIT 1) "
    "AS window_id, m.time, m.t_from, m.t_to, m.T_fuel, m.model, m.wall_time"
)
WRITE_COLUMNS = (
    "id, time, proposal_id, kind, kc, ti, apply_seq, status, who, why, detail, finished, "
    "wall_time, finished_wall"
)
"""The columns of a write of gains, in the order :func:`write_row` decodes (site and centre)."""
PROPOSAL_COLUMNS = "id, time, model_id, status, detail, wall_time"
"""The columns of a proposal, in the order :func:`proposal_row` decodes (site and centre)."""
REQUEST_COLUMNS = (
    "id, time, wall_time, kind, proposal_id, who, why, origin, status, outcome, done_wall"
)
"""The columns of a person's request, in the order :func:`request_row` decodes (the site's
``requests``, the central store's ``site_requests``)."""
SERVICE_KEY = "service"
"""The ``online_state`` key of the service record (written by :mod:`fuelid.online._liveness`,
read by every reader of a loop: the reports, the dashboard, the archive, the central store)."""
REQUEST_KINDS = ("approve", "reject", "revert", "excite_start", "excite_stop")
"""What a request asks for: approve or reject a proposal, revert to the last-known-good gains,
start or stop a test signal (issue 40)."""
REQUEST_STATUSES = ("waiting", "done", "refused", "expired")
"""``waiting`` until the service (or the CLI, when no service runs) applies it."""


def _dumps(value: Any) -> str:
    try:
        plain = json_ready(value)
    except TypeError as exc:
        raise StoreError(f"cannot be stored as JSON: {exc}") from None
    return json.dumps(plain, allow_nan=False, separators=(",", ":"))


def _loads(text: str | None) -> Any:
    return None if text is None else json.loads(text)


def _parsed(value: Any) -> Any:
    """A JSON column's value: SQLite's text parsed; PostgreSQL's jsonb comes parsed already."""
    return _loads(value) if isinstance(value, str) else value


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
    """The wall clock [s UTC] (or the given time, checked)."""
    return _time.time() if time is None else _finite("time", time)


def _plant(con: sqlite3.Connection, time: float | None) -> float:
    """Plant time [s UTC]: the given one, else the newest committed sample's.

    The wall clock in an empty store.
    """
    if time is not None:
        return _finite("time", time)
    value = con.execute("SELECT max(time) FROM samples").fetchone()[0]
    return _time.time() if value is None else float(value)


def _newest(query: str, order: str, limit: int | None) -> tuple[str, list[Any]]:
    """``query`` ordered oldest first by ``order``, keeping the newest ``limit`` rows."""
    if limit is None:
        return f"{query} ORDER BY {order}", []
    if isinstance(limit, bool) or not isinstance(limit, int) or limit < 0:
        raise StoreError(f"limit must be a non-negative integer, got {limit!r}")
    desc = ", ".join(f"{column} DESC" for column in order.split(", "))
    plain = ", ".join(column.split(".")[-1] for column in order.split(", "))
    return f"SELECT * FROM ({query} ORDER BY {desc} LIMIT ?) ORDER BY {plain}", [limit]


class HistoryConnection:
    """A connection of its own to a store's file, one lock around it, one transaction per call.

    The base of :class:`~fuelid.store._online.OnlineHistory`. The tables exist: opening the
    :class:`~fuelid.store._sqlite.SQLiteStore` created or upgraded them.

    Parameters
    ----------
    store : SQLiteStore
        An open store; only its ``path`` is used, its own connections are left alone.

    Raises
    ------
    StoreError
        The file cannot be opened (the reason in one line).
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
        except sqlite3.Error as error:
            con.close()
            raise StoreError(f"{self.path}: cannot open the online history ({error})") from None
        self._con = con
        # the service's plant clock (the newest sample it queued), so that its rows share the
        # time base of its events; None: the newest committed sample
        self.plant_clock: Callable[[], float | None] | None = None

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

    def _plant_time(self, con: sqlite3.Connection, time: float | None) -> float:
        """Plant time for a row: the given one, else the plant clock's, else the store's."""
        if time is None and self.plant_clock is not None:
            time = self.plant_clock()
        return _plant(con, time)

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


def _check_status(status: str) -> None:
    if status not in PROPOSAL_TRANSITIONS:
        known = ", ".join(PROPOSAL_STATUSES)
        raise StoreError(f"unknown proposal status {status!r}; known: {known}")


def _exists(con: sqlite3.Connection, table: str, row_id: int) -> bool:
    return con.execute(f"SELECT 1 FROM {table} WHERE id = ?", (int(row_id),)).fetchone() is not None


def window_row(row: Sequence[Any]) -> dict[str, Any]:
    """A window row (:data:`WINDOW_COLUMNS`) as a dict, ``accepted`` a bool, ``detail`` parsed."""
    keys = ("id", "t_from", "t_to", "time", "accepted", "reason", "T_fuel", "u_mean", "model_id")
    out = dict(zip(keys, row, strict=False))
    out["accepted"] = bool(out["accepted"])
    out["detail"] = _parsed(row[9])
    out["wall_time"] = row[10]
    return out


def _model(row: Sequence[Any]) -> dict[str, Any]:
    keys = ("id", "window_id", "time", "t_from", "t_to", "T_fuel")
    out = dict(zip(keys, row, strict=False))
    out["model"] = _loads(row[6])
    out["wall_time"] = row[7]
    return out


def proposal_row(row: Sequence[Any]) -> dict[str, Any]:
    """A proposals row ``(id, time, model_id, status, detail, wall_time)`` as a dict.

    ``detail`` is JSON text (SQLite) or already parsed (PostgreSQL's jsonb, the central store).
    """
    stored = _parsed(row[4]) or {}
    return {
        "id": row[0],
        "time": row[1],
        "model_id": row[2],
        "status": row[3],
        "old": stored.get("old"),
        "new": stored.get("new"),
        "detail": stored.get("detail"),
        "history": list(stored.get("history") or []),
        "wall_time": row[5] if len(row) > 5 else None,
    }


def history_counts(
    windows: int,
    accepted: int,
    models: int,
    proposals: Mapping[str, int],
    writes: Mapping[str, int],
) -> dict[str, int]:
    """The counts of a loop's history, as :meth:`OnlineHistory.counts` gives them.

    ``proposals`` and ``writes`` are counts by status: every known status is listed (0 when
    none), then any other the rows hold.

    >>> history_counts(3, 2, 2, {"pending": 1}, {})["proposals_pending"]
    1
    """
    out = {"windows": int(windows), "accepted": int(accepted), "models": int(models)}
    out["proposals"] = int(sum(proposals.values()))
    for status in (*PROPOSAL_STATUSES, *(s for s in proposals if s not in PROPOSAL_STATUSES)):
        out[f"proposals_{status}"] = int(proposals.get(status, 0))
    out["writes"] = int(sum(writes.values()))
    for status in (*WRITE_STATUSES, *(s for s in writes if s not in WRITE_STATUSES)):
        out[f"writes_{status}"] = int(writes.get(status, 0))
    return out


def _proposal_by_id(con: sqlite3.Connection, proposal_id: int) -> dict[str, Any] | None:
    row = con.execute(
        f"SELECT {PROPOSAL_COLUMNS} FROM proposals WHERE id = ?", (int(proposal_id),)
    ).fetchone()
    return None if row is None else proposal_row(row)


def write_row(row: Sequence[Any]) -> dict[str, Any]:
    """A write of gains (:data:`WRITE_COLUMNS`) as a dict, ``detail`` parsed."""
    out = dict(zip(WRITE_COLUMNS.split(", "), row, strict=True))
    out["detail"] = _parsed(out["detail"])
    return out


def _write_by_id(con: sqlite3.Connection, write_id: int) -> dict[str, Any] | None:
    row = con.execute(
        f"SELECT {WRITE_COLUMNS} FROM writes WHERE id = ?", (int(write_id),)
    ).fetchone()
    return None if row is None else write_row(row)


def request_row(row: Sequence[Any]) -> dict[str, Any]:
    """A person's request (:data:`REQUEST_COLUMNS`) as a dict."""
    return dict(zip(REQUEST_COLUMNS.split(", "), row, strict=True))
