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

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd

from fuelid.errors import DataError
from fuelid.io.tables import (
    Scale,
    apply_scale,
    check_scale,
    describe_scale,
    find_column,
    guess_unit,
    match_column,
    parse_scale,
    read_frame,
    to_float,
)
from fuelid.io.timeseries import (
    FUEL_TEMPERATURE_COLUMN,
    INPUT_COLUMN,
    INPUT_UNIT,
    OUTPUT_COLUMN,
    OUTPUT_UNIT,
    TIME_COLUMN,
    FloatArray,
    IOData,
)
from fuelid.units import celsius_to_kelvin

__all__ = ["ResampleMode", "Scale", "load_log", "parse_scale"]

IntArray = np.ndarray[tuple[int], np.dtype[np.int64]]
BoolArray = np.ndarray[tuple[int], np.dtype[np.bool_]]

ResampleMode = Literal["auto", "always", "never"]

MIN_SAMPLES = 10
"""Fewer samples than this are refused; a segment between gaps with fewer is dropped."""
HUGE = 1e12
"""Input or output values larger than this in magnitude are refused."""
JITTER_FRACTION = 0.4
"""Time stamps within ±0.4 of a period of a steady grid (one per slot) are placed on it."""
RESAMPLE_TOLERANCE = 0.10
"""``resample="auto"`` interpolates a stretch off any steady grid only if every interval is within
±10 % of the period."""
UNIFORM_TOLERANCE = 1e-3
"""Time stamps within this fraction of a period of the grid are uniform (no jitter to report)."""
DEFAULT_GAP_FACTOR = 3.0
"""Default ``max_gap``: this many median intervals."""
FILL_GAPS_MAX_PERIODS = 5.0
"""Longest gap ``fill_gaps`` may bridge, in sample periods (see :func:`load_log`)."""
SAMPLE_TIME_TOLERANCE = 0.01
"""A sample time given with a time column must agree with the column's period within 1 %."""
FUEL_TEMPERATURE_RANGE = (-60.0, 150.0)
"""Plausible fuel temperatures [°C]; outside is another unit (K, °F) or a broken sensor."""
GAPS_LISTED = 3
"""The gap note lists this many gaps with their time and data row, then counts the rest."""

