"""Preprocessing of PLC records before identification (docs/explanation/identification.md, step-ls).

Every function takes an :class:`~fuelid.io.timeseries.IOData` and returns a new one (the input
is never modified) with a short note appended to ``notes`` saying what was done or noticed.

* :func:`lowpass` — zero-phase Butterworth low-pass of the output y (never of the held command u),
  so no filter lag leaks into the fitted time constant or dead time.
* :func:`decimate` — from the PLC sample time (0.02 s) to the control period (1 s), anti-aliased
  with :func:`lowpass` and aligned with the controller's update instants.
* :func:`select` — a time window of the record.
* :func:`join_segments` — contiguous records (segments) as one record with gaps.

A record with gaps (``IOData.segment_starts``) is processed segment by segment: nothing is
filtered, decimated or selected across a gap, as if each segment were a record of its own; the
segments stay concatenated in one record.

Offsets need no preprocessing: both estimators fit a constant (and ``oe`` the initial state)
alongside the model.

Examples
--------
>>> import numpy as np
>>> t = np.arange(0.0, 30.0, 0.02)
>>> u = np.where(t >= 5.0, 1.5, 1.0)
>>> y = 14.6 + 8.0 * (u - 1.0) * (1.0 - np.exp(-np.clip(t - 5.0, 0.0, None) / 2.0))
>>> d = decimate(IOData(u, y, 0.02), 1.0)
>>> d.sample_time, d.n_samples, float(d.u[4]), float(d.u[5])
(1.0, 30, 1.0, 1.5)
>>> round(float(d.y[0]), 2), round(float(d.y[-1]), 2)
(14.6, 18.6)
"""

from __future__ import annotations

import functools
import math
from dataclasses import replace

import numpy as np
from scipy import signal

from fuelid.errors import DataError
from fuelid.io.timeseries import FloatArray, IOData

__all__ = ["decimate", "join_segments", "lowpass", "select"]

MIN_SELECTED_SAMPLES = 10
"""Fewest samples :func:`select` accepts."""

INTEGER_FACTOR_TOLERANCE = 1e-6
"""How far control_period/sample_time may be from an integer and still count as one."""

ANTIALIAS_FRACTION = 0.8
"""Anti-aliasing cutoff of :func:`decimate` as a fraction of the new Nyquist frequency."""


def _replace(
    data: IOData,
    note: str,
    *,
    u: FloatArray | None = None,
    y: FloatArray | None = None,
    sample_time: float | None = None,
    t0: float | None = None,
    kept: slice | None = None,
) -> IOData:
    """A new record with some fields replaced and ``note`` appended (the input is untouched).

    The segment layout and fuel temperature are kept: callers that change the number of samples
    pass records whose layout already matches (see :func:`join_segments`); ``kept`` is the
    slice of samples a contiguous record keeps (for the fuel temperature).
    """
    T_fuel = data.T_fuel if kept is None or data.T_fuel is None else data.T_fuel[kept].copy()
    return replace(
        data,
        T_fuel=T_fuel,
        u=data.u.copy() if u is None else u,
        y=data.y.copy() if y is None else y,
        sample_time=data.sample_time if sample_time is None else sample_time,
        t0=data.t0 if t0 is None else t0,
        notes=(*data.notes, note),
    )


def join_segments(parts: list[IOData], notes: tuple[str, ...] | None = None) -> IOData:
    """Contiguous records, in time order, as one record with a gap before each but the first.

    Parameters
    ----------
    parts : list of IOData
        Records at the same sample time, each starting after the previous one ends. Gaps inside
        a part are kept.
    notes : tuple of str, optional
        Notes of the joined record (default: the first part's).

    Returns
    -------
    IOData
        ``u``, ``y`` (and ``T_fuel`` when every part has it) concatenated; ``segment_starts``
        mark where each part (and each gap inside one) begins.

    Raises
    ------
    DataError
        No parts, different sample times, or parts that overlap in time.

    Examples
    --------
    >>> a = IOData([1.0, 1.0], [2.0, 2.0], 0.5)
    >>> b = IOData([1.5, 1.5, 1.5], [2.0, 2.1, 2.2], 0.5, t0=10.0)
    >>> j = join_segments([a, b])
    >>> j.segment_starts, j.segment_t0, j.n_segments
    ((2,), (10.0,), 2)
    """
    if not parts:
        raise DataError("no segments to join")
    first = parts[0]
    if len(parts) == 1:
        return first if notes is None else replace(first, notes=notes)
    h = first.sample_time
    starts: list[int] = []
    times: list[float] = []
    offset = 0
    t_end = -math.inf
    for part in parts:
        if not math.isclose(part.sample_time, h, rel_tol=1e-9):
            raise DataError("segments to join must share one sample time")
        t = part.t
        if t[0] <= t_end:
            raise DataError("segments to join must follow each other in time")
        if offset:
            starts.append(offset)
            times.append(float(t[0]))
        starts.extend(offset + i for i in part.segment_starts)
        times.extend(part.segment_t0)
        offset += part.n_samples
        t_end = float(t[-1])
    temperatures = [p.T_fuel for p in parts if p.T_fuel is not None]
    T_fuel = np.concatenate(temperatures) if len(temperatures) == len(parts) else None
    return replace(
        first,
        u=np.concatenate([p.u for p in parts]),
        y=np.concatenate([p.y for p in parts]),
        notes=first.notes if notes is None else notes,
        segment_starts=tuple(starts),
        segment_t0=tuple(times),
        T_fuel=T_fuel,
    )


