"""The one time-series container of fuelid, and the column names of its files.

Inside the program a record is a :class:`TimeSeries`: time in seconds (rows), named signals with
units. At the file edge the columns carry their unit as a suffix: ``t_s``, ``u_V``, ``q_Lpm``,
``T_fuel_degC`` are what ``fuelid simulate`` writes and what the other commands read by default.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from itertools import pairwise
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    import pandas as pd

from fuelid.errors import DataError

FloatArray = NDArray[np.float64]

TIME_COLUMN = "t_s"
INPUT_COLUMN = "u_V"
OUTPUT_COLUMN = "q_Lpm"
FUEL_TEMPERATURE_COLUMN = "T_fuel_degC"
PRESSURE_COLUMN = "p_pump_MPa"
"""Pump outlet pressure (gauge) [MPa], logged by ``fuelid simulate --pressure``."""
INPUT_UNIT = "V"
"""Engineering unit of the input: the drive's command signal (a scaled input is in it)."""
OUTPUT_UNIT = "L/min"
"""Engineering unit of the output: the flow (a scaled output is in it)."""


@dataclass(frozen=True)
class TimeSeries:
    """Sampled signals on a common, strictly increasing time axis.

    Parameters
    ----------
    time : array
        Sample times [s].
    signals : mapping of name to array
        One array per signal, as long as ``time``. Names are the file column names, which end in
        their unit (``q_Lpm``).
    units : mapping of name to str
        Unit of each signal (``"L/min"``).

    Examples
    --------
    >>> ts = TimeSeries([0.0, 0.02, 0.04], {"u_V": [1.0, 1.0, 1.5]}, {"u_V": "V"})
    >>> ts.sample_time, ts.to_pandas().columns.tolist()
    (0.02, ['t_s', 'u_V'])
    """

    time: FloatArray
    signals: Mapping[str, FloatArray]
    units: Mapping[str, str] = field(default_factory=dict)

    def __init__(
        self,
        time: ArrayLike,
        signals: Mapping[str, ArrayLike],
        units: Mapping[str, str] | None = None,
    ) -> None:
        t = np.asarray(time, dtype=float)
        if t.ndim != 1 or t.size == 0:
            raise DataError("a time series needs a non-empty one-dimensional time axis")
        if t.size > 1 and not np.all(np.diff(t) > 0.0):
            raise DataError("time must be strictly increasing")
        arrays = {name: np.asarray(values, dtype=float) for name, values in signals.items()}
        for name, values in arrays.items():
            if values.shape != t.shape:
                raise DataError(f"signal {name!r} has {values.size} samples, time has {t.size}")
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "signals", arrays)
        object.__setattr__(self, "units", dict(units or {}))

    def __len__(self) -> int:
        return int(self.time.size)

    def __getitem__(self, name: str) -> FloatArray:
        try:
            return self.signals[name]
        except KeyError:
            known = ", ".join(self.signals) or "none"
            raise DataError(f"no signal {name!r}; signals present: {known}") from None

    @property
    def sample_time(self) -> float:
        """Median sampling interval [s] (rounded to 1e-12 s)."""
        if self.time.size < 2:
            raise DataError("a single sample has no sample time")
        return round(float(np.median(np.diff(self.time))), 12)

    def to_pandas(self) -> pd.DataFrame:
        """The record as a DataFrame: ``t_s`` first, then the signals in order."""
        import pandas as pd  # only where a table is made: keeps `import fuelid` light

        return pd.DataFrame({TIME_COLUMN: self.time, **self.signals})

    def write(self, path: str | Path, overwrite: bool = False) -> Path:
        """Write as CSV or Parquet (chosen by the file extension); see :func:`write_table`."""
        from fuelid.io.files import write_table

        return write_table(self.to_pandas(), path, overwrite=overwrite)