MAX_SAMPLE_TIME = 3600.0
"""Longest sample interval [s] of a log (an hour): longer is a unit mix-up, not a flow log."""


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
    fill_gaps: float | None = None,
    drop_bad_rows: bool = False,
    fuel_temperature_col: str | None = FUEL_TEMPERATURE_COLUMN,
) -> IOData:
    """Read a PLC log (CSV-like text or Parquet) into an input/output record on a uniform grid.

    The time axis is checked against a steady period h (estimated robustly: the median interval,
    refined over ever longer spans of samples). Three things can be wrong with it:

    * **Jitter**: a log time-stamped on receipt (OPC UA subscriptions, historians, PC-side
      recorders; a Modbus poll at 20 ms scatters with a standard deviation of 0.7 ms, single
      intervals 7 to 33 ms) is not irregular. When every sample lies within ±0.4 h
      (:data:`JITTER_FRACTION`) of its own slot of a steady grid ``t0 + k·h``, one sample per
      slot, the samples are placed on the grid with their values unchanged, and the jitter is
      reported (standard deviation and largest deviation). The margin below half a period keeps
      a drifting clock from passing as a missing sample.
    * **Gaps**: an interval longer than ``max_gap`` (default 3 median intervals) is a gap, and so
      are missing grid slots after the placement (a single missing row). Nothing is interpolated
      across a gap unless ``fill_gaps`` asks for it: the log is returned as segments
      (``IOData.segment_starts``), to be identified jointly, each with its own initial state. A
      gap's length is the time between the samples on either side (on the grid: whole
      periods); its time and data row are those of the last sample before it. A segment of
      fewer than 10 samples (:data:`MIN_SAMPLES`) is dropped.
    * **Larger irregularity** (stamps off any steady grid): ``resample="auto"`` interpolates a
      stretch between gaps onto the grid only if every interval in it is within ±10 % of h
      (:data:`RESAMPLE_TOLERANCE`, a clock that drifts), where interpolation spans no missing
      sample; ``"always"`` interpolates any such stretch; ``"never"`` refuses it. Interpolation
      is linear for y and a zero-order hold for u (and the fuel temperature).

    Parameters
    ----------
    path : str or Path
        ``.csv``, ``.txt``, ``.tsv`` (text; separator ``,``, ``;`` or tab sniffed, decimal commas
        accepted, UTF-8 with or without BOM, or GBK) or ``.parquet``/``.pq``.
    time_col : str or None
        Time column: seconds, or date-time stamps (``2026-03-01 12:00:00.020``, ISO with ``T``,
        ``2026/03/01 12:00:00,020``, ``01.03.2026 12:00:00,020``) converted to seconds from the
        first sample.
    input_col, output_col : str
        Columns of the input u and the output y.
    sample_time : float, optional
        Sampling interval [s]. Without a time column (absent, or ``time_col=None``) the samples
        are taken as uniform at this interval, a dropped bad row keeping its slot. With a time
        column, its period must agree with ``sample_time`` within 1 %
        (:data:`SAMPLE_TIME_TOLERANCE`); the time column is then used (so gaps are seen) with a
        note, and a disagreement is refused with both values.
    input_scale, output_scale : sequence of 4 float, optional
        Linear scaling ``(raw_low, raw_high, eng_low, eng_high)`` of a raw column, e.g.
        ``(4, 20, 1, 5)`` for 4–20 mA → 1–5 V or ``(0, 27648, 0, 100)`` for counts → L/min. The
        scaled input is then in V and a scaled output in L/min, the engineering units of the
        gains.
    resample : {"auto", "always", "never"}
        What to do with a stretch whose stamps are off any steady grid (see above).
    max_gap : float, optional
        An interval longer than this [s] is a gap whatever the stamps around it; default 3 median
        intervals. Must exceed the median interval by more than 10 %. (CLI: ``--max-gap``.)
    fill_gaps : float, optional
        Bridge gaps up to this length [s] (missing samples: y interpolated linearly, u and the fuel
        temperature held) instead of splitting the log there; longer gaps stay segment breaks.
        At most 5 sample periods (:data:`FILL_GAPS_MAX_PERIODS`): the samples of a bridged gap are
        invented, and a command step inside it is moved to its end, shifting the dead time by up
        to the gap. A log fit for identification has at least 10 samples per dominant time
        constant T, so 5 periods is at most T/2, over which a linear interpolation of a
        first-order response is off by at most (Δ/T)²/8 ≈ 3 % of the step; for the fuel loop
        (h = 20 ms, T ≈ 1.3 s, dead time ≈ 0.2 s) it is 0.1 s. (CLI: ``--fill-gaps``.)
    drop_bad_rows : bool
        Drop rows with an empty or non-numeric cell if they are isolated (no two in a row) and
        bridge each by interpolation (y linear, u held), instead of refusing the log.
    fuel_temperature_col : str or None
        Fuel-temperature column [°C], read when present (finite, within −60 … 150 °C) and returned
        in kelvin as ``IOData.T_fuel``, aligned with u and y. The default name may be absent
        (``T_fuel`` is then None); another name that is absent is refused. None ignores it.

    Returns
    -------
    IOData
        ``sample_time`` is the period h [s] (the estimate, rounded to the fewest digits that
        keep every sample on its slot); ``t0`` the time of the first sample's slot (seconds from
        the first stamp for date-time stamps); ``segment_starts``/``segment_t0`` where the log
        resumes after a gap; units guessed from the column suffix (``u_V`` → V, ``q_Lpm`` →
        L/min); ``notes`` lists what was done (decoding, sorting, de-duplication, jitter, gaps,
        bridging, resampling, scaling).

    Raises
    ------
    DataError
        One line saying what is wrong and where: unreadable or empty file, not a table, missing
        column (naming those present), bad/infinite/huge cells (column, count, first data row),
        implausible fuel temperatures, conflicting duplicated times, a sample time that
        contradicts the time column, irregular sampling that cannot be placed or resampled
        safely (the worst interval, its time and data row), ``fill_gaps`` beyond its bound,
        constant signals, fewer than 10 samples (or no segment of 10 between the gaps).
    """
    source = str(path)
    if resample not in ("auto", "always", "never"):
        raise DataError(f"resample must be 'auto', 'always' or 'never', got {resample!r}")
    in_scale = None if input_scale is None else check_scale(input_scale, "input scale")
    out_scale = None if output_scale is None else check_scale(output_scale, "output scale")
    if sample_time is not None and not (
        np.isfinite(sample_time) and 0.0 < sample_time <= MAX_SAMPLE_TIME
    ):
        raise DataError(
            f"sample time must be a positive number of seconds up to {MAX_SAMPLE_TIME:g}, "
            f"got {sample_time}"
        )
    for name, value in (("max_gap (--max-gap)", max_gap), ("fill_gaps (--fill-gaps)", fill_gaps)):
        if value is not None and not (np.isfinite(value) and value > 0.0):
            raise DataError(f"{name} must be a positive number of seconds, got {value}")

    frame, notes = read_frame(Path(path), source)
    time_name = _time_column(frame, time_col, sample_time, source)
    u_name = find_column(frame, input_col, "input", source)
    y_name = find_column(frame, output_col, "output", source)
    if u_name == y_name:
        raise DataError(f"{source}: the input and the output are the same column {u_name!r}")
    T_name = _fuel_temperature_column(frame, fuel_temperature_col, source)
    if T_name is not None and T_name in (time_name, u_name, y_name):
        raise DataError(f"{source}: the fuel temperature is read from column {T_name!r} twice")

    table, unit_row, datetime_start, time_name = _read_table(
        frame, (time_name, u_name, y_name, T_name), sample_time, drop_bad_rows, source, notes
    )

    if in_scale is not None:
        table.u = apply_scale(table.u, in_scale)
        notes.append(f"input {u_name} scaled linearly: {describe_scale(in_scale)}")
    if out_scale is not None:
        table.y = apply_scale(table.y, out_scale)
        notes.append(f"output {y_name} scaled linearly: {describe_scale(out_scale)}")

    if table.t is None:  # uniform at the sample time given: the row number is the time
        assert sample_time is not None
        h = round(float(sample_time), 9)
        table.t = h * (table.rows - table.rows[0]).astype(np.float64)
        breaks = np.zeros(table.u.size - 1, dtype=bool)
    else:
        if datetime_start is not None:
            notes.append(f"date-time stamps converted to seconds from {datetime_start}")
        table = _sort_and_deduplicate(table, (u_name, y_name, T_name or ""), source, notes)
        _check_count(table.u.size, source)
        assert time_name is not None
        h, breaks = _period(table, time_name, sample_time, max_gap, source, notes)
    if fill_gaps is not None and fill_gaps > FILL_GAPS_MAX_PERIODS * h * (1.0 + 1e-9):
        raise DataError(
            f"{source}: fill_gaps (--fill-gaps) {fill_gaps:g} s is longer than "
            f"{FILL_GAPS_MAX_PERIODS:g} sample periods ({FILL_GAPS_MAX_PERIODS * h:g} s): "
            "interpolating across longer gaps invents the loop's dynamics"
        )
    record = _regularise(table, h, breaks, resample, fill_gaps, source, notes)
    if datetime_start is not None:
        record.t = record.t - record.t[0]  # seconds from the first sample

    # a scaling maps raw units to the engineering units of the contract: V and L/min
    u_unit = INPUT_UNIT if in_scale is not None else guess_unit(u_name) or unit_row.get(u_name, "")
    y_unit = (
        OUTPUT_UNIT if out_scale is not None else guess_unit(y_name) or unit_row.get(y_name, "")
    )
    _check_varies(record.u, "input", u_name, u_unit, source)
    _check_varies(record.y, "output", y_name, y_unit, source)
    starts = np.flatnonzero(record.starts[1:]) + 1
    return IOData(
        u=record.u,
        y=record.y,
        sample_time=h,
        t0=round(float(record.t[0]), 9),
        u_unit=u_unit,
        y_unit=y_unit,
        source=source,
        notes=tuple(notes),
        segment_starts=tuple(int(i) for i in starts),
        segment_t0=tuple(round(float(record.t[i]), 9) for i in starts),
        T_fuel=record.T,
    )


