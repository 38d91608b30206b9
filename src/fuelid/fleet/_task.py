"""One loop-day of re-identification: the online service's window analysis over archived samples.

The unit of work of ``fuelid reidentify`` (one Dask task each: a window's fit is ~0.1–0.2 s at
50 Hz, far above Dask's ~2 ms per task, but a task per window would still spend that overhead
288 times a day for nothing and lose the warm start).

**The schedule.** Windows end at ``day_start + k·identify_every_s`` for k = 1 …
86400/identify_every_s (the last one at the next midnight, exclusive), each holding the samples
with ``t_to − window_s ≤ time < t_to``, as the service reads its store. A window that reaches
back before midnight takes the previous day's tail from the archive, so every window holds its
data whatever day it falls in. A window with no samples is skipped (not a row). The schedule is
pinned to UTC midnight, not to the first sample as the live service's is: the day's windows are
the same whichever days are asked for, and a loop-day's result depends on that day (and the
previous day's last ``window_s``) alone.

**The state.** Each loop-day starts from a fixed state: a fresh
:class:`~fuelid.online._window.WindowAnalyser` (the day's first window cold, the estimator's own
start), then warm starts from the last accepted window inside the day, as the live analyser
does; BLAS on one thread. So a loop-day's numbers do not depend on which worker ran it, on
what ran there before, or on how many workers there are (the timing column ``seconds`` aside).

**The result** (:data:`RESULT_SCHEMA`, one row per window) goes to
``RESULT/windows/loop=<loop_id>/date=<date>/part.parquet`` through
:func:`fuelid.archive._layout.write_table` (a temporary file, fsync, re-read, rename): the file
is whole or absent, its presence marks the loop-day done, and a task retried after a killed
worker rewrites the same name, so a loop-day is never there twice.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from fuelid.archive import (
    SAMPLE_SCHEMA,
    LoopDay,
    arrays_of,
    day_bounds,
    partition_dir,
    read_loop_info,
    write_table,
)
from fuelid.errors import ConfigError, DataError, FuelidError
from fuelid.model import MODEL_KEYS
from fuelid.online import Online, WindowAnalyser, WindowResult, window_priors
from fuelid.plc.site import Controller
from fuelid.store import SampleArrays

__all__ = [
    "RESULT_SCHEMA",
    "LoopSettings",
    "day_windows",
    "loop_settings",
    "read_samples",
    "reidentify_day",
    "result_path",
    "result_row",
]

DAY_S = 86400.0

_FLOAT = pa.float64()
RESULT_SCHEMA = pa.schema(
    [
        pa.field("t_from", _FLOAT, nullable=False),
        pa.field("t_to", _FLOAT, nullable=False),
        pa.field("accepted", pa.bool_(), nullable=False),
        pa.field("reason", pa.string(), nullable=False),
        pa.field("mode", pa.string()),
        pa.field("method", pa.string()),
        pa.field("method_reason", pa.string()),
        pa.field("covariance", pa.string()),
        pa.field("samples", pa.int64(), nullable=False),
        pa.field("good_samples", pa.int64(), nullable=False),
        *[pa.field(key, _FLOAT) for key in MODEL_KEYS],
        *[pa.field(f"se_{key}", _FLOAT) for key in MODEL_KEYS],
        pa.field("order", pa.int64()),
        pa.field("fit_percent", _FLOAT),
        pa.field("T_fuel", _FLOAT),
        pa.field("u_mean", _FLOAT),
        pa.field("y_mean", _FLOAT),
        pa.field("plant_K", _FLOAT),
        pa.field("gates", pa.string(), nullable=False),
        pa.field("ok_share", _FLOAT),
        pa.field("time_in_auto", _FLOAT),
        pa.field("time_at_limits", _FLOAT),
        pa.field("oscillating", pa.bool_()),
        pa.field("harris_index", _FLOAT),
        pa.field("iae_per_unit_step_s", _FLOAT),
        pa.field("sensor_noise_Lpm", _FLOAT),
        pa.field("health", pa.string()),
        pa.field("structure", pa.string()),
        pa.field("step_ls", pa.string()),
        pa.field("warnings", pa.string(), nullable=False),
        pa.field("seconds", _FLOAT, nullable=False),
    ]
)
"""One row per window (docs/how-to/reidentify.md lists the columns and their units)."""

TIMING_COLUMNS = ("seconds",)
"""The columns that differ between runs of the same data (wall time)."""


@dataclass(frozen=True)
class LoopSettings:
    """What rebuilds a loop's window analyser: the service's settings as archived (or replaced).

    Parameters
    ----------
    online : Online
        The ``[online]`` table: the schedule and the gates' thresholds.
    sample_time : float
        ``[sampling] period_s`` [s].
    control_period : float
        ``[sampling] control_period_s`` [s] (step-ls's response length).
    ti_s : float
        The PI's integral time [s] for the oscillation detector: the commissioning Ti of the
        archived ``[controller]``, else 1 s (as the service without gains).
    source : str
        Where ``online`` came from ("archive" or "--settings FILE").
    step_ls : bool
        Also fit the article's step-ls (reported, never gated), as the service does by default.
    """

    online: Online
    sample_time: float
    control_period: float
    ti_s: float = 1.0
    source: str = "archive"
    step_ls: bool = True


def loop_settings(
    archive_root: str | Path, loop_id: str, override: Online | None = None, source: str = ""
) -> tuple[LoopSettings, str | None]:
    """The loop's analyser settings and plant file path from its archived record.

    Parameters
    ----------
    archive_root : path
        The archive.
    loop_id : str
        The loop.
    override : Online, optional
        An ``[online]`` table replacing the archived one (``--settings``).
    source : str
        Names the override in the results ("--settings FILE").

    Returns
    -------
    (LoopSettings, plant_path or None)

    Raises
    ------
    ConfigError
        The archived settings are not a valid ``[online]`` table, or the plant file named is
        missing.
    """
    from fuelid.tuning import BlockForm, from_block

    info = read_loop_info(archive_root, loop_id)
    recorded: dict[str, Any] = info.get("settings") or {}
    sampling = recorded.get("sampling") or {}
    sample_time = float(sampling.get("period_s") or info.get("period_s") or math.nan)
    if not (math.isfinite(sample_time) and sample_time > 0.0):
        raise ConfigError(f"loop {loop_id}: the archive records no sample period")
    if override is not None:
        online = override
    else:
        fields = set(Online.model_fields)
        try:
            online = Online(**{k: v for k, v in recorded.items() if k in fields})
        except ValueError as error:
            raise ConfigError(
                f"loop {loop_id}: the archived [online] settings are invalid: "
                f"{' '.join(str(error).split())}"
            ) from None
    ti_s = 1.0
    controller = recorded.get("controller")
    if controller:
        c = Controller(**{k: v for k, v in controller.items() if k in Controller.model_fields})
        if c.kc is not None and c.ti is not None:
            _, ti_s = from_block(c.kc, c.ti, BlockForm.of(c))
    plant_path = None
    if info.get("plant"):
        plant = Path(archive_root) / "loops" / loop_id / str(info["plant"])
        if not plant.is_file():
            raise ConfigError(f"loop {loop_id}: the archived plant file {plant} is missing")
        plant_path = str(plant)
    settings = LoopSettings(
        online=online,
        sample_time=sample_time,
        control_period=float(sampling.get("control_period_s") or 1.0),
        ti_s=float(ti_s),
        source=source if override is not None else "archive",
    )
    return settings, plant_path


def result_path(out_root: str | Path, loop_day: LoopDay) -> Path:
    """``RESULT/windows/loop=<loop_id>/date=<date>/part.parquet``."""
    return (
        Path(out_root)
        / "windows"
        / f"loop={loop_day.loop_id}"
        / f"date={loop_day.date}"
        / ("part.parquet")
    )


def day_windows(date: str, online: Online) -> list[tuple[float, float]]:
    """The day's windows (t_from, t_to) [s UTC] (module docstring: the schedule).

    Examples
    --------
    >>> w = day_windows("2026-01-01", Online())
    >>> len(w), w[0][1] - w[0][0], w[-1][1] - w[0][1]
    (288, 600.0, 86100.0)
    """
    start, _ = day_bounds(date)
    every = online.identify_every_s
    count = math.floor(DAY_S / every + 1e-9)
    return [(start + k * every - online.window_s, start + k * every) for k in range(1, count + 1)]


def read_samples(archive_root: str | Path, loop_day: LoopDay, lookback_s: float) -> SampleArrays:
    """The loop-day's samples and the previous day's last ``lookback_s`` [s], sorted by time.

    Nulls come back as NaN (values) and −1 (seq, mode), as a store reads them.
    """
    start, _ = day_bounds(loop_day.date)
    previous = LoopDay(loop_day.loop_id, _previous_date(loop_day.date))
    tables = []
    for day, condition in ((previous, ("time", ">=", start - lookback_s)), (loop_day, None)):
        for path in sorted(partition_dir(archive_root, "samples", day.loop_id, day.date).glob(
            "*.parquet"
        )):  # fmt: skip
            filters = None if condition is None else [condition]
            tables.append(pq.read_table(path, schema=SAMPLE_SCHEMA, filters=filters))
    if not tables:
        return arrays_of(SAMPLE_SCHEMA.empty_table())
    table = pa.concat_tables(tables).sort_by([("time", "ascending"), ("seq", "ascending")])
    return arrays_of(table)


def _key(loop_day: LoopDay) -> tuple[str, str]:
    return loop_day.loop_id, loop_day.date


def _previous_date(date: str) -> str:
    import datetime as _dt

    return (_dt.date.fromisoformat(date) - _dt.timedelta(days=1)).isoformat()


def _take(samples: SampleArrays, a: int, b: int) -> SampleArrays:
    return samples.take(slice(a, b))


def _number(value: Any) -> float | None:
    if value is None:
        return None
    number = float(value)
    return number if math.isfinite(number) else None


def _text(value: Any) -> str:
    return json.dumps(value, sort_keys=True, allow_nan=False)


def result_row(result: WindowResult) -> dict[str, Any]:
    """One window's row of :data:`RESULT_SCHEMA`, from :meth:`WindowResult.to_json`.

    Missing and non-finite numbers are null (never NaN), so that a file reads back equal.
    """
    d = result.to_json()
    model = d.get("model") or {}
    stderr = d.get("stderr") or {}
    health = d.get("health") or {}
    structure = d.get("structure")
    row: dict[str, Any] = {
        "t_from": float(d["start"]),
        "t_to": float(d["end"]),
        "accepted": bool(d["accepted"]),
        "reason": str(d["reason"]),
        "mode": d.get("mode"),
        "method": d.get("method") or None,
        "method_reason": d.get("method_reason") or None,
        "covariance": d.get("covariance") or None,
        "samples": int(d["samples"]),
        "good_samples": int(d["good_samples"]),
        **{key: _number(model.get(key)) for key in MODEL_KEYS},
        **{f"se_{key}": _number(stderr.get(key)) for key in MODEL_KEYS},
        "order": None if structure is None else structure.get("chosen_order"),
        "fit_percent": _number(d.get("fit_percent")),
        "T_fuel": _number(d.get("fuel_temperature")),
        "u_mean": _number((d.get("operating_point") or {}).get("u_V")),
        "y_mean": _number((d.get("operating_point") or {}).get("y_Lpm")),
        "plant_K": _number(d.get("plant_K")),
        "gates": _text(d.get("gates")),
        "ok_share": _number(health.get("ok_share")),
        "time_in_auto": _number(health.get("time_in_auto")),
        "time_at_limits": _number(health.get("time_at_limits")),
        "oscillating": (health.get("oscillation") or {}).get("oscillating"),
        "harris_index": _number((health.get("harris") or {}).get("index")),
        "iae_per_unit_step_s": _number(health.get("iae_per_unit_step_s")),
        "sensor_noise_Lpm": _number((health.get("sensor") or {}).get("noise_Lpm")),
        "health": None if not health else _text(health),
        "structure": None if structure is None else _text(structure),
        "step_ls": None if d.get("step_ls") is None else _text(d["step_ls"]),
        "warnings": _text(d.get("warnings") or []),
        "seconds": float(d.get("seconds") or 0.0),
    }
    return row


def _summary(loop_day: LoopDay, table: pa.Table, skipped: bool, seconds: float) -> dict[str, Any]:
    accepted = int(np.count_nonzero(table.column("accepted").to_numpy(zero_copy_only=False)))
    return {
        "loop_id": loop_day.loop_id,
        "date": loop_day.date,
        "windows": table.num_rows,
        "accepted": accepted,
        "skipped": skipped,
        "seconds": seconds,
        "fit_seconds": float(pc.sum(table.column("seconds")).as_py() or 0.0),
    }


def reidentify_day(
    archive_root: str | Path,
    loop_day: LoopDay,
    settings: LoopSettings,
    plant_path: str | None,
    out_root: str | Path,
) -> dict[str, Any]:
    """Re-identify one loop-day and write its result atomically (module docstring).

    Parameters
    ----------
    archive_root : path
        The archive (``samples/loop=…/date=…/``).
    loop_day : LoopDay
        The loop and UTC date.
    settings : LoopSettings
        The analyser's settings (:func:`loop_settings`).
    plant_path : str or None
        The loop's plant file (priors and the plant's K), None without one.
    out_root : path
        The result folder.

    Returns
    -------
    dict
        ``loop_id``, ``date``, ``windows``, ``accepted`` [-], ``skipped`` (True when the result
        was there already), ``seconds`` (the task's wall time) and ``fit_seconds`` (the
        windows' analyses) [s].
    """
    from fuelid.blas import single_threaded_blas

    started = time.perf_counter()
    path = result_path(out_root, loop_day)
    if path.exists():  # resumable: a finished loop-day is never recomputed
        return _summary(loop_day, pq.read_table(path, columns=["accepted", "seconds"]), True, 0.0)
    online = settings.online
    with single_threaded_blas():
        priors, k_plant = window_priors(plant_path, control_period=settings.control_period)
        analyser = WindowAnalyser(
            online,
            priors,
            settings.sample_time,
            k_plant=k_plant,
            step_ls=settings.step_ls,
            ti_s=settings.ti_s,
        )
        if not any(partition_dir(archive_root, "samples", *_key(loop_day)).glob("*.parquet")):
            # listed by the client, absent here: a worker that does not see the archive at the
            # same path must not mark the loop-day done with no windows
            import socket

            raise DataError(
                f"{loop_day.key}: no samples file under {archive_root} on worker "
                f"{socket.gethostname()}: is the archive readable at the same path on every "
                "worker?"
            )
        samples = read_samples(archive_root, loop_day, online.window_s)
        rows = []
        for t_from, t_to in day_windows(loop_day.date, online):
            a, b = np.searchsorted(samples.time, [t_from, t_to], side="left")
            if b <= a:
                continue
            try:
                result = analyser.analyse(_take(samples, int(a), int(b)), t_from, t_to)
            except FuelidError as error:  # analyse never raises on data; kept as a refusal
                raise FuelidError(f"{loop_day.key} window ending {t_to}: {error}") from error
            analyser.accept(result)  # warm start from an accepted window only
            rows.append(result_row(result))
    table = pa.Table.from_pylist(rows, schema=RESULT_SCHEMA)
    write_table(table, path)
    return _summary(loop_day, table, False, time.perf_counter() - started)
