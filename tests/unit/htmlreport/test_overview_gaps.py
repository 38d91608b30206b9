"""The report's overview breaks its lines one period after a gap starts."""

from __future__ import annotations

import numpy as np
import pytest

from fuelid.io.timeseries import IOData


def test_the_overview_breaks_its_lines_one_period_after_a_gap_starts() -> None:
    # a 100 s gap in a 0.1 s log: the held command must not be drawn across half of it
    from fuelid.htmlreport import _overview_series

    u = np.repeat([1.0, 2.0], 200)
    y = 20.0 + 13.8 * (u - 1.0)
    data = IOData(u, y, 0.1, segment_starts=(200,), segment_t0=(120.0,))
    series = _overview_series(data)
    t_break = series.time[200]
    assert np.isnan(series["u_V"][200])
    assert t_break == pytest.approx(19.9 + 0.1)  # the last sample's time plus one period
