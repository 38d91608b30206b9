"""One loop's history as the central store holds it, read as the site's own is.

:class:`CentralHistory` implements :class:`~fuelid.store.LoopHistory` (windows, models,
proposals, writes, the site's requests, counts, the ``online_state`` values) and
:class:`CentralStoreView` :class:`~fuelid.store.LoopStore` (site name, tag-map hash, the newest
sample's clocks, link events, events), both over the rows of one store of the central database,
decoded into the dictionaries the site's own history gives (the same keys, the JSON columns
parsed, the column lists and decoders of :mod:`fuelid.store._online_rows`): the report functions
(of :mod:`fuelid.online`) then build the same objects from either source.

Which store of a loop is shown (:func:`shown_store`), its liveness row (:func:`liveness_row`)
and the loops there are (:func:`central_loop_ids`) are read here too: every statement a central
reader runs is in this package.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

from fuelid.central._connect import CentralError
from fuelid.central._db import CentralDB
from fuelid.store import (
    PROPOSAL_COLUMNS,
    REQUEST_COLUMNS,
    SERVICE_KEY,
    WINDOW_COLUMNS,
    WRITE_COLUMNS,
    history_counts,
    proposal_row,
    request_row,
    window_row,
    write_row,
)

__all__ = [
    "LIVENESS_KEYS",
    "CentralHistory",
    "CentralStoreView",
    "central_loop_ids",
    "liveness_row",
    "shown_store",
]

_MODEL = "id, time, t_from, t_to, t_fuel, model, wall_time"
_MODEL_KEYS = ("id", "time", "t_from", "t_to", "T_fuel", "model", "wall_time")

_LIVENESS = (
    "service, backlog_rows, backlog_oldest_wall, last_send_wall, "
    "extract(epoch FROM updated)::float8 AS updated, "
    "extract(epoch FROM now() - updated)::float8 AS contact_age_s, site_wall, send_every_s, "
    "newest_sample_time, newest_sample_wall, first_sample_time, period_s, schema_version, "
    "site_state"
)
LIVENESS_KEYS = tuple(c.split(" AS ")[-1].strip() for c in _LIVENESS.split(", "))
"""The keys of :func:`liveness_row`'s dict (times [s UTC]; ``contact_age_s`` by the centre's
clock)."""


def _limit(limit: int) -> str:
    """``LIMIT n`` written into the statement, not a parameter.

    PostgreSQL plans a parameter's LIMIT as a tenth of the rows and then sorts them all rather
    than reading the few newest from the index (a year of windows: 50 ms instead of 1 ms).

    >>> _limit(30)
    'LIMIT 30'
    """
    return f"LIMIT {int(limit):d}"


def _newest_first(rows: list[Any]) -> list[Any]:
    rows.reverse()  # read newest first (for the limit), returned oldest first
    return rows


def central_loop_ids(db: CentralDB) -> list[str]:
    """The loops of the central store (``loops``), sorted."""
    return [str(loop_id) for (loop_id,) in db.query("SELECT loop_id FROM loops ORDER BY loop_id")]


def shown_store(db: CentralDB, loop_id: str) -> dict[str, Any]:
    """The loop's store shown: the one seen last.

    A dict of ``store_uuid``, ``loop_id``, ``site_name`` and ``tag_map_hash``.

    Raises
    ------
    CentralError
        The central store has no store of the loop.
    """
    rows = db.query(
        "SELECT store_uuid, loop_id, site_name, tag_map_hash FROM stores WHERE loop_id = %s "
        "ORDER BY last_seen DESC LIMIT 1",
        (loop_id,),
    )
    if not rows:
        raise CentralError(f"the central store has no store of loop {loop_id!r}")
    keys = ("store_uuid", "loop_id", "site_name", "tag_map_hash")
    return dict(zip(keys, rows[0], strict=True))


def liveness_row(db: CentralDB, store_uuid: str) -> dict[str, Any] | None:
    """The store's liveness row (:data:`LIVENESS_KEYS`); None when the site never sent one."""
    rows = db.query(f"SELECT {_LIVENESS} FROM liveness WHERE store_uuid = %s", (store_uuid,))
    return dict(zip(LIVENESS_KEYS, rows[0], strict=True)) if rows else None


