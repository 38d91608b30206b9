"""The store's schema and its migrations (issue 24): older stores open and are upgraded.

Pattern for the next migration: build a store at the version before with
:func:`fuelid.store._schema.build_at` (or load a dump written by a released fuelid, as
``tests/data/store_v0_1.sql``), put rows in it, open it with :class:`SQLiteStore` and compare
every row; :func:`test_a_store_of_every_older_version_opens_upgraded` does it for every version.
"""

from __future__ import annotations

import json
import math
import re
import sqlite3
from pathlib import Path

import pytest

from fuelid.cli import main
from fuelid.store import (
    MIGRATIONS,
    SCHEMA_VERSION,
    OnlineHistory,
    Sample,
    SQLiteStore,
    StoreError,
    build_at,
)
from fuelid.store import _schema as store_schema
from fuelid.store._schema import Migration, upgrade

DATA = Path(__file__).resolve().parents[2] / "data"
T0 = 1_700_000_000.0
SITE = {"site_name": "tunnel 2 fuel loop", "tag_map_hash": "ab12"}


def _load_dump(dump: Path, db: Path) -> None:
    con = sqlite3.connect(db)
    try:
        con.executescript(dump.read_text(encoding="utf-8"))
    finally:
        con.close()


def _tables(db: Path) -> dict[str, list[tuple[object, ...]]]:
    """Every row of every table, in rowid order."""
    con = sqlite3.connect(db)
    try:
        names = [
            row[0]
            for row in con.execute(
                "SELECT name FROM sqlite_schema WHERE type = 'table' ORDER BY name"
            )
        ]
        # samples_lod is WITHOUT ROWID: in the order of its key
        return {
            name: con.execute(
                f"SELECT * FROM {name} ORDER BY {'1, 2' if name == 'samples_lod' else 'rowid'}"
            ).fetchall()
            for name in names
        }
    finally:
        con.close()


def _schema(db: Path) -> set[tuple[str, str, str]]:
    con = sqlite3.connect(db)
    try:
        return set(con.execute("SELECT type, name, sql FROM sqlite_schema WHERE sql IS NOT NULL"))
    finally:
        con.close()


def _pragma(db: Path, name: str) -> int:
    con = sqlite3.connect(db)
    try:
        return int(con.execute(f"PRAGMA {name}").fetchone()[0])
    finally:
        con.close()


def test_migrations_are_numbered_one_by_one_and_the_newest_is_the_schema_version() -> None:
    assert [m.version for m in MIGRATIONS] == list(range(1, len(MIGRATIONS) + 1))
    assert MIGRATIONS[-1].version == SCHEMA_VERSION