def _span(data: IOData) -> str:
    """The record's time span for messages."""
    t_last = float(data.t[-1])
    gaps = f", {data.n_segments} segments" if data.n_segments > 1 else ""
    return (
        f"the record spans t = {data.t0:g} … {t_last:g} s "
        f"({data.n_samples} samples of {data.sample_time:g} s{gaps})"
    )


def lowpass(data: IOData, cutoff_hz: float, order: int = 4) -> IOData:
    """Zero-phase Butterworth low-pass filter of the output y.

    The filter runs forward and backward (:func:`scipy.signal.sosfiltfilt`), so it has no phase
    lag at all: the filtered output is not delayed, and no lag leaks into the identified time
    constant or dead time. Its magnitude response is the Butterworth one squared,
    ``|H(f)|² = 1 / (1 + (f/f_c)^(2·order))``. The input u is a held command and is never
    filtered. The ends are padded by odd reflection over about two cutoff periods (``2/f_c``,
    at most the record length) so that the end transients of the filter stay small. A record
    with gaps is filtered segment by segment, each padded at its own ends.

    Parameters
    ----------
    data : IOData
        The record.
    cutoff_hz : float
        Cutoff (−3 dB of one pass) frequency f_c [Hz]; strictly between 0 and the Nyquist
        frequency 1/(2h).
    order : int
        Butterworth order of one pass (the effective order is twice this).

    Returns
    -------
    IOData
        The record with y filtered, u unchanged.

    Raises
    ------
    DataError
        If the cutoff is not strictly between 0 and Nyquist, the order is below 1, or the record
        is too short for the filter's end padding.

    Examples
    --------
    >>> import numpy as np
    >>> t = 0.02 * np.arange(500)
    >>> d = IOData(np.ones(500), np.sin(2 * np.pi * 0.1 * t), 0.02)
    >>> f = lowpass(d, 2.0)
    >>> bool(np.max(np.abs(f.y - d.y)[100:-100]) < 1e-6), f.notes[-1]
    (True, 'y low-passed: zero-phase Butterworth, order 4, cutoff 2 Hz')
    """
    h = data.sample_time
    nyquist = 0.5 / h
    if not (math.isfinite(cutoff_hz) and 0.0 < cutoff_hz < nyquist):
        raise DataError(
            f"low-pass cutoff must lie strictly between 0 and the Nyquist frequency "
            f"{nyquist:g} Hz (sample time {h:g} s), got {cutoff_hz:g} Hz"
        )
    if order < 1:
        raise DataError(f"low-pass order must be at least 1, got {order}")
    sos = _butterworth(order, cutoff_hz, 1.0 / h).copy()  # scipy's filters want it writable
    min_pad = _min_padding(sos)
    y = data.y.copy()
    for index, (start, stop) in enumerate(data.segment_bounds()):
        n = stop - start
        if n <= min_pad:
            where = f"segment {index + 1} of {data.n_segments} " if data.n_segments > 1 else ""
            raise DataError(
                f"record {where}too short to low-pass: the order-{order} zero-phase filter pads "
                f"each end with {min_pad} samples and needs more than that ({n} given)"
            )
        # each segment is filtered on its own: never across a gap
        padlen = min(n - 1, max(min_pad, math.ceil(2.0 / (cutoff_hz * h))))
        y[start:stop] = signal.sosfiltfilt(sos, data.y[start:stop], padlen=padlen)
    return _replace(
        data, f"y low-passed: zero-phase Butterworth, order {order}, cutoff {cutoff_hz:g} Hz", y=y
    )


@functools.lru_cache(maxsize=32)
def _butterworth(order: int, cutoff_hz: float, fs: float) -> FloatArray:
    # designed once per (order, cutoff, rate): every online window's step-ls asks for the same
    # filter (the design was a tenth of step-ls's cost); read-only, as it is shared
    sos = np.asarray(signal.butter(order, cutoff_hz, fs=fs, output="sos"), dtype=np.float64)
    sos.setflags(write=False)
    return sos


