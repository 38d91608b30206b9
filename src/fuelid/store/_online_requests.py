"""People's requests in the online history: approve, reject, revert, filed and finished.

The CLI and the dashboard file a request (:meth:`PersonRequests.add_request`), the running
service (or, with none running, the filer itself) applies it and records the outcome
(:meth:`PersonRequests.finish_request`); see :mod:`fuelid.online._requests`. The table is
``requests`` (:mod:`fuelid.store._schema`). A part of
:class:`~fuelid.store._online.OnlineHistory`.
"""

from __future__ import annotations

import time as _time
from typing import Any

from fuelid.store._online_rows import (
    REQUEST_COLUMNS,
    REQUEST_KINDS,
    REQUEST_STATUSES,
    HistoryConnection,
    _exists,
    _newest,
    _plant,
    request_row,
)
from fuelid.store._records import StoreError

__all__ = ["PersonRequests"]


class PersonRequests(HistoryConnection):
    """The requests' methods of :class:`~fuelid.store._online.OnlineHistory`."""

    def add_request(
        self, kind: str, proposal_id: int | None, who: str, why: str, origin: str
    ) -> dict[str, Any]:
        """File a person's request (approve, reject, revert) for the service to apply.

        Parameters
        ----------
        kind : str
            One of :data:`REQUEST_KINDS`; approve and reject need ``proposal_id``.
        proposal_id : int or None
            The proposal decided on (None for a revert).
        who, why : str
            Who asks and why.
        origin : str
            Where it was filed: ``cli``, ``dashboard`` (later ``central``).

        Returns
        -------
        dict
            The request's row (every column: ``id``, ``time`` [plant s], ``wall_time`` [wall s],
            ``kind``, ``proposal_id``, ``who``, ``why``, ``origin``, ``status`` "waiting",
            ``outcome`` "", ``done_wall`` None).

        Raises
        ------
        StoreError
            An unknown kind or proposal, an approve or reject without a proposal.
        """
        if kind not in REQUEST_KINDS:
            raise StoreError(f"unknown request kind {kind!r}; known: {', '.join(REQUEST_KINDS)}")
        if kind in ("approve", "reject") and proposal_id is None:
            raise StoreError(f"a request to {kind} needs its proposal")
        wall = _time.time()
        with self._transaction() as con:
            if proposal_id is not None and not _exists(con, "proposals", proposal_id):
                raise StoreError(f"no proposal {proposal_id}")
            cursor = con.execute(
                f"INSERT INTO requests({REQUEST_COLUMNS.removeprefix('id, ')}) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, 'waiting', '', NULL)",
                (
                    _plant(con, None),
                    wall,
                    kind,
                    None if proposal_id is None else int(proposal_id),
                    str(who),
                    str(why),
                    str(origin),
                ),
            )
            row = con.execute(
                f"SELECT {REQUEST_COLUMNS} FROM requests WHERE id = ?", (cursor.lastrowid,)
            ).fetchone()
        return request_row(row)

    def requests(self, status: str | None = None, limit: int | None = None) -> list[dict[str, Any]]:
        """Requests, oldest first, all or those with ``status``; ``limit`` keeps the newest."""
        query = f"SELECT {REQUEST_COLUMNS} FROM requests"
        args: list[Any] = []
        if status is not None:
            query += " WHERE status = ?"
            args.append(str(status))
        sql, more = _newest(query, "id", limit)
        with self._transaction(write=False) as con:
            rows = con.execute(sql, [*args, *more]).fetchall()
        return [request_row(row) for row in rows]

    def request(self, request_id: int) -> dict[str, Any] | None:
        """One request as :meth:`requests` gives it; None when there is no such id."""
        with self._transaction(write=False) as con:
            row = con.execute(
                f"SELECT {REQUEST_COLUMNS} FROM requests WHERE id = ?", (int(request_id),)
            ).fetchone()
        return None if row is None else request_row(row)

    def request_of_origin(self, origin: str) -> dict[str, Any] | None:
        """The first request filed with ``origin`` (a relay's ``central:<id>``); None when none."""
        with self._transaction(write=False) as con:
            row = con.execute(
                f"SELECT {REQUEST_COLUMNS} FROM requests WHERE origin = ? ORDER BY id LIMIT 1",
                (str(origin),),
            ).fetchone()
        return None if row is None else request_row(row)

    def finish_request(self, request_id: int, status: str, outcome: str) -> dict[str, Any]:
        """Record what became of a waiting request (``done_wall`` = now, wall clock).

        Raises
        ------
        StoreError
            Unknown request or status, or a request no longer waiting.
        """
        if status not in REQUEST_STATUSES[1:]:
            raise StoreError(
                f"a request finishes as {', '.join(REQUEST_STATUSES[1:])}, not {status!r}"
            )
        with self._transaction() as con:
            row = con.execute(
                "SELECT status FROM requests WHERE id = ?", (int(request_id),)
            ).fetchone()
            if row is None:
                raise StoreError(f"no request {request_id}")
            if row[0] != "waiting":
                raise StoreError(f"request {request_id} is {row[0]}: it was already consumed")
            con.execute(
                "UPDATE requests SET status = ?, outcome = ?, done_wall = ? WHERE id = ?",
                (status, str(outcome), _time.time(), int(request_id)),
            )
            updated = con.execute(
                f"SELECT {REQUEST_COLUMNS} FROM requests WHERE id = ?", (int(request_id),)
            ).fetchone()
        return request_row(updated)
