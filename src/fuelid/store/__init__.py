"""The sample store: samples and events of one site, durable, behind a small interface.

:class:`SampleStore` is the interface, :class:`SQLiteStore` the default (one SQLite file in WAL
mode), :class:`SampleWriter` the one writer (a queue and a thread committing about once a
second). :func:`open_store` opens a store by URL (``sqlite:///path.db``, as ``[store] url`` of the
site file); a PostgreSQL store is one more entry in :data:`STORES`.

:class:`OnlineHistory` keeps the online service's history (windows, models, proposals, writes of
gains, a little state) in the same SQLite file, on a connection of its own. :class:`LoopHistory`
and :class:`LoopStore` are what the readers of a loop (the reports, the dashboard) read of a
history and of its store: the site's file and the central database (:mod:`fuelid.central`)
both implement them.

Every table, the schema's version (:data:`SCHEMA_VERSION`) and the migrations that upgrade an
older store (:data:`MIGRATIONS`) are written once, in the code that creates the tables
(``store/_schema.py``; docs/reference/store.md quotes it).

The public API
--------------
The names in ``__all__``, at ``fuelid.store`` itself.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import lazy_loader

from fuelid.store._archived import ARCHIVE_COLUMNS, StoreDays
from fuelid.store._base import SampleStore, iodata_from_samples
from fuelid.store._loop_history import LoopHistory, LoopStore
from fuelid.store._online import REQUEST_KINDS, OnlineHistory
from fuelid.store._online_rows import (
    PROPOSAL_COLUMNS,
    PROPOSAL_STATUSES,
    PROPOSAL_TRANSITIONS,
    REQUEST_COLUMNS,
    SERVICE_KEY,
    WINDOW_COLUMNS,
    WRITE_COLUMNS,
    WRITE_KINDS,
    WRITE_STATUSES,
    history_counts,
    proposal_row,
    request_row,
    window_row,
    write_row,
)
from fuelid.store._records import (
    EVENT_KINDS,
    Event,
    PruneResult,
    Quality,
    Sample,
    SampleArrays,
    StoreError,
    StoreInfo,
    tag_map_hash,
)
from fuelid.store._schema import MIGRATIONS, SCHEMA_VERSION, build_at, default_loop_id
from fuelid.store._schema_v4 import OUTBOX_TABLES
from fuelid.store._sqlite import SQLiteStore
from fuelid.store._writer import SampleWriter

if TYPE_CHECKING:
    from fuelid.store._export import export_log, parse_time

# Each name is imported from its private module on first use (lazy_loader, SPEC 1), so
# that importing the package stays cheap.
__getattr__ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "_export": ["export_log", "parse_time"],
    },
)[0]

__all__ = [
    "ARCHIVE_COLUMNS",
    "EVENT_KINDS",
    "MIGRATIONS",
    "OUTBOX_TABLES",
    "PROPOSAL_COLUMNS",
    "PROPOSAL_STATUSES",
    "PROPOSAL_TRANSITIONS",
    "REQUEST_COLUMNS",
    "REQUEST_KINDS",
    "SCHEMA_VERSION",
    "SERVICE_KEY",
    "STORES",
    "WINDOW_COLUMNS",
    "WRITE_COLUMNS",
    "WRITE_KINDS",
    "WRITE_STATUSES",
    "Event",
    "LoopHistory",
    "LoopStore",
    "OnlineHistory",
    "PruneResult",
    "Quality",
    "SQLiteStore",
    "Sample",
    "SampleArrays",
    "SampleStore",
    "SampleWriter",
    "StoreDays",
    "StoreError",
    "StoreInfo",
    "build_at",
    "default_loop_id",
    "export_log",
    "history_counts",
    "iodata_from_samples",
    "open_store",
    "parse_time",
    "proposal_row",
    "request_row",
    "tag_map_hash",
    "window_row",
    "write_row",
]

STORES: dict[str, Callable[..., SampleStore]] = {"sqlite": SQLiteStore}
"""Store kinds by URL scheme: each takes the location and the keyword arguments of
:func:`open_store`."""


def open_store(url: str | Path, **kwargs: Any) -> SampleStore:
    """Open a store by URL (``sqlite:///path.db``) or, for SQLite, by a plain file path.

    Parameters
    ----------
    url : str or Path
        ``scheme:///location``; a path without a scheme is an SQLite file.
    **kwargs
        ``site_name``, ``tag_map_hash`` (needed to create or write) and ``period_s`` [s].

    Raises
    ------
    StoreError
        Unknown scheme, or the store cannot be opened (see the store's class).

    Examples
    --------
    >>> sorted(STORES)
    ['sqlite']
    """
    text = str(url)
    scheme, sep, location = text.partition(":///")
    if not sep:
        scheme, location = "sqlite", text
    try:
        factory = STORES[scheme]
    except KeyError:
        known = ", ".join(f"{name}:///" for name in STORES)
        raise StoreError(f"{text}: unknown store kind {scheme!r}; known: {known}") from None
    return factory(location, **kwargs)
