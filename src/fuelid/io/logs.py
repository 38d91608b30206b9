"""Load real PLC logs into an :class:`~fuelid.io.timeseries.IOData`, or refuse them with the reason.

PLC exports are messier than what ``fuelid simulate`` writes: ``;`` or tab separators, decimal
commas, UTF-8 with a byte-order mark or GBK-encoded (Chinese) headers, date-time stamps instead of
seconds, raw units (4–20 mA, counts) that need a linear scaling, rows out of order or repeated,
jittered sampling, gaps and empty cells. :func:`load_log` handles what can be handled safely and
records it in ``IOData.notes``; everything else is refused with a one-line
:class:`~fuelid.errors.DataError` that says what is wrong and where (column, data row, time).

Data rows are numbered from 1 after the header line.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd

from fuelid.errors import DataError
from fuelid.io.tables import find_column, match_column, read_frame, to_float
from fuelid.io.timeseries import INPUT_COLUMN, OUTPUT_COLUMN, TIME_COLUMN, FloatArray, IOData

__all__ = ["ResampleMode", "Scale", "load_log", "parse_scale"]

Scale = tuple[float, float, float, float]
"""A linear scaling ``(raw_low, raw_high, eng_low, eng_high)``, e.g. 4–20 mA → 1–5 V."""

IntArray = np.ndarray[tuple[int], np.dtype[np.int64]]

ResampleMode = Literal["auto", "always", "never"]

MIN_SAMPLES = 10
"""Fewer samples than this are refused."""
HUGE = 1e12
"""Input or output values larger than this in magnitude are refused."""
JITTER_TOLERANCE = 0.10
"""``resample="auto"`` interpolates only if every interval is within ±10 % of the median."""
UNIFORM_TOLERANCE = 1e-3
"""Samples within this fraction of an interval of the uniform grid need no resampling."""
DEFAULT_GAP_FACTOR = 3.0
"""Default ``max_gap``: this many median intervals."""

_UNITS = {
    "V": "V",
    "mV": "mV",
    "A": "A",
    "mA": "mA",
    "Lpm": "L/min",
    "lpm": "L/min",
    "Lps": "L/s",
    "m3h": "m³/h",
    "kgh": "kg/h",
    "degC": "degC",
    "K": "K",
    "s": "s",
    "Hz": "Hz",
    "rpm": "rpm",
    "pct": "%",
    "Pa": "Pa",
    "kPa": "kPa",
    "MPa": "MPa",
    "bar": "bar",
}
_BRACKET_UNIT = re.compile(r"[\[(（]\s*([^\])）]+?)\s*[\])）]\s*$")


MAX_SAMPLE_TIME = 3600.0
"""Longest sample interval [s] of a log (an hour): longer is a unit mix-up, not a flow log."""


def parse_scale(text: str) -> Scale:
    """Parse the command-line syntax of a linear scaling, ``raw_low:raw_high:eng_low:eng_high``.

    Parameters
    ----------
    text : str
        Four numbers separated by ``:`` (decimal commas then allowed) or by ``,``.

    Returns
    -------
    tuple of 4 float
        ``(raw_low, raw_high, eng_low, eng_high)``.

    Raises
    ------
    DataError
        Not four finite numbers, or an empty raw or engineering range.

    Examples
    --------
    >>> parse_scale("4:20:1:5")
    (4.0, 20.0, 1.0, 5.0)
    >>> parse_scale("0, 27648, 0, 100")
    (0.0, 27648.0, 0.0, 100.0)
    >>> parse_scale("4:20:0:2,5")
    (4.0, 20.0, 0.0, 2.5)
    """
    if ":" in text:
        parts = [part.strip().replace(",", ".") for part in text.split(":")]
    else:
        parts = [part.strip() for part in text.split(",")]
    if len(parts) != 4:
        raise DataError(
            f"scale {text!r} must be four numbers raw_low:raw_high:eng_low:eng_high "
            f"(e.g. 4:20:1:5), got {len(parts)} part(s)"
        )
    try:
        numbers = [float(part) for part in parts]
    except ValueError:
        raise DataError(
            f"scale {text!r} must be four numbers raw_low:raw_high:eng_low:eng_high (e.g. 4:20:1:5)"
        ) from None
    return _check_scale((numbers[0], numbers[1], numbers[2], numbers[3]), f"scale {text!r}")


def load_log(
    path: str | Path,
    *,
    time_col: str | None = TIME_COLUMN,
    input_col: str = INPUT_COLUMN,
    output_col: str = OUTPUT_COLUMN,
    sample_time: float | None = None,
    input_scale: Sequence[float] | None = None,
    output_scale: Sequence[float] | None = None,
    resample: ResampleMode = "auto",
    max_gap: float | None = None,
    drop_bad_rows: bool = False,
) -> IOData:
    """Read a PLC log (CSV-like text or Parquet) into a uniformly sampled input/output record.

    Parameters
    ----------
    path : str or Path
        ``.csv``, ``.txt``, ``.tsv`` (text; separator ``,``, ``;`` or tab sniffed, decimal commas
        accepted, UTF-8 with or without BOM, or GBK) or ``.parquet``/``.pq``.
    time_col : str or None
        Time column: seconds, or date-time stamps (``2026-03-01 12:00:00.020``, ISO with ``T``,
        ``2026/03/01 12:00:00,020``, ``01.03.2026 12:00:00,020``) converted to seconds from the
        first sample. Ignored when ``sample_time`` is given.
    input_col, output_col : str
        Columns of the input u and the output y.
    sample_time : float, optional
        Sampling interval [s] of a log without a time column; samples are taken as uniform.
    input_scale, output_scale : sequence of 4 float, optional
        Linear scaling ``(raw_low, raw_high, eng_low, eng_high)`` of a raw column, e.g.
        ``(4, 20, 1, 5)`` for 4–20 mA → 1–5 V or ``(0, 27648, 0, 100)`` for counts → L/min. The
        unit of a scaled signal is unknown (``""``).
    resample : {"auto", "always", "never"}
        Irregular sampling: ``"auto"`` interpolates onto the median interval only if every
        interval is within ±10 % of it and refuses otherwise, ``"always"`` interpolates whenever
        there is no gap, ``"never"`` refuses any non-uniform time axis. Interpolation is linear
        for y and a zero-order hold for u.
    max_gap : float, optional
        Longest interval [s] accepted between two samples; default 3 median intervals.
    drop_bad_rows : bool
        Drop rows with an empty or non-numeric cell if they are isolated (no two in a row) and
        bridge them by interpolation, instead of refusing the log.

    Returns
    -------
    IOData
        ``sample_time`` is the median interval (rounded to 1e-9 s); ``t0`` the first time (0 for
        date-time stamps); units guessed from the column suffix (``u_V`` → V, ``q_Lpm`` → L/min);
        ``notes`` lists what was done (decoding, sorting, de-duplication, resampling, scaling).

    Raises
    ------
    DataError
        One line saying what is wrong and where: unreadable or empty file, not a table, missing
        column (naming those present), bad/infinite/huge cells (column, count, first data row),
        conflicting duplicated times, gaps, irregular sampling, constant signals, fewer than 10
        samples.
    """
    source = str(path)
    if resample not in ("auto", "always", "never"):
        raise DataError(f"resample must be 'auto', 'always' or 'never', got {resample!r}")
    in_scale = None if input_scale is None else _check_scale(input_scale, "input scale")
    out_scale = None if output_scale is None else _check_scale(output_scale, "output scale")
    if sample_time is not None and not (
        np.isfinite(sample_time) and 0.0 < sample_time <= MAX_SAMPLE_TIME
    ):
        raise DataError(
            f"sample time must be a positive number of seconds up to {MAX_SAMPLE_TIME:g}, "
            f"got {sample_time}"
        )
    if max_gap is not None and not (np.isfinite(max_gap) and max_gap > 0.0):
        raise DataError(f"max_gap must be a positive number of seconds, got {max_gap}")

    frame, notes = read_frame(Path(path), source)
    time_name = _time_column(frame, time_col, sample_time, source, notes)
    u_name = find_column(frame, input_col, "input", source)
    y_name = find_column(frame, output_col, "output", source)
    if u_name == y_name:
        raise DataError(f"{source}: the input and the output are the same column {u_name!r}")

    table = _Table(
        rows=np.arange(1, len(frame) + 1, dtype=np.int64),
        t=None,
        u=to_float(frame[u_name]),
        y=to_float(frame[y_name]),
    )
    datetime_start = None
    if time_name is not None:
        table.t, datetime_start = _to_seconds(frame[time_name])
    table, unit_row = _skip_unit_row(table, frame, (time_name, u_name, y_name), notes)
    columns = {u_name: table.u, y_name: table.y}
    if time_name is not None and table.t is not None:
        columns = {time_name: table.t, **columns}
    _check_values(columns, table.rows, (u_name, y_name), source)
    table = _handle_bad_rows(table, frame, columns, (u_name, y_name), drop_bad_rows, source, notes)
    _check_count(table.u.size, source)

    if in_scale is not None:
        table.u = _apply_scale(table.u, in_scale)
        notes.append(f"input {u_name} scaled linearly: {_describe_scale(in_scale)}")
    if out_scale is not None:
        table.y = _apply_scale(table.y, out_scale)
        notes.append(f"output {y_name} scaled linearly: {_describe_scale(out_scale)}")

    if table.t is None:
        assert sample_time is not None
        u, y, h, t0 = table.u, table.y, round(float(sample_time), 9), 0.0
    else:
        if datetime_start is not None:
            notes.append(f"date-time stamps converted to seconds from {datetime_start}")
        table = _sort_and_deduplicate(table, (u_name, y_name), source, notes)
        _check_count(table.u.size, source)
        u, y, h = _regularise(table, resample, max_gap, source, notes)
        if h > MAX_SAMPLE_TIME:
            raise DataError(
                f"{source}: samples {h:g} s apart; a flow-loop log is sampled at least every "
                f"{MAX_SAMPLE_TIME:g} s (is the time column in seconds?)"
            )
        assert table.t is not None
        t0 = 0.0 if datetime_start is not None else float(table.t[0])

    u_unit = "" if in_scale is not None else _guess_unit(u_name) or unit_row.get(u_name, "")
    y_unit = "" if out_scale is not None else _guess_unit(y_name) or unit_row.get(y_name, "")
    _check_varies(u, "input", u_name, u_unit, source)
    _check_varies(y, "output", y_name, y_unit, source)
    return IOData(
        u=u,
        y=y,
        sample_time=h,
        t0=t0,
        u_unit=u_unit,
        y_unit=y_unit,
        source=source,
        notes=tuple(notes),
    )


@dataclass
class _Table:
    """The selected columns as floats, with the data row number of each sample."""

    rows: IntArray
    t: FloatArray | None
    u: FloatArray
    y: FloatArray

    def take(self, index: np.ndarray[tuple[int], np.dtype[np.intp]]) -> _Table:
        """The samples at ``index``."""
        return _Table(
            self.rows[index],
            None if self.t is None else self.t[index],
            self.u[index],
            self.y[index],
        )


# --- columns and cells ---------------------------------------------------------------------------


def _time_column(
    frame: pd.DataFrame,
    time_col: str | None,
    sample_time: float | None,
    source: str,
    notes: list[str],
) -> str | None:
    """The name of the time column, or None when ``sample_time`` replaces it."""
    if sample_time is not None:
        if time_col is not None and match_column(frame, time_col) is not None:
            notes.append(f"time column {time_col} ignored: sample time {sample_time:g} s given")
        return None
    if time_col is None:
        raise DataError(f"{source}: give a time column or a sample time")
    return find_column(frame, time_col, "time", source, hint="or give a sample time")


def _to_seconds(series: pd.Series) -> tuple[FloatArray, str | None]:
    """Time in seconds; date-time stamps become seconds from the first valid stamp.

    Returns the times (NaN where a cell is not a time) and the first stamp, or None when the
    column holds plain numbers.
    """
    if pd.api.types.is_datetime64_any_dtype(series.dtype):
        return _stamps_to_seconds(pd.Series(pd.to_datetime(series)))
    numbers = to_float(series)
    if pd.api.types.is_numeric_dtype(series.dtype):
        return numbers, None
    text = series.astype(str).str.strip()
    filled = int(np.count_nonzero(text.to_numpy() != ""))
    if 2 * int(np.count_nonzero(~np.isnan(numbers))) >= filled:
        return numbers, None  # mostly plain numbers (bad cells among them are refused later)
    iso = (
        text.str.replace(r"^(\d{4})/(\d{1,2})/(\d{1,2})", r"\1-\2-\3", regex=True)
        .str.replace(r"^(\d{1,2})\.(\d{1,2})\.(\d{4})", r"\3-\2-\1", regex=True)
        .str.replace(r"(\d{1,2}:\d{2}:\d{2}),(\d+)", r"\1.\2", regex=True)
    )
    stamps = pd.to_datetime(iso, format="ISO8601", errors="coerce")
    return _stamps_to_seconds(pd.Series(stamps))


def _stamps_to_seconds(stamps: pd.Series) -> tuple[FloatArray, str | None]:
    """Seconds from the first valid stamp (NaN for NaT) and that stamp as text."""
    valid = stamps.dropna()
    if valid.empty:
        return np.full(len(stamps), np.nan), None
    start = valid.iloc[0]
    seconds = (stamps - start).dt.total_seconds()
    return np.asarray(seconds.to_numpy(dtype=float, na_value=np.nan), dtype=np.float64), str(start)


def _check_values(
    columns: dict[str, FloatArray], rows: IntArray, signals: Sequence[str], source: str
) -> None:
    """Refuse infinite values anywhere and huge ones (|x| > 1e12) in the signals."""
    for name, values in columns.items():
        limit = HUGE if name in signals else np.inf
        wrong = np.flatnonzero(np.isinf(values) | (np.abs(np.nan_to_num(values)) > limit))
        if wrong.size:
            what = "infinite or huge (|x| > 1e12)" if name in signals else "infinite"
            raise DataError(
                f"{source}: column {name!r} has {wrong.size} {what} value(s), "
                f"first at data row {int(rows[int(wrong[0])])}"
            )


def _handle_bad_rows(
    table: _Table,
    frame: pd.DataFrame,
    columns: dict[str, FloatArray],
    signals: Sequence[str],
    drop: bool,
    source: str,
    notes: list[str],
) -> _Table:
    """Refuse empty or non-numeric cells, or drop their rows when asked and they are isolated."""
    bad_any = np.zeros(table.u.size, dtype=bool)
    for name, values in columns.items():
        bad = np.isnan(values)
        if bad.any() and not drop:
            index = np.flatnonzero(bad)
            what = "empty or non-numeric" if name in signals else "empty or unreadable time"
            row = int(table.rows[int(index[0])])
            cell = str(frame[name].iloc[row - 1])
            shown = repr(cell if len(cell) <= 24 else cell[:21] + "...")
            hint = (
                "" if name in signals else "; expected seconds or stamps like 2026-03-01 12:00:00"
            )
            raise DataError(
                f"{source}: column {name!r} has {index.size} {what} cell(s), "
                f"first at data row {row} ({shown}){hint}"
            )
        bad_any |= bad
    if not bad_any.any():
        return table
    index = np.flatnonzero(bad_any)
    adjacent = np.flatnonzero(np.diff(index) == 1)
    if adjacent.size:
        row = int(table.rows[int(index[adjacent[0]])])
        raise DataError(
            f"{source}: bad cells in consecutive rows (data rows {row} and {row + 1}): "
            "only isolated bad rows can be dropped"
        )
    shown = ", ".join(str(int(table.rows[i])) for i in index[:5])
    shown += ", ..." if index.size > 5 else ""
    notes.append(
        f"dropped {index.size} row(s) with empty or non-numeric cells (data row(s) {shown})"
    )
    return table.take(np.flatnonzero(~bad_any))


def _skip_unit_row(
    table: _Table, frame: pd.DataFrame, names: Sequence[str | None], notes: list[str]
) -> tuple[_Table, dict[str, str]]:
    """Skip a first data row of units (text in every chosen column) and read the units from it."""
    first = [table.u[0], table.y[0]] + ([] if table.t is None else [table.t[0]])
    cells = {name: str(frame[name].iloc[0]).strip() for name in names if name is not None}
    if table.u.size < 2 or not np.all(np.isnan(first)) or not all(cells.values()):
        return table, {}
    shown = ", ".join(cells.values())
    notes.append(f"first data row ({shown}) holds no numbers: skipped as a row of units")
    units = {name: cell.strip("[]() ") for name, cell in cells.items()}
    return table.take(np.arange(1, table.u.size)), units


def _check_count(count: int, source: str) -> None:
    """Refuse fewer than :data:`MIN_SAMPLES` samples."""
    if count < MIN_SAMPLES:
        raise DataError(
            f"{source}: only {count} sample(s); at least {MIN_SAMPLES} are needed to identify"
        )


# --- scaling and units ---------------------------------------------------------------------------


def _check_scale(scale: Sequence[float], what: str) -> Scale:
    """Validate a ``(raw_low, raw_high, eng_low, eng_high)`` scaling."""
    if len(scale) != 4:
        raise DataError(f"{what} needs 4 numbers (raw_low, raw_high, eng_low, eng_high)")
    values = tuple(float(value) for value in scale)
    if not all(np.isfinite(values)):
        raise DataError(f"{what} must hold finite numbers, got {values}")
    raw_low, raw_high, eng_low, eng_high = values
    if raw_low == raw_high:
        raise DataError(f"{what}: the raw range {raw_low:g}..{raw_high:g} is empty")
    if eng_low == eng_high:
        raise DataError(f"{what}: the engineering range {eng_low:g}..{eng_high:g} is empty")
    return raw_low, raw_high, eng_low, eng_high


def _apply_scale(values: FloatArray, scale: Scale) -> FloatArray:
    """Map ``raw_low..raw_high`` linearly onto ``eng_low..eng_high``."""
    raw_low, raw_high, eng_low, eng_high = scale
    return eng_low + (values - raw_low) * ((eng_high - eng_low) / (raw_high - raw_low))


def _describe_scale(scale: Scale) -> str:
    """``"4..20 -> 1..5"``."""
    raw_low, raw_high, eng_low, eng_high = scale
    return f"{raw_low:g}..{raw_high:g} -> {eng_low:g}..{eng_high:g}"


def _guess_unit(name: str) -> str:
    """Unit from a column name: suffix ``u_V`` → V, ``q_Lpm`` → L/min, or brackets ``q [L/min]``.

    Examples
    --------
    >>> _guess_unit("q_Lpm"), _guess_unit("流量(L/min)"), _guess_unit("flow")
    ('L/min', 'L/min', '')
    """
    bracket = _BRACKET_UNIT.search(name)
    if bracket:
        return bracket.group(1)
    if "_" in name:
        return _UNITS.get(name.rsplit("_", 1)[1], "")
    return ""


def _check_varies(values: FloatArray, role: str, name: str, unit: str, source: str) -> None:
    """Refuse a constant signal: nothing to identify."""
    if float(np.ptp(values)) <= 1e-12 * max(1.0, float(np.max(np.abs(values)))):
        value = np.format_float_positional(values[0], precision=6, unique=True, trim="0")
        shown = f"{value} {unit}".strip()
        raise DataError(f"{source}: {role} {name} is constant ({shown}): nothing to identify")


# --- time axis -----------------------------------------------------------------------------------


def _sort_and_deduplicate(
    table: _Table, names: tuple[str, str], source: str, notes: list[str]
) -> _Table:
    """Sort by time, drop identical repeated rows, refuse conflicting ones."""
    assert table.t is not None
    dt = np.diff(table.t)
    if np.any(dt < 0.0):
        first = int(table.rows[int(np.flatnonzero(dt < 0.0)[0]) + 1])
        table = table.take(np.argsort(table.t, kind="stable"))
        notes.append(f"timestamps out of order (first at data row {first}): sorted by time")
        assert table.t is not None
        dt = np.diff(table.t)
    repeated = dt == 0.0
    if not repeated.any():
        return table
    conflict = repeated & ((table.u[1:] != table.u[:-1]) | (table.y[1:] != table.y[:-1]))
    if conflict.any():
        assert table.t is not None
        i = int(np.flatnonzero(conflict)[0])
        row_a, row_b = int(table.rows[i]), int(table.rows[i + 1])
        name = names[0] if table.u[i] != table.u[i + 1] else names[1]
        values = table.u if name == names[0] else table.y
        raise DataError(
            f"{source}: conflicting samples at t = {table.t[i]:.6g} s (data rows {row_a} and "
            f"{row_b}): {name} is {values[i]:g} and {values[i + 1]:g}"
        )
    keep = np.concatenate(([True], ~repeated))
    notes.append(f"dropped {int(repeated.sum())} duplicated row(s) (same time, same values)")
    return table.take(np.flatnonzero(keep))


def _regularise(
    table: _Table, mode: ResampleMode, max_gap: float | None, source: str, notes: list[str]
) -> tuple[FloatArray, FloatArray, float]:
    """Check the time axis for gaps and jitter; resample onto the median interval if needed."""
    t = table.t
    assert t is not None
    dt = np.diff(t)
    h = round(float(np.median(dt)), 9)
    if h <= 0.0:
        raise DataError(f"{source}: the median sampling interval is zero")
    limit = DEFAULT_GAP_FACTOR * h if max_gap is None else float(max_gap)
    gaps = np.flatnonzero(dt > limit)
    if gaps.size:
        i = int(gaps[0])
        more = f"; {gaps.size} gaps longer than {limit:g} s" if gaps.size > 1 else ""
        raise DataError(
            f"{source}: gap of {dt[i]:.6g} s at t = {t[i]:.6g} s (data row {int(table.rows[i])})"
            f" in samples {h:g} s apart{more}"
        )
    deviation = np.abs(t - t[0] - h * np.arange(t.size))
    bridged = np.diff(table.rows) > 1  # a dropped bad row lies in between
    if float(np.max(deviation)) <= UNIFORM_TOLERANCE * h:
        return table.u, table.y, h
    jitter = (np.abs(dt - h) > JITTER_TOLERANCE * h) & ~bridged
    if mode == "never" or (mode == "auto" and jitter.any()):
        candidates = np.flatnonzero(jitter) if jitter.any() else np.arange(dt.size)
        i = int(candidates[np.argmax(np.abs(dt[candidates] - h))])
        raise DataError(
            f"{source}: irregular sampling: interval of {dt[i]:.6g} s at t = {t[i]:.6g} s "
            f"(data row {int(table.rows[i])}) against a median of {h:g} s; "
            "resample='always' interpolates it"
        )
    grid = t[0] + h * np.arange(int(np.floor((t[-1] - t[0]) / h + 1e-6)) + 1)
    y = np.interp(grid, t, table.y)
    held = np.clip(np.searchsorted(t, grid + 1e-6 * h, side="right") - 1, 0, t.size - 1)
    u = table.u[held]
    notes.append(
        f"resampled onto a uniform {h:g} s grid (intervals {float(dt.min()):.6g} to "
        f"{float(dt.max()):.6g} s): y interpolated linearly, u held"
    )
    return u, y, h
