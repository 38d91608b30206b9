"""Archive a store: each finished UTC day's raw samples and events as Parquet (``fuelid archive``).

:func:`archive_store` walks the store's UTC days (of plant time) before ``before`` — by default
the day of the store's newest sample, so that only finished days are archived — and for each:

1. reads the day's rows straight from the store (:class:`~fuelid.store._archived.StoreDays`) in
   one short read transaction (a NULL stays null; WAL readers never block the recorder's
   commits), a batch of rows at a time;
2. merges them with the file this store already has for the day (the store may have been
   thinned since: a re-archive never replaces raw rows by fewer — the union by ``seq``, or by
   ``time`` where ``seq`` is null, the store's values winning where both have a row);
3. writes the samples and the day's events with :func:`~fuelid.archive._layout.write_table`
   (temporary file, fsync, re-read, rename) when they differ from what is there;
4. records the day in the store's ``archived_days`` only after that, in a transaction of its
   own.

A day already archived whose rows have not changed since (no more rows than recorded, none
written after) is left alone, so archiving again changes nothing. Beside the days:
``loops/<loop_id>/<store_uuid>.json`` (the store's identity and the service record's settings,
:func:`~fuelid.archive._layout.read_loop_info`) and the plant file the service ran with, copied
to ``loops/<loop_id>/plant-<sha256>.toml`` when it still exists with the recorded hash (else the
json says why not in ``plant_note``).
"""

from __future__ import annotations

import hashlib
import json
import os
import sqlite3  # its errors: the store could not be read
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from fuelid.archive._layout import (
    EVENT_SCHEMA,
    SAMPLE_SCHEMA,
    day_bounds,
    day_of,
    partition_dir,
    write_table,
)
from fuelid.store import ARCHIVE_COLUMNS, SERVICE_KEY, SQLiteStore, StoreDays, StoreError

__all__ = ["ArchiveReport", "DayReport", "archive_store"]


@dataclass(frozen=True)
class DayReport:
    """One archived loop-day.

    Attributes
    ----------
    date : str
        The UTC date (YYYY-MM-DD).
    rows : int
        Samples in the day's file after archiving (the store's and any earlier raw rows).
    store_rows : int
        Samples the store holds for the day.
    events : int
        Events in the day's events file.
    bytes_written : int
        Bytes of Parquet written for the day (0 when nothing changed) [B].
    parquet_bytes : int
        Size of the day's samples and events files [B].
    store_bytes : int
        The store's bytes for the day's samples: its file size times its share of the rows [B].
    written : bool
        Whether a file was (re)written; False when the day was archived and unchanged.
    """

    date: str
    rows: int
    store_rows: int
    events: int
    bytes_written: int
    parquet_bytes: int
    store_bytes: int
    written: bool


@dataclass(frozen=True)
class ArchiveReport:
    """What :func:`archive_store` did (``fuelid archive --json`` prints :meth:`to_json`)."""

    store: str
    root: str
    loop_id: str
    store_uuid: str
    before: str | None
    days: tuple[DayReport, ...]
    seconds: float
    plant: str | None
    plant_note: str | None
    units: dict[str, str] = field(
        default_factory=lambda: {"bytes_written": "B", "parquet_bytes": "B", "store_bytes": "B"}
    )

    @property
    def rows(self) -> int:
        """Samples in the archived days' files."""
        return sum(d.rows for d in self.days)

    @property
    def bytes_written(self) -> int:
        """Parquet bytes written by this run [B]."""
        return sum(d.bytes_written for d in self.days)

    @property
    def parquet_bytes(self) -> int:
        """Parquet bytes of the days archived [B]."""
        return sum(d.parquet_bytes for d in self.days)

    @property
    def store_bytes(self) -> int:
        """The store's bytes for the same samples (by their share of its file) [B]."""
        return sum(d.store_bytes for d in self.days)

    def to_json(self) -> dict[str, Any]:
        """The report as one JSON object (keys in ``docs/reference/json.md``)."""
        return {
            "store": self.store,
            "archive": self.root,
            "loop_id": self.loop_id,
            "store_uuid": self.store_uuid,
            "before": self.before,
            "days": [d.__dict__ for d in self.days],
            "rows": self.rows,
            "bytes_written": self.bytes_written,
            "parquet_bytes": self.parquet_bytes,
            "store_bytes": self.store_bytes,
            "compression": self.store_bytes / self.parquet_bytes if self.parquet_bytes else None,
            "seconds": self.seconds,
            "plant": self.plant,
            "plant_note": self.plant_note,
            "units": self.units | {"seconds": "s"},
        }


