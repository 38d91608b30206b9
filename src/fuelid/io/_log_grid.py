"""The time axis of a PLC log: sorting, the steady period, jitter, gaps, bridging, resampling.

The second half of :func:`fuelid.io.logs.load_log`, on the samples :mod:`fuelid.io._log_columns`
read: what :func:`~fuelid.io.logs.load_log`'s docstring promises about the time axis is done
here. Every refusal is a one-line :class:`~fuelid.errors.DataError` with the place (time, data
row).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from fuelid.errors import DataError
from fuelid.io._log_columns import MIN_SAMPLES, BoolArray, IntArray, LogTable
from fuelid.io.timeseries import FloatArray

__all__ = [
    "BACKWARDS_FRACTION",
    "DEFAULT_GAP_FACTOR",
    "FILL_GAPS_MAX_PERIODS",
    "MAX_SAMPLE_TIME",
    "GridRecord",
    "ResampleMode",
    "check_clock_direction",
    "period",
    "regularise",
    "sort_and_deduplicate",
]

ResampleMode = Literal["auto", "always", "never"]

JITTER_FRACTION = 0.4
"""Stamps within ±0.4 of a period of their slots are jitter; one beyond is a late or early poll,
and stamps beyond it either side of an empty slot are a clock slipping a period."""
RESAMPLE_TOLERANCE = 0.10
"""``resample="auto"`` interpolates a stretch off any steady grid only if every interval is within
±10 % of the period."""
UNIFORM_TOLERANCE = 1e-3
"""Time stamps within this fraction of a period of the grid are uniform (no jitter to report)."""
DEFAULT_GAP_FACTOR = 3.0
"""Default ``max_gap``: this many median intervals."""
FILL_GAPS_MAX_PERIODS = 5.0
"""Longest gap ``fill_gaps`` may bridge, in sample periods (see :func:`fuelid.io.logs.load_log`)."""
SAMPLE_TIME_TOLERANCE = 0.01
"""A sample time given with a time column must agree with the column's period within 1 %."""
EXACT_DRIFT = 0.02
"""For stamps on an exact grid, a rounded period may move no sample by more than this fraction
of a period over the log."""
JITTERED_DRIFT = 0.1
"""For jittered stamps, a rounded period may move the stamps of the longest stretch between
gaps by this fraction of a period end to end (±0.05 about its mean phase, well inside the
±0.4 the jitter may take), or lie within three standard errors of the fit. Receipt delays
that wander slowly (a loaded recorder) make the standard error, which takes them as
independent, too small; the drift bound does not rest on it."""
PHASE_SAMPLES = 200_000
"""Stamps whose mean phase places a stretch's grid, at most (spread evenly over the log)."""
REFINE_PAIRS = 200_000
"""Pairs of samples whose median refines the first estimate of the period, at most."""
COARSE_STAMPS = 0.1
"""When this share of the rows repeat their stamp, the stamps are coarser than the samples."""
GAPS_LISTED = 3
"""The gap note lists this many gaps with their time and data row, then counts the rest."""

MAX_SAMPLE_TIME = 3600.0
"""Longest sample interval [s] of a log (an hour): longer is a unit mix-up, not a flow log."""

BACKWARDS_FRACTION = 0.75
"""A time column whose steps go back in time more often than this (a share of the steps that
change the time) runs backwards and is refused, not sorted. A reversed clock column (or a
newest-first export) makes every step go back, or all but a few stray rows; rows merely out of
order make few steps go back (a swapped pair, pages of an export in the wrong order) or, shuffled
at random, about half (50 % ± 3 % for 100 rows): such a table still has a clock that runs forward
and is sorted. Three quarters lies well clear of both. A repeated time stamp is no step either
way."""


