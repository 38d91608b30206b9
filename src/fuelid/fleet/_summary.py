"""The per-loop pass after the loop-days: the K(T) tracker and the loop's summary.

**K(T).** The service's own :class:`~fuelid.online._tracking.KTracker` over the loop's accepted
windows in time order, all of them (the service keeps its newest few hundred; a period's
re-identification asks about the whole period): the ratio K/K_plant(u, T) against fuel
temperature with a plant file, K per command band without one. Written to
``RESULT/tracking/<loop_id>.json``.

**K drift over the period.** Each accepted window's K is first *referred* to a common operating
point, so that a period that happened to run warmer or at another command does not look like
wear: with a plant file, q = K / K_plant(u, T) (the plant model's gain at the window's command
and temperature; se_q = se_K / K_plant); without one, q = K − b·(T − T_ref) with b from one
weighted fit K = a + b·(T − T_ref) + c·(t − t̄) over the period (the time term keeps a seasonal
temperature trend from absorbing real wear into b; no correction when the temperatures spread
less than the tracker's 2 °C). Only windows that do not overlap are used (the service's windows
overlap by default: 600 s every 300 s, so neighbours share half their samples and are not
independent evidence). The drift is the relative change of the inverse-variance weighted mean
of q between the first and the last tenth of those windows (at least one window each)::

    drift = q̄_last / q̄_first − 1,   se by the delta method from the two means' standard errors,

both means' variances inflated by the Birge ratio max(1, χ²/dof) of a straight line q(t) over
the whole period (the scatter the stated errors do not explain, slow correlations included as
far as they show as scatter; a tenth of one window would have none of its own), and, without a
plant file, b's standard error carried through the two tenths' mean temperatures. Tenths rather
than calendar weeks: the period may be two days or a year, and a tenth of the windows always
holds the same share of the evidence.

**K(T) slope.** The tracker's slope with its 95 % interval (Student's t with the fit's degrees
of freedom, the Birge inflation included): d(K/K_plant)/dT [1/°C] in ratio mode, dK/dT
[(L/min)/V/°C] of the command band with the most windows in band mode.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from fuelid.online import KTracker, PlantGain, TrackingError, observation_of

__all__ = ["SUMMARY_UNITS", "k_drift", "loop_summary", "read_results", "track_loop"]

SUMMARY_UNITS = {
    "k_drift": "1 (relative change)",
    "k_drift_se": "1",
    "k_slope": "1/degC (ratio) or (L/min)/V/degC (band)",
    "k_slope_ci95": "as k_slope",
    "accepted_share": "1",
    "seconds": "s",
    "windows_per_s": "1/s",
}
"""Units of the per-loop summary's numbers."""


def read_results(
    out_root: str | Path, loop_id: str, date_from: str | None = None, date_to: str | None = None
) -> pa.Table:
    """The finished loop-days of ``loop_id`` in ``RESULT/windows`` (dates inclusive), by end."""
    from fuelid.fleet._task import RESULT_SCHEMA

    folder = Path(out_root) / "windows" / f"loop={loop_id}"
    files = [
        f
        for f in sorted(folder.glob("date=*/part.parquet"))
        if (date_from is None or f.parent.name[5:] >= date_from)
        and (date_to is None or f.parent.name[5:] <= date_to)
    ]
    if not files:
        return RESULT_SCHEMA.empty_table()
    table = pa.concat_tables([pq.read_table(f, schema=RESULT_SCHEMA) for f in files])
    return table.sort_by("t_to")


def _accepted_rows(table: pa.Table) -> list[dict[str, Any]]:
    columns = ["t_from", "t_to", "K", "se_K", "T_fuel", "u_mean", "plant_K"]
    rows = table.filter(table.column("accepted")).select(columns).to_pylist()
    return [r for r in rows if r["K"] is not None and r["se_K"] is not None]


def track_loop(table: pa.Table, k_plant: PlantGain | None) -> tuple[KTracker | None, str]:
    """The K(T) tracker fitted on the accepted windows; (None, the reason) when it refuses."""
    observations = []
    for row in _accepted_rows(table):
        model = {
            "model": {"K": row["K"]},
            "stderr": {"K": row["se_K"]},
            "T_fuel": row["T_fuel"],
            "u_mean": row["u_mean"],
            "plant_K": row["plant_K"],
            "window_end": row["t_to"],
        }
        obs = observation_of({"model": model, "t_to": row["t_to"]})
        if obs is not None:
            observations.append(obs)
    try:
        return KTracker(k_plant=k_plant).fit(observations), ""
    except TrackingError as error:
        return None, str(error)


