"""The raw archive: a loop's samples and events as hive-partitioned Parquet (issue 26).

``_layout.py`` is the format (paths, columns, atomic writes, readers), ``_writer.py`` the writer
from a store, ``_reader.py`` a loop read back like a store (:class:`ArchiveLoop`),
``_retention.py`` archive then prune.

The public API
--------------
The names in ``__all__``, each loaded on first use (pyarrow loads with the first of them).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from fuelid.archive._layout import (
        SAMPLE_SCHEMA,
        LoopDay,
        arrays_of,
        day_bounds,
        day_of,
        list_loop_days,
        partition_dir,
        read_day,
        read_day_table,
        read_loop_info,
        write_table,
    )
    from fuelid.archive._reader import ArchiveLoop
    from fuelid.archive._retention import archiver, keep_store
    from fuelid.archive._writer import archive_store

_HOMES = {
    "archive_store": "fuelid.archive._writer",
    "ArchiveLoop": "fuelid.archive._reader",
    "archiver": "fuelid.archive._retention",
    "arrays_of": "fuelid.archive._layout",
    "day_bounds": "fuelid.archive._layout",
    "day_of": "fuelid.archive._layout",
    "keep_store": "fuelid.archive._retention",
    "list_loop_days": "fuelid.archive._layout",
    "LoopDay": "fuelid.archive._layout",
    "partition_dir": "fuelid.archive._layout",
    "read_day": "fuelid.archive._layout",
    "read_day_table": "fuelid.archive._layout",
    "read_loop_info": "fuelid.archive._layout",
    "SAMPLE_SCHEMA": "fuelid.archive._layout",
    "write_table": "fuelid.archive._layout",
}
"""Exported name → the private module that defines it, imported on first use (PEP 562)."""

__all__ = [
    "SAMPLE_SCHEMA",
    "ArchiveLoop",
    "LoopDay",
    "archive_store",
    "archiver",
    "arrays_of",
    "day_bounds",
    "day_of",
    "keep_store",
    "list_loop_days",
    "partition_dir",
    "read_day",
    "read_day_table",
    "read_loop_info",
    "write_table",
]


def __getattr__(name: str) -> Any:
    # imported on use: importing the package loads none of its modules
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