def _min_padding(sos: FloatArray) -> int:
    """The minimum padding of sosfiltfilt [samples]; a record must be longer than it."""
    n_zero = min(int(np.sum(sos[:, 2] == 0.0)), int(np.sum(sos[:, 5] == 0.0)))
    return 3 * (2 * int(sos.shape[0]) + 1 - n_zero)


def _update_phase(u: FloatArray, factor: int) -> int:
    """Index (0…factor−1, modulo factor) at which most changes of u occur; 0 if u never changes."""
    changes = np.flatnonzero(u[1:] != u[:-1]) + 1
    if changes.size == 0:
        return 0
    counts = np.bincount(changes % factor, minlength=factor)
    return int(np.argmax(counts))  # ties: the earliest phase


def decimate(
    data: IOData,
    control_period: float,
    *,
    phase: int | None = None,
    antialias: bool = True,
) -> IOData:
    """Reduce PLC samples to the control period, aligned with the controller's updates.

    The decimation factor m = control_period/h must be an integer (within 1e-6). With
    ``antialias`` the output is first low-passed by :func:`lowpass` (zero phase, cutoff
    0.8 × the new Nyquist frequency 1/(2·control_period)); then every m-th sample is kept, starting
    at index ``phase``.

    Convention: the kept samples are the controller's update instants t_j = t0 + (phase + j·m)·h.
    The PLC's controller output changes only at those instants, and the logged u[k] at an update
    instant is already the new command, so the decimated u[j] is the command held from t_j to
    t_j + control_period (exactly the sample-and-hold input of the step-response regression),
    and the decimated y[j] is the (filtered) output measured at t_j.

    Parameters
    ----------
    data : IOData
        The record at the PLC sample time h [s].
    control_period : float
        New sample time T_s [s], an integer multiple of h.
    phase : int, optional
        Index (0 … m−1) of the first kept sample. By default it is the residue modulo m at which
        most of u's changes occur (index k with u[k] ≠ u[k−1]), i.e. the controller's update
        instants; 0 if u never changes.
    antialias : bool
        Low-pass y before keeping every m-th sample.

    Returns
    -------
    IOData
        The decimated record: ``sample_time = control_period``, ``t0`` the time of the first
        kept sample.

    Raises
    ------
    DataError
        If the factor is not an integer, the phase is out of range, or fewer than two samples
        would remain.

    Examples
    --------
    >>> import numpy as np
    >>> u = np.repeat([1.0, 1.2, 1.5], 10)[3:]  # updates every 10 samples, record starts late
    >>> d = decimate(IOData(u, u, 0.1), 1.0, antialias=False)
    >>> d.t0, d.u.tolist()
    (0.7, [1.2, 1.5])
    """
    h = data.sample_time
    if not (math.isfinite(control_period) and control_period > 0.0):
        raise DataError(f"control period must be positive, got {control_period:g} s")
    ratio = control_period / h
    factor = round(ratio)
    if factor < 1 or abs(ratio - factor) >= INTEGER_FACTOR_TOLERANCE:
        raise DataError(
            f"cannot decimate: the control period {control_period:g} s is not an integer "
            f"multiple of the sample time {h:g} s (ratio {ratio:.9g})"
        )
    if factor == 1:
        return _replace(data, f"not decimated: the sample time is already {h:g} s")
    if data.n_segments > 1:
        return _decimate_segments(data, control_period, factor, phase, antialias)
    if phase is None:
        phase = _update_phase(data.u, factor)
        how = "at the controller's update instants"
    elif not 0 <= phase < factor:
        raise DataError(f"decimation phase must lie in 0 … {factor - 1}, got {phase}")
    else:
        how = "as requested"
    n_kept = len(range(phase, data.n_samples, factor))
    if n_kept < 2:
        raise DataError(
            f"cannot decimate by {factor}: fewer than 2 samples would remain; {_span(data)}"
        )
    source = data
    if antialias:
        source = lowpass(data, ANTIALIAS_FRACTION * 0.5 / control_period)
    t0 = round(data.t0 + phase * h, 12)  # no 0.7000000000000001 in messages and reports
    return _replace(
        source,
        f"decimated by {factor} to {control_period:g} s, phase {phase} ({how}; first sample at "
        f"t = {t0:g} s); u[j] is the command held from t_j to t_j + {control_period:g} s",
        u=data.u[phase::factor].copy(),
        y=source.y[phase::factor].copy(),
        sample_time=control_period,
        t0=t0,
        kept=slice(phase, None, factor),
    )


