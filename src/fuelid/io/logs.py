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

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from fuelid.errors import DataError
from fuelid.io._bad_values import DEFAULT_BAD_VALUES
from fuelid.io._log_columns import (
    MIN_SAMPLES,
    check_count,
    check_varies,
    fuel_temperature_column,
    read_columns,
    require_columns,
    time_column,
)
from fuelid.io._log_grid import (
    FILL_GAPS_MAX_PERIODS,
    MAX_SAMPLE_TIME,
    ResampleMode,
    period,
    regularise,
    sort_and_deduplicate,
)
from fuelid.io._log_time import StampFormat, check_timezone
from fuelid.io.tables import (
    HeaderSearch,
    Scale,
    apply_scale,
    check_scale,
    describe_scale,
    find_column,
    guess_unit,
    parse_scale,
    read_frame,
)
from fuelid.io.timeseries import (
    FUEL_TEMPERATURE_COLUMN,
    INPUT_COLUMN,
    INPUT_UNIT,
    OUTPUT_COLUMN,
    OUTPUT_UNIT,
    TIME_COLUMN,
    IOData,
)

__all__ = [
    "DEFAULT_BAD_VALUES",
    "FILL_GAPS_MAX_PERIODS",
    "GRIDDING",
    "MIN_SAMPLES",
    "READING",
    "ResampleMode",
    "Scale",
    "load_log",
    "parse_scale",
]

