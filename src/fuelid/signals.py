"""The one time-series container of fuelid and its CSV/Parquet edges.

Inside the program a record is a :class:`TimeSeries`: time in seconds (rows), named signals with
units. At the file edge the columns carry their unit as a suffix: ``t_s``, ``u_V``, ``q_Lpm``,
``T_fuel_degC`` are what ``fuelid simulate`` writes and what the other commands read by default.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from fuelid.errors import DataError

FloatArray = NDArray[np.float64]

TIME_COLUMN = "t_s"
INPUT_COLUMN = "u_V"
OUTPUT_COLUMN = "q_Lpm"
FUEL_TEMPERATURE_COLUMN = "T_fuel_degC"
TABLE_SUFFIXES = {".csv": "csv", ".parquet": "parquet", ".pq": "parquet"}


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
        return pd.DataFrame({TIME_COLUMN: self.time, **self.signals})

    def write(self, path: str | Path, overwrite: bool = False) -> Path:
        """Write as CSV or Parquet (chosen by the file extension); see :func:`write_table`."""
        return write_table(self.to_pandas(), path, overwrite=overwrite)


def _publish(temporary: str, target: Path) -> None:
    """Give a finished temporary file the usual permissions and rename it onto the target.

    ``mkstemp`` creates files readable by their owner only; a log or a report is meant to be
    shared like any file the user creates, so the umask decides, as for ``open()``.
    """
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(temporary, 0o666 & ~umask)
    os.replace(temporary, target)


def atomic_write_bytes(path: str | Path, payload: bytes) -> Path:
    """Write bytes to a temporary file beside ``path``, then rename: never a half-written file."""
    out = Path(path)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent or ".")
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(payload)
        _publish(tmp_name, out)
    except BaseException:
        Path(tmp_name).unlink(missing_ok=True)
        raise
    return out


def table_format(path: str | Path) -> str:
    """``"csv"`` or ``"parquet"`` from a file name, or a :class:`DataError` naming the choices."""
    suffix = Path(path).suffix.lower()
    try:
        return TABLE_SUFFIXES[suffix]
    except KeyError:
        choices = ", ".join(TABLE_SUFFIXES)
        raise DataError(
            f"cannot tell the table format of {str(path)!r}: use one of the extensions {choices}"
        ) from None


def check_output_path(path: str | Path, overwrite: bool = False) -> Path:
    """Validate where a table will be written, before any work is done.

    Refuses an unknown extension, a missing folder, a folder given as the file, and an existing
    file unless ``overwrite`` (so a typo never destroys a log).
    """
    out = Path(path)
    table_format(out)
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise DataError(f"output folder {str(parent)!r} does not exist")
    if out.is_dir():
        raise DataError(f"output path {str(out)!r} is a folder, not a file")
    if out.exists() and not overwrite:
        raise DataError(f"{str(out)!r} exists; pass --force (overwrite=True) to replace it")
    return out


def write_table(frame: pd.DataFrame, path: str | Path, overwrite: bool = False) -> Path:
    """Write a table atomically: to a temporary file beside the target, then renamed.

    A failed write never leaves a half-written file nor destroys an existing one.

    Parameters
    ----------
    frame : DataFrame
        The table.
    path : str or Path
        Target; ``.csv`` or ``.parquet``/``.pq``.
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    Path
        The written file.
    """
    out = check_output_path(path, overwrite)
    fmt = table_format(out)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent or ".")
    os.close(fd)
    try:
        if fmt == "csv":
            frame.to_csv(tmp_name, index=False, float_format="%.10g")
        else:
            frame.to_parquet(tmp_name, index=False)
        _publish(tmp_name, out)
    except Exception:
        Path(tmp_name).unlink(missing_ok=True)
        raise
    return out


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

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.u.size)

    @property
    def t(self) -> FloatArray:
        """Sample times [s]."""
        return self.t0 + self.sample_time * np.arange(self.u.size, dtype=np.float64)

    def segment(self, start: int, stop: int | None = None) -> IOData:
        """Samples ``start:stop`` as a new record (time origin kept)."""
        return IOData(
            u=self.u[start:stop],
            y=self.y[start:stop],
            sample_time=self.sample_time,
            t0=self.t0 + start * self.sample_time,
            u_unit=self.u_unit,
            y_unit=self.y_unit,
            source=self.source,
            notes=self.notes,
        )

    def with_notes(self, *notes: str) -> IOData:
        """The same record with more notes."""
        return IOData(
            self.u,
            self.y,
            self.sample_time,
            self.t0,
            self.u_unit,
            self.y_unit,
            self.source,
            self.notes + notes,
        )
