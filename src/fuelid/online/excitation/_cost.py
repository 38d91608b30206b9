"""What a test signal cost the loop, measured on a window's own samples (issue 40).

The design states the cost before a burst from the model (:mod:`~fuelid.online.excitation.
design`); after the window, the service stores what the data say beside it: the control error
e = y − setpoint over the stretch the signal touched (its first to its last non-zero sample and
one settling time after) against the rest of the window, which the signal did not touch.

- ``added_flow_sd_Lpm`` = √(max(0, var(e | touched) − var(e | quiet)) × the touched share of the
  window) [L/min]: the flow's added spread over the whole window, as the design states it;
- ``added_iae`` = (mean|e| touched − mean|e| quiet) × the touched duration [(L/min)·s].

Units: time [s], signal [V], flows [L/min].
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

MIN_QUIET_SAMPLES = 500
"""Fewest untouched samples the comparison needs (10 s at 50 Hz) [-]."""


def measured_cost(
    t: ArrayLike,
    y: ArrayLike,
    setpoint: ArrayLike,
    signal: ArrayLike,
    good: ArrayLike,
    tail_s: float,
) -> dict[str, Any] | None:
    """The signal's cost measured on one window; None when no signal ran in it.

    Parameters
    ----------
    t, y, setpoint, signal : array
        Sample times [s], flow and setpoint [L/min], the applied signal [V] (NaN: not recorded).
    good : array of bool
        Samples of good quality.
    tail_s : float
        How long the loop answers after the signal ends [s] (a settling time).

    Returns
    -------
    dict or None
        ``amplitude_V`` (largest |signal|), ``share`` (of the good samples with a signal),
        ``touched_s``, and ``added_flow_sd_Lpm`` and ``added_iae`` (None when fewer than
        :data:`MIN_QUIET_SAMPLES` untouched samples are left to compare with).

    Examples
    --------
    >>> t = np.arange(0.0, 100.0, 0.02)
    >>> s = np.where(t < 20.0, np.sign(np.sin(t)), 0.0) * 0.1
    >>> e = np.random.default_rng(0).normal(0.0, 0.1, t.size) + np.where(t < 25.0, s * 10, 0.0)
    >>> cost = measured_cost(t, 60.0 + e, np.full(t.size, 60.0), s, np.ones(t.size, bool), 5.0)
    >>> round(cost["added_flow_sd_Lpm"], 2), cost["amplitude_V"]
    (0.45, 0.1)
    """
    tt = np.asarray(t, dtype=float)
    ss = np.asarray(signal, dtype=float)
    ok = np.asarray(good, dtype=bool) & np.isfinite(ss)
    on = ok & (np.abs(np.nan_to_num(ss)) > 0.0)
    if not np.any(on):
        return None
    first, last = float(tt[on][0]), float(tt[on][-1])
    touched = (tt >= first) & (tt <= last + tail_s)
    error = np.asarray(y, dtype=float) - np.asarray(setpoint, dtype=float)
    usable = np.asarray(good, dtype=bool) & np.isfinite(error)
    out: dict[str, Any] = {
        "amplitude_V": float(np.max(np.abs(ss[on]))),
        "share": float(np.count_nonzero(on)) / float(max(int(np.count_nonzero(ok)), 1)),
        "touched_s": last + tail_s - first,
        "added_flow_sd_Lpm": None,
        "added_iae": None,
    }
    hit, quiet = error[usable & touched], error[usable & ~touched]
    if quiet.size < MIN_QUIET_SAMPLES or hit.size < 2:
        return out
    added = float(np.var(hit) - np.var(quiet)) * hit.size / (hit.size + quiet.size)
    out["added_flow_sd_Lpm"] = math.sqrt(max(added, 0.0))
    out["added_iae"] = float(np.mean(np.abs(hit)) - np.mean(np.abs(quiet))) * out["touched_s"]
    return out