def _check_folder(root: Path) -> None:
    """Refuse an archive folder that cannot be created or written, before reading anything."""
    try:
        root.mkdir(parents=True, exist_ok=True)
        probe = root / f".probe.{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as error:
        raise StoreError(f"cannot write to the archive folder {root}: {error.strerror}") from None


def _check_date(text: str) -> None:
    """Refuse a ``before`` that is not a calendar date written YYYY-MM-DD."""
    import datetime as _dt

    try:
        day_bounds(text)
        _dt.date.fromisoformat(text)
    except (StoreError, ValueError):
        raise StoreError(f"--before {text!r} is not a date (YYYY-MM-DD, UTC)") from None


def _day_table(source: StoreDays, start: float, end: float) -> pa.Table:
    """The day's samples as a table of :data:`SAMPLE_SCHEMA` (NULL → null), in batches."""
    batches = []
    for rows in source.sample_batches(start, end):
        columns = list(zip(*rows, strict=True))
        arrays = [
            pa.array(columns[ARCHIVE_COLUMNS.index(f.name)], type=f.type) for f in SAMPLE_SCHEMA
        ]
        batches.append(pa.RecordBatch.from_arrays(arrays, schema=SAMPLE_SCHEMA))
    return pa.Table.from_batches(batches, schema=SAMPLE_SCHEMA)  # no copy into one chunk


def _event_table(source: StoreDays, start: float, end: float) -> pa.Table:
    rows = source.event_rows(start, end)
    columns: list[Any] = list(zip(*rows, strict=True)) if rows else [[] for _ in EVENT_SCHEMA]
    return pa.table(
        [pa.array(c, type=f.type) for c, f in zip(columns, EVENT_SCHEMA, strict=True)],
        schema=EVENT_SCHEMA,
    )


def _merged_samples(new: pa.Table, old: pa.Table) -> pa.Table:
    """``new`` plus the rows of ``old`` it lacks: by ``seq``, or by ``time`` where seq is null."""
    if old.num_rows == 0:
        return new
    new_seq, old_seq = new.column("seq"), old.column("seq")
    new_valid = new_seq.is_valid().to_numpy(zero_copy_only=False)
    old_valid = old_seq.is_valid().to_numpy(zero_copy_only=False)
    keep = np.zeros(old.num_rows, dtype=bool)
    seqs = new_seq.fill_null(-1).to_numpy()
    old_seqs = old_seq.fill_null(-1).to_numpy()
    keep[old_valid] = ~np.isin(old_seqs[old_valid], seqs[new_valid])
    times = new.column("time").to_numpy()[~new_valid]
    old_times = old.column("time").to_numpy()
    keep[~old_valid] = ~np.isin(old_times[~old_valid], times)
    if not keep.any():
        return new
    merged = pa.concat_tables([new, old.filter(pa.array(keep))])
    return merged.sort_by([("time", "ascending"), ("seq", "ascending")]).combine_chunks()


def _merged_events(new: pa.Table, old: pa.Table) -> pa.Table:
    """``new`` plus the events of ``old`` it lacks (by time, kind and detail)."""
    seen = set(zip(*(new.column(c).to_pylist() for c in ("time", "kind", "detail")), strict=True))
    extra = [
        i
        for i, key in enumerate(
            zip(*(old.column(c).to_pylist() for c in ("time", "kind", "detail")), strict=True)
        )
        if key not in seen
    ]
    if not extra:
        return new
    merged = pa.concat_tables([new, old.take(pa.array(extra, type=pa.int64()))])
    return merged.sort_by("time").combine_chunks()


