"""A long line drawn thinned per pixel column keeps its extremes and its gaps."""

from __future__ import annotations

import numpy as np

from fuelid.plots._common import MAX_LINE_POINTS, pixel_extremes

H = 0.02


def test_a_long_line_keeps_its_extremes_and_its_gaps_per_pixel_column() -> None:
    rng = np.random.default_rng(0)
    n = 3 * MAX_LINE_POINTS
    t = np.arange(n) * H
    y = np.cumsum(rng.normal(size=n))
    y[n // 3] = np.nan  # a gap: the line must still break there
    tr, yr = pixel_extremes(t, y, columns=500)
    assert tr.size <= 4 * 500 + 3
    assert np.all(np.diff(tr) > 0.0)
    # every run of samples keeps its first, last, lowest and highest value
    width = -(-n // 500)
    for start in range(0, n, width):
        block, kept = y[start : start + width], yr[(tr >= t[start]) & (tr < t[start] + width * H)]
        assert np.nanmin(kept) == np.nanmin(block)
        assert np.nanmax(kept) == np.nanmax(block)
        assert kept[0] == block[0] or np.isnan(block[0])
    assert np.isnan(yr).sum() == 1
    short = np.arange(10.0)
    assert pixel_extremes(short, short)[1] is short or np.array_equal(
        pixel_extremes(short, short)[1], short
    )
