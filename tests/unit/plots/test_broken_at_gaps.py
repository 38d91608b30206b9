"""A contiguous record is drawn as it is: no break where there is no gap."""

from __future__ import annotations

import numpy as np

from fuelid.plots._identification import broken_at_gaps

H = 0.1


def test_broken_at_gaps_leaves_a_contiguous_record_alone() -> None:
    t = H * np.arange(50)
    out_t, out_y = broken_at_gaps(t, np.ones(50))
    np.testing.assert_array_equal(out_t, t)
    np.testing.assert_array_equal(out_y, np.ones(50))