def _write_if_changed(table: pa.Table, path: Path) -> int:
    """Write ``table`` to ``path`` unless the file there holds the same rows; bytes written."""
    if path.exists() and pq.read_table(path, schema=table.schema).equals(table):
        return 0
    write_table(table, path)
    return path.stat().st_size


def _size(path: Path) -> int:
    return path.stat().st_size if path.exists() else 0


def archive_store(store: SQLiteStore, root: str | Path, before: str | None = None) -> ArchiveReport:
    """Archive the store's UTC days before ``before`` into the archive folder ``root``.

    Parameters
    ----------
    store : SQLiteStore
        The store (open; a running service may be writing it: the archive reads and records on
        a connection of its own, in short transactions).
    root : str or Path
        The archive folder (created when absent).
    before : str, optional
        A UTC date (YYYY-MM-DD): only days before it are archived. Default: the day of the
        store's newest sample (every finished day; the day still being recorded is not).

    Returns
    -------
    ArchiveReport
        The days, rows and bytes, and the time taken [s].

    Raises
    ------
    StoreError
        ``before`` is not a date, the store has no loop id or store UUID, the folder cannot be
        written, or a file did not read back as written (the day is then not recorded).
    """
    start_clock = _time.perf_counter()
    if before is not None:
        _check_date(before)
    folder = Path(root).resolve()
    _check_folder(folder)
    source = StoreDays(store.path)
    try:
        meta = source.meta()
        loop_id, store_uuid = meta.get("loop_id"), meta.get("store_uuid")
        if not loop_id or not store_uuid:
            raise StoreError(
                f"{store.path}: the store has no loop id or store uuid (a store of fuelid "
                "before schema 3 that was never opened by this fuelid)"
            )
        newest = source.newest_time()
        limit = before or (None if newest is None else day_of(newest))
        days = sorted(set(source.days_with("samples")) | set(source.days_with("events")))
        total_rows = source.sample_count()
        file_bytes = sum(
            _size(Path(store.path + suffix)) for suffix in ("", "-wal")
        )  # the store's share per row, for the comparison
        done = source.archived_days(loop_id)
        reports = []
        for day in days:
            date = day_of(day * 86400.0)
            if limit is None or date >= limit:
                continue
            reports.append(_archive_day(source, folder, loop_id, store_uuid, date, done.get(date)))
        reports = [
            DayReport(
                **{
                    **r.__dict__,
                    "store_bytes": round(file_bytes * r.store_rows / total_rows)
                    if total_rows
                    else 0,
                }
            )
            for r in reports
        ]
        plant, note = _write_loop_info(source, folder, meta)
    except OSError as error:
        raise StoreError(f"archive {folder}: {error}") from None
    except sqlite3.Error as error:
        raise StoreError(f"{store.path}: cannot read the store for the archive ({error})") from None
    finally:
        source.close()
    return ArchiveReport(
        store=store.path,
        root=str(folder),
        loop_id=loop_id,
        store_uuid=store_uuid,
        before=limit,
        days=tuple(reports),
        seconds=_time.perf_counter() - start_clock,
        plant=plant,
        plant_note=note,
    )


