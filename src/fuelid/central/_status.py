"""The fleet as the central store sees it: one row per loop (``fuelid central status``).

Read-only queries on the indexes the fleet page uses: the loops and their stores, each store's
liveness row (its service record, its backlog when it last sent), the newest window and KPIs
of each loop, its open proposals and its waiting central requests.
"""

from __future__ import annotations

import time as _time
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import psycopg

__all__ = ["fleet_status"]

_LOOPS = """
SELECT l.loop_id, l.site_name,
       (SELECT count(*) FROM stores s WHERE s.loop_id = l.loop_id) AS stores,
       (SELECT extract(epoch FROM max(v.updated))::float8 FROM liveness v
         WHERE v.loop_id = l.loop_id) AS last_seen,
       cur.backlog_rows, cur.backlog_oldest_wall, cur.service,
       (SELECT k.time FROM kpis k WHERE k.loop_id = l.loop_id ORDER BY k.time DESC LIMIT 1)
         AS last_window_time,
       (SELECT count(*) FROM proposals p WHERE p.loop_id = l.loop_id
         AND p.status IN ('pending', 'approved')) AS open_proposals,
       (SELECT count(*) FROM requests r WHERE r.loop_id = l.loop_id
         AND r.status = 'waiting') AS waiting_requests
FROM loops l LEFT JOIN LATERAL (
    -- the loop's current store (fuelid.central._requests.newest_store): the one whose service
    -- beat last; a replaced store's stale backlog is not the loop's
    SELECT v.backlog_rows, v.backlog_oldest_wall, v.service FROM stores s
    JOIN liveness v USING (store_uuid) WHERE s.loop_id = l.loop_id
    ORDER BY (v.service ->> 'beat')::float8 DESC NULLS LAST, s.first_seen DESC LIMIT 1
) cur ON true
ORDER BY l.loop_id
"""


def fleet_status(con: psycopg.Connection, now: float | None = None) -> list[dict[str, Any]]:
    """One row per loop of the central store, by loop id.

    Keys: ``loop_id``, ``site_name``, ``stores``, ``last_seen`` [wall s UTC] and
    ``last_seen_age_s`` [s], ``backlog_rows`` and ``backlog_oldest_wall`` (of the loop's current
    store, whose service beat last: a replaced store's last backlog is not the loop's),
    ``service_beat`` (the
    site's last beat [wall s UTC]), ``service_stopped`` (its clean stop, None while it ran),
    ``last_window_time`` [plant s UTC], ``open_proposals``, ``waiting_requests``.
    """
    when = _time.time() if now is None else float(now)
    with con.transaction():
        rows = con.execute(_LOOPS).fetchall()
    out = []
    for (
        loop_id,
        site_name,
        stores,
        last_seen,
        backlog_rows,
        oldest,
        service,
        last_window,
        proposals,
        requests,
    ) in rows:
        record = service if isinstance(service, dict) else {}
        out.append(
            {
                "loop_id": loop_id,
                "site_name": site_name,
                "stores": int(stores),
                "last_seen": last_seen,
                "last_seen_age_s": None if last_seen is None else max(0.0, when - last_seen),
                "backlog_rows": None if backlog_rows is None else int(backlog_rows),
                "backlog_oldest_wall": oldest,
                "service_beat": record.get("beat"),
                "service_stopped": record.get("stopped"),
                "last_window_time": last_window,
                "open_proposals": int(proposals),
                "waiting_requests": int(requests),
            }
        )
    return out
