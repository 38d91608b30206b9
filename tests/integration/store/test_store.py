"""The sample store (issue 14, item 4): SQLite files in tmp_path, durability under kill -9."""

from __future__ import annotations

import math
import random
import signal
import sqlite3
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from fuelid.errors import FuelidError
from fuelid.store import (
    SCHEMA_VERSION,
    Event,
    Quality,
    Sample,
    SampleWriter,
    SQLiteStore,
    StoreError,
    open_store,
    tag_map_hash,
)
from support.waiting import wait_until

T0 = 1_700_000_000.0  # UTC seconds
H = 0.02  # s
SITE = {"site_name": "tunnel 2 fuel loop", "tag_map_hash": tag_map_hash({"flow": "ir:20"})}


def _samples(seqs: range | list[int], quality: int = Quality.OK) -> list[Sample]:
    return [
        Sample(T0 + H * k, k, 2.0 + 0.001 * k, 40.0 + 0.01 * k, 41.0, 20.0, 1, quality)
        for k in seqs
    ]


def _new(tmp_path: Path, name: str = "loop.db") -> SQLiteStore:
    return SQLiteStore(tmp_path / name, period_s=H, **SITE)


def test_round_trip_keeps_every_column_and_missing_values(tmp_path: Path) -> None:
    rows = [
        *_samples(range(3)),
        Sample(T0 + 0.06, 3, 2.5, math.nan, math.nan, math.nan, None, Quality.BAD_VALUE),
    ]
    with _new(tmp_path) as store:
        assert store.append_samples(rows) == 4
        store.append_events([Event(T0, "link_up", "connected")])
        data = store.read()
        events = store.read_events()
    np.testing.assert_allclose(data.time, [T0 + H * k for k in range(4)], rtol=0, atol=1e-6)
    assert data.seq.tolist() == [0, 1, 2, 3]
    np.testing.assert_allclose(data.u, [2.0, 2.001, 2.002, 2.5])
    assert np.isnan(data.y[3])
    assert np.isnan(data.setpoint[3])
    assert np.isnan(data.fuel_temperature[3])
    assert data.mode.tolist() == [1, 1, 1, -1]
    assert data.quality.tolist() == [0, 0, 0, Quality.BAD_VALUE]
    assert events == [Event(T0, "link_up", "connected")]
    with SQLiteStore(tmp_path / "loop.db") as reader:  # a reader needs no identity
        assert len(reader.read(T0 + 0.01, T0 + 0.05)) == 2


def test_schema_is_versioned_strict_and_in_wal_mode(tmp_path: Path) -> None:
    _new(tmp_path).close()
    con = sqlite3.connect(tmp_path / "loop.db")
    try:
        assert con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
        assert con.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
        tables = dict(con.execute("SELECT name, sql FROM sqlite_schema WHERE type = 'table'"))
        assert set(tables) == {
            *("meta", "samples", "events", "models", "proposals"),
            *("windows", "writes", "online_state"),  # every store has them since schema 2
            *("requests", "samples_lod"),  # since schema 3
            *("outbox", "archived_days"),  # since schema 4
        }
        assert all(
            sql.rstrip().endswith(("STRICT", "STRICT, WITHOUT ROWID")) for sql in tables.values()
        )
        meta = dict(con.execute("SELECT key, value FROM meta"))
        assert meta["site_name"] == SITE["site_name"]
        assert meta["tag_map_hash"] == SITE["tag_map_hash"]
        with pytest.raises(sqlite3.IntegrityError):  # STRICT: no text in a REAL column
            con.execute(
                "INSERT INTO samples VALUES (1.0, 1, 'x', 1.0, 1.0, 1.0, 1, 0, NULL, NULL, NULL)"
            )
    finally:
        con.close()


def test_restart_appends_without_duplicates(tmp_path: Path) -> None:
    with _new(tmp_path) as store:
        assert store.append_samples(_samples(range(100))) == 100
        no_seq = [Sample(T0 + 100.0 + H * k, None, 1.0, 2.0) for k in range(5)]
        assert store.append_samples(no_seq) == 5
    with _new(tmp_path) as store:  # the recorder restarts and re-sends what it still has
        assert store.append_samples(_samples(range(50, 150))) == 50
        assert store.append_samples(no_seq) == 0  # keyed on time without a counter
        data = store.read()
        info = store.info()
    seqs = data.seq[data.seq >= 0]
    assert seqs.tolist() == list(range(150))
    assert info.rows == 155
    assert info.gaps == 0


