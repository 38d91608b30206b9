"""The raw archive's layout: where each loop-day's Parquet lives, its columns, how to read it.

An archive is a folder that any Parquet reader opens as a hive-partitioned dataset::

    DIR/
      samples/loop=<loop_id>/date=YYYY-MM-DD/<store_uuid>.parquet   raw samples of one loop-day
      events/loop=<loop_id>/date=YYYY-MM-DD/<store_uuid>.parquet    the recording's events
      loops/<loop_id>/<store_uuid>.json                             the loop's identity and
                                                                    settings, per store
      loops/<loop_id>/plant-<sha256>.toml                           the plant file the service
                                                                    ran with (when known)

The partition keys ``loop`` and ``date`` are in the path only, never as columns in the files
(a reader that adds them from the path and finds them inside too fails on the type clash). The
date is the UTC date of the samples' plant time. A loop-day holds one file per store that
recorded it (a loop whose store was replaced has two), named by the store's UUID, so that
archiving the same day again rewrites that store's file instead of adding a second copy.

**Samples** (:data:`SAMPLE_SCHEMA`): ``time`` (plant time [s UTC], float64, never null),
``wall_time`` (wall clock at commit [s UTC]), ``seq`` (the unwrapped sequence number, int64),
``u`` [V], ``y`` [L/min], ``setpoint`` [L/min], ``fuel_temperature`` [°C] (float64),
``mode`` (0 MAN, 1 AUTO, int64), ``quality`` (0 ok, 1 stale, 2 link_down, 3 bad_value; int64,
never null), ``excitation`` (the test signal applied [V], float64) and ``run`` (the wind-tunnel
run flag, 0 or 1, int64), both since store schema 5. Every other column is nullable, and null
where the store holds SQL NULL: a value the PLC did not give stays missing (it is not NaN).
Sorted by ``time``. A file written before ``excitation`` and ``run`` reads with both null (its
reader asks for :data:`SAMPLE_SCHEMA`, which fills a column the file lacks with nulls).

**Events** (:data:`EVENT_SCHEMA`): ``time`` [plant s UTC], ``kind``, ``detail``, ``wall_time``.

Files are zstd-compressed Parquet, written whole to a temporary name, flushed to disk, re-read
and compared, then renamed into place (:func:`write_table`): a partition is complete or absent.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from fuelid.store import SampleArrays, StoreError

__all__ = [
    "EVENT_SCHEMA",
    "SAMPLE_SCHEMA",
    "LoopDay",
    "arrays_of",
    "day_bounds",
    "day_of",
    "list_loop_days",
    "loop_info_files",
    "partition_dir",
    "read_day",
    "read_day_table",
    "read_loop_info",
    "read_range_table",
    "write_table",
]

SAMPLE_SCHEMA = pa.schema(
    [
        pa.field("time", pa.float64(), nullable=False),
        pa.field("wall_time", pa.float64()),
        pa.field("seq", pa.int64()),
        pa.field("u", pa.float64()),
        pa.field("y", pa.float64()),
        pa.field("setpoint", pa.float64()),
        pa.field("fuel_temperature", pa.float64()),
        pa.field("mode", pa.int64()),
        pa.field("quality", pa.int64(), nullable=False),
        pa.field("excitation", pa.float64()),
        pa.field("run", pa.int64()),
    ]
)
"""The columns of a samples file, in order (module docstring)."""

EVENT_SCHEMA = pa.schema(
    [
        pa.field("time", pa.float64(), nullable=False),
        pa.field("kind", pa.string(), nullable=False),
        pa.field("detail", pa.string(), nullable=False),
        pa.field("wall_time", pa.float64()),
    ]
)
"""The columns of an events file, in order."""

KINDS = ("samples", "events")
"""The two partitioned datasets of an archive."""

COMPRESSION = "zstd"
"""The files' compression codec."""

_LOOP_ID = re.compile(r"^[a-z0-9][a-z0-9-]*$")
_DATE = re.compile(r"^\d{4}-\d{2}-\d{2}$")


@dataclass(frozen=True, order=True)
class LoopDay:
    """One loop's one UTC day: the unit of archiving and of re-identification."""

    loop_id: str
    date: str  # YYYY-MM-DD (UTC)

    @property
    def key(self) -> str:
        """``<loop_id>/<date>``: a name for logs and result files."""
        return f"{self.loop_id}/{self.date}"