@dataclass
class _Table:
    """The selected columns as floats, with the data row number of each sample."""

    rows: IntArray
    t: FloatArray | None
    u: FloatArray
    y: FloatArray
    T: FloatArray | None = None
    """Fuel temperature (°C as read, K once checked)."""

    def take(self, index: np.ndarray[tuple[int], np.dtype[np.intp]]) -> _Table:
        """The samples at ``index``."""
        return _Table(
            self.rows[index],
            None if self.t is None else self.t[index],
            self.u[index],
            self.y[index],
            None if self.T is None else self.T[index],
        )


# --- columns and cells ---------------------------------------------------------------------------


def _read_table(
    frame: pd.DataFrame,
    names: tuple[str | None, str, str, str | None],
    sample_time: float | None,
    drop_bad_rows: bool,
    source: str,
    notes: list[str],
) -> tuple[_Table, dict[str, str], str | None, str | None]:
    """The time, u, y and fuel-temperature columns as checked floats.

    ``names`` are the columns of the time, u, y and fuel temperature (None: absent). A time
    column without a single readable time is left out when a sample time is given. Returns the
    table (fuel temperature in kelvin), the units of a skipped row of units, the first date-time
    stamp (None for times in seconds or no time column) and the time column used.
    """
    time_name, u_name, y_name, T_name = names
    table = _Table(
        rows=np.arange(1, len(frame) + 1, dtype=np.int64),
        t=None,
        u=to_float(frame[u_name]),
        y=to_float(frame[y_name]),
        T=None if T_name is None else to_float(frame[T_name]),
    )
    datetime_start = None
    if time_name is not None:
        table.t, datetime_start = _to_seconds(frame[time_name])
        if sample_time is not None and bool(np.all(np.isnan(table.t))):
            cell = str(frame[time_name].iloc[0])
            notes.append(
                f"time column {time_name} holds no readable time ({cell[:24]!r}, ...): the "
                f"sample time {sample_time:g} s replaces it, so gaps cannot be seen"
            )
            table.t, time_name = None, None
    table, unit_row = _skip_unit_row(table, frame, (time_name, *names[1:]), notes)
    columns = {u_name: table.u, y_name: table.y}
    if T_name is not None and table.T is not None:
        columns[T_name] = table.T
    if time_name is not None and table.t is not None:
        columns = {time_name: table.t, **columns}
    signals = tuple(name for name in (u_name, y_name, T_name) if name is not None)
    _check_values(columns, table.rows, signals, source)
    table = _handle_bad_rows(table, frame, columns, signals, drop_bad_rows, source, notes)
    _check_count(table.u.size, source)
    if T_name is not None and table.T is not None:
        table.T = _fuel_temperature_kelvin(table.T, table.rows, T_name, source)
    return table, unit_row, datetime_start, time_name


