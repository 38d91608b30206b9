"""The data side of excitation on demand (issue 40): the store, the recorder, the archive.

``samples`` gains ``excitation`` (the test signal the PLC applied [V]) and ``run`` (the
wind-tunnel run flag, 0/1) in store schema 5: a real store made at version 4 opens migrated,
its rows NULL there; the columns are written and read back (NaN where NULL); the recorder fills
them from ``[tags.excitation]``, ``[tags.run]`` and the ring field ``excitation`` (a replayed
log and a Modbus PLC written here, both sources under the test's control), and a site without
them records exactly as before; the archive carries them (older files read as NaN); the central
store, which holds no samples, syncs a schema-5 store as before.
"""

from __future__ import annotations

import math
import sqlite3
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from fuelid.plc import encode
from fuelid.store import (
    MIGRATIONS,
    SCHEMA_VERSION,
    Quality,
    Sample,
    SampleArrays,
    SQLiteStore,
    StoreError,
    build_at,
    export_log,
)
from support.recorder import REPLAY, kinds, load, record, rows, write_log

T0 = 1_767_225_600.0  # 2026-01-01T00:00:00Z
SITE = {"site_name": "tunnel 2 fuel loop", "tag_map_hash": "ab12"}
UINT32 = 1 << 32


def _columns(db: Path) -> list[str]:
    con = sqlite3.connect(db)
    try:
        return [row[1] for row in con.execute("PRAGMA table_info(samples)")]
    finally:
        con.close()


def _sql_rows(db: Path, sql: str) -> list[tuple[Any, ...]]:
    con = sqlite3.connect(db)
    try:
        return [tuple(row) for row in con.execute(sql).fetchall()]
    finally:
        con.close()


# --- the store: migration 5, written and read back ------------------------------------------


def test_migration_5_adds_the_columns_to_a_store_made_at_version_4(tmp_path: Path) -> None:
    assert SCHEMA_VERSION == 5
    assert MIGRATIONS[4].version == 5
    db = tmp_path / "v4.db"
    build_at(str(db), 4, SITE)
    assert "excitation" not in _columns(db)
    con = sqlite3.connect(db)
    con.executemany(
        "INSERT INTO samples(time, seq, u, y, setpoint, fuel_temperature, mode, quality, "
        "wall_time) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
        [(T0 + 0.02 * k, k, 2.0, 40.0 + k, 40.0, 20.0, 1, 0, T0 + 1.0) for k in range(5)],
    )
    con.commit()
    con.close()
    before = _sql_rows(db, "SELECT * FROM samples ORDER BY seq")
    with SQLiteStore(db, **SITE) as store:
        assert store.schema_version == 5
        old = store.read()
        assert np.isnan(old.excitation).all()
        assert np.isnan(old.run).all()
        store.append_samples(
            [
                Sample(T0 + 0.1, 5, 2.1, 45.0, excitation=0.05, run=1),
                Sample(T0 + 0.12, 6, 2.1, 45.0, excitation=math.nan, run=0),
                Sample(T0 + 0.14, 7, 2.1, 45.0),  # neither recorded
            ]
        )
        data = store.read()
    assert _columns(db)[-3:] == ["wall_time", "excitation", "run"]
    # the old rows are kept value for value, NULL in the new columns
    after = _sql_rows(db, "SELECT * FROM samples ORDER BY seq")
    assert after[:5] == [(*row, None, None) for row in before]
    assert [row[-2:] for row in after[5:]] == [(0.05, 1), (None, 0), (None, None)]
    np.testing.assert_array_equal(data.excitation[5:], [0.05, np.nan, np.nan])
    np.testing.assert_array_equal(data.run[5:], [1.0, 0.0, np.nan])
    assert data.excitation.dtype == data.run.dtype == np.float64
    assert _sql_rows(db, "PRAGMA user_version") == [(5,)]
    assert _sql_rows(db, "SELECT value FROM meta WHERE key = 'schema_version'") == [("5",)]


