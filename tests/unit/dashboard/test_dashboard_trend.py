"""The trend's choice of source and its thinning (fuelid.dashboard._trend)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("tsdownsample")
pytest.importorskip("fastapi")

from fuelid.dashboard._trend import LOD_MAX_BUCKETS, RAW_MAX_SAMPLES, choose_source, thin


@pytest.mark.parametrize(
    ("span_s", "period_s", "level"),
    [
        (RAW_MAX_SAMPLES * 0.02, 0.02, None),  # exactly the raw limit: raw
        (RAW_MAX_SAMPLES * 0.02 + 1.0, 0.02, 1),  # one second more: 1 s buckets
        (LOD_MAX_BUCKETS * 1.0, 0.02, 1),
        (LOD_MAX_BUCKETS * 1.0 + 1.0, 0.02, 10),
        (86_400.0, 0.02, 10),  # a day at 50 Hz never reads raw rows
        (30 * 86_400.0, 0.02, 10),  # coarser than the coarsest level: still 10 s
        (3_600.0, 1.0, None),  # a 1 Hz loop's hour is 3,600 samples: raw
    ],
)
def test_the_source_follows_the_span(span_s: float, period_s: float, level: int | None) -> None:
    assert choose_source(span_s, period_s) == level


def test_thinning_keeps_about_n_points_in_order_and_an_isolated_spike() -> None:
    rng = np.random.default_rng(3)
    x = np.arange(1_000_000) * 0.02
    y = rng.normal(0.0, 1.0, x.size)
    y[654_321] = 50.0  # a spike 50 sigma high: the largest triangle of its bucket
    keep = thin(x, y, 2000)
    assert keep.size <= 2000
    assert np.all(np.diff(keep) > 0)
    assert 654_321 in keep


def test_thinning_leaves_nan_out_and_returns_short_series_whole() -> None:
    y = np.array([1.0, np.nan, 3.0, 4.0])
    assert thin(np.arange(4.0), y, 100).tolist() == [0, 2, 3]
    x = np.arange(10_000.0)
    y = np.sin(x / 100.0)
    y[::7] = np.nan
    keep = thin(x, y, 500)
    assert keep.size <= 500
    assert np.all(np.isfinite(y[keep]))