def check_clock_direction(table: LogTable, time_name: str, source: str) -> None:
    """Refuse a time column that runs backwards over most of its steps.

    Sorting such a log would reverse its rows: if the clock column counts down while the rows
    are in time order (a historian export with a reversed clock), every response would come
    before its cause, and any model fitted to it would be meaningless. Which of the two is in
    time order (the rows, newest first, or the clock) the log cannot say: the user must.

    Examples
    --------
    >>> rows, ones = np.arange(1, 11), np.ones(10)
    >>> t = np.arange(10.0)
    >>> t[[3, 4]] = t[[4, 3]]  # a swapped pair: sorted later, with a note
    >>> check_clock_direction(LogTable(rows, t, ones, ones), "t_s", "log.csv")
    >>> try:
    ...     check_clock_direction(LogTable(rows, 9.0 - t, ones, ones), "t_s", "log.csv")
    ... except DataError as error:
    ...     for part in str(error).split(": ")[:3]:
    ...         print(part)
    log.csv
    the time column 't_s' runs backwards
    it falls from t = 9 s at data row 1 to t = 0 s at data row 10 (8 of 9 steps go back in time)
    """
    assert table.t is not None
    dt = np.diff(table.t)
    steps = int(np.count_nonzero(dt))
    backwards = int(np.count_nonzero(dt < 0.0))
    if steps == 0 or backwards <= BACKWARDS_FRACTION * steps:
        return
    first, last = int(table.rows[0]), int(table.rows[-1])
    raise DataError(
        f"{source}: the time column {time_name!r} runs backwards: it falls from "
        f"t = {table.t[0]:.6g} s at data row {first} to t = {table.t[-1]:.6g} s at data row "
        f"{last} ({backwards} of {steps} steps go back in time): a reversed clock column, or "
        "rows in reverse order; if the rows are newest first, reverse them (oldest first), "
        "otherwise check the time column (--time-col)"
    )


def sort_and_deduplicate(
    table: LogTable,
    names: tuple[str, str, str],
    source: str,
    notes: list[str],
    time_name: str = "time",
) -> LogTable:
    """Sort by time, drop identical repeated rows, refuse conflicting ones.

    ``names`` are the columns of u, y and the fuel temperature (``""`` when there is none),
    ``time_name`` the time column's. A time column that runs backwards over most of its steps
    is refused (:func:`check_clock_direction`); a few rows out of order are sorted, with a note.
    """
    assert table.t is not None
    check_clock_direction(table, time_name, source)
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
            + _coarse_stamps_hint(table.t, int(repeated.sum()))
        )
    keep = np.concatenate(([True], ~repeated))
    notes.append(f"dropped {int(repeated.sum())} duplicated row(s) (same time, same values)")
    return table.take(np.flatnonzero(keep))


def _coarse_stamps_hint(t: FloatArray, repeated: int) -> str:
    """Advice when many stamps repeat: a clock written coarser than the samples come."""
    if repeated < COARSE_STAMPS * t.size:
        return ""
    steps = np.diff(t)
    tick = float(np.min(steps[steps > 0.0])) if np.any(steps > 0.0) else 0.0
    per_row = (t[-1] - t[0] + tick) / t.size  # the rows fill the last stamp's tick too
    written = "whole minutes" if tick >= 59.5 else "whole seconds" if tick >= 0.95 else "coarse"
    return (
        f"; {repeated} of {t.size} rows repeat the stamp before them: stamps written coarser "
        f"than the samples ({written}?) cannot time them; give the sample time with no "
        f"time column (--sample-time {per_row:.2g} --time-col '') to take the rows as uniform "
        "(a gap then goes unseen)"
    )


