"""The columns of a PLC log as checked floats: cells, units row, bad-value markers, time stamps.

The first half of :func:`fuelid.io.logs.load_log`: from the table as read to the time, input,
output and fuel-temperature samples with the data row of each (numbered from 1 after the header
line). Historian bad-value markers (:mod:`fuelid.io._bad_values`) are taken out here as missing
samples; any other cell that is not a number is refused, naming the column, the row and the text.
The time axis (gaps, jitter, resampling) is :mod:`fuelid.io._log_grid`'s.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from fuelid.errors import DataError
from fuelid.io._bad_values import describe_bad_marks, find_bad_marks
from fuelid.io._log_time import ANY_STAMPS, StampFormat, stamps_to_seconds
from fuelid.io.tables import find_column, match_column, to_float
from fuelid.io.timeseries import FUEL_TEMPERATURE_COLUMN, FloatArray
from fuelid.units import FUEL_TEMPERATURE_RANGE_C, celsius_to_kelvin

__all__ = [
    "MIN_SAMPLES",
    "BoolArray",
    "IntArray",
    "LogTable",
    "check_count",
    "check_varies",
    "fuel_temperature_column",
    "read_columns",
    "require_columns",
    "time_column",
]

IntArray = np.ndarray[tuple[int], np.dtype[np.int64]]
BoolArray = np.ndarray[tuple[int], np.dtype[np.bool_]]

MIN_SAMPLES = 10
"""Fewer samples than this are refused; a segment between gaps with fewer is dropped."""
HUGE = 1e12
"""Input or output values larger than this in magnitude are refused."""


@dataclass
class LogTable:
    """The selected columns as floats, with the data row number of each sample."""

    rows: IntArray
    t: FloatArray | None
    u: FloatArray
    y: FloatArray
    T: FloatArray | None = None
    """Fuel temperature (°C as read, K once checked)."""

    def take(self, index: np.ndarray[tuple[int], np.dtype[np.intp]]) -> LogTable:
        """The samples at ``index``."""
        return LogTable(
            self.rows[index],
            None if self.t is None else self.t[index],
            self.u[index],
            self.y[index],
            None if self.T is None else self.T[index],
        )


# --- columns and cells ---------------------------------------------------------------------------


def read_columns(
    frame: pd.DataFrame,
    names: tuple[str | None, str, str, str | None],
    sample_time: float | None,
    drop_bad_rows: bool,
    source: str,
    notes: list[str],
    bad_values: Sequence[str] = (),
    form: StampFormat = ANY_STAMPS,
) -> tuple[LogTable, dict[str, str], str | None, str | None, IntArray]:
    """The time, u, y and fuel-temperature columns as checked floats.

    ``names`` are the columns of the time, u, y and fuel temperature (None: absent). A time
    column without a single readable time is left out when a sample time is given. A row whose
    signal (u, y or fuel temperature) holds a bad-value marker (``bad_values`` besides the
    defaults of :mod:`fuelid.io._bad_values`) is taken out: a missing sample, counted in a note.
    Returns the table (fuel temperature in kelvin), the units of a skipped row of units, the
    first date-time stamp (None for times in seconds or no time column), the time column used,
    and the data rows dropped that a single-sample gap may be bridged over (``drop_bad_rows``).
    Date-time stamps are read as ``form`` says (:mod:`fuelid.io._log_time`).
    """
    time_name, u_name, y_name, T_name = names
    table = LogTable(
        rows=np.arange(1, len(frame) + 1, dtype=np.int64),
        t=None,
        u=to_float(frame[u_name]),
        y=to_float(frame[y_name]),
        T=None if T_name is None else to_float(frame[T_name]),
    )
    datetime_start = None
    if time_name is not None:
        table.t, datetime_start = stamps_to_seconds(
            frame[time_name], form, time_name, source, notes
        )
        if sample_time is not None and bool(np.all(np.isnan(table.t))):
            cell = str(frame[time_name].iloc[0])
            notes.append(
                f"time column {time_name} holds no readable time ({cell[:24]!r}, ...): the "
                f"sample time {sample_time:g} s replaces it, so gaps cannot be seen"
            )
            table.t, time_name = None, None
    signals = tuple(name for name in (u_name, y_name, T_name) if name is not None)
    marks = {name: find_bad_marks(frame[name], bad_values) for name in signals}
    for name, (mask, counts) in marks.items():
        _refuse_all_marked(name, mask, counts, source)
    marked = np.logical_or.reduce([mask for mask, _ in marks.values()])
    table, unit_row = _skip_unit_row(table, frame, (time_name, *names[1:]), notes, marked)
    dropped = table.rows[marked[table.rows - 1]]
    for name, (mask, counts) in marks.items():
        if mask.any():
            rows = np.flatnonzero(mask) + 1
            notes.append(
                f"{describe_bad_marks(name, counts, rows.tolist())}: taken out as missing samples"
            )
    if marked.any():
        table = table.take(np.flatnonzero(~marked[table.rows - 1]))
    columns = {u_name: table.u, y_name: table.y}
    if T_name is not None and table.T is not None:
        columns[T_name] = table.T
    if time_name is not None and table.t is not None:
        columns = {time_name: table.t, **columns}
    _check_values(columns, table.rows, signals, source)
    kept = table.rows
    table = _handle_bad_rows(
        table, frame, columns, signals, drop_bad_rows, source, notes, form.time_format
    )
    check_count(table.u.size, source)
    # only rows dropped on request are bridged; a marked sample is otherwise a gap like any other
    bridgeable = (
        np.union1d(dropped, np.setdiff1d(kept, table.rows))
        if drop_bad_rows
        else np.zeros(0, dtype=np.int64)
    )
    if T_name is not None and table.T is not None:
        table.T = _fuel_temperature_kelvin(table.T, table.rows, T_name, source)
    return table, unit_row, datetime_start, time_name, bridgeable.astype(np.int64)


def _refuse_all_marked(name: str, mask: BoolArray, counts: Counter[str], source: str) -> None:
    """Refuse a signal column none of whose cells holds a number (every cell a marker)."""
    marked = int(mask.sum())
    if mask.size < 2 or marked < mask.size - 1:  # a first row of units may be the one exception
        return
    texts = ", ".join(f"{text or '(empty)'!r} ×{count}" for text, count in counts.most_common(3))
    raise DataError(
        f"{source}: column {name!r} holds no samples: {marked} of its {mask.size} cells are "
        f"bad-value markers or empty ({texts}): was the tag recorded, and is this the column "
        "meant?"
    )


def require_columns(
    frame: pd.DataFrame, wanted: Sequence[tuple[str, str, str]], source: str
) -> None:
    """Refuse a log that lacks any of the ``wanted`` columns, naming all of them at once.

    ``wanted`` holds (name, role, hint) triples; the hints of the missing ones end the message.
    A newcomer whose export calls every column differently learns every name in one go.
    """
    missing = [item for item in wanted if match_column(frame, item[0]) is None]
    if not missing:
        return
    present = ", ".join(str(column) for column in frame.columns)
    names = ", ".join(f"{name!r} ({role})" for name, role, _ in missing)
    hints = "; ".join(hint for _, _, hint in missing if hint)
    noun = "column" if len(missing) == 1 else "columns"
    raise DataError(
        f"{source}: missing {noun}: {names}; columns present: {present}"
        + (f" ({hints})" if hints else "")
    )


def time_column(
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


def fuel_temperature_column(frame: pd.DataFrame, name: str | None, source: str) -> str | None:
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
    low, high = FUEL_TEMPERATURE_RANGE_C
    wrong = np.flatnonzero((T_degC < low) | (T_degC > high))
    if wrong.size:
        i = int(wrong[0])
        raise DataError(
            f"{source}: column {name!r} has {wrong.size} fuel temperature(s) outside {low:g} to "
            f"{high:g} °C, first at data row {int(rows[i])} ({T_degC[i]:g}): is it in °C?"
        )
    return T_degC + celsius_to_kelvin(0.0)  # the offset of fuelid.units, on every sample


def _check_values(
    columns: dict[str, FloatArray], rows: IntArray, signals: Sequence[str], source: str
) -> None:
    """Refuse infinite values anywhere and huge ones (|x| > 1e12) in the signals."""
    for name, values in columns.items():
        limit = HUGE if name in signals else np.inf
        # NaN compares false: an empty cell is judged later, as a missing sample
        wrong = np.flatnonzero(np.isinf(values) if np.isinf(limit) else np.abs(values) > limit)
        if wrong.size:
            what = "infinite or huge (|x| > 1e12)" if name in signals else "infinite"
            raise DataError(
                f"{source}: column {name!r} has {wrong.size} {what} value(s), "
                f"first at data row {int(rows[int(wrong[0])])}"
            )


def _handle_bad_rows(
    table: LogTable,
    frame: pd.DataFrame,
    columns: dict[str, FloatArray],
    signals: Sequence[str],
    drop: bool,
    source: str,
    notes: list[str],
    time_format: str | None = None,
) -> LogTable:
    """Refuse empty or non-numeric cells, or drop their rows when asked and they are isolated.

    ``time_format`` is the form the stamps were given in (``--time-format``), named in the
    refusal of a stamp that does not match it.
    """
    bad_any = np.zeros(table.u.size, dtype=bool)
    for name, values in columns.items():
        bad = np.isnan(values)
        if bad.any() and not drop:
            index = np.flatnonzero(bad)
            what = "non-numeric" if name in signals else "empty or unreadable time"
            row = int(table.rows[int(index[0])])
            cell = str(frame[name].iloc[row - 1])
            shown = repr(cell if len(cell) <= 40 else cell[:37] + "...")
            hint = (
                f"; if the historian writes {cell.strip()!r} for a bad sample, name it with "
                "--bad-values (bad_values) and it is read as a missing sample"
                if name in signals
                else _time_hint(time_format)
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
    notes.append(f"dropped {index.size} row(s) with non-numeric cells (data row(s) {shown})")
    return table.take(np.flatnonzero(~bad_any))


def _time_hint(time_format: str | None) -> str:
    """What to do about a time cell that is not a time: the form expected, or given."""
    if time_format is not None:
        return f"; it does not match the time format given, {time_format!r}"
    return (
        "; expected seconds or stamps like 2026-03-01 12:00:00 (give --time-format for another "
        "form, e.g. '%d-%b-%y %H:%M:%S')"
    )


def _skip_unit_row(
    table: LogTable,
    frame: pd.DataFrame,
    names: Sequence[str | None],
    notes: list[str],
    marked: BoolArray,
) -> tuple[LogTable, dict[str, str]]:
    """Skip a first data row of units (text in every signal column) and read the units from it.

    ``names`` are the time, u, y and fuel-temperature columns; the time column's cell may be
    empty (exports often leave it so). A first row of bad-value markers (``marked``) is a
    missing sample, not a row of units.
    """
    first = [table.u[0], table.y[0]] + [x[0] for x in (table.t, table.T) if x is not None]
    cells = {name: str(frame[name].iloc[0]).strip() for name in names if name is not None}
    signal_cells = [str(frame[name].iloc[0]).strip() for name in names[1:] if name is not None]
    if table.u.size < 2 or not np.all(np.isnan(first)) or not all(signal_cells) or bool(marked[0]):
        return table, {}
    cells = {name: cell for name, cell in cells.items() if cell}
    shown = ", ".join(cells.values())
    notes.append(f"first data row ({shown}) holds no numbers: skipped as a row of units")
    units = {name: cell.strip("[]() ") for name, cell in cells.items()}
    return table.take(np.arange(1, table.u.size)), units


def check_count(count: int, source: str) -> None:
    """Refuse fewer than :data:`MIN_SAMPLES` samples."""
    if count < MIN_SAMPLES:
        raise DataError(
            f"{source}: only {count} sample(s); at least {MIN_SAMPLES} are needed to identify"
        )


def check_varies(values: FloatArray, role: str, name: str, unit: str, source: str) -> None:
    """Refuse a constant signal: nothing to identify."""
    if float(np.ptp(values)) <= 1e-12 * max(1.0, float(np.max(np.abs(values)))):
        value = np.format_float_positional(values[0], precision=6, unique=True, trim="0")
        shown = f"{value} {unit}".strip()
        raise DataError(f"{source}: {role} {name} is constant ({shown}): nothing to identify")