def _check_loop_id(loop_id: str) -> str:
    if not _LOOP_ID.match(loop_id):
        raise StoreError(
            f"not a loop id: {loop_id!r} (lower-case letters, digits and '-', as [site] loop_id)"
        )
    return loop_id


def day_of(time_s: float) -> str:
    """The UTC date (YYYY-MM-DD) of a plant time [s UTC]."""
    return _dt.datetime.fromtimestamp(math.floor(time_s), tz=_dt.UTC).date().isoformat()


def day_bounds(date: str) -> tuple[float, float]:
    """The plant-time span [s UTC] of a UTC date: ``start <= time < end``."""
    if not _DATE.match(date):
        raise StoreError(f"not a date: {date!r} (YYYY-MM-DD)")
    start = _dt.datetime.fromisoformat(date).replace(tzinfo=_dt.UTC).timestamp()
    return start, start + 86400.0


def partition_dir(root: str | Path, kind: str, loop_id: str, date: str) -> Path:
    """The folder of one loop-day of ``kind`` ("samples" or "events")."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}")
    day_bounds(date)  # validates
    return Path(root) / kind / f"loop={_check_loop_id(loop_id)}" / f"date={date}"


def write_table(table: pa.Table, path: Path) -> None:
    """Write ``table`` to ``path`` atomically: a temporary file, fsync, re-read check, rename.

    Raises :class:`StoreError` when the file read back differs from the table (a full disk or
    a failing device), leaving nothing at ``path``'s name but what was there before.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        pq.write_table(table, tmp, compression=COMPRESSION)
        with open(tmp, "rb") as handle:
            os.fsync(handle.fileno())
        back = pq.read_table(tmp, schema=table.schema)
        if not back.equals(table):
            raise StoreError(f"the archive file {path} did not read back as written")
        os.replace(tmp, path)
        _remove_stale_temporaries(path)
        directory = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(directory)
        finally:
            os.close(directory)
    finally:
        if tmp.exists():
            tmp.unlink()


def _remove_stale_temporaries(path: Path) -> None:
    """Remove the temporary files of ``path`` that writers killed mid-write left behind.

    A writer names its temporary file by its process id; one whose process is gone (killed
    between writing and renaming) will never rename it, and the file written now replaces
    what it was for. A live writer's file is left alone.
    """
    for stale in path.parent.glob(f".{path.name}.*.tmp"):
        pid = stale.name.removeprefix(f".{path.name}.").removesuffix(".tmp")
        if pid.isdigit() and int(pid) != os.getpid() and not _process_alive(int(pid)):
            stale.unlink(missing_ok=True)


def _process_alive(pid: int) -> bool:
    """Whether a process with this id runs (one of another user's counts as running)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def list_loop_days(
    root: str | Path,
    loops: Iterable[str] | None = None,
    date_from: str | None = None,
    date_to: str | None = None,
) -> list[LoopDay]:
    """The loop-days with samples in the archive, sorted; ``date_from <= date <= date_to``."""
    base = Path(root) / "samples"
    if not base.is_dir():
        raise StoreError(f"not a fuelid archive (no samples/ folder): {root}")
    wanted = None if loops is None else {_check_loop_id(loop) for loop in loops}
    days = []
    for loop_dir in base.glob("loop=*"):
        loop_id = loop_dir.name.removeprefix("loop=")
        if wanted is not None and loop_id not in wanted:
            continue
        for day_dir in loop_dir.glob("date=*"):
            date = day_dir.name.removeprefix("date=")
            if not _DATE.match(date) or not any(day_dir.glob("*.parquet")):
                continue
            if (date_from is None or date >= date_from) and (date_to is None or date <= date_to):
                days.append(LoopDay(loop_id, date))
    return sorted(days)


def read_day_table(root: str | Path, kind: str, loop_id: str, date: str) -> pa.Table:
    """Every file of one loop-day of ``kind`` as one table, sorted by time (empty when none)."""
    schema = SAMPLE_SCHEMA if kind == "samples" else EVENT_SCHEMA
    files = sorted(partition_dir(root, kind, loop_id, date).glob("*.parquet"))
    if not files:
        return schema.empty_table()
    table = pa.concat_tables([pq.read_table(f, schema=schema) for f in files])
    return table.sort_by("time")


def read_day(root: str | Path, loop_id: str, date: str) -> SampleArrays:
    """One loop-day's samples as arrays (nulls as NaN and −1, as a store reads them)."""
    return arrays_of(read_day_table(root, "samples", loop_id, date))