def period(
    table: LogTable,
    time_name: str,
    sample_time: float | None,
    max_gap: float | None,
    source: str,
    notes: list[str],
) -> tuple[float, BoolArray]:
    """The period h [s] of the time column and where its intervals exceed ``max_gap``.

    h is fitted to the stamps (:func:`fit_period`) and rounded to the fewest digits the stamps
    support (:func:`round_period`). A sample time given must agree with the stamps within 1 %;
    it is the grid when the stamps lie on it within the jitter, else the stamps' own period is
    (:func:`_given_period`).
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
    fitted = fit_period(t, breaks, _refine_period(t, breaks, h0))
    if sample_time is not None:
        return _given_period(t, breaks, fitted, float(sample_time), time_name, source, notes), (
            breaks
        )
    h = round_period(fitted, (t[-1] - t[0]) / fitted.h, _longest_stretch(t, breaks) / fitted.h)
    if not fitted.exact and h != round(fitted.h, 12):
        notes.append(
            f"sample time {h:g} s, fitted to the time stamps ({fitted.h:.9g} ± {fitted.se:.2g} s "
            f"over {t.size} samples) and rounded to the digits they support"
        )
    return h, breaks


@dataclass(frozen=True)
class PeriodFit:
    """The period fitted to the stamps: ``h`` [s] and its standard error ``se`` [s]."""

    h: float
    se: float
    sigma: float = 0.0
    """The stamps' scatter about the fitted grid [s]."""

    @property
    def exact(self) -> bool:
        """Whether the stamps lie on the grid to within rounding (no jitter)."""
        return self.sigma <= UNIFORM_TOLERANCE * self.h


def fit_period(t: FloatArray, breaks: BoolArray, h: float) -> PeriodFit:
    """The period [s] as the least-squares slope of the stamps on their slot numbers.

    Each stretch between gaps has an origin of its own and all share the period: for stamps
    that scatter independently around a steady grid (jitter of standard deviation σ) this is
    the most precise estimate, with a standard error σ / √Σ(k − k̄)² that falls as N^-3/2.
    ``h`` is a first estimate good enough to number the slots (:func:`_refine_period`).
    """
    chunk = np.concatenate(([0], np.cumsum(breaks)))
    first = np.flatnonzero(np.concatenate(([True], breaks)))
    counts = np.bincount(chunk).astype(np.float64)
    # in place where it can be: a day of samples is 35 MB an array
    t_c = t - t[first][chunk]  # each stretch's times from its first stamp
    k_c = np.rint(t_c / h)
    k_c -= (np.bincount(chunk, weights=k_c) / counts)[chunk]
    t_c -= (np.bincount(chunk, weights=t_c) / counts)[chunk]
    spread = float(k_c @ k_c)
    if spread == 0.0:
        return PeriodFit(h, 0.0)
    slope = float(k_c @ t_c) / spread
    k_c *= slope
    t_c -= k_c  # the residuals
    dof = max(t.size - counts.size - 1, 1)
    sigma = float(np.sqrt(t_c @ t_c / dof))
    return PeriodFit(slope, sigma / np.sqrt(spread), sigma)


def round_period(fit: PeriodFit, slots: float, stretch: float | None = None) -> float:
    """The period with the fewest significant digits the stamps support.

    ``slots`` is the log's length and ``stretch`` its longest stretch between gaps, in
    periods. For stamps on an exact grid a rounding may move no sample by more than 2 % of a
    period over the log (:data:`EXACT_DRIFT`); for jittered stamps it may lie within three
    standard errors of the fit, or move the longest stretch's stamps by 0.1 of a period end to
    end (:data:`JITTERED_DRIFT`).

    Examples
    --------
    >>> round_period(PeriodFit(0.1000012, 4e-7, 0.0087), 3000.0)  # ±15 ms of jitter, 300 s
    0.1
    >>> round_period(PeriodFit(0.0204, 0.0), 50.0)  # a clock 2 % slow
    0.0204
    >>> round_period(PeriodFit(0.0203994, 1.8e-7, 7e-4), 1000.0)  # delays that wander
    0.0204
    """
    if fit.exact:
        tolerance = EXACT_DRIFT * fit.h / max(slots, 1.0)
    else:
        longest = slots if stretch is None else stretch
        tolerance = max(3.0 * fit.se, JITTERED_DRIFT * fit.h / max(longest, 1.0))
    for digits in range(1, 10):
        candidate = float(f"{fit.h:.{digits}g}")
        if abs(candidate - fit.h) <= tolerance:
            return candidate
    return round(fit.h, 12)