def test_store_written_by_fuelid_0_1_is_upgraded_without_losing_a_row(tmp_path: Path) -> None:
    db = tmp_path / "old.db"
    _load_dump(DATA / "store_v0_1.sql", db)
    assert _pragma(db, "user_version") == 1
    before = _tables(db)
    with SQLiteStore(db) as store:  # a reader opens it too, and upgrades it
        assert store.schema_version == SCHEMA_VERSION
        samples = store.read()
        events = store.read_events()
    after = _tables(db)
    assert _pragma(db, "user_version") == SCHEMA_VERSION
    assert set(before) <= set(after)
    # samples and events: value for value, in the same order, with wall_time NULL (unknown);
    # the online rows' wall times (the windows ran at real time: plant = wall − 1 s by the
    # anchors (601, 600) and (901, 900)) mapped onto plant time, the old value kept as wall_time
    # (events gain a stable id in version 4: 1, 2, … in their stored order; samples the
    # columns excitation and run in version 5, NULL: not recorded)
    assert after["samples"] == [(*row, None, None, None) for row in before["samples"]]
    assert after["events"] == [(k, *row, None) for k, row in enumerate(before["events"], start=1)]
    assert after["online_state"] == before["online_state"]
    assert after["models"] == [
        (*row[:1], row[1] - 1.0, *row[2:], row[1]) for row in before["models"]
    ]
    assert after["windows"] == [
        (row[0], max(row[3], row[1] - 1.0), *row[2:], row[1]) for row in before["windows"]
    ]
    (write,) = before["writes"]
    assert after["writes"] == [
        (*write[:1], write[1] - 1.0, *write[2:11], write[11] - 1.0, write[1], write[11])
    ]
    (proposal,) = after["proposals"]
    assert proposal[1] == before["proposals"][0][1] - 1.0
    assert proposal[-1] == before["proposals"][0][1]
    history = json.loads(proposal[6])["history"]
    assert [(h["time"], h["wall_time"]) for h in history] == [
        (1700000901.0, 1700000902.0),
        (1700000902.0, 1700000903.0),
    ]
    meta_before, meta_after = dict(before["meta"]), dict(after["meta"])
    assert re.fullmatch("[0-9a-f]{32}", meta_after.pop("store_uuid"))
    assert meta_after == {
        **meta_before,
        "schema_version": str(SCHEMA_VERSION),
        "loop_id": "tunnel-2-fuel-loop",
    }
    # the level-of-detail rows of the six samples: 1 s buckets T0 (5 samples) and T0 + 5
    lod = {(row[0], row[1]): row[2:] for row in after["samples_lod"]}
    assert lod[(1, T0)] == (5, 2.0, 2.3, 40.0, 41.75, 40.0, 42.0, 21.5, 21.625, 3)
    assert lod[(1, T0 + 5.0)] == (1, 1.5, 1.5, 30.0, 30.0, None, None, 22.0, 22.0, 0)
    assert lod[(10, T0)] == (6, 1.5, 2.3, 30.0, 41.75, 40.0, 42.0, 21.5, 22.0, 3)
    assert len(samples) == len(before["samples"]) == 6
    assert math.isnan(samples.y[2])
    assert samples.seq[5] == -1
    assert samples.quality[4] == 2
    assert [e.kind for e in events] == ["link_up", "gap", "gain_change"]
    with SQLiteStore(
        db, period_s=0.02, **{**SITE, "tag_map_hash": meta_before["tag_map_hash"]}
    ) as store:
        with OnlineHistory(store) as history:
            assert history.model(1)["model"]["K"] == 12.5
            assert [w["accepted"] for w in history.windows()] == [True, False]
            assert history.proposal(1)["status"] == "approved"
            assert history.write(1)["status"] == "verified"
            assert history.state("last_known_good") == {"Kc": 0.06, "Ti": 1.1}
            assert history.last_apply_seq() == 1
        assert store.append_samples([Sample(T0 + 6.0, 7, 2.0, 40.0)]) == 1
        assert store.integrity_check() == "ok"


def test_an_upgraded_store_has_the_schema_of_a_new_one(tmp_path: Path) -> None:
    old, new = tmp_path / "old.db", tmp_path / "new.db"
    _load_dump(DATA / "store_v0_1.sql", old)
    SQLiteStore(old).close()
    SQLiteStore(new, **SITE).close()
    assert _schema(old) == _schema(new)
    assert _pragma(old, "application_id") == _pragma(new, "application_id")


@pytest.mark.parametrize("version", range(1, SCHEMA_VERSION))
def test_a_store_of_every_older_version_opens_upgraded(tmp_path: Path, version: int) -> None:
    db = tmp_path / "old.db"
    build_at(str(db), version, SITE)
    con = sqlite3.connect(db)
    con.executemany(
        "INSERT INTO samples(time, seq, u, y, setpoint, fuel_temperature, mode, quality) "
        "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
        [Sample(T0 + 0.02 * k, k, 2.0, 40.0 + k)[:8] for k in range(5)],  # the columns of v1
    )
    con.commit()
    con.close()
    before = _tables(db)
    with SQLiteStore(db, **SITE) as store:
        assert store.info().schema_version == SCHEMA_VERSION
        assert store.read().y.tolist() == [40.0, 41.0, 42.0, 43.0, 44.0]
    wall = [None] if version < 3 else []  # the wall_time column version 3 adds
    excitation_run = [None, None] if version < 5 else []  # the columns version 5 adds
    assert _tables(db)["samples"] == [(*row, *wall, *excitation_run) for row in before["samples"]]
    assert _schema(db) == _schema(_new_store(tmp_path))