def _time_column(
    frame: pd.DataFrame, time_col: str | None, sample_time: float | None, source: str
) -> str | None:
    """The name of the time column, or None: no time column and a sample time given."""
    if time_col is None:
        if sample_time is None:
            raise DataError(f"{source}: give a time column or a sample time")
        return None
    found = match_column(frame, time_col)
    if found is None and sample_time is not None:
        return None
    return find_column(frame, time_col, "time", source, hint="or give a sample time")


def _fuel_temperature_column(frame: pd.DataFrame, name: str | None, source: str) -> str | None:
    """The fuel-temperature column; None if not asked for, or the default name is absent."""
    if name is None:
        return None
    found = match_column(frame, name)
    if found is None and name != FUEL_TEMPERATURE_COLUMN:
        return find_column(frame, name, "fuel-temperature", source)
    return found


def _fuel_temperature_kelvin(
    T_degC: FloatArray, rows: IntArray, name: str, source: str
) -> FloatArray:
    """Fuel temperatures [°C] in kelvin, refusing implausible ones (another unit, a bad sensor)."""
    low, high = FUEL_TEMPERATURE_RANGE
    wrong = np.flatnonzero((T_degC < low) | (T_degC > high))
    if wrong.size:
        i = int(wrong[0])
        raise DataError(
            f"{source}: column {name!r} has {wrong.size} fuel temperature(s) outside {low:g} to "
            f"{high:g} °C, first at data row {int(rows[i])} ({T_degC[i]:g}): is it in °C?"
        )
    return T_degC + celsius_to_kelvin(0.0)  # the offset of fuelid.units, on every sample


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
    first = [table.u[0], table.y[0]] + [x[0] for x in (table.t, table.T) if x is not None]
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