def _longest_stretch(t: FloatArray, breaks: BoolArray) -> float:
    """The longest time [s] between a stretch's first and last stamps."""
    first = np.flatnonzero(np.concatenate(([True], breaks)))
    last = np.concatenate((first[1:] - 1, [t.size - 1]))
    return float(np.max(t[last] - t[first]))


def _given_period(
    t: FloatArray,
    breaks: BoolArray,
    fitted: PeriodFit,
    sample_time: float,
    time_name: str,
    source: str,
    notes: list[str],
) -> float:
    """The sample time given, as the grid, when the stamps fit it within the jitter."""
    if abs(fitted.h - sample_time) > SAMPLE_TIME_TOLERANCE * sample_time * (1.0 + 1e-9):
        raise DataError(
            f"{source}: time column {time_name!r} says {fitted.h:.6g} s between samples, the "
            f"sample time given (sample_time, --sample-time) says {sample_time:g} s: give one "
            "of them"
        )
    placement = place_on_grid(t, breaks, sample_time)
    worst = float(np.max(np.abs(placement.deviation)))
    if placement.fits(sample_time):
        notes.append(
            f"time column {time_name} used (gaps and jitter checked on it): its stamps lie on "
            f"the {sample_time:g} s grid given (sample_time, --sample-time) within "
            f"{worst * 1e3:.2g} ms"
        )
        return sample_time
    longest = _longest_stretch(t, breaks) / fitted.h
    h = round_period(fitted, (t[-1] - t[0]) / fitted.h, longest)
    drift = abs(fitted.h - sample_time) / sample_time * longest
    notes.append(
        f"time column {time_name} used (gaps and jitter checked on it): its stamps drift off "
        f"the {sample_time:g} s grid given (sample_time, --sample-time) by {drift:.2g} periods "
        f"over the longest stretch, so their own period, {h:.6g} s, is the grid"
    )
    return h


@dataclass(frozen=True)
class Placement:
    """The slot of every sample on a grid of period h, one origin per stretch between gaps.

    ``k`` the slot numbers, ``origin`` [s] each stretch's grid origin, ``deviation`` [s] each
    stamp's distance from its slot, ``moved`` the late and early polls put on the slot next to
    the nearest (:func:`place_on_grid`), ``collided`` the stretches where two samples still
    share a slot.
    """

    k: IntArray
    origin: FloatArray
    deviation: FloatArray
    moved: BoolArray
    collided: BoolArray
    chunk: IntArray
    first: IntArray

    def late_or_early(self, h: float) -> BoolArray:
        """The polls placed beyond ±0.4 of a period: moved ones, and those up to half a period.

        A sample rounds onto its nearest slot, so it lies within half a period of it; one
        beyond ±0.4 (:data:`JITTER_FRACTION`) is a poll answered late or early.
        """
        return self.moved | (np.abs(self.deviation) > JITTER_FRACTION * h)

    def slipped(self, h: float) -> BoolArray:
        """The intervals across which the stamps slip a whole period: a clock, not a lost sample.

        A clock slower than the grid pushes its stamps ever later until one rounds onto the slot
        after next: an empty slot between a stamp beyond +0.4 of a period and one beyond −0.4.
        """
        late = self.deviation[:-1] > JITTER_FRACTION * h
        early = self.deviation[1:] < -JITTER_FRACTION * h
        slips: BoolArray = (np.diff(self.k) == 2) & (self.chunk[1:] == self.chunk[:-1])
        return slips & late & early

    def placed(self, h: float) -> BoolArray:
        """The stretches whose every sample lies on a slot of its own, none slipping a period.

        A sample lies within half a period of its slot (a late or early poll moved to the empty
        slot beside it, within a period).
        """
        bound = np.where(self.moved, h, 0.5 * h)
        off = np.abs(self.deviation) > bound * (1.0 - 1e-9)
        off[1:] |= self.slipped(h)
        worst = np.maximum.reduceat(off.astype(np.int8), self.first).astype(bool)
        return ~worst & ~self.collided

    def fits(self, h: float) -> bool:
        """Whether every stretch is placed."""
        return bool(self.placed(h).all())