def test_the_run_column_holds_only_0_and_1_and_a_newer_store_is_refused(tmp_path: Path) -> None:
    db = tmp_path / "loop.db"
    SQLiteStore(db, **SITE).close()
    con = sqlite3.connect(db)
    try:
        with pytest.raises(sqlite3.IntegrityError):
            con.execute("INSERT INTO samples(time, seq, quality, run) VALUES (1.0, 1, 0, 2)")
        con.execute("PRAGMA user_version=6")
        con.commit()
    finally:
        con.close()
    with pytest.raises(StoreError, match="version 6 is newer than this fuelid's \\(5\\)"):
        SQLiteStore(db)


def test_arrays_built_without_the_new_columns_hold_nan_and_take_keeps_every_column() -> None:
    n = 4
    arrays = SampleArrays(
        time=T0 + np.arange(n, dtype=float),
        seq=np.arange(n, dtype=np.int64),
        u=np.full(n, 2.0),
        y=np.full(n, 40.0),
        setpoint=np.full(n, np.nan),
        fuel_temperature=np.full(n, 20.0),
        mode=np.ones(n, dtype=np.int64),
        quality=np.zeros(n, dtype=np.int64),
    )
    assert arrays.excitation.shape == arrays.run.shape == (n,)
    assert np.isnan(arrays.excitation).all()
    assert np.isnan(arrays.run).all()
    given = SampleArrays.from_rows(
        [(T0 + k, k, 2.0, 40.0, None, None, 1, 0, 0.01 * k, k % 2) for k in range(n)]
    )
    part = given.take(given.seq >= 2)
    assert part.excitation.tolist() == [0.02, 0.03]
    assert part.run.tolist() == [0.0, 1.0]


def test_export_writes_the_signal_and_the_run_flag_only_when_recorded(tmp_path: Path) -> None:
    import pandas as pd

    db = tmp_path / "loop.db"
    with SQLiteStore(db, **SITE) as store:
        store.append_samples(
            [
                Sample(T0 + 0.02 * k, k, 2.0, 40.0 + k, excitation=0.1 if k % 2 else 0.0, run=1)
                for k in range(6)
            ]
        )
        result = export_log(store, tmp_path / "log.csv")
        plain = tmp_path / "plain.db"
        with SQLiteStore(plain, **SITE) as other:
            other.append_samples([Sample(T0 + 0.02 * k, k, 2.0, 40.0) for k in range(6)])
            before = export_log(other, tmp_path / "plain.csv")
    assert result.columns[:5] == ("t_s", "u_V", "q_Lpm", "sp_Lpm", "mode")
    assert result.columns[5:7] == ("excitation_V", "run")
    frame = pd.read_csv(result.path)
    assert frame["excitation_V"].tolist() == [0.0, 0.1, 0.0, 0.1, 0.0, 0.1]
    assert frame["run"].tolist() == [1] * 6
    assert "excitation_V" not in before.columns
    assert "run" not in before.columns


# --- the recorder ----------------------------------------------------------------------------

EXCITATION_TAGS = '[tags.excitation]\naddress = "exc"\nunit = "V"\n'
RUN_TAG = '[tags.run]\naddress = "run"\ntype = "uint16"\n'
SEQ_TAG = '[tags.seq]\naddress = "seq"\ntype = "uint32"\n'


