"""Actions taken centrally: requests the site's service fetches and carries out itself.

The central store never talks to a PLC. The dashboard's fleet page files an approve, reject or
revert with :func:`file_central_request` (a row of ``requests``, status ``waiting``, with an
expiry); the site's service fetches the waiting, unexpired requests of its loop at every sync
(:func:`fetch_waiting`), files each in its own store as a local request (origin
``central:<id>``, the who and why kept) that its beat applies like any other, and reports the
outcome back (:func:`finish_central_request`). Before filing, the site compares the proposal as
the requester saw it (``seen_status`` and ``seen_history_len``, the entries of its history)
with the proposal now: a proposal that changed meanwhile is refused with the reason ("proposal
12 is now superseded (was pending)"), never decided on a stale view.

A request that no site fetched before its ``expires`` is marked ``expired`` (by the site's next
fetch or :func:`expire_requests`) and never applied; once fetched (``fetched`` set, the local
request's id in ``local_id``) it is the site's, and finishes as ``done`` or ``refused`` with the
site's outcome.

Who may act is the dashboard's concern (its central users file): this module records ``who``
as given.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from fuelid.central.connect import CentralError

if TYPE_CHECKING:
    import psycopg

__all__ = [
    "DEFAULT_EXPIRY_S",
    "KINDS",
    "central_requests",
    "expire_requests",
    "fetch_waiting",
    "file_central_request",
    "finish_central_request",
    "mark_fetched",
]

KINDS = ("approve", "reject", "revert")
"""What a central request asks for."""
DEFAULT_EXPIRY_S = 3600.0
"""A request waits this long for its site by default [s of wall time]."""

_COLUMNS = (
    "id, loop_id, kind, proposal_id, seen_status, seen_history_len, who, why, origin, status, "
    "outcome, extract(epoch FROM created)::float8 AS created, "
    "extract(epoch FROM expires)::float8 AS expires, "
    "extract(epoch FROM fetched)::float8 AS fetched, local_id, "
    "extract(epoch FROM done)::float8 AS done"
)
_NAMES = tuple(c.split(" AS ")[-1].strip() for c in _COLUMNS.split(", ") if c.strip())


def _row(values: Any) -> dict[str, Any]:
    return dict(zip(_NAMES, values, strict=True))


def file_central_request(
    con: psycopg.Connection,
    loop_id: str,
    kind: str,
    proposal_id: int | None,
    who: str,
    why: str,
    *,
    seen_status: str | None = None,
    seen_history_len: int | None = None,
    origin: str = "dashboard",
    expires_s: float = DEFAULT_EXPIRY_S,
) -> dict[str, Any]:
    """File an action for a loop's service to carry out; the request's row.

    Parameters
    ----------
    con : psycopg.Connection
        The central store.
    loop_id : str
        The loop (``[site] loop_id``).
    kind : str
        approve, reject or revert (a revert needs no proposal).
    proposal_id : int or None
        The proposal's id in the loop's store (the central ``proposals.id``).
    who, why : str
        Who acts (as the central users file names them) and why.
    seen_status, seen_history_len : optional
        The proposal as the requester saw it (its status and the entries of its history);
        by default as the central store has it now.
    origin : str
        Where it was filed ("dashboard").
    expires_s : float
        How long it may wait for the site [s of wall time].

    Returns
    -------
    dict
        ``id``, ``loop_id``, ``kind``, ``proposal_id``, ``seen_status``, ``seen_history_len``,
        ``who``, ``why``, ``origin``, ``status`` ("waiting"), ``outcome``, ``created``,
        ``expires``, ``fetched``, ``local_id``, ``done`` (times in s UTC).

    Raises
    ------
    CentralError
        An unknown kind, a missing proposal, an unknown loop, a non-positive expiry.
    """
    if kind not in KINDS:
        raise CentralError(f"unknown request kind {kind!r}; known: {', '.join(KINDS)}")
    if kind != "revert" and proposal_id is None:
        raise CentralError(f"a request to {kind} needs its proposal")
    if not expires_s > 0.0:
        raise CentralError(f"expires_s must be positive, got {expires_s}")
    with con.transaction():
        if con.execute("SELECT 1 FROM loops WHERE loop_id = %s", (loop_id,)).fetchone() is None:
            raise CentralError(f"no loop {loop_id!r} in the central store")
        if proposal_id is not None:
            # the loop's newest store (a loop replaced its store file: the newer one counts)
            row = con.execute(
                "SELECT p.status, p.history_len FROM proposals p JOIN stores s USING "
                "(store_uuid) WHERE p.loop_id = %s AND p.id = %s ORDER BY s.last_seen DESC "
                "LIMIT 1",
                (loop_id, int(proposal_id)),
            ).fetchone()
            if row is None:
                raise CentralError(f"loop {loop_id!r} has no proposal {proposal_id}")
            if seen_status is None:
                seen_status, seen_history_len = str(row[0]), int(row[1])
        created = con.execute(
            "INSERT INTO requests(loop_id, kind, proposal_id, seen_status, seen_history_len, "
            "who, why, origin, expires) VALUES (%s, %s, %s, %s, %s, %s, %s, %s, "
            "now() + make_interval(secs => %s)) "
            f"RETURNING {_COLUMNS}",
            (
                loop_id,
                kind,
                None if proposal_id is None else int(proposal_id),
                seen_status,
                seen_history_len,
                str(who),
                str(why),
                str(origin),
                float(expires_s),
            ),
        ).fetchone()
    return _row(created)


def expire_requests(con: psycopg.Connection, loop_id: str | None = None) -> list[dict[str, Any]]:
    """Mark the waiting, unfetched requests past their expiry ``expired``; those rows."""
    where = "" if loop_id is None else " AND loop_id = %s"
    with con.transaction():
        rows = con.execute(
            "UPDATE requests SET status = 'expired', done = now(), outcome = "
            "'expired before the site fetched it' WHERE status = 'waiting' AND fetched IS NULL "
            f"AND expires <= now(){where} RETURNING {_COLUMNS}",
            () if loop_id is None else (loop_id,),
        ).fetchall()
    return [_row(r) for r in rows]


def fetch_waiting(con: psycopg.Connection, loop_id: str) -> list[dict[str, Any]]:
    """The loop's waiting requests, oldest first (expired ones marked so first, not returned).

    Fetched ones (``fetched`` set) are returned too: their site reports their outcome.
    """
    expire_requests(con, loop_id)
    with con.transaction():
        rows = con.execute(
            f"SELECT {_COLUMNS} FROM requests WHERE loop_id = %s AND status = 'waiting' "
            "ORDER BY id",
            (loop_id,),
        ).fetchall()
    return [_row(r) for r in rows]


def mark_fetched(con: psycopg.Connection, request_id: int, local_id: int) -> bool:
    """The site filed the request locally as ``local_id``; False when it is no longer waiting."""
    with con.transaction():
        row = con.execute(
            "UPDATE requests SET fetched = coalesce(fetched, now()), local_id = %s "
            "WHERE id = %s AND status = 'waiting' RETURNING id",
            (int(local_id), int(request_id)),
        ).fetchone()
    return row is not None


def finish_central_request(
    con: psycopg.Connection, request_id: int, status: str, outcome: str
) -> bool:
    """Record the site's outcome (``done`` or ``refused``); False when it was not waiting."""
    if status not in ("done", "refused"):
        raise CentralError(f"a central request finishes as done or refused, not {status!r}")
    with con.transaction():
        row = con.execute(
            "UPDATE requests SET status = %s, outcome = %s, done = now() "
            "WHERE id = %s AND status = 'waiting' RETURNING id",
            (status, str(outcome), int(request_id)),
        ).fetchone()
    return row is not None


def central_requests(
    con: psycopg.Connection, loop_id: str | None = None, status: str | None = None
) -> list[dict[str, Any]]:
    """Central requests, oldest first, of a loop and/or a status (all by default)."""
    where, args = [], []
    if loop_id is not None:
        where.append("loop_id = %s")
        args.append(loop_id)
    if status is not None:
        where.append("status = %s")
        args.append(status)
    sql = f"SELECT {_COLUMNS} FROM requests"
    if where:
        sql += " WHERE " + " AND ".join(where)
    with con.transaction():
        rows = con.execute(sql + " ORDER BY id", args).fetchall()
    return [_row(r) for r in rows]