def place_on_grid(t: FloatArray, breaks: BoolArray, h: float) -> Placement:
    """Each sample on its slot of a steady grid; a late poll followed by an early one too.

    A poll answered late (by more than half a period) rounds onto the next slot, where the
    next, early, sample also lands, and leaves its own slot empty: two samples share a slot
    beside an empty one. The samples keep their order, so the late one goes back to the empty
    slot before it (or an early one forward to the empty slot after it); such a sample may lie
    up to a period off its slot. Each stretch's origin is the stamps' mean phase.
    """
    chunk = np.concatenate(([0], np.cumsum(breaks)))
    first = np.flatnonzero(np.concatenate(([True], breaks)))
    origin = t[first] + _mean_phase(t, chunk, first, h) * h
    # in place where it can be: a day of samples is 35 MB an array
    deviation = t - origin[chunk]
    k = np.rint(deviation / h).astype(np.int64)
    moved = _unshare_slots(k, ~breaks)
    deviation -= h * k
    worst = np.maximum.reduceat(np.abs(deviation), first)
    exact = worst <= UNIFORM_TOLERANCE * h
    if exact.any():  # a grid without jitter starts at the first stamp, exactly
        shift = np.where(exact, t[first] - origin, 0.0)
        origin = origin + shift
        deviation -= shift[chunk]
    collided = np.zeros(first.size, dtype=bool)
    collided[chunk[1:][~breaks & (np.diff(k) < 1)]] = True
    return Placement(k, origin, deviation, moved, collided, chunk, first)