def _log(path: Path, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A replay log with the signal ``exc`` [V] and the flag ``run`` (a step at row n/2)."""
    k = np.arange(n)
    exc = np.where(k % 20 < 10, 0.05, -0.05)
    run = (k >= n // 2).astype(float)
    write_log(path, n, seq=k.astype(float), exc=exc, run=run)
    return exc, run


def test_a_polled_recording_stores_the_signal_and_the_flag_of_each_sample(tmp_path: Path) -> None:
    n = 150
    log = tmp_path / "log.csv"
    exc, run = _log(log, n)
    site = load(
        REPLAY.format(path=log, speed=1.0, period=0.01) + SEQ_TAG + EXCITATION_TAGS + RUN_TAG
    )
    record(site, tmp_path / "s.db", duration_s=30.0)
    data, _, _ = rows(tmp_path / "s.db")
    assert len(data) > n // 2
    k = data.seq
    # read in the same poll as u and y: the signal and the flag of the very sample
    np.testing.assert_array_equal(data.excitation, exc[k])
    np.testing.assert_array_equal(data.run, run[k])
    assert (data.quality == Quality.OK).all()


def test_a_bad_signal_is_stored_as_null_and_the_sample_stays_ok(tmp_path: Path) -> None:
    n = 120
    log = tmp_path / "log.csv"
    k = np.arange(n)
    exc = np.where(k % 20 < 10, 0.05, -0.05)
    exc[40:43] = np.nan
    write_log(log, n, seq=k.astype(float), exc=exc, run=np.zeros(n))
    site = load(
        REPLAY.format(path=log, speed=2.0, period=0.01) + SEQ_TAG + EXCITATION_TAGS + RUN_TAG
    )
    record(site, tmp_path / "b.db", duration_s=30.0)
    data, events, _ = rows(tmp_path / "b.db")
    seq = data.seq
    bad = (seq >= 40) & (seq < 43)
    assert bad.any()
    assert np.isnan(data.excitation[bad]).all()
    assert np.isfinite(data.excitation[~bad]).all()
    assert (data.quality == Quality.OK).all()
    assert (data.run == 0.0).all()
    (event,) = [e for e in kinds(events, "bad_value") if "excitation" in e.detail]
    assert event.detail.startswith("excitation = nan")
    nulls = _sql_rows(tmp_path / "b.db", "SELECT seq FROM samples WHERE excitation IS NULL")
    assert sorted(s for (s,) in nulls) == seq[bad].tolist()


def test_a_site_without_the_tags_records_as_before(tmp_path: Path) -> None:
    log = tmp_path / "log.csv"
    _log(log, 100)
    site = load(REPLAY.format(path=log, speed=2.0, period=0.01) + SEQ_TAG)
    record(site, tmp_path / "p.db", duration_s=30.0)
    data, _, info = rows(tmp_path / "p.db")
    assert info.rows == len(data) > 0
    assert np.isnan(data.excitation).all()
    assert np.isnan(data.run).all()
    assert _sql_rows(
        tmp_path / "p.db",
        "SELECT count(*) FROM samples WHERE excitation IS NOT NULL OR run IS NOT NULL",
    ) == [(0,)]


RING_WITH = (
    '[ring]\nhead = "seq"\naddress = "seq"\nsize = 512\n'
    'fields = ["seq", "command", "flow", "excitation"]\n'
)
RING_WITHOUT = (
    '[ring]\nhead = "seq"\naddress = "seq"\nsize = 512\nfields = ["seq", "command", "flow"]\n'
)


def test_a_ring_with_the_field_gives_each_records_signal(tmp_path: Path) -> None:
    n = 600
    log = tmp_path / "log.csv"
    exc, _run = _log(log, n)
    site = load(
        REPLAY.format(path=log, speed=10.0, period=0.02) + EXCITATION_TAGS + RUN_TAG + RING_WITH
    )
    record(site, tmp_path / "r.db", duration_s=30.0)
    data, _, _ = rows(tmp_path / "r.db")
    first = int(data.seq[0])
    assert data.seq.tolist() == list(range(first, n))  # from the ring: none lost
    np.testing.assert_array_equal(data.excitation, exc[data.seq])  # scan-consistent
    # the run flag is read with the tags, once per ring poll (at its head), and attached to the
    # poll's records: the step at n/2 comes at or before its record, never after
    assert data.run[0] == 0.0
    assert (data.run[data.seq >= n // 2] == 1.0).all()
    assert (np.diff(data.run) >= 0.0).all()


def test_a_ring_without_the_field_takes_the_signal_from_the_tag(tmp_path: Path) -> None:
    n = 600
    log = tmp_path / "log.csv"
    k = np.arange(n)
    step = np.where(k >= n // 2, 0.1, 0.0)
    write_log(log, n, seq=k.astype(float), exc=step, run=np.ones(n))
    site = load(
        REPLAY.format(path=log, speed=10.0, period=0.02) + EXCITATION_TAGS + RUN_TAG + RING_WITHOUT
    )
    record(site, tmp_path / "t.db", duration_s=30.0)
    data, _, _ = rows(tmp_path / "t.db")
    assert np.isfinite(data.excitation).all()
    # as the setpoint: read at each poll's head and attached to the poll's records
    assert data.excitation[0] == 0.0
    assert (data.excitation[data.seq >= n // 2] == 0.1).all()
    assert (np.diff(data.excitation) >= 0.0).all()
    assert (data.run == 1.0).all()


# --- a Modbus PLC whose ring records carry the signal ---------------------------------------

MODBUS_SITE = """
[site]
name = "excited loop"
[plc]
protocol = "modbus"
host = "127.0.0.1"
port = {port}
[sampling]
period_s = 0.01
control_period_s = 1.0
[tags.seq]
address = "ir:0"
type = "uint32"
[tags.flow]
address = "ir:2"
unit = "L/min"
[tags.command]
address = "ir:4"
unit = "V"
[tags.excitation]
address = "ir:6"
unit = "V"
[tags.mode]
address = "ir:10"
type = "uint16"
[tags.run]
address = "ir:11"
type = "uint16"
[ring]
head = "ir:100"
address = "ir:1000"
size = {size}
fields = ["seq", "command", "flow", "setpoint", "excitation"]
"""


def _excitation_of(seq: Any) -> Any:
    return np.float32(np.where(np.asarray(seq) % 50 < 25, 0.04, -0.04))


class _ExcitedRing:
    """A scan: u, y, the setpoint and the applied signal of sample seq, then the head."""

    def __init__(self, size: int) -> None:
        self.size = size
        self.seq = -1
        self.lock = threading.Lock()

    def __call__(self, plc: Any) -> list[tuple[int, list[int]]]:
        with self.lock:
            self.seq = (self.seq + 1) % UINT32
            seq = self.seq
        u, y = 2.0 + (seq % 100) * 0.01, 20.0 + (seq % 97) * 0.1
        e = float(_excitation_of(seq))
        record = encode(seq, "uint32") + encode(u, "float32") + encode(y, "float32")
        record += encode(40.0, "float32") + encode(e, "float32")
        return [
            (1000 + 10 * (seq % self.size), record),
            (100, encode(seq, "uint32")),
            (0, encode(seq, "uint32") + encode(y, "float32") + encode(u, "float32")),
            (6, [*encode(e, "float32"), 0, 0, 1, 1]),  # excitation, mode AUTO, run
        ]


@pytest.fixture
def excited_plc() -> Iterator[Any]:
    pytest.importorskip("pymodbus", reason="the [plc] extra (pymodbus) is not installed")
    from support.modbus import FakePlc

    size = 256
    plc = FakePlc(ir=1000 + 10 * size + 10, program=_ExcitedRing(size))
    plc.size = size
    plc.wait_scans(10)  # the PLC is running (its ring filling) when the recorder starts
    try:
        yield plc
    finally:
        plc.close()


def test_a_modbus_ring_of_five_fields_gives_the_applied_signal(
    excited_plc: Any, tmp_path: Path
) -> None:
    site = load(MODBUS_SITE.format(port=excited_plc.port, size=excited_plc.size))
    record(site, tmp_path / "m.db", duration_s=1.0)
    data, events, info = rows(tmp_path / "m.db")
    assert len(data) > 50
    assert info.missing_samples == 0
    np.testing.assert_array_equal(data.excitation, _excitation_of(data.seq).astype(np.float64))
    np.testing.assert_array_equal(data.setpoint, np.full(len(data), 40.0))
    assert (data.run == 1.0).all()
    assert (data.mode == 1).all()
    assert not kinds(events, "bad_value")
    assert not kinds(events, "ring_mismatch")


# --- the archive ------------------------------------------------------------------------------


def _two_days(db: Path) -> list[Sample]:
    """Samples of 2026-01-01 (every kind of signal and flag) and one of the next day."""
    samples = [
        Sample(
            T0 + 60.0 * k, k, 2.0, 40.0 + k, 40.0, 20.0, 1, 0,
            excitation=math.nan if k % 3 == 0 else 0.01 * k,
            run=None if k % 4 == 0 else k % 2,
        )
        for k in range(20)
    ]  # fmt: skip
    samples.append(Sample(T0 + 86_400.0 + 5.0, 20, 2.0, 40.0, excitation=0.2, run=1))
    with SQLiteStore(db, loop_id="exc-loop", **SITE) as store:
        store.append_samples(samples)
    return samples


def test_the_archive_carries_the_columns_and_reads_them_back(tmp_path: Path) -> None:
    from fuelid.archive import SAMPLE_SCHEMA, ArchiveLoop, archive_store, read_day, read_day_table

    db = tmp_path / "loop.db"
    samples = _two_days(db)[:20]
    with SQLiteStore(db) as store:
        report = archive_store(store, tmp_path / "archive")
    assert [d.date for d in report.days] == ["2026-01-01"]
    assert SAMPLE_SCHEMA.names[-2:] == ["excitation", "run"]
    table = read_day_table(tmp_path / "archive", "samples", "exc-loop", "2026-01-01")
    # NULL stays null in the file, value for value with the store
    stored = _sql_rows(db, "SELECT excitation, run FROM samples WHERE seq < 20 ORDER BY seq")
    assert (
        list(
            zip(
                table.column("excitation").to_pylist(), table.column("run").to_pylist(), strict=True
            )
        )
        == stored
    )
    assert table.column("excitation").null_count == sum(math.isnan(s.excitation) for s in samples)
    assert table.column("run").null_count == sum(s.run is None for s in samples)
    day = read_day(tmp_path / "archive", "exc-loop", "2026-01-01")
    with SQLiteStore(db) as store:
        whole = store.read(T0, T0 + 86_400.0)
    np.testing.assert_array_equal(day.excitation, whole.excitation)
    np.testing.assert_array_equal(day.run, whole.run)
    loop = ArchiveLoop(tmp_path / "archive", "exc-loop")
    np.testing.assert_array_equal(loop.read().run, whole.run)


def test_an_archive_file_written_before_the_columns_reads_them_as_nan(tmp_path: Path) -> None:
    from fuelid.archive import SAMPLE_SCHEMA, ArchiveLoop, archive_store, partition_dir, read_day

    old_schema = pa.schema([f for f in SAMPLE_SCHEMA if f.name not in ("excitation", "run")])
    n = 5
    old = pa.table(
        {
            "time": T0 - 86_400.0 + np.arange(n, dtype=float),
            "wall_time": np.full(n, T0),
            "seq": np.arange(n, dtype=np.int64),
            "u": np.full(n, 2.0),
            "y": np.full(n, 40.0),
            "setpoint": np.full(n, 40.0),
            "fuel_temperature": np.full(n, 20.0),
            "mode": np.ones(n, dtype=np.int64),
            "quality": np.zeros(n, dtype=np.int64),
        },
        schema=old_schema,
    )
    root = tmp_path / "archive"
    folder = partition_dir(root, "samples", "exc-loop", "2025-12-31")
    folder.mkdir(parents=True)
    pq.write_table(old, folder / "old-store.parquet")
    day = read_day(root, "exc-loop", "2025-12-31")
    assert len(day) == n
    assert np.isnan(day.excitation).all()
    assert np.isnan(day.run).all()
    # a newer store archives its days beside it; the loop reads both, old rows as NaN
    db = tmp_path / "loop.db"
    _two_days(db)
    with SQLiteStore(db) as store:
        archive_store(store, root)
    every = ArchiveLoop(root, "exc-loop").read()
    assert len(every) == n + 20
    assert np.isnan(every.excitation[:n]).all()
    assert np.isfinite(every.excitation[n:]).any()
    assert pq.read_schema(folder / "old-store.parquet").names == old_schema.names  # untouched


# --- the central store: no samples, a schema-5 store syncs as before --------------------------


def test_a_schema_5_store_syncs_to_the_central_store(tmp_path: Path, central_url: str) -> None:
    from fuelid.central import Sender, connect
    from fuelid.store import Event

    db = tmp_path / "loop.db"
    _two_days(db)
    with SQLiteStore(db, loop_id="exc-loop", **SITE) as store:
        store.append_events([Event(T0 + 30.0, "restart", "PLC restart: test")])
    with Sender(db, central_url, batch_rows=100) as sender:
        result = sender.sync()
    assert result.error is None
    assert result.backlog_rows == 0
    with connect(central_url) as con:
        version = con.execute("SELECT schema_version FROM liveness").fetchone()
        events = con.execute("SELECT kind, detail FROM events").fetchall()
        samples = con.execute("SELECT to_regclass('samples') IS NULL").fetchone()
    assert version == (5,)
    assert events == [("restart", "PLC restart: test")]
    assert samples == (True,)  # raw samples stay at the site (store and archive)