def _check_varies(values: FloatArray, role: str, name: str, unit: str, source: str) -> None:
    """Refuse a constant signal: nothing to identify."""
    if float(np.ptp(values)) <= 1e-12 * max(1.0, float(np.max(np.abs(values)))):
        value = np.format_float_positional(values[0], precision=6, unique=True, trim="0")
        shown = f"{value} {unit}".strip()
        raise DataError(f"{source}: {role} {name} is constant ({shown}): nothing to identify")


# --- time axis -----------------------------------------------------------------------------------


def _sort_and_deduplicate(
    table: _Table, names: tuple[str, str, str], source: str, notes: list[str]
) -> _Table:
    """Sort by time, drop identical repeated rows, refuse conflicting ones.

    ``names`` are the columns of u, y and the fuel temperature (``""`` when there is none).
    """
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
    signals = [table.u, table.y] + ([] if table.T is None else [table.T])
    differs = [repeated & (values[1:] != values[:-1]) for values in signals]
    conflict = np.logical_or.reduce(differs)
    if conflict.any():
        assert table.t is not None
        i = int(np.flatnonzero(conflict)[0])
        row_a, row_b = int(table.rows[i]), int(table.rows[i + 1])
        which = next(j for j, d in enumerate(differs) if d[i])
        values = signals[which]
        raise DataError(
            f"{source}: conflicting samples at t = {table.t[i]:.6g} s (data rows {row_a} and "
            f"{row_b}): {names[which]} is {values[i]:g} and {values[i + 1]:g}"
        )
    keep = np.concatenate(([True], ~repeated))
    notes.append(f"dropped {int(repeated.sum())} duplicated row(s) (same time, same values)")
    return table.take(np.flatnonzero(keep))


def _period(
    table: _Table,
    time_name: str,
    sample_time: float | None,
    max_gap: float | None,
    source: str,
    notes: list[str],
) -> tuple[float, BoolArray]:
    """The period h [s] of the time column and where its intervals exceed ``max_gap``.

    Checks a sample time given against the column (1 %), and rounds h to the fewest digits that
    move no sample by more than 2 % of a period over the log.
    """
    t = table.t
    assert t is not None
    dt = np.diff(t)
    h0 = float(np.median(dt))
    if h0 > MAX_SAMPLE_TIME:
        raise DataError(
            f"{source}: samples {h0:g} s apart; a flow-loop log is sampled at least every "
            f"{MAX_SAMPLE_TIME:g} s (is the time column in seconds?)"
        )
    limit = DEFAULT_GAP_FACTOR * h0 if max_gap is None else float(max_gap)
    if limit <= (1.0 + RESAMPLE_TOLERANCE) * h0:
        raise DataError(
            f"{source}: max_gap (--max-gap) {limit:g} s must be longer than the median interval "
            f"{h0:.6g} s by more than {RESAMPLE_TOLERANCE:.0%}"
        )
    breaks = dt > limit
    h = _refine_period(t, breaks, h0)
    if sample_time is not None:
        if abs(h - sample_time) > SAMPLE_TIME_TOLERANCE * sample_time:
            raise DataError(
                f"{source}: time column {time_name!r} says {h:.6g} s between samples, the sample "
                f"time given (sample_time, --sample-time) says {sample_time:g} s: give one of them"
            )
        notes.append(
            f"time column {time_name} used (gaps and jitter checked on it): its period "
            f"{h:.6g} s agrees with the sample time given, {sample_time:g} s"
        )
    slots = (t[-1] - t[0]) / h
    preferred = [] if sample_time is None else [float(sample_time)]
    for candidate in preferred + [float(f"{h:.{digits}g}") for digits in range(1, 10)]:
        if abs(candidate - h) * slots <= 0.02 * h:
            return candidate, breaks
    return round(h, 12), breaks