def _non_overlapping(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The windows, in time order, that share no sample with the one kept before them."""
    kept: list[dict[str, Any]] = []
    for row in rows:
        if not kept or row["t_from"] >= kept[-1]["t_to"]:
            kept.append(row)
    return kept


def _weighted_mean(
    q: np.ndarray[Any, Any], se: np.ndarray[Any, Any], birge: float
) -> tuple[float, float]:
    w = 1.0 / se**2
    mean = float(np.sum(w * q) / np.sum(w))
    return mean, math.sqrt(birge / float(np.sum(w)))


def _weighted_fit(
    X: np.ndarray[Any, Any], y: np.ndarray[Any, Any], se: np.ndarray[Any, Any]
) -> tuple[np.ndarray[Any, Any], np.ndarray[Any, Any], float]:
    """Weighted least squares: coefficients, their covariance (unscaled) and the Birge ratio."""
    sw = 1.0 / se
    coef, *_ = np.linalg.lstsq(X * sw[:, None], y * sw, rcond=None)
    cov = np.linalg.pinv((X * sw[:, None]).T @ (X * sw[:, None]))
    dof = y.size - X.shape[1]
    chi2 = float(np.sum(((y - X @ coef) * sw) ** 2))
    return coef, cov, max(1.0, chi2 / dof) if dof > 0 else 1.0


def k_drift(table: pa.Table) -> tuple[float | None, float | None, str]:
    """Relative K drift over the period and its standard error (module docstring); a note."""
    rows = _non_overlapping(
        [
            r
            for r in _accepted_rows(table)
            if r["se_K"] > 0.0 and r["K"] > 0.0 and r["T_fuel"] is not None
        ]
    )
    if len(rows) < 2:
        return None, None, f"K drift needs at least 2 accepted windows apart, got {len(rows)}"
    K = np.array([r["K"] for r in rows])
    se = np.array([r["se_K"] for r in rows])
    T = np.array([r["T_fuel"] for r in rows])
    t = np.array([r["t_to"] for r in rows])
    t = (t - t.mean()) / 86400.0  # [d] about the period's middle
    plant = [r["plant_K"] for r in rows]
    n = max(1, math.ceil(len(rows) / 10))
    se_b = 0.0
    if all(p is not None and p > 0.0 for p in plant):
        Kp = np.array(plant, dtype=float)
        q, se_q = K / Kp, se / Kp
        how = "K/K_plant(u, T)"
    else:
        T_ref = float(np.sum(T / se**2) / np.sum(1.0 / se**2))
        if float(np.ptp(T)) < 2.0 or len(rows) < 4:
            slope = 0.0
        else:
            X = np.column_stack([np.ones(len(rows)), T - T_ref, t])
            coef, cov, birge_fit = _weighted_fit(X, K, se)
            slope, se_b = float(coef[1]), math.sqrt(birge_fit * float(cov[1, 1]))
        q, se_q = K - slope * (T - T_ref), se
        how = f"K referred to {T_ref:.1f} degC by dK/dT = {slope:.4g} (L/min)/V/degC"
    # the scatter about a straight line q(t) over the whole period, beyond the stated errors
    birge = _weighted_fit(np.column_stack([np.ones(len(rows)), t]), q, se_q)[2]
    first, se_first = _weighted_mean(q[:n], se_q[:n], birge)
    last, se_last = _weighted_mean(q[-n:], se_q[-n:], birge)
    drift = last / first - 1.0
    # without a plant file both means lean on b: their difference by b·(T̄_first − T̄_last)
    dT = float(np.mean(T[-n:]) - np.mean(T[:n]))
    se_diff_b = abs(dT) * se_b / first
    se_drift = math.sqrt((se_last / first) ** 2 + (last * se_first / first**2) ** 2 + se_diff_b**2)
    return (
        drift,
        se_drift,
        f"{how}; first vs last {n} of {len(rows)} accepted windows that do not overlap "
        f"(errors inflated by the period's Birge ratio {birge:.2f})",
    )


def _slope(tracker: KTracker | None) -> tuple[float | None, list[float] | None, str]:
    from scipy import stats

    if tracker is None:
        return None, None, ""
    if tracker.fit_ is not None:
        line, unit = tracker.fit_, "1/degC (ratio K/K_plant)"
    else:
        fitted = [(b, f) for b, f in tracker.bands_.items() if f is not None and f.slope]
        if not fitted:
            return None, None, "no command band with a slope"
        band, line = max(fitted, key=lambda item: item[1].n)
        width = tracker.band_width_V
        unit = f"(L/min)/V/degC (band {band * width:g}-{(band + 1) * width:g} V)"
    if line.slope is None:
        return None, None, line.note
    se = line.se[1]
    assert se is not None
    quantile = float(stats.t.ppf(0.975, line.dof)) if line.dof > 0 else math.inf
    return line.slope, [line.slope - quantile * se, line.slope + quantile * se], unit


def loop_summary(
    loop_id: str, table: pa.Table, tracker: KTracker | None, note: str = ""
) -> dict[str, Any]:
    """The loop's row of the summary table (keys in docs/reference/json.md)."""
    dates = sorted({_date(t) for t in table.column("t_to").to_pylist()}) if table.num_rows else []
    accepted = int(np.count_nonzero(table.column("accepted").to_numpy(zero_copy_only=False)))
    drift, se_drift, drift_note = k_drift(table)
    slope, ci, unit = _slope(tracker)
    return {
        "loop_id": loop_id,
        "loop_days": len(dates),
        "first_date": dates[0] if dates else None,
        "last_date": dates[-1] if dates else None,
        "windows": table.num_rows,
        "accepted": accepted,
        "accepted_share": accepted / table.num_rows if table.num_rows else None,
        "k_drift": drift,
        "k_drift_se": se_drift,
        "k_drift_method": drift_note,
        "k_slope": slope,
        "k_slope_ci95": ci,
        "k_slope_unit": unit or None,
        "tracking_mode": None if tracker is None else tracker.mode_,
        "tracking_note": note or None,
    }


def _date(t_to: float) -> str:
    from fuelid.archive import day_of

    return day_of(t_to - 1e-6)  # a window ending at midnight belongs to the day before


def write_tracking(
    out_root: str | Path, loop_id: str, tracker: KTracker | None, summary: dict[str, Any]
) -> Path:
    """``RESULT/tracking/<loop_id>.json`` (the tracker's JSON and the summary), atomically."""
    from fuelid.io.jsonsafe import json_ready

    path = Path(out_root) / "tracking" / f"{loop_id}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "loop_id": loop_id,
        "summary": summary,
        "tracking": None if tracker is None else tracker.to_json(),
    }
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(json_ready(payload), indent=2, allow_nan=False), encoding="utf-8")
    os.replace(tmp, path)
    return path
