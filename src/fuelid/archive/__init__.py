"""The raw archive: a loop's samples and events as hive-partitioned Parquet (issue 26).

The format: a loop-day's partition (:class:`LoopDay`, :func:`partition_dir`,
:func:`list_loop_days`), its columns (:data:`SAMPLE_SCHEMA`), atomic writes
(:func:`write_table`) and readers (:func:`read_day`, :func:`read_day_table`). A store's finished
days are written by :func:`archive_store`; :class:`ArchiveLoop` reads a loop back like a store;
:func:`archiver` and :func:`keep_store` archive, then prune.

The public API
--------------
The names in ``__all__``, each loaded on first use (pyarrow loads with the first of them).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

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

# Each name is imported from its private module on first use (lazy_loader, SPEC 1), so
# that importing the package stays cheap.
__getattr__ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "_layout": [
            "LoopDay",
            "SAMPLE_SCHEMA",
            "arrays_of",
            "day_bounds",
            "day_of",
            "list_loop_days",
            "partition_dir",
            "read_day",
            "read_day_table",
            "read_loop_info",
            "write_table",
        ],
        "_reader": ["ArchiveLoop"],
        "_retention": ["archiver", "keep_store"],
        "_writer": ["archive_store"],
    },
)[0]

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
