"""Array types and the quality mask the loop-health modules share."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def _ok_mask(n: int, ok: ArrayLike | None) -> BoolArray:
    return np.ones(n, dtype=bool) if ok is None else np.asarray(ok, dtype=bool)