def _refine_period(t: FloatArray, breaks: BoolArray, h0: float) -> float:
    """The period [s], from pairs of samples ever further apart (4, 16, 64, ... samples).

    The time between two samples n slots apart, divided by n, scatters by the jitter over n: the
    median over pairs at a lag four times longer refines the period without letting a gap or an
    outlier pull it. Pairs across an interval longer than the gap limit are left out.
    """
    chunk = np.concatenate(([0], np.cumsum(breaks)))
    h = h0
    lag = 4
    while lag <= t.size // 2:
        same = chunk[lag:] == chunk[:-lag]
        if not same.any():
            break
        span = (t[lag:] - t[:-lag])[same]
        h = float(np.median(span / np.maximum(np.rint(span / h), 1.0)))
        lag *= 4
    return h


@dataclass
class _Record:
    """The samples on the grid: times [s], u, y, fuel temperature [K], where segments start."""

    t: FloatArray
    u: FloatArray
    y: FloatArray
    T: FloatArray | None
    starts: BoolArray


def _regularise(
    table: _Table,
    h: float,
    breaks: BoolArray,
    mode: ResampleMode,
    fill_gaps: float | None,
    source: str,
    notes: list[str],
) -> _Record:
    """Place the samples on the grid, split the log at its gaps, bridge or resample where asked."""
    t = table.t
    assert t is not None
    n = t.size
    dt = np.diff(t)
    chunk = np.concatenate(([0], np.cumsum(breaks)))
    first = np.flatnonzero(np.concatenate(([True], breaks)))

    # each stretch between long intervals on a grid of its own phase, each sample on its slot
    cycles = (t - t[first][chunk]) / h
    phase = np.add.reduceat(np.exp(2j * np.pi * (cycles - np.rint(cycles))), first)
    origin = t[first] + np.angle(phase) / (2.0 * np.pi) * h
    k = np.rint((t - origin[chunk]) / h).astype(np.int64)
    deviation = t - origin[chunk] - h * k
    worst = np.maximum.reduceat(np.abs(deviation), first)
    origin = np.where(worst <= UNIFORM_TOLERANCE * h, t[first], origin)
    same = ~breaks
    steps = np.diff(k)
    collided = np.zeros(first.size, dtype=bool)
    collided[chunk[1:][same & (steps < 1)]] = True
    placed = (worst <= JITTER_FRACTION * h) & ~collided
    if not placed.all():
        _check_resampling(table, h, chunk, placed, mode, source)

    # gaps: long intervals and missing slots; bridged when short enough (or a dropped bad row)
    on_grid = placed[chunk]
    both = on_grid[:-1] & on_grid[1:]
    slots = np.where(same, steps, np.maximum(np.rint(dt / h), 1.0)).astype(np.int64)
    gap = np.where(same, (slots > 1) & both, True)
    length = np.where(same, slots * h, dt)  # whole periods within a stretch
    bad_row = same & (slots == 2) & (np.diff(table.rows) == 2)
    fill = -np.inf if fill_gaps is None else fill_gaps * (1.0 + 1e-9)
    filled = gap & both & (length <= fill)
    bridge = filled | (gap & both & bad_row)
    split = gap & ~bridge

    pieces = [_placed_samples(table, h, chunk, on_grid, k, origin, slots, bridge, split)]
    for c in np.flatnonzero(~placed):
        stop = int(first[c + 1]) if c + 1 < first.size else n
        pieces.append(_resampled_samples(table, h, int(first[c]), stop, int(c)))
    order = np.argsort(np.concatenate([piece[0] for piece in pieces]), kind="stable")
    rows = np.concatenate([piece[1] for piece in pieces])[order]
    signals = [
        np.concatenate([piece[2][j] for piece in pieces])[order]
        for j in range(4 if table.T is not None else 3)
    ]
    record = _Record(
        t=signals[0],
        u=signals[1],
        y=signals[2],
        T=signals[3] if table.T is not None else None,
        starts=np.concatenate([piece[3] for piece in pieces])[order],
    )

    if on_grid.any() and float(np.max(np.abs(deviation[on_grid]))) > UNIFORM_TOLERANCE * h:
        jitter = deviation[on_grid]
        notes.append(
            f"time stamps scatter around a steady {h:g} s period (sd {np.std(jitter) * 1e3:.2g}"
            f" ms, at most {np.max(np.abs(jitter)) * 1e3:.2g} ms, within ±{JITTER_FRACTION:g} of"
            f" a period): samples placed on the {h:g} s grid, values unchanged"
        )
    if not placed.all():
        stretches = "" if first.size == 1 else f"{int(np.sum(~placed))} of {first.size} stretches "
        off = ~on_grid[:-1] & same
        notes.append(
            f"resampled {stretches}onto a uniform {h:g} s grid (intervals "
            f"{float(dt[off].min()):.6g} to {float(dt[off].max()):.6g} s): y interpolated "
            "linearly, u held"
        )
    if filled.any():
        changes = int(np.count_nonzero(filled & (table.u[1:] != table.u[:-1])))
        moved = (
            f"; the input changes across {changes} of them (its step moved to the gap's end)"
            if changes
            else ""
        )
        notes.append(
            f"bridged {int(filled.sum())} gap(s) up to {float(length[filled].max()):.3g} s "
            f"(fill_gaps, --fill-gaps {fill_gaps:g} s): {int(np.sum(slots[filled] - 1))} "
            f"sample(s) inserted, y interpolated linearly, u held{moved}"
        )
    if split.any():
        notes.append(_describe_gaps(np.flatnonzero(split), length, t, table.rows))
    return _drop_short_segments(record, rows, split, length, h, source, notes)


