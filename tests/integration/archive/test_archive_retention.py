"""Archiving again, after thinning, after a failed write; retention with and without an archive.

Stores from :func:`support.archive.days_store`: whole UTC days at one sample per 10 s, so each
day holds exactly 8,640 samples; thinning to one per 60 s leaves exactly 1,440 of a day.
"""

from __future__ import annotations

import os
import shutil
import sqlite3
from pathlib import Path

import pyarrow.compute as pc
import pytest

from fuelid.archive import _layout as layout
from fuelid.archive import archive_store, keep_store, list_loop_days, read_day_table
from fuelid.store import Sample, SQLiteStore, StoreError
from support.archive import DATES, T0, archived_rows, days_store, rows_per_day

PER_DAY = 8640  # 86400 s / 10 s
THINNED = 1440  # one per 60 s
NOW = T0 + 10 * 86400.0  # every sample is older than a retention of 0 days


@pytest.fixture(scope="module")
def template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Four days (2026-01-01 … 04) written once; tests copy it."""
    return days_store(tmp_path_factory.mktemp("days") / "loop.db")


@pytest.fixture
def store_path(template: Path, tmp_path: Path) -> Path:
    target = tmp_path / "loop.db"
    shutil.copyfile(template, target)
    return target


def _writable(path: Path) -> SQLiteStore:
    return SQLiteStore(path, site_name="site line-x", tag_map_hash="ab12", loop_id="line-x")


def _files(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())


def test_default_archives_only_finished_days_and_again_changes_nothing(
    store_path: Path, tmp_path: Path
) -> None:
    root = tmp_path / "archive"
    with SQLiteStore(store_path) as store:
        first = archive_store(store, root)
        # the newest sample's day (2026-01-04) is still being recorded: not archived
        assert first.before == DATES[3]
        assert [d.date for d in first.days] == list(DATES[:3])
        assert [d.rows for d in first.days] == [PER_DAY] * 3
        assert all(d.written and d.bytes_written > 0 for d in first.days)
        files = {f: (root / f).read_bytes() for f in _files(root)}
        again = archive_store(store, root)
    assert [d.written for d in again.days] == [False] * 3
    assert again.bytes_written == 0
    assert {f: (root / f).read_bytes() for f in _files(root)} == files  # nothing rewritten
    assert archived_rows(store_path) == dict.fromkeys(DATES[:3], PER_DAY)
    assert [d.date for d in list_loop_days(root)] == list(DATES[:3])


def test_a_re_archive_after_thinning_keeps_the_raw_rows(store_path: Path, tmp_path: Path) -> None:
    root = tmp_path / "archive"
    with _writable(store_path) as store:
        archive_store(store, root, before=DATES[2])
        raw = read_day_table(root, "samples", "line-x", DATES[0])
        store.prune(0.0, 60.0, now=NOW, archived_only=True)
        assert rows_per_day(store_path)[DATES[0]] == THINNED
        # a late sample of day 1 (a new sequence number) arrives after the thinning
        late = Sample(T0 + 3.0, 10_000_000, 2.0, 41.0, 40.0, 20.0, 1, 0)
        assert store.append_samples([late]) == 1
        report = archive_store(store, root, before=DATES[2])
    day1 = read_day_table(root, "samples", "line-x", DATES[0])
    # the union: every raw row of the first archive and the late one; nothing thinned away
    assert day1.num_rows == PER_DAY + 1
    assert day1.filter(pc.not_equal(day1.column("seq"), 10_000_000)).equals(raw)
    assert day1.filter(pc.equal(day1.column("seq"), 10_000_000)).num_rows == 1
    assert [d.rows for d in report.days] == [PER_DAY + 1, PER_DAY]
    assert [d.store_rows for d in report.days] == [THINNED + 1, THINNED]
    assert archived_rows(store_path) == {DATES[0]: PER_DAY + 1, DATES[1]: PER_DAY}


def test_a_write_that_fails_midway_leaves_no_file_and_no_record(
    store_path: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    root = tmp_path / "archive"
    renames: list[str] = []
    real_replace = os.replace

    def replace(src: object, dst: object) -> None:
        renames.append(str(dst))
        # the temporary file of day 2's samples is written, fsynced and read back: the
        # rename fails (a full or vanished disk)
        if "date=2026-01-02" in str(dst) and "samples" in str(dst):
            assert Path(str(src)).exists()
            raise OSError(28, "No space left on device")
        real_replace(src, dst)  # type: ignore[arg-type]

    monkeypatch.setattr(layout.os, "replace", replace)
    with SQLiteStore(store_path) as store, pytest.raises(StoreError, match="No space left"):
        archive_store(store, root, before=DATES[3])
    monkeypatch.undo()
    # day 1 is complete and recorded; day 2 has no file (not even the temporary one), no row
    assert archived_rows(store_path) == {DATES[0]: PER_DAY}
    day2 = root / "samples" / "loop=line-x" / "date=2026-01-02"
    assert (list(day2.iterdir()) if day2.exists() else []) == []
    assert "samples/loop=line-x/date=2026-01-02" in renames[-1]  # where it failed
    assert [d.date for d in list_loop_days(root)] == [DATES[0]]
    # the next run completes the rest
    with SQLiteStore(store_path) as store:
        archive_store(store, root, before=DATES[3])
    assert archived_rows(store_path) == dict.fromkeys(DATES[:3], PER_DAY)


def test_retention_with_an_archive_thins_only_archived_days(
    store_path: Path, tmp_path: Path
) -> None:
    with _writable(store_path) as store:
        kept = keep_store(store, 0.0, 60.0, now=NOW, archive_dir=str(tmp_path / "a"), auto=True)
        # archived: the three finished days; the fourth (the newest) is kept whole
        assert kept.archive is not None
        assert kept.archive_error is None
        result = kept.prune
    assert rows_per_day(store_path) == {
        DATES[0]: THINNED, DATES[1]: THINNED, DATES[2]: THINNED, DATES[3]: PER_DAY,
    }  # fmt: skip
    assert result.deleted == 3 * (PER_DAY - THINNED)
    assert (result.kept_thinned, result.kept_unarchived) == (3 * THINNED, PER_DAY)
    detail = _last_prune_detail(store_path)
    assert f"{PER_DAY} of them not archived" in detail


def test_retention_deletes_only_archived_days_and_keeps_a_day_with_late_rows(
    store_path: Path,
) -> None:
    root = store_path.parent / "archive"
    with _writable(store_path) as store:
        archive_store(store, root, before=DATES[2])  # days 1 and 2
        store.append_samples([Sample(T0 + 86400.0 + 7.0, 20_000_000, 2.0, 40.0, 40.0, 20.0, 1, 0)])
        result = store.prune(0.0, None, now=NOW, archived_only=True)
    # day 1 deleted; day 2 got a row after it was archived: kept whole, as days 3 and 4
    assert rows_per_day(store_path) == {
        DATES[1]: PER_DAY + 1, DATES[2]: PER_DAY, DATES[3]: PER_DAY,
    }  # fmt: skip
    assert (result.deleted, result.kept_unarchived) == (PER_DAY, 3 * PER_DAY + 1)
    con = sqlite3.connect(store_path)
    try:  # the level-of-detail rows of the kept days stay, the deleted day's go
        lod = dict(
            con.execute(
                "SELECT date(CAST(bucket AS INTEGER), 'unixepoch') AS d, sum(n) FROM samples_lod "
                "WHERE level = 10 GROUP BY d"
            ).fetchall()
        )
    finally:
        con.close()
    assert lod == {DATES[1]: PER_DAY + 1, DATES[2]: PER_DAY, DATES[3]: PER_DAY}


def test_retention_without_an_archive_is_as_before(store_path: Path) -> None:
    with _writable(store_path) as store:
        kept = keep_store(store, 0.0, 60.0, now=NOW)
    assert kept.archive is None
    assert rows_per_day(store_path) == dict.fromkeys(DATES[:4], THINNED)
    assert (kept.prune.deleted, kept.prune.kept_unarchived) == (4 * (PER_DAY - THINNED), 0)
    assert "not archived" not in _last_prune_detail(store_path)


def test_an_archive_that_cannot_be_written_keeps_everything(
    store_path: Path, tmp_path: Path
) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with _writable(store_path) as store:
        kept = keep_store(store, 0.0, 60.0, now=NOW, archive_dir=str(blocker / "archive"))
    assert kept.archive is None
    assert kept.archive_error is not None
    assert "cannot write to the archive folder" in kept.archive_error
    assert rows_per_day(store_path) == dict.fromkeys(DATES[:4], PER_DAY)
    assert kept.prune.kept_unarchived == 4 * PER_DAY


def _last_prune_detail(path: Path) -> str:
    con = sqlite3.connect(path)
    try:
        row = con.execute(
            "SELECT detail FROM events WHERE kind = 'prune' ORDER BY id DESC LIMIT 1"
        ).fetchone()
    finally:
        con.close()
    return str(row[0])


def _service_record(path: Path, settings: dict[str, object]) -> None:
    """An ``online_state`` service record as a service writes it (only what the archive reads)."""
    import json

    con = sqlite3.connect(path)
    con.execute(
        "INSERT INTO online_state(key, value, time) VALUES ('service', ?, 0.0)",
        (json.dumps({"pid": 1, "settings": settings}),),
    )
    con.commit()
    con.close()


def test_the_plant_file_is_copied_when_it_has_the_recorded_hash(
    store_path: Path, tmp_path: Path
) -> None:
    import hashlib

    from fuelid.archive import read_loop_info

    plant = tmp_path / "plant.toml"
    plant.write_text('[vfd]\nname = "test"\n', encoding="utf-8")
    digest = hashlib.sha256(plant.read_bytes()).hexdigest()
    settings = {"plant_file": str(plant), "plant_hash": digest, "window_s": 600.0}
    _service_record(store_path, settings)
    root = tmp_path / "archive"
    with SQLiteStore(store_path) as store:
        report = archive_store(store, root)
    info = read_loop_info(root, "line-x")
    assert report.plant == info["plant"] == f"plant-{digest}.toml"
    assert info["plant_note"] is None
    assert info["settings"] == settings
    assert (root / "loops" / "line-x" / f"plant-{digest}.toml").read_bytes() == plant.read_bytes()
    # edited since: the copy made while it matched stays the loop's plant file
    plant.write_text('[vfd]\nname = "edited"\n', encoding="utf-8")
    with SQLiteStore(store_path) as store:
        assert archive_store(store, root).plant == f"plant-{digest}.toml"


def test_a_plant_file_changed_before_the_first_archive_is_not_copied(
    store_path: Path, tmp_path: Path
) -> None:
    plant = tmp_path / "plant.toml"
    plant.write_text('[vfd]\nname = "edited"\n', encoding="utf-8")
    _service_record(store_path, {"plant_file": str(plant), "plant_hash": "0" * 64})
    with SQLiteStore(store_path) as store:
        report = archive_store(store, tmp_path / "archive")
    assert report.plant is None
    assert report.plant_note is not None
    assert "changed since the service started" in report.plant_note
    assert not list((tmp_path / "archive" / "loops" / "line-x").glob("plant-*"))