class CentralHistory:
    """A loop's :class:`~fuelid.store.LoopHistory` from the central rows of one store.

    Parameters
    ----------
    db : CentralDB
        The central store.
    store_uuid : str
        The loop's store shown.
    liveness : dict
        Its liveness row (the service record and the site's state values).
    """

    def __init__(self, db: CentralDB, store_uuid: str, liveness: dict[str, Any]) -> None:
        self.db = db
        self.uuid = store_uuid
        self.liveness = liveness

    def windows(
        self, t_from: float | None = None, t_to: float | None = None, limit: int | None = None
    ) -> list[dict[str, Any]]:
        """Windows ending in ``[t_from, t_to)`` [plant s], oldest first; the newest ``limit``."""
        sql = f"SELECT {WINDOW_COLUMNS} FROM windows WHERE store_uuid = %s"
        args: list[Any] = [self.uuid]
        if t_from is not None:
            sql += " AND t_to >= %s"
            args.append(float(t_from))
        if t_to is not None:
            sql += " AND t_to < %s"
            args.append(float(t_to))
        if limit is None:
            return [window_row(r) for r in self.db.query(sql + " ORDER BY t_to, id", args)]
        rows = self.db.query(sql + f" ORDER BY t_to DESC, id DESC {_limit(limit)}", args)
        return [window_row(r) for r in _newest_first(rows)]

    def window(self, window_id: int) -> dict[str, Any] | None:
        """One window by its id; None when absent."""
        rows = self.db.query(
            f"SELECT {WINDOW_COLUMNS} FROM windows WHERE store_uuid = %s AND id = %s",
            (self.uuid, int(window_id)),
        )
        return window_row(rows[0]) if rows else None

    def windows_of_models(self, model_ids: Sequence[int]) -> list[dict[str, Any]]:
        """The first window naming each of ``model_ids``, by id (one per model, its index)."""
        ids = sorted({int(i) for i in model_ids})
        if not ids:
            return []
        rows = self.db.query(
            f"SELECT {WINDOW_COLUMNS} FROM windows WHERE store_uuid = %s AND id IN "
            "(SELECT min(id) FROM windows WHERE store_uuid = %s AND model_id = ANY(%s) "
            "GROUP BY model_id) ORDER BY id",
            (self.uuid, self.uuid, ids),
        )
        return [window_row(r) for r in rows]

    def last_window(self) -> dict[str, Any] | None:
        """The newest window; None when none."""
        rows = self.windows(limit=1)
        return rows[0] if rows else None

    def accepted_models(self, limit: int | None = None) -> list[dict[str, Any]]:
        """The models, oldest first (by their window's end); the newest ``limit``.

        ``window_id`` (the first window naming the model, as the site's join gives it) comes from
        one query over the models read (a subquery per model would probe every monthly
        partition for each of the K(T) tracker's 2,000 models).
        """
        sql = f"SELECT {_MODEL} FROM models WHERE store_uuid = %s ORDER BY t_to DESC, id DESC"
        if limit is not None:
            sql += f" {_limit(limit)}"
        rows = _newest_first(self.db.query(sql, (self.uuid,)))
        first = (
            dict(
                self.db.query(
                    "SELECT model_id, min(id) FROM windows WHERE store_uuid = %s "
                    "AND model_id = ANY(%s) GROUP BY model_id",
                    (self.uuid, [int(r[0]) for r in rows]),
                )
            )
            if rows
            else {}
        )
        out = []
        for r in rows:
            row = dict(zip(_MODEL_KEYS, r, strict=True))
            out.append({"id": row["id"], "window_id": first.get(row["id"]), **row})
        return out

    def model(self, model_id: int) -> dict[str, Any] | None:
        """One model as :meth:`accepted_models` gives it (``window_id`` None); None when absent."""
        rows = self.db.query(
            f"SELECT {_MODEL} FROM models WHERE store_uuid = %s AND id = %s",
            (self.uuid, int(model_id)),
        )
        if not rows:
            return None
        return {"window_id": None, **dict(zip(_MODEL_KEYS, rows[0], strict=True))}

    def plant_now(self) -> float | None:
        """Plant time at the site's last send: its newest sample's [s UTC]; None without one."""
        t = self.liveness.get("newest_sample_time")
        return None if t is None else float(t)

    def writes(self, limit: int | None = None) -> list[dict[str, Any]]:
        """Writes of gains, oldest first; the newest ``limit``."""
        sql = f"SELECT {WRITE_COLUMNS} FROM writes WHERE store_uuid = %s ORDER BY id DESC"
        if limit is not None:
            sql += f" {_limit(limit)}"
        return [write_row(r) for r in _newest_first(self.db.query(sql, (self.uuid,)))]

    def proposals(self, status: str | Sequence[str] | None = None) -> list[dict[str, Any]]:
        """Proposals, oldest first, all or those of ``status``."""
        sql = f"SELECT {PROPOSAL_COLUMNS} FROM proposals WHERE store_uuid = %s"
        args: list[Any] = [self.uuid]
        if status is not None:
            wanted = [status] if isinstance(status, str) else [str(s) for s in status]
            sql += " AND status = ANY(%s)"
            args.append(wanted)
        return [proposal_row(r) for r in self.db.query(sql + " ORDER BY time, id", args)]

    def proposal(self, proposal_id: int) -> dict[str, Any] | None:
        """One proposal; None when absent."""
        rows = self.db.query(
            f"SELECT {PROPOSAL_COLUMNS} FROM proposals WHERE store_uuid = %s AND id = %s",
            (self.uuid, int(proposal_id)),
        )
        return proposal_row(rows[0]) if rows else None

    def requests(self, status: str | None = None, limit: int | None = None) -> list[dict[str, Any]]:
        """The site's requests (its ``requests`` table), oldest first."""
        sql = f"SELECT {REQUEST_COLUMNS} FROM site_requests WHERE store_uuid = %s"
        args: list[Any] = [self.uuid]
        if status is not None:
            sql += " AND status = %s"
            args.append(str(status))
        sql += " ORDER BY id DESC"
        if limit is not None:
            sql += f" {_limit(limit)}"
        return [request_row(r) for r in _newest_first(self.db.query(sql, args))]

    def counts(self) -> dict[str, int]:
        """Counts as :meth:`OnlineHistory.counts <fuelid.store.OnlineHistory.counts>` gives them."""
        uuid = (self.uuid,)
        ((windows, accepted),) = self.db.query(
            "SELECT count(*), coalesce(sum(accepted), 0) FROM windows WHERE store_uuid = %s", uuid
        )
        ((models,),) = self.db.query("SELECT count(*) FROM models WHERE store_uuid = %s", uuid)
        proposals = dict(
            self.db.query(
                "SELECT status, count(*) FROM proposals WHERE store_uuid = %s GROUP BY 1", uuid
            )
        )
        writes = dict(
            self.db.query(
                "SELECT status, count(*) FROM writes WHERE store_uuid = %s GROUP BY 1", uuid
            )
        )
        return history_counts(windows, accepted, models, proposals, writes)

    def state(self, key: str, default: Any = None) -> Any:
        """The site's ``online_state`` value as its last send told it (``default`` when not)."""
        if key == SERVICE_KEY:
            value = self.liveness.get("service")
            return default if value is None else value
        state = self.liveness.get("site_state") or {}
        return state.get(key, default)