def test_samples_from_another_site_are_refused(tmp_path: Path) -> None:
    _new(tmp_path).close()
    for other in (
        {"site_name": "tunnel 3 fuel loop", "tag_map_hash": SITE["tag_map_hash"]},
        {"site_name": SITE["site_name"], "tag_map_hash": tag_map_hash({"flow": "ir:22"})},
    ):
        with pytest.raises(StoreError, match="belongs to site 'tunnel 2 fuel loop'") as caught:
            SQLiteStore(tmp_path / "loop.db", **other)
        assert "\n" not in str(caught.value)
        assert isinstance(caught.value, FuelidError)
    with SQLiteStore(tmp_path / "loop.db") as reader:
        assert [e.kind for e in reader.read_events()] == ["site_mismatch", "site_mismatch"]
        assert reader.info().rows == 0
        with pytest.raises(StoreError, match="cannot be written"):
            reader.append_samples(_samples(range(3)))


def test_files_that_are_not_a_current_fuelid_store_are_refused(tmp_path: Path) -> None:
    text = tmp_path / "notes.db"
    text.write_text("this is not a database\n" * 100)
    with pytest.raises(StoreError, match="not a fuelid store"):
        SQLiteStore(text, **SITE)
    other = tmp_path / "other.db"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE t(x)")
    con.commit()
    con.close()
    with pytest.raises(StoreError, match="not a fuelid store"):
        SQLiteStore(other)
    _new(tmp_path).close()
    con = sqlite3.connect(tmp_path / "loop.db")
    con.execute(
        "UPDATE meta SET value = ? WHERE key = 'schema_version'", (str(SCHEMA_VERSION + 1),)
    )
    con.commit()
    con.close()
    with pytest.raises(StoreError, match="newer"):
        SQLiteStore(tmp_path / "loop.db", **SITE)
    with pytest.raises(StoreError, match="no such store"):
        SQLiteStore(tmp_path / "absent.db")
    with pytest.raises(StoreError, match="unknown store kind"):
        open_store("postgresql:///fuel")


def _rows_seen_by_another_connection(path: Path) -> int:
    con = sqlite3.connect(path)
    try:
        return int(con.execute("SELECT count(*) FROM samples").fetchone()[0])
    finally:
        con.close()


def test_writer_batches_commits_and_flush_makes_them_visible(tmp_path: Path) -> None:
    store = _new(tmp_path)
    commits: list[int] = []
    writer = SampleWriter(store, commit_interval_s=60.0, on_commit=lambda s, e: commits.append(1))
    writer.put_many(_samples(range(100)))
    writer.event("link_up", "connected", time=T0)
    time.sleep(0.1)  # a negative check's window: a commit of the rows put would come in it
    assert _rows_seen_by_another_connection(store._file) == 0  # nothing committed yet
    writer.flush()
    assert _rows_seen_by_another_connection(store._file) == 100
    assert len(commits) == 1  # the 100 samples and the event in one transaction
    writer.put_many(_samples(range(100, 150)))
    writer.close()  # commits what is pending
    assert _rows_seen_by_another_connection(store._file) == 150
    assert writer.rows_written == 150
    with pytest.raises(StoreError, match="closed"):
        writer.put(_samples([150])[0])
    store.close()


def test_writer_commits_on_its_own_about_every_interval(tmp_path: Path) -> None:
    with _new(tmp_path) as store, SampleWriter(store, commit_interval_s=0.1) as writer:
        writer.put_many(_samples(range(10)))
        wait_until(
            lambda: _rows_seen_by_another_connection(store._file) >= 10,
            5.0,
            "the writer's own commit (interval 0.1 s)",
        )


def test_prune_keeps_recent_samples_raw_and_thins_older_ones(tmp_path: Path) -> None:
    now = T0 + 10 * 86400.0
    old = [Sample(T0 + H * k, k, 1.0, 2.0) for k in range(500)]  # 10 s, 10 days ago
    recent = [Sample(now - 10.0 + H * k, 10_000 + k, 1.0, 2.0) for k in range(500)]
    with _new(tmp_path) as store:
        store.append_samples(old + recent)
        result = store.prune(older_than_days=2.0, thin_to_period_s=1.0, now=now)
        assert (result.deleted, result.kept_thinned) == (490, 10)
        data = store.read()
        old_times = data.time[data.time < result.cutoff]
        np.testing.assert_allclose(np.diff(old_times), 1.0, atol=1e-6)  # one per second
        assert np.count_nonzero(data.time >= result.cutoff) == 500
        again = store.prune(older_than_days=2.0, thin_to_period_s=1.0, now=now)
        assert again.deleted == 0
        gone = store.prune(older_than_days=2.0, thin_to_period_s=None, now=now)
        assert (gone.deleted, store.info().rows) == (10, 500)
        assert store.info().events == {"prune": 3}
        details = [e.detail for e in store.read_events() if e.kind == "prune"]
    # the retention said as an age: the events table dates each row in plant time in the
    # site's zone, so a detail names no second clock (issue 39: "(at … UTC wall clock)")
    assert details == [
        "samples older than 2 d: 490 deleted, 10 kept (one per 1.0 s)",
        "samples older than 2 d: 0 deleted, 10 kept (one per 1.0 s)",
        "samples older than 2 d: 10 deleted, 0 kept (none)",
    ]