def _new_store(tmp_path: Path) -> Path:
    db = tmp_path / "reference.db"
    SQLiteStore(db, **SITE).close()
    return db


def test_opening_an_up_to_date_store_changes_nothing(tmp_path: Path) -> None:
    db = _new_store(tmp_path)
    before = (_tables(db), _schema(db))
    SQLiteStore(db).close()
    assert (_tables(db), _schema(db)) == before


def test_a_store_newer_than_this_fuelid_is_refused_naming_both_versions(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = _new_store(tmp_path)
    con = sqlite3.connect(db)
    con.execute(f"PRAGMA user_version={SCHEMA_VERSION + 1}")  # the meta table not told
    con.commit()
    con.close()
    newer = (
        f"store schema version {SCHEMA_VERSION + 1} is newer than this fuelid's ({SCHEMA_VERSION})"
    )
    with pytest.raises(StoreError, match=re.escape(newer)):
        SQLiteStore(db)
    assert _pragma(db, "user_version") == SCHEMA_VERSION + 1  # left untouched
    capsys.readouterr()
    assert main(["store", "info", "--store", str(db)]) == 2
    err = capsys.readouterr().err
    assert newer in err
    assert len(err.strip().splitlines()) == 1


def test_a_failed_migration_leaves_the_store_at_the_version_before(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    db = _new_store(tmp_path)
    broken = Migration(
        SCHEMA_VERSION + 1,
        "a table, then a statement that fails",
        ("CREATE TABLE future(id INTEGER PRIMARY KEY) STRICT", "SELECT * FROM no_such_table"),
    )
    monkeypatch.setattr(store_schema, "MIGRATIONS", (*MIGRATIONS, broken))
    monkeypatch.setattr(store_schema, "SCHEMA_VERSION", SCHEMA_VERSION + 1)
    con = sqlite3.connect(db, isolation_level=None)
    try:
        with pytest.raises(
            StoreError, match=f"from schema {SCHEMA_VERSION} to {SCHEMA_VERSION + 1}"
        ):
            upgrade(con, str(db), to_version=SCHEMA_VERSION + 1)
    finally:
        con.close()
    assert _pragma(db, "user_version") == SCHEMA_VERSION
    assert "future" not in _tables(db)


def test_the_outbox_logs_every_change_of_the_sent_tables_only_while_it_is_on(
    tmp_path: Path,
) -> None:
    db = _new_store(tmp_path)
    con = sqlite3.connect(db, isolation_level=None)
    try:
        con.execute("INSERT INTO events(time, kind, detail) VALUES (1.0, 'restart', 'off')")
        assert con.execute("SELECT count(*) FROM outbox").fetchone()[0] == 0
        con.execute("INSERT INTO meta VALUES ('outbox', 'on')")
        con.execute("INSERT INTO events(time, kind, detail) VALUES (2.0, 'restart', 'on')")
        con.execute(
            "INSERT INTO proposals(time, kc, ti, status, detail) "
            "VALUES (3.0, 1, 2, 'pending', '{}')"
        )
        con.execute("UPDATE proposals SET status = 'approved'")
        con.execute("INSERT INTO samples(time, seq, quality) VALUES (4.0, 1, 0)")  # not sent
        rows = con.execute("SELECT tbl, row_id FROM outbox ORDER BY id").fetchall()
    finally:
        con.close()
    assert rows == [("events", 2), ("proposals", 1), ("proposals", 1)]


def test_every_sent_table_keeps_its_outbox_triggers_after_every_migration(tmp_path: Path) -> None:
    """Migration 5 makes ``requests`` anew (a wider CHECK): its triggers must come back too.

    Dropping a table drops its triggers; without them a central store would never hear of a
    request again (a two-sender test found it).
    """
    from fuelid.store import OUTBOX_TABLES

    db = _new_store(tmp_path)
    con = sqlite3.connect(db, isolation_level=None)
    try:
        names = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='trigger'")}
        con.execute("INSERT INTO meta VALUES ('outbox', 'on')")
        con.execute(
            "INSERT INTO requests(time, wall_time, kind, who, why, origin, status, outcome) "
            "VALUES (1.0, 1.0, 'excite_start', 'op', 'quiet loop', 'cli', 'waiting', '')"
        )
        rows = con.execute("SELECT tbl FROM outbox").fetchall()
    finally:
        con.close()
    for table in OUTBOX_TABLES:
        assert {f"outbox_{table}_insert", f"outbox_{table}_update"} <= names, table
    assert rows == [("requests",)]


def test_a_migration_with_a_data_step_fills_rows_in_its_transaction(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the shape of a migration that fills a new column for the old rows
    db = _new_store(tmp_path)
    with SQLiteStore(db, **SITE) as store:
        store.append_samples([Sample(T0, 0, 2.0, 40.0), Sample(T0 + 0.02, 1, 2.0, 40.0)])

    def fill(con: sqlite3.Connection) -> None:
        con.execute("UPDATE samples SET t_copy = time")

    wall = Migration(
        SCHEMA_VERSION + 1,
        "a copy of the time",
        ("ALTER TABLE samples ADD COLUMN t_copy REAL",),
        data=fill,
    )
    monkeypatch.setattr(store_schema, "MIGRATIONS", (*MIGRATIONS, wall))
    monkeypatch.setattr(store_schema, "SCHEMA_VERSION", SCHEMA_VERSION + 1)
    con = sqlite3.connect(db, isolation_level=None)
    try:
        assert upgrade(con, str(db), to_version=SCHEMA_VERSION + 1) == SCHEMA_VERSION + 1
        assert upgrade(con, str(db), to_version=SCHEMA_VERSION + 1) == SCHEMA_VERSION + 1
        rows = con.execute("SELECT time, t_copy FROM samples ORDER BY time").fetchall()
    finally:
        con.close()
    assert rows == [(T0, T0), (T0 + 0.02, T0 + 0.02)]
    assert _pragma(db, "user_version") == SCHEMA_VERSION + 1


def _lod_by_numpy(samples: list[Sample], level: int) -> dict[float, tuple[object, ...]]:
    """min/max per bucket of ``level`` s by numpy, NaN ignored (None when all NaN)."""
    import numpy as np

    t = np.array([s.time for s in samples])
    buckets = np.floor(t / level) * level
    out: dict[float, tuple[object, ...]] = {}
    for b in np.unique(buckets):
        rows = [s for s, bb in zip(samples, buckets, strict=True) if bb == b]
        values: list[object] = [len(rows)]
        for name in ("u", "y", "setpoint", "fuel_temperature"):
            x = np.array([getattr(s, name) for s in rows], dtype=float)
            x = x[~np.isnan(x)]
            values += [None, None] if x.size == 0 else [float(x.min()), float(x.max())]
        values.append(sum(s.quality != 0 for s in rows))
        out[float(b)] = tuple(values)
    return out


def _stored_lod(db: Path, level: int) -> dict[float, tuple[object, ...]]:
    con = sqlite3.connect(db)
    try:
        rows = con.execute(
            "SELECT bucket, n, u_min, u_max, y_min, y_max, sp_min, sp_max, tf_min, tf_max, bad "
            "FROM samples_lod WHERE level = ? ORDER BY bucket",
            (level,),
        ).fetchall()
    finally:
        con.close()
    return {row[0]: tuple(row[1:]) for row in rows}


def test_a_v2_store_of_a_virtual_time_run_is_mapped_onto_plant_time(tmp_path: Path) -> None:
    # a virtual PLC at 20x: every window's data (t_to) runs ahead of its wall analysis time.
    # Written the v2 way: windows/models/proposals/writes timed by the wall clock.
    db = tmp_path / "v2.db"
    build_at(str(db), 2, SITE)
    wall0 = T0 + 1_000.0
    plant0 = T0 + 50_000.0
    speed = 20.0
    anchors = [(wall0 + 15.0 * k, plant0 + 15.0 * k * speed) for k in range(5)]
    rng = __import__("numpy").random.default_rng(3)
    samples = [
        Sample(
            plant0 + 0.5 * k,
            k,
            float(rng.uniform(1, 3)),
            float("nan") if k % 7 == 0 else float(rng.uniform(30, 50)),
            40.0,
            float(rng.uniform(20, 22)),
            1,
            int(k % 11 == 0),
        )
        for k in range(2_500)
    ]
    con = sqlite3.connect(db)
    con.executemany(
        "INSERT INTO samples VALUES (?, ?, ?, ?, ?, ?, ?, ?)", [row[:8] for row in samples]
    )
    for k, (wall, plant) in enumerate(anchors, start=1):
        con.execute(
            "INSERT INTO models VALUES (?, ?, ?, ?, 21.0, '{}')", (k, wall, plant - 600.0, plant)
        )
        con.execute(
            "INSERT INTO windows VALUES (?, ?, ?, ?, 1, 'ok', 21.0, 2.0, ?, '{}')",
            (k, wall, plant - 600.0, plant, k),
        )
    proposal_wall = [wall0 + 20.0, wall0 + 47.5, wall0 + 70.0]  # the last after every window
    for k, wall in enumerate(proposal_wall, start=1):
        detail = {
            "old": {"Kc": 1.0, "Ti": 2.0},
            "new": {"Kc": 1.1, "Ti": 1.9},
            "detail": {},
            "history": [
                {"time": wall, "status": "pending", "who": "online", "why": ""},
                {"time": wall + 3.0, "status": "approved", "who": "anna", "why": ""},
            ],
        }
        con.execute(
            "INSERT INTO proposals VALUES (?, ?, ?, 1.1, 1.9, 'approved', ?)",
            (k, wall, k, json.dumps(detail)),
        )
    con.execute(
        "INSERT INTO writes VALUES (1, ?, 1, 'proposal', 1.1, 1.9, 1, 'verified', 'anna', '', "
        "'{}', ?)",
        (wall0 + 24.0, wall0 + 24.5),
    )
    con.commit()
    con.close()

    def plant(w: float) -> float:  # the stated band: exactly the interpolation
        walls, plants = zip(*anchors, strict=True)
        if w > walls[-1]:
            return plants[-1] + (w - walls[-1])
        return float(__import__("numpy").interp(w, walls, plants))

    with SQLiteStore(db, **SITE) as store:
        assert store.schema_version == SCHEMA_VERSION
        assert re.fullmatch("[0-9a-f]{32}", str(store.store_uuid))
        assert store.loop_id == "tunnel-2-fuel-loop"
        with OnlineHistory(store) as history:
            windows = history.windows()
            proposals = history.proposals()
            (write,) = history.writes()
            models = history.accepted_models()
    assert [w["time"] for w in windows] == [p for _, p in anchors]
    assert [w["wall_time"] for w in windows] == [w for w, _ in anchors]
    assert [m["time"] for m in models] == [p for _, p in anchors]
    for proposal, wall in zip(proposals, proposal_wall, strict=True):
        assert proposal["time"] == pytest.approx(plant(wall), abs=1e-6)
        assert proposal["wall_time"] == wall
        assert [(h["time"], h["wall_time"]) for h in proposal["history"]] == [
            pytest.approx((plant(wall), wall)),
            pytest.approx((plant(wall + 3.0), wall + 3.0)),
        ]
    # each proposal lies between the windows around it in plant time, after its model's t_to
    assert anchors[1][1] < proposals[0]["time"] < anchors[2][1]
    assert anchors[3][1] < proposals[1]["time"] < anchors[4][1]
    assert proposals[2]["time"] == anchors[-1][1] + 10.0  # real time after the last window
    assert write["time"] == pytest.approx(plant(wall0 + 24.0))
    assert write["finished"] == pytest.approx(plant(wall0 + 24.5))
    assert (write["wall_time"], write["finished_wall"]) == (wall0 + 24.0, wall0 + 24.5)
    assert write["time"] >= proposals[0]["time"]
    for level in (1, 10):
        assert _stored_lod(db, level) == _lod_by_numpy(samples, level)  # exact: min/max


def test_the_lod_at_ingest_counts_a_resent_batch_once(tmp_path: Path) -> None:
    db = tmp_path / "new.db"
    samples = [
        Sample(T0 + 0.3 * k, k, 2.0 + 0.01 * k, 40.0 - 0.02 * k, 40.0, 21.0, 1, int(k % 9 == 0))
        for k in range(200)
    ]
    from fuelid.store import SampleWriter

    with SQLiteStore(db, **SITE) as store:
        assert store.append_samples(samples[:120]) == 120
        assert store.append_samples(samples[100:]) == 80  # 20 re-sent: ignored
        assert store.append_samples(samples[150:170]) == 0  # a whole batch re-sent
        # the recorder's path: the writer thread, a restart re-sending what it had sent
        more = [s._replace(time=s.time + 60.0, seq=s.seq + 200) for s in samples]
        writer = SampleWriter(store)
        writer.put_many(more[:150])
        writer.flush()
        writer.put_many(more[90:])
        writer.close()
        samples = samples + more
    for level in (1, 10):
        assert _stored_lod(db, level) == _lod_by_numpy(samples, level)  # each sample once
    con = sqlite3.connect(db)
    try:
        walls = [row[0] for row in con.execute("SELECT wall_time FROM samples")]
        meta = dict(con.execute("SELECT key, value FROM meta"))
    finally:
        con.close()
    assert all(w is not None and abs(w - __import__("time").time()) < 60 for w in walls)
    assert meta["loop_id"] == "tunnel-2-fuel-loop"
    assert len(meta["store_uuid"]) == 32


def test_a_store_keeps_its_loop_id_and_refuses_another(tmp_path: Path) -> None:
    db = tmp_path / "loop.db"
    with SQLiteStore(db, loop_id="t2-fuel", **SITE) as store:
        assert store.loop_id == "t2-fuel"
    with SQLiteStore(db, **SITE) as store:  # no loop_id given: whatever the store has
        assert store.loop_id == "t2-fuel"
    with pytest.raises(StoreError, match="belongs to loop 't2-fuel', not 'other'"):
        SQLiteStore(db, loop_id="other", **SITE)
    with pytest.raises(StoreError, match="loop_id must match"):
        SQLiteStore(tmp_path / "x.db", loop_id="Bad Id", **SITE)


def test_retention_ages_a_virtual_runs_samples_by_the_wall_clock(tmp_path: Path) -> None:
    import time

    db = tmp_path / "virtual.db"
    now = time.time()
    ahead = float(int(now)) + 20 * 86400.0  # a virtual PLC's plant time 20 days ahead
    samples = [Sample(ahead + 0.5 * k, k, 2.0, 40.0) for k in range(100)]
    with SQLiteStore(db, **SITE) as store:
        store.append_samples(samples)
        kept = store.prune(older_than_days=2.0, thin_to_period_s=None)  # wall clock now
        assert kept.deleted == 0  # written just now: young, whatever their plant time
        con = sqlite3.connect(db)
        con.execute("UPDATE samples SET wall_time = ? WHERE seq < 50", (now - 3 * 86400.0,))
        con.commit()
        con.close()
        gone = store.prune(older_than_days=2.0, thin_to_period_s=None)
        assert gone.deleted == 50
        assert store.read().seq.tolist() == list(range(50, 100))
    lod = _stored_lod(db, 1)
    assert min(lod) == ahead + 25.0  # the LOD rows of the deleted samples went with them
    assert sum(row[0] for row in lod.values()) == 50


def test_a_reflag_recounts_the_bad_samples_of_the_buckets_it_touches(tmp_path: Path) -> None:
    from fuelid.store._base import Requalify

    db = tmp_path / "reflag.db"
    samples = [Sample(T0 + 0.25 * k, k, 2.0, 40.0, 40.0, 21.0, 1, int(k == 3)) for k in range(80)]
    with SQLiteStore(db, **SITE) as store:
        store.append_samples(samples)
        # 3.0 … 7.5 s: 19 samples still OK become bad (k = 3 already was: kept as it was)
        assert store.requalify([Requalify(T0 + 3.0, T0 + 7.5, 3)]) == 19
        flagged = [
            s._replace(quality=3) if T0 + 3.0 <= s.time <= T0 + 7.5 and s.quality == 0 else s
            for s in samples
        ]
    for level in (1, 10):
        assert _stored_lod(db, level) == _lod_by_numpy(flagged, level)
