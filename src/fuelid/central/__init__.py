"""The central PostgreSQL store every loop's service sends to (issue 26).

One database shared by all loops holds their windows, KPIs, models, proposals, writes, events,
requests and liveness, keyed by each site store's UUID and row id; the site's SQLite store stays
the durable buffer. :func:`migrate` creates or upgrades the schema and its versioned migrations
(monthly partitions, retention: :func:`drop_old_partitions`); :func:`connect` connects from a
libpq URL; :func:`enable_outbox` switches on the site's change log; :class:`Sender` is the sync
engine (COPY into staging, upsert, exactly once); :func:`file_central_request` files an action
taken centrally, which each site fetches (:func:`fetch_waiting`) and carries out itself;
:func:`fleet_status` gives the fleet's rows. A reader of the central store (the dashboard) holds
one :class:`CentralDB` and reads a loop through :class:`CentralHistory` and
:class:`CentralStoreView`, the central implementations of :class:`fuelid.store.LoopHistory`
and :class:`fuelid.store.LoopStore`. The service's side is :class:`fuelid.online.CentralLink`;
the reference: docs/reference/central.md.

psycopg (the ``fleet`` extra) is imported only when a connection is made.

The public API
--------------
The names in ``__all__``, at ``fuelid.central`` itself.
"""

from __future__ import annotations

from fuelid.central._connect import CentralError, connect, redact
from fuelid.central._db import CentralDB
from fuelid.central._history import (
    LIVENESS_KEYS,
    CentralHistory,
    CentralStoreView,
    central_loop_ids,
    liveness_row,
    shown_store,
)
from fuelid.central._outbox import enable_outbox, open_store_file, sync_status
from fuelid.central._reidentified import register_run, send_loop_day
from fuelid.central._requests import (
    DEFAULT_EXPIRY_S,
    EXCITE_START_EXPIRY_S,
    KINDS,
    central_requests,
    claim,
    fetch_waiting,
    file_central_request,
    finish_central_request,
    mark_fetched,
    newest_store,
)
from fuelid.central._schema import (
    SCHEMA_VERSION,
    check_schema,
    drop_old_partitions,
    migrate,
    schema_version,
)
from fuelid.central._sender import Sender, SyncResult
from fuelid.central._status import fleet_status

__all__ = [
    "DEFAULT_EXPIRY_S",
    "EXCITE_START_EXPIRY_S",
    "KINDS",
    "LIVENESS_KEYS",
    "SCHEMA_VERSION",
    "CentralDB",
    "CentralError",
    "CentralHistory",
    "CentralStoreView",
    "Sender",
    "SyncResult",
    "central_loop_ids",
    "central_requests",
    "check_schema",
    "claim",
    "connect",
    "drop_old_partitions",
    "enable_outbox",
    "fetch_waiting",
    "file_central_request",
    "finish_central_request",
    "fleet_status",
    "liveness_row",
    "mark_fetched",
    "migrate",
    "newest_store",
    "open_store_file",
    "redact",
    "register_run",
    "schema_version",
    "send_loop_day",
    "shown_store",
    "sync_status",
]