def test_to_iodata_makes_gaps_segments_and_drops_bad_samples(tmp_path: Path) -> None:
    seqs = [k for k in range(200) if not 50 <= k < 60]
    rows = _samples(seqs)
    rows[seqs.index(120)] = rows[seqs.index(120)]._replace(quality=Quality.STALE)
    with _new(tmp_path) as store:
        store.append_samples(rows)
        data = store.to_iodata()
        info = store.info()
    assert data.n_samples == 189
    assert data.sample_time == pytest.approx(H, rel=1e-6)
    assert data.segment_starts == (50, 110)
    assert data.segment_t0 == pytest.approx((T0 + 60 * H, T0 + 121 * H))
    np.testing.assert_allclose(data.t[:50], T0 + H * np.arange(50), rtol=0, atol=1e-6)
    assert data.T_fuel is not None
    np.testing.assert_allclose(data.T_fuel, 293.15)
    assert [len(s.u) for s in data.segments()] == [50, 60, 79]
    assert (info.gaps, info.missing_samples) == (1, 10)


def test_to_iodata_without_a_counter_breaks_on_missing_time_slots(tmp_path: Path) -> None:
    times = [T0 + H * k for k in range(100) if not 30 <= k < 35]
    with _new(tmp_path) as store:
        store.append_samples([Sample(t, None, 1.0, 2.0) for t in times])
        data = store.to_iodata(sample_time=H)
        assert store.info().gaps == 1
    assert data.segment_starts == (30,)
    assert data.T_fuel is None
    with _new(tmp_path, "empty.db") as empty, pytest.raises(FuelidError, match="usable"):
        empty.to_iodata()


CHILD = """
import sys, time
from fuelid.store import Sample, SampleWriter, SQLiteStore
db, log, start = sys.argv[1], sys.argv[2], int(sys.argv[3])
store = SQLiteStore(db, site_name="crash site", tag_map_hash="abc", period_s=0.02)
out = open(log, "a", buffering=1)  # one write per line: a line is whole or absent
def committed(samples, events):
    if samples:
        out.write(f"{samples[-1].seq}\\n")
writer = SampleWriter(store, commit_interval_s=0.05, on_commit=committed)
writer.event("restart", f"from seq {start}")
seq = start
while True:
    writer.put_many(Sample(1.7e9 + 0.02 * k, k, 1.0, 2.0, 3.0, 20.0, 1, 0)
                    for k in range(seq, seq + 20))
    seq += 20
    time.sleep(0.005)  # the producer's pace: 20 samples every 5 ms
"""


def _last_reported(log: Path) -> int:
    lines = [line for line in log.read_text().splitlines() if line.strip()]
    return int(lines[-1]) if lines else -1


def _reported_past(log: Path, seen: int, child: subprocess.Popen[bytes]) -> Callable[[], bool]:
    """A condition: the child reported a commit past ``seen`` (and is still running)."""

    def past() -> bool:
        assert child.poll() is None, "the writer process died on its own"
        return log.exists() and _last_reported(log) > seen

    return past