class CentralStoreView:
    """A loop's :class:`~fuelid.store.LoopStore` from the central rows.

    ``path`` is None: there is no file here (the report's sync block is the site's own; the
    central reader gives its own, see :meth:`fuelid.dashboard.CentralLoop.status`).
    """

    path = None

    def __init__(self, db: CentralDB, store: dict[str, Any], liveness: dict[str, Any]) -> None:
        self.db = db
        self.uuid = str(store["store_uuid"])
        self.loop_id = str(store["loop_id"])
        self.site_name = str(store["site_name"])
        self.tag_map_hash = str(store["tag_map_hash"])
        self.liveness = liveness

    def newest_sample_clocks(self) -> tuple[float, float] | None:
        """The newest sample's plant and wall time at the last send [s UTC]; None without one."""
        t = self.liveness.get("newest_sample_time")
        if t is None:
            return None
        wall = self.liveness.get("newest_sample_wall")
        return float(t), math.nan if wall is None else float(wall)

    def last_event(self, kinds: Iterable[str]) -> tuple[float, str, str, float | None] | None:
        """The newest event of one of ``kinds``: (time, kind, detail, wall_time)."""
        rows = self.db.query(
            # loop_id too: the (loop_id, time DESC) index, read backwards, finds it at once
            "SELECT time, kind, detail, wall_time FROM events WHERE loop_id = %s "
            "AND store_uuid = %s AND kind = ANY(%s) ORDER BY time DESC, id DESC LIMIT 1",
            (self.loop_id, self.uuid, [str(k) for k in kinds]),
        )
        if not rows:
            return None
        t, kind, detail, wall = rows[0]
        return float(t), str(kind), str(detail), wall

    def read_event_rows(self) -> list[dict[str, object]]:
        """Every event, oldest first: ``time``, ``kind``, ``detail``, ``wall_time``."""
        rows = self.db.query(
            "SELECT time, kind, detail, wall_time FROM events WHERE store_uuid = %s "
            "ORDER BY time, id",
            (self.uuid,),
        )
        return [dict(zip(("time", "kind", "detail", "wall_time"), r, strict=True)) for r in rows]