@dataclass(frozen=True)
class IOData:
    """One input and one output, uniformly sampled: what the estimators fit.

    Parameters
    ----------
    u : array
        Input samples (for the fuel loop the VFD command [V]), held between samples.
    y : array
        Output samples (the measured flow [L/min]).
    sample_time : float
        Sampling interval h [s]; sample k is at ``t0 + k·h``.
    t0 : float
        Time of the first sample [s].
    u_unit, y_unit : str
        Units of u and y (K is reported in y_unit/u_unit).
    source : str
        Where the data came from (file name), for messages.
    notes : tuple of str
        What loading and preprocessing did or noticed (warnings to pass on to the user).
    segment_starts : tuple of int
        Indices of the samples that begin a new segment after a gap in the log (strictly
        increasing, each in 1 … n−1); empty for one contiguous record. The samples of all
        segments are concatenated in ``u`` and ``y``; nothing is interpolated across a gap.
    segment_t0 : tuple of float
        Time [s] of each sample in ``segment_starts`` (same length); within a segment sample k is
        ``h`` after sample k−1.
    T_fuel : array, optional
        Fuel temperature per sample [K], when the log has a fuel-temperature column.

    Examples
    --------
    >>> d = IOData(u=[1.0, 1.0, 1.5], y=[10.0, 10.0, 10.2], sample_time=0.02)
    >>> d.n_samples, d.t.tolist()
    (3, [0.0, 0.02, 0.04])
    """

    u: FloatArray
    y: FloatArray
    sample_time: float
    t0: float = 0.0
    u_unit: str = "V"
    y_unit: str = "L/min"
    source: str = ""
    notes: tuple[str, ...] = ()
    segment_starts: tuple[int, ...] = ()
    segment_t0: tuple[float, ...] = ()
    T_fuel: FloatArray | None = None

    def __post_init__(self) -> None:
        u = np.asarray(self.u, dtype=float)
        y = np.asarray(self.y, dtype=float)
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "y", y)
        if u.ndim != 1 or u.shape != y.shape:
            raise DataError("input and output must be one-dimensional and equally long")
        if not (np.isfinite(self.sample_time) and self.sample_time > 0.0):
            raise DataError(f"sample time must be positive, got {self.sample_time}")
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
            raise DataError("input and output must be finite")
        starts = tuple(int(i) for i in self.segment_starts)
        object.__setattr__(self, "segment_starts", starts)
        object.__setattr__(self, "segment_t0", tuple(float(t) for t in self.segment_t0))
        if len(starts) != len(self.segment_t0):
            raise DataError("every segment start needs its time (segment_t0)")
        if starts and not (
            starts[0] > 0 and starts[-1] < u.size and all(a < b for a, b in pairwise(starts))
        ):
            raise DataError("segment starts must increase strictly inside the record")
        if self.T_fuel is not None:
            T_fuel = np.asarray(self.T_fuel, dtype=float)
            if T_fuel.shape != u.shape:
                raise DataError("the fuel temperature must have one value per sample")
            object.__setattr__(self, "T_fuel", T_fuel)

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.u.size)

    @property
    def t(self) -> FloatArray:
        """Sample times [s] (jumping across the gaps between segments)."""
        k = np.arange(self.u.size, dtype=np.float64)
        t = self.t0 + self.sample_time * k
        for start, t_start in zip(self.segment_starts, self.segment_t0, strict=True):
            t[start:] = t_start + self.sample_time * (k[start:] - start)
        return t

    @property
    def n_segments(self) -> int:
        """Number of contiguous segments (1 for a record without gaps)."""
        return len(self.segment_starts) + 1

    def segment_bounds(self) -> list[tuple[int, int]]:
        """``(start, stop)`` sample indices of each contiguous segment, in order."""
        edges = (0, *self.segment_starts, self.n_samples)
        return list(pairwise(edges))

    def segments(self) -> list[IOData]:
        """The contiguous segments as records of their own (``[self]`` without gaps)."""
        if not self.segment_starts:
            return [self]
        return [self.segment(start, stop) for start, stop in self.segment_bounds()]

    def segment(self, start: int, stop: int | None = None) -> IOData:
        """Samples ``start:stop`` as a new record (times kept, gaps inside it kept)."""
        begin, end, _ = slice(start, stop).indices(self.n_samples)
        t = self.t
        inside = [
            (i - begin, t_i)
            for i, t_i in zip(self.segment_starts, self.segment_t0, strict=True)
            if begin < i < end
        ]
        return IOData(
            u=self.u[begin:end],
            y=self.y[begin:end],
            sample_time=self.sample_time,
            t0=float(t[begin]) if end > begin else self.t0,
            u_unit=self.u_unit,
            y_unit=self.y_unit,
            source=self.source,
            notes=self.notes,
            segment_starts=tuple(i for i, _ in inside),
            segment_t0=tuple(t_i for _, t_i in inside),
            T_fuel=None if self.T_fuel is None else self.T_fuel[begin:end],
        )

    def with_notes(self, *notes: str) -> IOData:
        """The same record with more notes."""
        return replace(self, notes=self.notes + notes)