def _placed_samples(
    table: _Table,
    h: float,
    chunk: IntArray,
    on_grid: BoolArray,
    k: IntArray,
    origin: FloatArray,
    slots: IntArray,
    bridge: BoolArray,
    split: BoolArray,
) -> tuple[IntArray, IntArray, list[FloatArray], BoolArray]:
    """The samples placed on their slots, with the bridged gaps filled in.

    Returns the chunk and data row of each output sample, its time, u, y and fuel temperature,
    and whether a segment starts at it.
    """
    n = table.u.size
    index = np.flatnonzero(on_grid)
    extra = np.zeros(n, dtype=np.int64)
    extra[:-1] = np.where(bridge, slots - 1, 0)
    count = 1 + extra[index]
    source = np.repeat(index, count)
    j = np.arange(source.size) - np.repeat(np.cumsum(count) - count, count)
    following = np.minimum(source + 1, n - 1)
    fraction = j / (1.0 + extra[source])
    y = table.y[source] + (table.y[following] - table.y[source]) * fraction
    t = origin[chunk[source]] + h * (k[source] + j)
    signals = [t, table.u[source], y] + ([] if table.T is None else [table.T[source]])
    starts = (j == 0) & np.concatenate(([True], split))[source]
    return chunk[source], table.rows[source], signals, starts


def _resampled_samples(
    table: _Table, h: float, start: int, stop: int, chunk: int
) -> tuple[IntArray, IntArray, list[FloatArray], BoolArray]:
    """Samples ``start:stop`` interpolated onto a grid from their first time (y linear, u held)."""
    assert table.t is not None
    t = table.t[start:stop]
    grid = t[0] + h * np.arange(int(np.floor((t[-1] - t[0]) / h + 1e-6)) + 1)
    held = np.clip(np.searchsorted(t, grid + 1e-6 * h, side="right") - 1, 0, t.size - 1)
    y = np.interp(grid, t, table.y[start:stop])
    signals = [grid, table.u[start:stop][held], y]
    if table.T is not None:
        signals.append(table.T[start:stop][held])
    starts = np.zeros(grid.size, dtype=bool)
    starts[0] = True
    return np.full(grid.size, chunk), table.rows[start:stop][held], signals, starts