READING = "reading the log"
"""Stage of :func:`load_log`: the file read and its columns parsed."""
GRIDDING = "placing the samples on their grid"
"""Stage of :func:`load_log`: sorting, the period, jitter, gaps, resampling."""


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
    bad_values: Sequence[str] = (),
    output_unit: str | None = None,
    progress: Callable[[str], None] | None = None,
    timezone: str | None = None,
    time_format: str | None = None,
    skip_rows: int | None = None,
) -> IOData:
    """Read a PLC log (CSV-like text or Parquet) into an input/output record on a uniform grid.

    The time axis is checked against a steady period h (estimated robustly: the median interval,
    refined over ever longer spans of samples). Three things can be wrong with it:

    * **Jitter**: a log time-stamped on receipt (OPC UA subscriptions, historians, PC-side
      recorders; a Modbus poll at 20 ms scatters with a standard deviation of 0.7 ms, single
      intervals 7 to 33 ms) is not irregular. When every sample has a slot of its own (its
      nearest) on a steady grid ``t0 + k·h``, the samples are placed on the grid with their
      values unchanged, and the jitter is reported (standard deviation and largest deviation
      within ±0.4 h, :data:`JITTER_FRACTION`; samples beyond it counted as late or early
      polls). A late poll that rounds onto the next sample's slot goes back to its own empty
      one. Two samples in one slot with no empty slot beside, or an empty slot between stamps
      beyond +0.4 h and −0.4 h (a clock slipping a period), make a stretch irregular.
    * **Gaps**: an interval longer than ``max_gap`` (default 3 median intervals) is a gap, and so
      are missing grid slots after the placement (a single missing row). Nothing is interpolated
      across a gap unless ``fill_gaps`` asks for it: the log is returned as segments
      (``IOData.segment_starts``), to be identified jointly, each with its own initial state. A
      gap's length is the time between the samples on either side (on the grid: whole
      periods); its time and data row are those of the last sample before it. A segment of
      fewer than 10 samples (:data:`MIN_SAMPLES`) is dropped.
    * **Larger irregularity** (stamps no steady grid can place): ``resample="auto"`` interpolates a
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
        Drop rows with a non-numeric cell if they are isolated (no two in a row) and bridge each
        by interpolation (y linear, u held), instead of refusing the log; an isolated sample
        marked bad (``bad_values``) is then bridged too instead of splitting the log.
    bad_values : sequence of str
        Site-specific texts a historian writes for a bad sample, besides the defaults
        (:data:`~fuelid.io._bad_values.DEFAULT_BAD_VALUES`: ``#N/A``, ``Bad Input``, ``Bad``,
        ``I/O Timeout``, ``Comm Fail``, ``Shutdown``, ``NaN`` and empty cells; case and
        surrounding spaces ignored). A signal cell (u, y, fuel temperature) holding one is a
        missing sample: its row is taken out and the log has a gap there (segments, as for any
        gap), and a note counts the markers per column and text. Any other text in a numeric
        column is refused, naming the column, the data row and the text. (CLI:
        ``--bad-values``.)
    output_unit : str, optional
        Unit of the output column when neither its name (``q_Lpm``, ``F [L/min]``) nor a row of
        units says it; a scaling (``output_scale``) gives L/min instead. (CLI: ``--flow-unit``.)
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
        column (naming those present), non-numeric text that is no bad-value marker, infinite or
        huge cells (column, count, first data row, the text),
        implausible fuel temperatures, a time column that runs backwards (more than three
        quarters of its steps go back in time: a reversed clock, or rows newest first; a few
        rows out of order are sorted instead), conflicting duplicated times, a sample time that
        contradicts the time column, irregular sampling that cannot be placed or resampled
        safely (the worst interval, its time and data row), ``fill_gaps`` beyond its bound,
        constant signals, fewer than 10 samples (or no segment of 10 between the gaps).
    """
    source = str(path)
    _check_options(resample, sample_time, max_gap, fill_gaps, skip_rows)
    in_scale = None if input_scale is None else check_scale(input_scale, "input scale")
    out_scale = None if output_scale is None else check_scale(output_scale, "output scale")
    form = StampFormat(
        timezone=None if timezone is None else check_timezone(timezone).key,
        time_format=time_format or None,
    )
    if progress is not None:
        progress(READING)
    names = tuple(name for name in (time_col, input_col, output_col) if name)
    frame, notes = read_frame(Path(path), source, HeaderSearch(names, skip_rows))
    wanted = [(input_col, "input", ""), (output_col, "output", "")]
    if time_col is not None and sample_time is None:
        wanted.insert(0, (time_col, "time", "or give a sample time"))
    if fuel_temperature_col not in (None, FUEL_TEMPERATURE_COLUMN):
        wanted.append((fuel_temperature_col, "fuel temperature", ""))
    require_columns(frame, wanted, source)
    time_name = time_column(frame, time_col, sample_time, source)
    u_name = find_column(frame, input_col, "input", source)
    y_name = find_column(frame, output_col, "output", source)
    if u_name == y_name:
        raise DataError(f"{source}: the input and the output are the same column {u_name!r}")
    T_name = fuel_temperature_column(frame, fuel_temperature_col, source)
    if T_name is not None and T_name in (time_name, u_name, y_name):
        raise DataError(f"{source}: the fuel temperature is read from column {T_name!r} twice")

    table, unit_row, datetime_start, time_name, bridgeable = read_columns(
        frame,
        (time_name, u_name, y_name, T_name),
        sample_time,
        drop_bad_rows,
        source,
        notes,
        bad_values,
        form,
    )
    del frame  # a day of samples: the table as read is not needed past here

    if in_scale is not None:
        table.u = apply_scale(table.u, in_scale)
        notes.append(f"input {u_name} scaled linearly: {describe_scale(in_scale)}")
    if out_scale is not None:
        table.y = apply_scale(table.y, out_scale)
        notes.append(f"output {y_name} scaled linearly: {describe_scale(out_scale)}")

    if progress is not None:
        progress(GRIDDING)
    if table.t is None:  # uniform at the sample time given: the row number is the time
        assert sample_time is not None
        h = round(float(sample_time), 9)
        table.t = h * (table.rows - table.rows[0]).astype(np.float64)
        breaks = np.zeros(table.u.size - 1, dtype=bool)
    else:
        if datetime_start is not None:
            notes.append(f"date-time stamps converted to seconds from {datetime_start}")
        assert time_name is not None
        table = sort_and_deduplicate(
            table, (u_name, y_name, T_name or ""), source, notes, time_name
        )
        check_count(table.u.size, source)
        h, breaks = period(table, time_name, sample_time, max_gap, source, notes)
    if fill_gaps is not None and fill_gaps > FILL_GAPS_MAX_PERIODS * h * (1.0 + 1e-9):
        raise DataError(
            f"{source}: fill_gaps (--fill-gaps) {fill_gaps:g} s is longer than "
            f"{FILL_GAPS_MAX_PERIODS:g} sample periods ({FILL_GAPS_MAX_PERIODS * h:g} s): "
            "interpolating across longer gaps invents the loop's dynamics"
        )
    record = regularise(table, h, breaks, resample, fill_gaps, source, notes, bridgeable)
    if datetime_start is not None:
        record.t = record.t - record.t[0]  # seconds from the first sample

    # a scaling maps raw units to the engineering units of the contract: V and L/min
    u_unit = INPUT_UNIT if in_scale is not None else guess_unit(u_name) or unit_row.get(u_name, "")
    y_unit = (
        OUTPUT_UNIT
        if out_scale is not None
        else output_unit or guess_unit(y_name) or unit_row.get(y_name, "")
    )
    check_varies(record.u, "input", u_name, u_unit, source)
    check_varies(record.y, "output", y_name, y_unit, source)
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


def _check_options(
    resample: str,
    sample_time: float | None,
    max_gap: float | None,
    fill_gaps: float | None,
    skip_rows: int | None,
) -> None:
    """Refuse options no log can satisfy, before the file is read."""
    if resample not in ("auto", "always", "never"):
        raise DataError(f"resample must be 'auto', 'always' or 'never', got {resample!r}")
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
    if skip_rows is not None and skip_rows < 0:
        raise DataError(f"skip_rows (--skip-rows) must be 0 or more lines, got {skip_rows}")
