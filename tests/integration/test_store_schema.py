"""The store's schema and its migrations (issue 24): older stores open and are upgraded.

Pattern for the next migration: build a store at the version before with
:func:`fuelid.store.schema.build_at` (or load a dump written by a released fuelid, as
``tests/data/store_v0_1.sql``), put rows in it, open it with :class:`SQLiteStore` and compare
every row; :func:`test_a_store_of_every_older_version_opens_upgraded` does it for every version.
"""

from __future__ import annotations

import math
import re
import sqlite3
from pathlib import Path

import pytest

from fuelid.cli import main
from fuelid.store import SCHEMA_VERSION, OnlineHistory, Sample, SQLiteStore, StoreError
from fuelid.store import schema as store_schema
from fuelid.store.schema import MIGRATIONS, Migration, build_at, upgrade

DATA = Path(__file__).resolve().parents[1] / "data"
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
        return {
            name: con.execute(f"SELECT * FROM {name} ORDER BY rowid").fetchall() for name in names
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
    for table, rows in before.items():
        if table == "meta":
            continue
        assert after[table] == rows, table  # value for value, in the same order
    meta_before, meta_after = dict(before["meta"]), dict(after["meta"])
    assert meta_after == {**meta_before, "schema_version": str(SCHEMA_VERSION)}
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
        "INSERT INTO samples VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
        [Sample(T0 + 0.02 * k, k, 2.0, 40.0 + k) for k in range(5)],
    )
    con.commit()
    con.close()
    before = _tables(db)
    with SQLiteStore(db, **SITE) as store:
        assert store.info().schema_version == SCHEMA_VERSION
        assert store.read().y.tolist() == [40.0, 41.0, 42.0, 43.0, 44.0]
    assert _tables(db)["samples"] == before["samples"]
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
        ("CREATE TABLE outbox(id INTEGER PRIMARY KEY) STRICT", "SELECT * FROM no_such_table"),
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
    assert "outbox" not in _tables(db)


def test_a_migration_with_a_data_step_fills_rows_in_its_transaction(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the shape of the planned wall-clock migration: a new column, filled for the old rows
    db = _new_store(tmp_path)
    with SQLiteStore(db, **SITE) as store:
        store.append_samples([Sample(T0, 0, 2.0, 40.0), Sample(T0 + 0.02, 1, 2.0, 40.0)])

    def fill(con: sqlite3.Connection) -> None:
        con.execute("UPDATE samples SET wall_time = time")

    wall = Migration(
        SCHEMA_VERSION + 1,
        "wall-clock time beside plant time",
        ("ALTER TABLE samples ADD COLUMN wall_time REAL",),
        data=fill,
    )
    monkeypatch.setattr(store_schema, "MIGRATIONS", (*MIGRATIONS, wall))
    monkeypatch.setattr(store_schema, "SCHEMA_VERSION", SCHEMA_VERSION + 1)
    con = sqlite3.connect(db, isolation_level=None)
    try:
        assert upgrade(con, str(db), to_version=SCHEMA_VERSION + 1) == SCHEMA_VERSION + 1
        assert upgrade(con, str(db), to_version=SCHEMA_VERSION + 1) == SCHEMA_VERSION + 1
        rows = con.execute("SELECT time, wall_time FROM samples ORDER BY time").fetchall()
    finally:
        con.close()
    assert rows == [(T0, T0), (T0 + 0.02, T0 + 0.02)]
    assert _pragma(db, "user_version") == SCHEMA_VERSION + 1