def _check_resampling(
    table: _Table,
    h: float,
    chunk: IntArray,
    placed: BoolArray,
    mode: ResampleMode,
    source: str,
) -> None:
    """Refuse stretches off any steady grid that ``mode`` does not let be resampled safely."""
    assert table.t is not None
    t = table.t
    dt = np.diff(t)
    inside = (chunk[1:] == chunk[:-1]) & ~placed[chunk[1:]]
    off = np.abs(dt - h) > RESAMPLE_TOLERANCE * h
    safe = np.ones(placed.size, dtype=bool)
    safe[chunk[1:][inside & off]] = False
    if mode == "always" or (mode == "auto" and safe[~placed].all()):
        return
    refused = inside & ~safe[chunk[1:]] if mode == "auto" else inside
    candidates = np.flatnonzero(refused & off) if (refused & off).any() else np.flatnonzero(refused)
    i = int(candidates[np.argmax(np.abs(dt[candidates] - h))])
    why = (
        "resampling is off"
        if mode == "never"
        else f"interpolating an interval beyond ±{RESAMPLE_TOLERANCE:.0%} of it is not safe"
    )
    hint = (
        f"; a max_gap (--max-gap) below {dt[i]:.6g} s makes it a gap"
        if dt[i] > (1.0 + RESAMPLE_TOLERANCE) * h
        else ""
    )
    raise DataError(
        f"{source}: irregular sampling: interval of {dt[i]:.6g} s at t = {t[i]:.6g} s (data row "
        f"{int(table.rows[i])}) against a period of {h:g} s; the time stamps fit no steady grid "
        f"within ±{JITTER_FRACTION:g} of a period and {why}{hint}"
    )


def _describe_gaps(where: IntArray, length: FloatArray, t: FloatArray, rows: IntArray) -> str:
    """``"2 gaps split the log into 3 segments, ...: 0.04 s at t = 1.98 s (data row 100), ..."``."""
    count = where.size
    listed = ", ".join(
        f"{float(length[i]):.3g} s at t = {float(t[i]):.6g} s (data row {int(rows[i])})"
        for i in where[:GAPS_LISTED]
    )
    more = f", and {count - GAPS_LISTED} more" if count > GAPS_LISTED else ""
    verb = "gap splits" if count == 1 else "gaps split"
    return (
        f"{count} {verb} the log into {count + 1} segments, identified jointly (each with its own "
        f"initial state): {listed}{more}"
    )


def _drop_short_segments(
    record: _Record,
    rows: IntArray,
    split: BoolArray,
    length: FloatArray,
    h: float,
    source: str,
    notes: list[str],
) -> _Record:
    """Drop the segments of fewer than :data:`MIN_SAMPLES` samples, or refuse if none is left."""
    segment = np.cumsum(record.starts) - 1
    sizes = np.bincount(segment)
    short = sizes < MIN_SAMPLES
    if not short.any():
        return record
    if short.all():
        could = bool(np.any(length[split] <= FILL_GAPS_MAX_PERIODS * h))
        hint = "; bridging the short gaps (fill_gaps, --fill-gaps) may help" if could else ""
        raise DataError(
            f"{source}: no stretch of {MIN_SAMPLES} samples or more between the "
            f"{int(split.sum())} gap(s) (the longest has {int(sizes.max())}){hint}"
        )
    keep = ~short[segment]
    first = int(np.flatnonzero(~keep)[0])
    notes.append(
        f"dropped {int(short.sum())} segment(s) shorter than {MIN_SAMPLES} samples "
        f"({int(sizes[short].sum())} samples, the first at t = {float(record.t[first]):.6g} s, "
        f"data row {int(rows[first])}): {int(np.sum(~short))} segment(s) left"
    )
    return _Record(
        record.t[keep],
        record.u[keep],
        record.y[keep],
        None if record.T is None else record.T[keep],
        record.starts[keep],
    )
