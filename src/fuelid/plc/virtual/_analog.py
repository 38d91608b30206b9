"""The virtual PLC's analog inputs: engineering values as int16 counts and back.

A scale is ``(raw0, raw1, eng0, eng1)``: two points of the linear map, as a Siemens analog input
reads 0…27648 counts for its span (:data:`~fuelid.plc.virtual._points.FLOW_COUNTS`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

__all__ = ["from_counts", "to_counts"]


def to_counts(value: float | FloatArray, scale: tuple[float, float, float, float]) -> FloatArray:
    """Analog-input counts (int16 range) of engineering values, rounded."""
    raw0, raw1, eng0, eng1 = scale
    counts = raw0 + (np.asarray(value, dtype=float) - eng0) * (raw1 - raw0) / (eng1 - eng0)
    clipped: FloatArray = np.clip(np.round(counts), -32768.0, 32767.0)
    return clipped


def from_counts(counts: FloatArray, scale: tuple[float, float, float, float]) -> FloatArray:
    """Engineering values of analog-input counts (the inverse of :func:`to_counts`)."""
    raw0, raw1, eng0, eng1 = scale
    eng: FloatArray = eng0 + (counts - raw0) * (eng1 - eng0) / (raw1 - raw0)
    return eng
