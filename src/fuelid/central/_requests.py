"""Actions taken centrally: requests the site's service fetches and carries out itself.

The central store never talks to a PLC. The dashboard's fleet page files an approve, reject or
revert, or a start or stop of the test signal (``excite_start``, ``excite_stop``: schema
version 4), with :func:`file_central_request` (a row of ``requests``, status ``waiting``, with an
expiry, for the loop's current store: ``store_uuid``); the site's service fetches the waiting,
unexpired requests of its store at every sync (:func:`fetch_waiting`), claims each
(:func:`claim`: one atomic update, refused once it expired or another sender claimed it) and
only then files it in its own store as a local request (origin ``central:<id>``, the who and
why kept) that its beat applies like any other, and reports the outcome back
(:func:`finish_central_request`). Before filing, the site compares the proposal as
the requester saw it (``seen_status`` and ``seen_history_len``, the entries of its history)
with the proposal now: a proposal that changed meanwhile is refused with the reason ("proposal
12 is now superseded (was pending)"), never decided on a stale view.

A request that no site claimed before its ``expires`` is marked ``expired`` (by the site's next
fetch or :func:`expire_requests`) and never applied; once claimed (``fetched`` set; the local
request's id in ``local_id`` when filed) it is the site's, and finishes as ``done`` or
``refused`` with the site's outcome (a claimed request the site then failed to file is refused:
"claimed but the site has no record of it"). A replaced store (a loop's old file backfilled by
``fuelid central sync``) never takes a request meant for the loop's current store: the store
ids of proposals restart with every store.

Who may act is the dashboard's concern (its central users file): this module records ``who``
as given.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from fuelid.central._connect import CentralError

if TYPE_CHECKING:
    import psycopg

__all__ = [
    "DEFAULT_EXPIRY_S",
    "EXCITE_KINDS",
    "EXCITE_START_EXPIRY_S",
    "KINDS",
    "NEEDS_PROPOSAL",
    "central_requests",
    "claim",
    "expire_requests",
    "fetch_waiting",
    "file_central_request",
    "finish_central_request",
    "mark_fetched",
    "newest_store",
]

KINDS = ("approve", "reject", "revert", "excite_start", "excite_stop")
"""What a central request asks for (the site's ``fuelid.store.REQUEST_KINDS``)."""
EXCITE_KINDS = ("excite_start", "excite_stop")
"""The test signal's kinds (issue 40; the site's ``fuelid.online._requests.EXCITE_KINDS``)."""
NEEDS_PROPOSAL = ("approve", "reject")
"""The kinds that act on a proposal; the others (a revert, the test signal's) refer to none."""
DEFAULT_EXPIRY_S = 3600.0
"""A request waits this long for its site by default [s of wall time]."""
EXCITE_START_EXPIRY_S = 300.0
"""A start of the test signal waits at most this long [s of wall time]: a signal asked for now
is not wanted when a site that was out of contact comes back an hour later."""

_COLUMNS = (
    "id, loop_id, kind, proposal_id, seen_status, seen_history_len, who, why, origin, status, "
    "outcome, extract(epoch FROM created)::float8 AS created, "
    "extract(epoch FROM expires)::float8 AS expires, "
    "extract(epoch FROM fetched)::float8 AS fetched, local_id, "
    "extract(epoch FROM done)::float8 AS done, store_uuid"
)
_NAMES = tuple(c.split(" AS ")[-1].strip() for c in _COLUMNS.split(", ") if c.strip())


def _row(values: Any) -> dict[str, Any]:
    return dict(zip(_NAMES, values, strict=True))


def newest_store(con: psycopg.Connection, loop_id: str) -> str | None:
    """The store UUID of the loop's current store; None for an unknown loop.

    The store whose service beat last (its liveness row's service record, the site's wall
    clock), else the one first seen last: a replaced store backfilled by hand sends its old
    service record (an old beat) and never takes the place of the store its service runs on.
    """
    row = con.execute(
        "SELECT s.store_uuid FROM stores s LEFT JOIN liveness v USING (store_uuid) "
        "WHERE s.loop_id = %s ORDER BY (v.service ->> 'beat')::float8 DESC NULLS LAST, "
        "s.first_seen DESC LIMIT 1",
        (loop_id,),
    ).fetchone()
    return None if row is None else str(row[0])


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
    store_uuid: str | None = None,
) -> dict[str, Any]:
    """File an action for a loop's service to carry out; the request's row.

    Parameters
    ----------
    con : psycopg.Connection
        The central store.
    loop_id : str
        The loop (``[site] loop_id``).
    kind : str
        approve, reject, revert, excite_start or excite_stop (:data:`KINDS`); only approve and
        reject need a proposal, and the test signal's refer to none.
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
    store_uuid : str, optional
        The loop's store it is for (its proposal ids are that store's); by default the loop's
        current store (:func:`newest_store`).

    Returns
    -------
    dict
        ``id``, ``loop_id``, ``kind``, ``proposal_id``, ``seen_status``, ``seen_history_len``,
        ``who``, ``why``, ``origin``, ``status`` ("waiting"), ``outcome``, ``created``,
        ``expires``, ``fetched``, ``local_id``, ``done`` (times in s UTC), ``store_uuid``.

    Raises
    ------
    CentralError
        An unknown kind, a missing proposal (one given to the test signal's kinds), an unknown
        loop or store, a non-positive expiry.
    """
    if kind not in KINDS:
        raise CentralError(f"unknown request kind {kind!r}; known: {', '.join(KINDS)}")
    if kind in NEEDS_PROPOSAL and proposal_id is None:
        raise CentralError(f"a request to {kind} needs its proposal")
    if kind in EXCITE_KINDS and proposal_id is not None:
        # the site files it with no proposal: a given one would be dropped unsaid
        raise CentralError(f"a request {kind} refers to no proposal, got {proposal_id}")
    if not expires_s > 0.0:
        raise CentralError(f"expires_s must be positive, got {expires_s}")
    with con.transaction():
        if con.execute("SELECT 1 FROM loops WHERE loop_id = %s", (loop_id,)).fetchone() is None:
            raise CentralError(f"no loop {loop_id!r} in the central store")
        if store_uuid is None:
            store_uuid = newest_store(con, loop_id)
        elif (
            con.execute(
                "SELECT 1 FROM stores WHERE store_uuid = %s AND loop_id = %s", (store_uuid, loop_id)
            ).fetchone()
            is None
        ):
            raise CentralError(f"loop {loop_id!r} has no store {store_uuid}")
        if store_uuid is None:
            raise CentralError(f"loop {loop_id!r} has no store in the central store")
        if proposal_id is not None:
            row = con.execute(
                "SELECT status, history_len FROM proposals WHERE store_uuid = %s AND id = %s",
                (store_uuid, int(proposal_id)),
            ).fetchone()
            if row is None:
                raise CentralError(f"loop {loop_id!r} has no proposal {proposal_id}")
            if seen_status is None:
                seen_status, seen_history_len = str(row[0]), int(row[1])
        created = con.execute(
            "INSERT INTO requests(loop_id, kind, proposal_id, seen_status, seen_history_len, "
            "who, why, origin, expires, store_uuid) VALUES (%s, %s, %s, %s, %s, %s, %s, %s, "
            "now() + make_interval(secs => %s), %s) "
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
                store_uuid,
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


def fetch_waiting(
    con: psycopg.Connection, loop_id: str, store_uuid: str | None = None
) -> list[dict[str, Any]]:
    """The loop's waiting requests, oldest first (expired ones marked so first, not returned).

    Claimed ones (``fetched`` set) are returned too: their site reports their outcome; an
    unclaimed one only while unexpired. With ``store_uuid``, only that store's (a replaced
    store never takes its loop's current requests).
    """
    expire_requests(con, loop_id)
    store = "" if store_uuid is None else " AND store_uuid = %s"
    with con.transaction():
        rows = con.execute(
            f"SELECT {_COLUMNS} FROM requests WHERE loop_id = %s AND status = 'waiting' "
            f"AND (fetched IS NOT NULL OR expires > now()){store} ORDER BY id",
            (loop_id,) if store_uuid is None else (loop_id, store_uuid),
        ).fetchall()
    return [_row(r) for r in rows]


def claim(con: psycopg.Connection, request_id: int, store_uuid: str | None = None) -> bool:
    """Take a waiting request for the site, before it files it; False when it may not.

    One update: the request must still be waiting, unclaimed, unexpired (on the server's clock)
    and, with ``store_uuid``, for that store. Only a True lets the site file it: a request that
    expired between the fetch and the claim is never applied, and two senders never both
    file one.
    """
    store = "" if store_uuid is None else " AND store_uuid = %s"
    args: list[Any] = [int(request_id)]
    if store_uuid is not None:
        args.append(store_uuid)
    with con.transaction():
        row = con.execute(
            "UPDATE requests SET fetched = now() WHERE id = %s AND status = 'waiting' "
            f"AND fetched IS NULL AND expires > now(){store} RETURNING id",
            args,
        ).fetchone()
    return row is not None


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