def _decimate_segments(
    data: IOData, control_period: float, factor: int, phase: int | None, antialias: bool
) -> IOData:
    """:func:`decimate` of a record with gaps: each segment on its own, on one controller clock.

    The controller's update instants are one clock for the whole log, but a gap need not last a
    whole number of control periods: the phase is therefore found once, in samples counted from
    the record's first sample time (``round((t − t0)/h)``), and each segment keeps the samples
    on that clock. ``phase`` counts from the first segment's first sample. A segment too short
    to low-pass, or without a sample on the clock, is left out (a note says so).
    """
    h = data.sample_time
    bounds = data.segment_bounds()
    # index of each segment's first sample on the whole log's sample clock
    origins = [round((t_j - data.t0) / h) for t_j in (data.t0, *data.segment_t0)]
    if phase is None:
        changes = np.concatenate(
            [
                origin + np.flatnonzero(data.u[a + 1 : b] != data.u[a : b - 1]) + 1
                for (a, b), origin in zip(bounds, origins, strict=True)
            ]
        )
        phase = (
            int(np.argmax(np.bincount(changes % factor, minlength=factor))) if changes.size else 0
        )
        how = "at the controller's update instants"
    elif not 0 <= phase < factor:
        raise DataError(f"decimation phase must lie in 0 … {factor - 1}, got {phase}")
    else:
        how = "as requested"
    cutoff = ANTIALIAS_FRACTION * 0.5 / control_period
    parts: list[IOData] = []
    left_out: list[str] = []
    for index, ((a, b), origin) in enumerate(zip(bounds, origins, strict=True)):
        part = data.segment(a, b)
        first = (phase - origin) % factor
        if first >= part.n_samples:
            left_out.append(f"{index + 1} ({part.n_samples} samples: none on the clock)")
            continue
        source = part
        if antialias:
            try:
                source = lowpass(part, cutoff)
            except DataError:
                left_out.append(f"{index + 1} ({part.n_samples} samples: too short to low-pass)")
                continue
        parts.append(
            replace(
                part,
                u=part.u[first::factor].copy(),
                y=source.y[first::factor].copy(),
                sample_time=control_period,
                t0=round(part.t0 + first * h, 12),
                T_fuel=None if part.T_fuel is None else part.T_fuel[first::factor].copy(),
            )
        )
    if sum(p.n_samples for p in parts) < 2:
        raise DataError(
            f"cannot decimate by {factor}: fewer than 2 samples would remain; {_span(data)}"
        )
    note = (
        f"decimated by {factor} to {control_period:g} s segment by segment ({len(parts)} of "
        f"{data.n_segments}), on the controller's clock (phase {phase} from t = {data.t0:g} s, "
        f"{how}); u[j] is the command held from t_j to t_j + {control_period:g} s"
    )
    notes: tuple[str, ...] = (*data.notes, note)
    if left_out:
        notes = (*notes, f"segments left out by the decimation: {', '.join(left_out)}")
    return join_segments(parts, notes=notes)


def select(data: IOData, t_start: float | None = None, t_stop: float | None = None) -> IOData:
    """Samples with ``t_start <= t < t_stop``.

    Sample times that lie within 1e-9 samples of a bound count as on it.

    Parameters
    ----------
    data : IOData
        The record.
    t_start : float, optional
        First time kept [s] (inclusive); default the start of the record.
    t_stop : float, optional
        End of the window [s] (exclusive); default the end of the record.

    Returns
    -------
    IOData
        The selected samples, time origin kept.

    Raises
    ------
    DataError
        If the window is empty, inverted, or holds fewer than 10 samples; the message names the
        record's time span.

    Examples
    --------
    >>> import numpy as np
    >>> d = select(IOData(np.zeros(100), np.zeros(100), 0.5), 10.0, 20.0)
    >>> d.t0, d.n_samples
    (10.0, 20)
    """
    h = data.sample_time
    n = data.n_samples
    if data.n_segments > 1:
        # times jump at the gaps: find the bounds on the true time axis
        t = data.t
        k_start = 0 if t_start is None else int(np.searchsorted(t, t_start - 1e-9 * h))
        k_stop = n if t_stop is None else int(np.searchsorted(t, t_stop - 1e-9 * h))
    else:
        k_start = 0 if t_start is None else math.ceil((t_start - data.t0) / h - 1e-9)
        k_stop = n if t_stop is None else math.ceil((t_stop - data.t0) / h - 1e-9)
    k_start, k_stop = max(k_start, 0), min(k_stop, n)
    window = f"[{'start' if t_start is None else f'{t_start:g}'}, "
    window += f"{'end' if t_stop is None else f'{t_stop:g}'}) s"
    if k_stop <= k_start:
        raise DataError(f"the time window {window} selects no samples; {_span(data)}")
    if k_stop - k_start < MIN_SELECTED_SAMPLES:
        raise DataError(
            f"the time window {window} selects only {k_stop - k_start} samples "
            f"(at least {MIN_SELECTED_SAMPLES} needed); {_span(data)}"
        )
    part = data.segment(k_start, k_stop)
    t_last = float(part.t[-1])
    return _replace(part, f"selected t = {part.t0:g} … {t_last:g} s ({part.n_samples} samples)")