@pytest.mark.parametrize("kills", [5, pytest.param(20, marks=pytest.mark.slow)])
def test_kill_9_loses_nothing_committed_and_never_corrupts(tmp_path: Path, kills: int) -> None:
    db, log, script = tmp_path / "crash.db", tmp_path / "committed.log", tmp_path / "child.py"
    script.write_text(CHILD)
    rng = random.Random(14)
    for _ in range(kills):
        seen = _last_reported(log) if log.exists() else -1
        start = max(seen + 1 - 30, 0)  # re-send the last samples, as a ring buffer back-fill does
        child = subprocess.Popen([sys.executable, str(script), str(db), str(log), str(start)])
        try:
            wait_until(
                _reported_past(log, seen, child), 30.0, "the writer process's first commit",
                every=0.01,
            )  # fmt: skip
            time.sleep(rng.uniform(0.0, 0.15))  # the behaviour: a kill at a random (seeded) point
            child.send_signal(signal.SIGKILL)
        finally:
            child.kill()
            child.wait(10.0)
        reported = _last_reported(log)
        con = sqlite3.connect(db)
        try:
            assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
            n_upto = con.execute("SELECT count(*) FROM samples WHERE seq <= ?", (reported,))
            assert n_upto.fetchone()[0] == reported + 1  # nothing reported committed is lost
        finally:
            con.close()
    with SQLiteStore(db, site_name="crash site", tag_map_hash="abc") as store:
        data = store.read()
        info = store.info()
        assert store.integrity_check() == "ok"
    assert data.seq.tolist() == list(range(len(data)))  # appended, no duplicates, no holes
    assert info.events["restart"] == kills
    assert info.gaps == 0


def test_open_store_by_url_and_a_file_left_empty_by_a_crash(tmp_path: Path) -> None:
    empty = tmp_path / "crashed.db"
    con = sqlite3.connect(empty)
    con.execute("PRAGMA journal_mode=WAL")  # created, killed before the schema was committed
    con.close()
    with open_store(f"sqlite:///{empty}", period_s=H, **SITE) as store:
        assert store.append_samples(_samples(range(3))) == 3
    with open_store(empty) as store:
        assert store.info().rows == 3


def test_a_failing_write_stops_the_writer_with_the_reason(tmp_path: Path) -> None:
    with _new(tmp_path) as store:
        writer = SampleWriter(store, commit_interval_s=60.0)
        writer.put_many(_samples(range(3), quality=9))  # not a quality code
        with pytest.raises(StoreError, match="writer failed"):
            writer.flush()
        with pytest.raises(StoreError, match="writer failed"):
            writer.close()
        assert store.info().rows == 0


def _journal_mode(path: Path) -> tuple[str, int, int]:
    """The file's journal mode, and its header's write/read format bytes (2 = WAL)."""
    header = path.read_bytes()[:20]
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    try:
        mode = str(con.execute("PRAGMA journal_mode").fetchone()[0])
    finally:
        con.close()
    return mode, header[18], header[19]


@pytest.mark.parametrize("identity", [True, False])
def test_a_foreign_sqlite_file_is_refused_before_anything_is_written_to_it(
    tmp_path: Path, identity: bool
) -> None:
    other = tmp_path / "other.db"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE t(x)")
    con.execute("INSERT INTO t VALUES (1)")
    con.commit()
    con.close()
    before = other.read_bytes()
    assert _journal_mode(other) == ("delete", 1, 1)
    name, digest = (SITE["site_name"], SITE["tag_map_hash"]) if identity else (None, None)
    with pytest.raises(StoreError, match="not a fuelid store"):
        SQLiteStore(other, name, digest)
    assert _journal_mode(other) == ("delete", 1, 1)  # not switched to WAL
    assert other.read_bytes() == before  # not a byte changed
    assert not other.with_name("other.db-wal").exists()


def test_set_quality_flags_ok_samples_of_a_stretch_in_the_writers_order(tmp_path: Path) -> None:
    with _new(tmp_path) as store:
        store.append_samples(_samples(range(10)))
        store.append_samples(_samples([10], quality=Quality.LINK_DOWN))
        # both ends included; samples already flagged keep their flag
        assert store.set_quality(T0 + 5 * H, T0 + 10 * H, Quality.BAD_VALUE) == 5
        q = store.read().quality.tolist()
        assert q == [0] * 5 + [Quality.BAD_VALUE] * 5 + [Quality.LINK_DOWN]
        plan = store._con.execute(
            "EXPLAIN QUERY PLAN UPDATE samples SET quality = 3 "
            "WHERE time >= 1.0 AND time <= 2.0 AND quality = 0"
        ).fetchall()
        assert "samples_time" in " ".join(str(row) for row in plan)  # an indexed update
        # through the writer: queued after samples not yet committed, it reaches them too, in
        # the same transaction
        commits: list[int] = []
        writer = SampleWriter(
            store, commit_interval_s=60.0, on_commit=lambda s, e: commits.append(1)
        )
        writer.put_many(_samples(range(11, 20)))
        writer.set_quality(T0 + 15 * H, T0 + 17 * H)
        writer.put_many(_samples(range(20, 22)))
        writer.close()
        assert commits == [1]
        q = store.read().quality.tolist()
        assert q[15:18] == [Quality.BAD_VALUE] * 3
        assert q[11:15] == [0] * 4
        assert q[18:] == [0] * 4