def arrays_of(table: pa.Table) -> SampleArrays:
    """A samples table (:data:`SAMPLE_SCHEMA`) as arrays: nulls as NaN and −1, as a store reads.

    ``run`` is a float array (NaN where null), as :class:`~fuelid.store._records.SampleArrays`
    holds it.

    Examples
    --------
    >>> arrays_of(SAMPLE_SCHEMA.empty_table()).time.size
    0
    """

    def floats(name: str) -> np.ndarray[Any, Any]:
        column = table.column(name).cast(pa.float64()).to_numpy(zero_copy_only=False)
        return np.asarray(column, dtype=np.float64)  # nulls come back as NaN

    def ints(name: str) -> np.ndarray[Any, Any]:
        return np.asarray(table.column(name).fill_null(-1).to_numpy(), dtype=np.int64)

    return SampleArrays(
        time=floats("time"),
        seq=ints("seq"),
        u=floats("u"),
        y=floats("y"),
        setpoint=floats("setpoint"),
        fuel_temperature=floats("fuel_temperature"),
        mode=ints("mode"),
        quality=ints("quality"),
        excitation=floats("excitation"),
        run=floats("run"),
    )


def read_range_table(
    root: str | Path,
    kind: str,
    loop_id: str,
    t_from: float | None = None,
    t_to: float | None = None,
) -> pa.Table:
    """A loop's rows of ``kind`` with ``t_from <= time < t_to`` [plant s UTC], across days.

    Only the days that overlap the range are opened; sorted by time (empty when none).
    """
    import pyarrow.compute as pc

    schema = SAMPLE_SCHEMA if kind == "samples" else EVENT_SCHEMA
    date_from = None if t_from is None else day_of(t_from)
    date_to = None if t_to is None else day_of(t_to)
    base = Path(root) / kind / f"loop={_check_loop_id(loop_id)}"
    dates = sorted(
        d.name.removeprefix("date=")
        for d in base.glob("date=*")
        if _DATE.match(d.name.removeprefix("date="))
    )
    tables = [
        read_day_table(root, kind, loop_id, date)
        for date in dates
        if (date_from is None or date >= date_from) and (date_to is None or date <= date_to)
    ]
    table = pa.concat_tables(tables) if tables else schema.empty_table()
    time = table.column("time")
    if t_from is not None:
        table = table.filter(pc.greater_equal(time, float(t_from)))
        time = table.column("time")
    if t_to is not None:
        table = table.filter(pc.less(time, float(t_to)))
    return table


def loop_info_files(root: str | Path, loop_id: str) -> list[Path]:
    """The loop's ``<store_uuid>.json`` files, oldest store first (by their ``created``)."""
    folder = Path(root) / "loops" / _check_loop_id(loop_id)
    files = list(folder.glob("*.json"))
    return sorted(files, key=lambda f: (json.loads(f.read_text()).get("created") or 0.0, f.name))


def read_loop_info(root: str | Path, loop_id: str) -> dict[str, Any]:
    """The newest store's identity and settings of a loop (``loops/<loop_id>/*.json``).

    Keys: ``loop_id``, ``store_uuid``, ``site_name``, ``tag_map_hash``, ``created`` [wall s
    UTC], ``period_s`` [s], ``settings`` (the service record's settings: every ``[online]``
    setting, ``sampling``, ``controller``, ``plant_hash``…; None when no service ran on the
    store) and ``plant`` (the archived plant file's name in the loop's folder, or None).
    """
    files = loop_info_files(root, loop_id)
    if not files:
        raise StoreError(f"the archive has no settings for loop {loop_id!r} (loops/{loop_id}/)")
    info: dict[str, Any] = json.loads(files[-1].read_text())
    return info
