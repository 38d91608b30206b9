"""A store's samples as a log that ``fuelid identify`` reads without options (``fuelid export``).

Columns: ``t_s`` (seconds from the first exported sample), ``u_V``, ``q_Lpm`` (the names
``identify`` reads by default), then ``sp_Lpm``, ``T_fuel_degC`` (only when every exported sample
has a fuel temperature: ``identify`` reads that column when present and refuses empty cells),
``mode`` (0 MAN, 1 AUTO, empty when not exposed), then ``excitation_V`` (the test signal the PLC
applied [V]) and ``run`` (1 during a wind-tunnel run, else 0) only when some exported sample has
one (empty cells where a sample has none), ``quality``, ``seq`` and ``time_utc`` (ISO 8601, the
absolute time; a CSV keeps ten significant digits, too few for UTC seconds at 20 ms).

Only samples of quality ``ok`` with a finite u and y are written, so a stretch that was lost,
flagged or recorded during an outage is a gap in the time column, never an interpolated value
(``identify`` splits the log there into segments).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Protocol

import numpy as np

from fuelid.errors import DataError
from fuelid.io.files import check_output_path, write_table
from fuelid.store._records import Quality, SampleArrays


class SampleSource(Protocol):
    """What :func:`export_log` reads: a store, or a loop of an archive (``ArchiveLoop``)."""

    @property
    def path(self) -> str:
        """The source's name, for messages."""

    def read(self, t_from: float | None = None, t_to: float | None = None) -> SampleArrays:
        """Samples with ``t_from <= time < t_to`` [s UTC], sorted by time."""


def parse_time(text: str) -> float:
    """A time bound from the command line: UTC seconds since the epoch, or ISO 8601.

    An ISO time without a zone is UTC.

    Examples
    --------
    >>> parse_time("1700000000.5")
    1700000000.5
    >>> parse_time("2023-11-14T22:13:20Z")
    1700000000.0
    """
    value = text.strip()
    try:
        seconds = float(value)
    except ValueError:
        pass
    else:
        if not math.isfinite(seconds):
            raise DataError(f"time {text!r} is not a finite number of seconds")
        return seconds
    try:
        stamp = datetime.fromisoformat(value.replace("Z", "+00:00"))
    except ValueError:
        raise DataError(
            f"time {text!r} is neither UTC seconds nor ISO 8601 (2026-03-01T12:00:00Z)"
        ) from None
    if stamp.tzinfo is None:
        stamp = stamp.replace(tzinfo=UTC)
    return stamp.timestamp()


@dataclass(frozen=True)
class ExportResult:
    """What :func:`export_log` wrote.

    Attributes
    ----------
    path : Path
        The log written.
    rows : int
        Samples written.
    left_out : int
        Samples in the range left out (quality not ok, or u or y missing).
    t_first, t_last : float
        UTC seconds of the first and last sample written [s].
    columns : tuple of str
        The columns written.
    """

    path: Path
    rows: int
    left_out: int
    t_first: float
    t_last: float
    columns: tuple[str, ...]


def export_log(
    store: SampleSource,
    out: str | Path,
    t_from: float | None = None,
    t_to: float | None = None,
    overwrite: bool = False,
) -> ExportResult:
    """Write the ok samples of ``t_from <= time < t_to`` [s UTC] as a CSV or Parquet log.

    Raises
    ------
    DataError
        The output path is refused (exists without ``overwrite``, unknown extension, no folder),
        or no ok sample is in the range.
    """
    import pandas as pd

    path = check_output_path(out, overwrite)
    data = store.read(t_from, t_to)
    keep = (data.quality == Quality.OK) & np.isfinite(data.u) & np.isfinite(data.y)
    rows = int(np.count_nonzero(keep))
    if rows == 0:
        raise DataError(f"{store.path}: no ok sample in the range ({len(data)} sample(s), none ok)")
    t = data.time[keep]
    temperature = data.fuel_temperature[keep]
    mode = data.mode[keep]
    frame = pd.DataFrame(
        {
            "t_s": np.round(t - t[0], 6),
            "u_V": data.u[keep],
            "q_Lpm": data.y[keep],
            "sp_Lpm": data.setpoint[keep],
        }
    )
    if np.all(np.isfinite(temperature)):
        frame["T_fuel_degC"] = temperature
    frame["mode"] = pd.array([None if m < 0 else int(m) for m in mode], dtype="Int64")
    excitation, run = data.excitation[keep], data.run[keep]
    if np.any(np.isfinite(excitation)):
        frame["excitation_V"] = excitation
    if np.any(np.isfinite(run)):
        frame["run"] = pd.array([int(r) if np.isfinite(r) else None for r in run], dtype="Int64")
    frame["quality"] = "ok"
    seq = data.seq[keep]
    frame["seq"] = pd.array([None if s < 0 else int(s) for s in seq], dtype="Int64")
    frame["time_utc"] = [
        datetime.fromtimestamp(float(x), tz=UTC).isoformat(timespec="milliseconds") for x in t
    ]
    write_table(frame, path, overwrite=overwrite)
    return ExportResult(
        path=path,
        rows=rows,
        left_out=len(data) - rows,
        t_first=float(t[0]),
        t_last=float(t[-1]),
        columns=tuple(str(c) for c in frame.columns),
    )