def _mean_phase(t: FloatArray, chunk: IntArray, first: IntArray, h: float) -> FloatArray:
    """Each stretch's mean phase [periods] of its stamps on a grid from its first stamp.

    The mean of the unit phasors (a circular mean), over at most :data:`PHASE_SAMPLES` stamps of
    each stretch spread evenly: the jitter averages out long before, and a day of samples would
    otherwise need four arrays of its length.
    """
    sample = np.arange(0, t.size, max(1, t.size // PHASE_SAMPLES))
    sample = np.union1d(sample, first)  # every stretch has its first stamp among them
    cycles = (t[sample] - t[first][chunk[sample]]) / h
    phasors = np.exp(2j * np.pi * (cycles - np.rint(cycles)))
    phase = np.add.reduceat(phasors, np.searchsorted(sample, first))
    return np.asarray(np.angle(phase) / (2.0 * np.pi), dtype=np.float64)


def _unshare_slots(k: IntArray, same: BoolArray) -> BoolArray:
    """Move a sample that shares a slot beside an empty one onto the empty slot (in place).

    ``same`` says which intervals lie within a stretch. A late poll shares the next sample's
    slot and leaves its own empty (or one of several empty, after a lost sample), or starts a
    stretch after a stall: it goes back one slot. Otherwise the later sample, an early poll,
    goes forward one slot when that one is empty (or its stretch ends). Returns which moved.
    """
    moved = np.zeros(k.size, dtype=bool)
    steps = np.diff(k)
    shared = np.flatnonzero(same & (steps == 0))
    if shared.size == 0:
        return moved
    opens = np.concatenate(([True], ~same))  # a sample that starts its stretch
    closes = np.concatenate((~same, [True]))  # a sample that ends its stretch
    previous = np.concatenate(([0], steps))
    following = np.concatenate((steps, [0]))
    back = opens[shared] | (previous[shared] >= 2)
    forward = ~back & (closes[shared + 1] | (following[shared + 1] >= 2))
    k[shared[back]] -= 1
    k[shared[forward] + 1] += 1
    moved[shared[back]] = True
    moved[shared[forward] + 1] = True
    return moved


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
        # a median over a sample of the pairs is as good as over all of them
        start = np.arange(0, t.size - lag, max(1, t.size // REFINE_PAIRS))
        same = chunk[start + lag] == chunk[start]
        if not same.any():
            break
        span = (t[start + lag] - t[start])[same]
        h = float(np.median(span / np.maximum(np.rint(span / h), 1.0)))
        lag *= 4
    return h


Piece = tuple[IntArray, IntArray, list[FloatArray], BoolArray]
"""Samples on the grid: their stretch, data row, signals (t, u, y[, T]), segment starts."""


@dataclass
class GridRecord:
    """The samples on the grid: times [s], u, y, fuel temperature [K], where segments start."""

    t: FloatArray
    u: FloatArray
    y: FloatArray
    T: FloatArray | None
    starts: BoolArray


def regularise(
    table: LogTable,
    h: float,
    breaks: BoolArray,
    mode: ResampleMode,
    fill_gaps: float | None,
    source: str,
    notes: list[str],
    bridgeable: IntArray | None = None,
) -> GridRecord:
    """Place the samples on the grid, split the log at its gaps, bridge or resample where asked.

    ``bridgeable`` are the data rows dropped on request (``drop_bad_rows``): a single missing
    sample there is bridged; any other missing sample is a gap.
    """
    t = table.t
    assert t is not None
    # each stretch between long intervals on a grid of its own phase, each sample on its slot
    placement = place_on_grid(t, breaks, h)
    placed = placement.placed(h)
    if not placed.all():
        _check_resampling(table, h, placement.chunk, placed, mode, source, _misfit(placement, h))
    on_grid = placed[placement.chunk]
    gaps = _find_gaps(table, h, breaks, placement.k, on_grid, fill_gaps, bridgeable)

    pieces = [_placed_samples(table, h, placement, on_grid, gaps)]
    first = placement.first
    for c in np.flatnonzero(~placed):
        stop = int(first[c + 1]) if c + 1 < first.size else t.size
        pieces.append(_resampled_samples(table, h, int(first[c]), stop, int(c)))
    record, rows = _merged(pieces, table.T is not None)
    notes.extend(_grid_notes(table, h, placement, placed, on_grid, breaks))
    notes.extend(_gap_notes(table, gaps, fill_gaps))
    return _drop_short_segments(record, rows, gaps.split, gaps.length, h, source, notes)


@dataclass
class Gaps:
    """Where the log has missing slots or long intervals, and what becomes of each.

    Per interval between consecutive samples: ``slots`` the periods it spans, ``length`` [s]
    (whole periods where the interval is near them), ``filled`` bridged on request
    (``fill_gaps``), ``bridge`` bridged (those and single dropped bad rows), ``split`` a
    segment break.
    """

    slots: IntArray
    length: FloatArray
    filled: BoolArray
    bridge: BoolArray
    split: BoolArray


def _find_gaps(
    table: LogTable,
    h: float,
    breaks: BoolArray,
    k: IntArray,
    on_grid: BoolArray,
    fill_gaps: float | None,
    bridgeable: IntArray | None,
) -> Gaps:
    """Long intervals and missing slots; bridged when short enough (or a dropped bad row)."""
    assert table.t is not None
    slots = np.diff(k)
    at_breaks = np.flatnonzero(breaks)
    # across a long interval the stretches' grids differ: count its periods from the stamps
    periods = (table.t[at_breaks + 1] - table.t[at_breaks]) / h
    slots[at_breaks] = np.maximum(np.rint(periods), 1.0)
    both = on_grid[:-1] & on_grid[1:]
    gap = (slots > 1) & both
    gap[at_breaks] = True
    length = slots * h  # a jittered stamp does not lengthen a gap: whole periods
    far = np.abs(periods - np.rint(periods)) > JITTER_FRACTION  # a restart off the grid
    length[at_breaks[far]] = periods[far] * h
    bridge = np.zeros_like(gap)
    if bridgeable is not None and bridgeable.size:
        bridge = (
            ~breaks
            & (slots == 2)
            & (np.diff(table.rows) == 2)
            & np.isin(table.rows[:-1] + 1, bridgeable)
        )
    fill = -np.inf if fill_gaps is None else fill_gaps * (1.0 + 1e-9)
    filled = gap & both & (length <= fill)
    bridge = filled | (gap & both & bridge)
    return Gaps(slots, length, filled, bridge, gap & ~bridge)


def _grid_notes(
    table: LogTable,
    h: float,
    placement: Placement,
    placed: BoolArray,
    on_grid: BoolArray,
    breaks: BoolArray,
) -> list[str]:
    """The notes on the placement: the jitter, the late and early polls, the resampling."""
    assert table.t is not None
    notes = []
    deviation = placement.deviation
    polls = placement.late_or_early(h) & on_grid
    regular = on_grid & ~polls
    if on_grid.any() and float(np.max(np.abs(deviation), where=on_grid, initial=0.0)) > (
        UNIFORM_TOLERANCE * h
    ):
        notes.append(_describe_jitter(deviation, regular if regular.any() else on_grid, h))
    if polls.any():
        off_ms = float(np.max(np.abs(deviation), where=polls, initial=0.0)) * 1e3
        notes.append(
            f"{int(polls.sum())} late or early poll(s) put on their own slots (beyond ±"
            f"{JITTER_FRACTION:g} of a period, their neighbours within it; at most {off_ms:.3g} "
            "ms off): values unchanged"
        )
    if not placed.all():
        first = placement.first
        stretches = "" if first.size == 1 else f"{int(np.sum(~placed))} of {first.size} stretches "
        dt = np.diff(table.t)[~on_grid[:-1] & ~breaks]
        notes.append(
            f"resampled {stretches}onto a uniform {h:g} s grid (intervals "
            f"{float(dt.min()):.6g} to {float(dt.max()):.6g} s): y interpolated "
            "linearly, u held"
        )
    return notes


def _gap_notes(table: LogTable, gaps: Gaps, fill_gaps: float | None) -> list[str]:
    """The notes on the gaps bridged and the gaps that split the log."""
    assert table.t is not None
    notes = []
    filled = gaps.filled
    if filled.any():
        changes = int(np.count_nonzero(filled & (table.u[1:] != table.u[:-1])))
        moved = (
            f"; the input changes across {changes} of them (its step moved to the gap's end)"
            if changes
            else ""
        )
        notes.append(
            f"bridged {int(filled.sum())} gap(s) up to {float(gaps.length[filled].max()):.3g} s "
            f"(fill_gaps, --fill-gaps {fill_gaps:g} s): {int(np.sum(gaps.slots[filled] - 1))} "
            f"sample(s) inserted, y interpolated linearly, u held{moved}"
        )
    if gaps.split.any():
        notes.append(_describe_gaps(np.flatnonzero(gaps.split), gaps.length, table.t, table.rows))
    return notes


def _merged(pieces: list[Piece], with_temperature: bool) -> tuple[GridRecord, IntArray]:
    """The pieces in time order (by stretch) as one record, and the data row of each sample."""
    if len(pieces) == 1:  # all placed: already in order, no copy
        _, rows, signals, starts = pieces[0]
    else:
        order = np.argsort(np.concatenate([piece[0] for piece in pieces]), kind="stable")
        rows = np.concatenate([piece[1] for piece in pieces])[order]
        signals = [
            np.concatenate([piece[2][j] for piece in pieces])[order]
            for j in range(4 if with_temperature else 3)
        ]
        starts = np.concatenate([piece[3] for piece in pieces])[order]
    record = GridRecord(
        t=signals[0],
        u=signals[1],
        y=signals[2],
        T=signals[3] if with_temperature else None,
        starts=starts,
    )
    return record, rows


def _describe_jitter(deviation: FloatArray, regular: BoolArray, h: float) -> str:
    """The note on stamps that scatter around their slots (the late and early polls apart)."""
    sd = float(np.std(deviation, where=regular))
    most = float(np.max(np.abs(deviation), where=regular, initial=0.0))
    return (
        f"time stamps scatter around a steady {h:g} s period (sd {sd * 1e3:.2g}"
        f" ms, at most {most * 1e3:.2g} ms, within ±{JITTER_FRACTION:g} of"
        f" a period): samples placed on the {h:g} s grid, values unchanged"
    )


def _placed_samples(
    table: LogTable, h: float, placement: Placement, on_grid: BoolArray, gaps: Gaps
) -> Piece:
    """The samples placed on their slots, with the bridged gaps filled in.

    Returns the chunk and data row of each output sample, its time, u, y and fuel temperature,
    and whether a segment starts at it.
    """
    chunk, k, origin = placement.chunk, placement.k, placement.origin
    bridge, split, slots = gaps.bridge, gaps.split, gaps.slots
    n = table.u.size
    signals: list[FloatArray]
    starts: BoolArray
    if not bridge.any() and on_grid.all():  # every sample once, as it is: no copies
        t: FloatArray = k.astype(np.float64)
        t *= h
        t += origin[chunk]
        signals = [t] + [x for x in (table.u, table.y, table.T) if x is not None]
        starts = np.concatenate(([True], split))
        return chunk, table.rows, signals, starts
    index = np.flatnonzero(on_grid)
    if not bridge.any():  # every sample once: no gather through repeated indices
        t = origin[chunk[index]] + h * k[index]
        signals = [t] + [x[index] for x in (table.u, table.y, table.T) if x is not None]
        starts = np.concatenate(([True], split))[index]
        return chunk[index], table.rows[index], signals, starts
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


def _resampled_samples(table: LogTable, h: float, start: int, stop: int, chunk: int) -> Piece:
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
    table: LogTable,
    h: float,
    chunk: IntArray,
    placed: BoolArray,
    mode: ResampleMode,
    source: str,
    misfit: int | None = None,
) -> None:
    """Refuse stretches off any steady grid that ``mode`` does not let be resampled safely.

    ``misfit`` is the first sample where the stamps fit no grid (:func:`_misfit`), named too.
    """
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
        f"(two in one slot, or a clock slipping a period{_misfit_place(table, misfit)}) and "
        f"{why}{hint}"
    )


def _misfit(placement: Placement, h: float) -> int | None:
    """The first sample that shares its slot with the next, or slips a period after it."""
    same = placement.chunk[1:] == placement.chunk[:-1]
    wrong = np.flatnonzero((same & (np.diff(placement.k) < 1)) | placement.slipped(h))
    return int(wrong[0]) if wrong.size else None


def _misfit_place(table: LogTable, misfit: int | None) -> str:
    """``", first at t = 6 s, data rows 301 and 302"`` (empty without a place)."""
    if misfit is None or table.t is None:
        return ""
    rows = table.rows[misfit : misfit + 2]
    return f", first at t = {table.t[misfit]:.6g} s, data rows {int(rows[0])} and {int(rows[-1])}"


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
    record: GridRecord,
    rows: IntArray,
    split: BoolArray,
    length: FloatArray,
    h: float,
    source: str,
    notes: list[str],
) -> GridRecord:
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
    return GridRecord(
        record.t[keep],
        record.u[keep],
        record.y[keep],
        None if record.T is None else record.T[keep],
        record.starts[keep],
    )