def _archive_day(
    source: StoreDays,
    folder: Path,
    loop_id: str,
    store_uuid: str,
    date: str,
    recorded: tuple[int, float, str] | None,
) -> DayReport:
    """Archive one day (module docstring, steps 1–4)."""
    start, end = day_bounds(date)
    sample_path = partition_dir(folder, "samples", loop_id, date) / f"{store_uuid}.parquet"
    event_path = partition_dir(folder, "events", loop_id, date) / f"{store_uuid}.parquet"
    with source.snapshot():  # one moment of the day
        wall = _time.time()
        since = -1.0 if recorded is None else recorded[1]
        count, newer, new_events = source.day_counts(start, end, since)
        unchanged = (
            recorded is not None
            and count <= recorded[0]
            and newer == 0
            and new_events == 0
            and sample_path.exists()
        )
        if not unchanged:
            samples = _day_table(source, start, end)
            events_table = _event_table(source, start, end)
    if unchanged:
        assert recorded is not None
        events = pq.read_metadata(event_path).num_rows if event_path.exists() else 0
        return DayReport(
            date, recorded[0], count, events, 0,
            _size(sample_path) + _size(event_path), 0, False,
        )  # fmt: skip
    old = (
        pq.read_table(sample_path, schema=SAMPLE_SCHEMA)
        if sample_path.exists()
        else SAMPLE_SCHEMA.empty_table()
    )
    merged = _merged_samples(samples, old)
    old_events = (
        pq.read_table(event_path, schema=EVENT_SCHEMA)
        if event_path.exists()
        else EVENT_SCHEMA.empty_table()
    )
    merged_events = _merged_events(events_table, old_events)
    # a day with events only (a long outage) has no samples file: an empty one would list it
    # among the archive's sample days
    written = _write_if_changed(merged, sample_path) if merged.num_rows else 0
    if merged_events.num_rows:
        written += _write_if_changed(merged_events, event_path)
    times = merged.column("time")
    t_first = float(times[0].as_py()) if merged.num_rows else None
    t_last = float(times[-1].as_py()) if merged.num_rows else None
    path = sample_path if merged.num_rows else event_path
    source.record_day(loop_id, date, merged.num_rows, t_first, t_last, str(path), wall)
    return DayReport(
        date, merged.num_rows, samples.num_rows, merged_events.num_rows, written,
        _size(sample_path) + _size(event_path), 0, True,
    )  # fmt: skip


def _write_text(path: Path, text: str) -> None:
    """Write ``text`` atomically (temporary file, fsync, rename) unless it is there already."""
    if path.exists() and path.read_text(encoding="utf-8") == text:
        return
    _write_bytes(path, text.encode("utf-8"))


def _write_bytes(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _write_loop_info(
    source: StoreDays, folder: Path, meta: dict[str, str]
) -> tuple[str | None, str | None]:
    """``loops/<loop_id>/<store_uuid>.json`` and the plant file; (plant name, note)."""
    loop_id, store_uuid = meta["loop_id"], meta["store_uuid"]
    record = source.state_value(SERVICE_KEY)
    settings: dict[str, Any] | None = None
    if isinstance(record, dict) and isinstance(record.get("settings"), dict):
        settings = record["settings"]
    plant, note = _copy_plant(folder / "loops" / loop_id, settings)
    info = {
        "loop_id": loop_id,
        "store_uuid": store_uuid,
        "site_name": meta.get("site_name"),
        "tag_map_hash": meta.get("tag_map_hash"),
        "created": float(meta["created"]) if "created" in meta else None,
        "period_s": float(meta["period_s"]) if "period_s" in meta else None,
        "settings": settings,
        "plant": plant,
        "plant_note": note,
    }
    text = json.dumps(info, indent=2, sort_keys=True, allow_nan=False) + "\n"
    _write_text(folder / "loops" / loop_id / f"{store_uuid}.json", text)
    return plant, note


def _copy_plant(
    loop_folder: Path, settings: dict[str, Any] | None
) -> tuple[str | None, str | None]:
    """Copy the service's plant file when it still has the recorded hash; (name, note)."""
    if settings is None:
        return None, "no service ran on this store: its plant file is not known"
    source, recorded = settings.get("plant_file"), settings.get("plant_hash")
    if source is None:
        return None, "the service ran with the built-in reference plant (no plant file)"
    if recorded and (loop_folder / f"plant-{recorded}.toml").exists():
        return f"plant-{recorded}.toml", None  # copied by an earlier run: the very bytes
    try:
        data = Path(source).read_bytes()
    except OSError as error:
        return None, f"the plant file {source} cannot be read now ({error.strerror})"
    digest = hashlib.sha256(data).hexdigest()
    if digest != recorded:
        return None, (
            f"the plant file {source} changed since the service started (sha256 {digest[:12]}, "
            f"recorded {str(recorded)[:12]})"
        )
    name = f"plant-{digest}.toml"
    if not (loop_folder / name).exists():
        _write_bytes(loop_folder / name, data)
    return name, None
