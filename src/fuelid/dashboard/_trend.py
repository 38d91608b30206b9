"""A trend of one loop's samples at the detail a chart can show, never more.

A chart ``width`` pixels wide shows at most about two points per pixel. ``trend`` picks the
source by the span asked for: raw samples when they are few enough (at most
``RAW_MAX_SAMPLES`` in the span), else the finest level of the level-of-detail table
(min/max per 1 s or 10 s bucket, written at ingest) that keeps the bucket count under
``LOD_MAX_BUCKETS``. A day at 50 Hz (4.3 million samples) is then 8,640 buckets of 10 s, and
raw rows are never fetched for a day-long view. What comes back is thinned further with
tsdownsample's MinMaxLTTB to about ``2 × width`` points per series (the shape and its peaks
kept; the charts ask again for a zoomed range).

A bucket becomes two points, its minimum at the bucket's start and its maximum at its middle,
so a thinned envelope still shows the band a noisy signal covers.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fuelid.dashboard._source import TREND_COLUMNS, LoopReader, Trend
from fuelid.io.jsonsafe import json_ready

__all__ = ["LOD_LEVELS", "LOD_MAX_BUCKETS", "RAW_MAX_SAMPLES", "choose_source", "thin", "trend"]

LOD_LEVELS = (1, 10)
"""Bucket widths of the level-of-detail table [s] (the store's ``samples_lod``)."""
RAW_MAX_SAMPLES = 40_000
"""Raw samples are read when the span holds at most this many (13 min at 50 Hz)."""
LOD_MAX_BUCKETS = 20_000
"""The finest level with at most this many buckets in the span is read (5.5 h of 1 s buckets)."""
POINTS_PER_PIXEL = 2


def choose_source(span_s: float, period_s: float | None) -> int | None:
    """The level [s] to read for a span, None for raw samples.

    Examples
    --------
    >>> choose_source(600.0, 0.02)  # 30,000 samples: raw
    >>> choose_source(3600.0, 0.02)  # 180,000 samples: 1 s buckets
    1
    >>> choose_source(86400.0, 0.02)  # a day: 10 s buckets
    10
    """
    period = period_s if period_s and period_s > 0.0 else 0.02
    if span_s / period <= RAW_MAX_SAMPLES:
        return None
    for level in LOD_LEVELS:
        if span_s / level <= LOD_MAX_BUCKETS:
            return level
    return LOD_LEVELS[-1]


def thin(x: np.ndarray[Any, Any], y: np.ndarray[Any, Any], n_out: int) -> np.ndarray[Any, Any]:
    """Indices of about ``n_out`` points of (x, y) that keep its shape (MinMaxLTTB).

    NaN values are kept out of the choice (tsdownsample needs finite data) and the indices of
    finite points returned, sorted; every point when there are few.
    """
    finite = np.flatnonzero(np.isfinite(y))
    if finite.size <= max(n_out, 3):
        return finite
    from tsdownsample import MinMaxLTTBDownsampler

    chosen = MinMaxLTTBDownsampler().downsample(  # type: ignore[no-untyped-call]
        np.ascontiguousarray(x[finite], dtype=np.float64),
        np.ascontiguousarray(y[finite], dtype=np.float64),
        n_out=int(n_out),
    )
    return np.asarray(finite[np.asarray(chosen, dtype=np.int64)])


def trend(loop: LoopReader, start: float, end: float, width: int = 1000) -> Trend:
    """The loop's samples in ``[start, end)`` [plant s] for a chart ``width`` pixels wide.

    Returns
    -------
    Trend
        See :class:`~fuelid.dashboard._source.Trend`: per series its own thinned times (``t`` is
        a dict of series → times, as each series keeps different points).
    """
    width = int(min(max(width, 50), 4000))
    n_out = POINTS_PER_PIXEL * width
    period = loop.identity().get("period_s")
    level = choose_source(max(end - start, 0.0), period)
    series: dict[str, dict[str, list[float | None]]] = {}
    if level is None:
        raw = loop.samples(start, end)
        points = len(raw)
        bad = raw.time[raw.quality != 0]
        for name in TREND_COLUMNS:
            values = np.asarray(getattr(raw, name), dtype=np.float64)
            keep = thin(raw.time, values, n_out)
            series[name] = {"t": json_ready(raw.time[keep]), "v": json_ready(values[keep])}
    else:
        rows = loop.lod(level, start, end)
        bucket = rows["bucket"]
        points = int(bucket.size * 2)
        bad = bucket[rows["bad"] > 0]
        # two points a bucket: the minimum at its start, the maximum at its middle
        x = np.empty(2 * bucket.size)
        x[0::2], x[1::2] = bucket, bucket + 0.5 * level
        for name in TREND_COLUMNS:
            v = np.empty(2 * bucket.size)
            v[0::2], v[1::2] = rows[f"{name}_min"], rows[f"{name}_max"]
            keep = thin(x, v, n_out)
            series[name] = {"t": json_ready(x[keep]), "v": json_ready(v[keep])}
    if bad.size > n_out:  # a mark per pixel is all a chart can show
        bad = bad[np.linspace(0, bad.size - 1, n_out).astype(np.int64)]
    return Trend(
        source="raw" if level is None else "lod",
        level_s=level,
        start=float(start),
        end=float(end),
        series=series,
        bad=json_ready(np.asarray(bad, dtype=np.float64)),
        points=points,
    )
