"""The level-of-detail table at ingest: min/max per bucket of the samples a batch added.

``samples_lod`` (:mod:`fuelid.store._schema`) holds, per bucket of ``level`` seconds of plant time,
the count, the minimum and maximum of u, flow, setpoint and fuel temperature, and the number of
samples not ok. :func:`lod_rows` summarises a batch; :data:`UPSERT_LOD` merges those rows into
the table in the batch's transaction; :data:`RECOUNT_BAD` recounts a bucket's bad samples after
a re-flag; :func:`read_lod` reads a level's buckets back as arrays (the dashboard's trend).
"""

from __future__ import annotations

import math
import sqlite3
from collections.abc import Sequence
from typing import Any

import numpy as np

from fuelid.store._records import Sample

__all__ = ["LOD_SERIES", "RECOUNT_BAD", "UPSERT_LOD", "lod_rows", "read_lod"]

_LOD_VALUES = ("u", "y", "sp", "tf")
LOD_SERIES = {"y": "y", "setpoint": "sp", "u": "u", "fuel_temperature": "tf"}
"""The series ``samples_lod`` keeps, by the samples' field name: its column's short name."""


def _lod_merge(name: str) -> str:
    """``name_min``/``name_max`` of a bucket merged with a new one (a NULL side is ignored)."""
    return ", ".join(
        f"{name}_{op} = {op}(coalesce({name}_{op}, excluded.{name}_{op}), "
        f"coalesce(excluded.{name}_{op}, {name}_{op}))"
        for op in ("min", "max")
    )


UPSERT_LOD = (
    "INSERT INTO samples_lod VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) "
    "ON CONFLICT(level, bucket) DO UPDATE SET n = n + excluded.n, "
    + ", ".join(_lod_merge(name) for name in _LOD_VALUES)
    + ", bad = bad + excluded.bad"
)
# a re-flag: the buckets it touched recount their bad samples (never lower than before:
# thinning may have deleted some of the samples a bucket counted)
RECOUNT_BAD = (
    "UPDATE samples_lod SET bad = max(bad, (SELECT count(*) FROM samples WHERE time >= bucket "
    "AND time < bucket + level AND quality != 0)) "
    "WHERE level = ?3 AND bucket >= floor(?1 / ?3) * ?3 AND bucket <= ?2"
)


def lod_rows(samples: Sequence[Sample], level: int) -> list[tuple[object, ...]]:
    """The ``samples_lod`` rows of some samples at one level [s]: one row per bucket touched.

    Min and max ignore NaN (as SQL's MIN and MAX ignore NULL); a bucket whose values are all
    NaN has NULL there.
    """
    if not samples:
        return []
    t = np.array([s.time for s in samples], dtype=float)
    bucket = np.floor(t / level) * level
    values = [
        np.array([np.nan if v is None else v for v in column], dtype=float)
        for column in (
            [s.u for s in samples],
            [s.y for s in samples],
            [s.setpoint for s in samples],
            [s.fuel_temperature for s in samples],
        )
    ]
    bad = np.array([int(s.quality) != 0 for s in samples], dtype=int)
    order = np.argsort(bucket, kind="stable")
    keys, starts, counts = np.unique(bucket[order], return_index=True, return_counts=True)
    rows: list[tuple[object, ...]] = []
    extremes = []
    for column in values:
        c = column[order]
        extremes.append((np.fmin.reduceat(c, starts), np.fmax.reduceat(c, starts)))
    bads = np.add.reduceat(bad[order], starts)
    for k, key in enumerate(keys):
        row: list[object] = [int(level), float(key), int(counts[k])]
        for lo, hi in extremes:
            row.extend(None if np.isnan(x) else float(x) for x in (lo[k], hi[k]))
        row.append(int(bads[k]))
        rows.append(tuple(row))
    return rows


def read_lod(
    con: sqlite3.Connection, level: int, t_from: float, t_to: float
) -> dict[str, np.ndarray[Any, Any]]:
    """The buckets of ``level`` s that start in ``[t_from, t_to)`` [plant s], as arrays.

    From the bucket that holds ``t_from``. Keys ``bucket`` (its start [plant s]), ``n``,
    ``bad``, and ``<series>_min`` / ``<series>_max`` for each of :data:`LOD_SERIES` (NaN where
    a bucket has no value).
    """
    cols = ", ".join(f"{c}_min, {c}_max" for c in LOD_SERIES.values())
    rows = con.execute(
        f"SELECT bucket, n, bad, {cols} FROM samples_lod "
        "WHERE level = ? AND bucket >= ? AND bucket < ? ORDER BY bucket",
        (int(level), math.floor(t_from / level) * level, float(t_to)),
    ).fetchall()
    data = np.array(
        [[math.nan if v is None else v for v in row] for row in rows], dtype=np.float64
    ).reshape(len(rows), 3 + 2 * len(LOD_SERIES))
    out = {"bucket": data[:, 0], "n": data[:, 1], "bad": data[:, 2]}
    for k, name in enumerate(LOD_SERIES):
        out[f"{name}_min"] = data[:, 3 + 2 * k]
        out[f"{name}_max"] = data[:, 4 + 2 * k]
    return out
