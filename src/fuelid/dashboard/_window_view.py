"""What the window page shows: the window's data against its model, the residuals, every gate.

The stored model is simulated on the window's own samples (each segment between gaps from rest
at its first command, the output offset by least squares: the free response the estimator also
fitted is not stored, so the first settling time of each segment may disagree; the page says
so). The residuals' autocorrelation is drawn with the gate's bound (``max_residual_acf``) and,
for reference, the ±1.96/√n band of white noise.

Every gate's measured value is set against its threshold from the settings the service ran with
(its record in the store), or the defaults of ``[online]`` when the store has no record (then
said so).
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np

from fuelid.errors import FuelidError
from fuelid.identify import residual_whiteness
from fuelid.model import nrmse_fit, simulate_model
from fuelid.online import Online, model_of
from fuelid.store import SampleArrays, iodata_from_samples

__all__ = ["ACF_MAX_LAGS", "MAX_POINTS", "gate_table", "window_evidence"]

ACF_MAX_LAGS = 2000
"""Lags of the residual autocorrelation drawn at most [samples]."""
MAX_POINTS = 6000
"""Points per series sent to the page at most (every k-th sample beyond)."""

# gate: (measured key, setting key, relation, what it is)
_GATES: tuple[tuple[str, str, str, str], ...] = (
    ("bad_share", "max_bad_share", "<=", "share of lost or flagged samples"),
    ("limit_share", "max_limit_share", "<=", "share of the window with the drive at a limit"),
    ("excitation_events", "", ">=1", "setpoint or command moves that excite the loop"),
    ("rel_stderr_K", "max_rel_stderr_K", "<=", "relative standard error of K"),
    ("rel_stderr_T", "max_rel_stderr_T", "<=", "relative standard error of T"),
    ("fit_percent", "min_fit_percent", ">=", "validation fit [%]"),
    ("residual_acf_max", "max_residual_acf", "<=", "largest |residual autocorrelation|"),
    ("plant_ratio", "plant_ratio_event", "in", "K / the plant file's K (an event, not a gate)"),
)


def gate_table(measured: dict[str, Any], settings: dict[str, Any] | None) -> list[dict[str, Any]]:
    """Each gate's measured value, threshold and verdict (None where it was not measured).

    Parameters
    ----------
    measured : dict
        The window's ``gates.measured``.
    settings : dict or None
        The ``[online]`` table the service ran with; None: its defaults (the rows say so).
    """
    source = "the service's settings" if settings else "the defaults of [online]"
    values = {**Online().model_dump(), **(settings or {})}
    rows = []
    for key, setting, relation, what in _GATES:
        value = measured.get(key)
        threshold: Any = 1 if relation == ">=1" else values.get(setting)
        passed: bool | None = None
        if isinstance(value, int | float) and threshold is not None:
            if relation == "<=":
                passed = value <= threshold
            elif relation in (">=", ">=1"):
                passed = value >= threshold
            elif relation == "in":
                passed = threshold[0] <= value <= threshold[1]
        if relation == "in" and isinstance(threshold, list | tuple):
            threshold_text = f"in [{threshold[0]:g}, {threshold[1]:g}]"
        elif threshold is None:
            threshold_text = "-"
        else:
            shown = ">=" if relation == ">=1" else relation
            threshold_text = f"{shown} {threshold:.3g}"
        rows.append(
            {
                "gate": key,
                "threshold_text": threshold_text,
                "what": what,
                "measured": value,
                "threshold": threshold,
                "relation": ">=" if relation == ">=1" else relation,
                "passed": passed,
                "threshold_from": source,
            }
        )
    return rows


def _every(n: int) -> int:
    return max(1, math.ceil(n / MAX_POINTS))


def window_evidence(
    row: dict[str, Any],
    samples: SampleArrays,
    period_s: float | None,
    settings: dict[str, Any] | None,
) -> dict[str, Any]:
    """The window page's numbers: data, simulation, residuals, ACF, gates.

    Returns
    -------
    dict
        ``samples`` (stored in the window's span), ``expected`` (span / period),
        ``thinned`` (True when retention left fewer than 90 % of the expected samples),
        ``t`` [plant s], ``y``, ``y_sim``, ``residual`` [L/min], ``u`` [V] (every k-th sample
        beyond :data:`MAX_POINTS`), ``fit_percent`` of the simulation [%], ``acf`` (lags [s],
        values), ``acf_bound`` (the gate's), ``white_band`` (1.96/√n), ``gates``
        (:func:`gate_table`), ``note`` (how the simulation starts), ``reason`` when the model
        could not be simulated.
    """
    detail = row.get("detail") or {}
    measured = (detail.get("gates") or {}).get("measured") or {}
    span = float(row["t_to"]) - float(row["t_from"])
    expected = None if not period_s else round(span / period_s)
    out: dict[str, Any] = {
        "samples": len(samples),
        "expected": expected,
        "thinned": bool(expected and len(samples) < 0.9 * expected),
        "gates": gate_table(measured, settings),
        "note": "the model simulated from rest at each segment's first command, its offset "
        "fitted by least squares (the estimator's fitted free response is not stored: the "
        "first settling time of a segment may differ)",
    }
    model = model_of(detail)
    try:
        data = iodata_from_samples(samples, period_s, source="window")
    except FuelidError as error:
        return {**out, "reason": str(error)}
    t = data.t0 + data.sample_time * np.arange(data.u.size)
    y_sim = np.full(data.y.size, math.nan)
    if model is not None:
        bounds = [0, *data.segment_starts, data.u.size]
        for a, b in itertools.pairwise(bounds):
            if b - a < 2:
                continue
            sim = simulate_model(model, data.u[a:b] - data.u[a], data.sample_time)
            y_sim[a:b] = sim + float(np.mean(data.y[a:b] - sim))
        # real times: segments after gaps start at their own t0
        for start, t0 in zip(data.segment_starts, data.segment_t0, strict=True):
            t[start:] = t0 + data.sample_time * np.arange(data.u.size - start)
    residual = data.y - y_sim
    k = _every(data.y.size)
    out.update(
        t=t[::k].tolist(),
        y=data.y[::k].tolist(),
        u=data.u[::k].tolist(),
        y_sim=[None if not math.isfinite(v) else v for v in y_sim[::k].tolist()],
        residual=[None if not math.isfinite(v) else v for v in residual[::k].tolist()],
    )
    if model is None:
        return {**out, "reason": "no model was fitted in this window"}
    out["fit_percent"] = nrmse_fit(data.y, y_sim)
    lags = int(
        min(measured.get("residual_acf_lags") or ACF_MAX_LAGS, ACF_MAX_LAGS, residual.size - 1)
    )
    # as identify and the gate compute it: within segments, over the record's variance
    test = residual_whiteness(residual, lags, data.segment_starts)
    out["acf"] = {"lag_s": (test.lags * data.sample_time).tolist(), "value": test.values.tolist()}
    values = {**Online().model_dump(), **(settings or {})}
    out["acf_bound"] = values.get("max_residual_acf")
    out["acf_basis"] = measured.get("residual_acf_basis")
    out["white_band"] = test.bound
    return out
