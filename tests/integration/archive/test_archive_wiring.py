"""``fuelid record`` with an ``[archive]`` table: the finished days archived, then retention.

As the recorder's retention test (tests/integration/plc/test_recorder.py): 500 samples at 50 Hz
recorded three days ago (10 s), past a retention of one day; then a replayed log. With the
archive (``auto``) the old day is archived whole (500 rows) and then thinned to one per
second (10 left); with ``auto = false`` and no archive job it is kept whole.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from fuelid.archive import list_loop_days, read_day_table
from fuelid.cli import main
from fuelid.plc import record_site, site_identity
from fuelid.store import Sample, SQLiteStore
from support.archive import archived_rows
from support.recorder import REPLAY, kinds, load, rows, write_log
from support.waiting import await_until


def _old_samples(db: Path, site_text: str) -> float:
    old = float(int(time.time())) - 3 * 86400.0  # whole seconds: ten 1 s bins
    with SQLiteStore(db, period_s=0.02, **site_identity(load(site_text))) as store:
        store.append([Sample(old + 0.001 + 0.02 * k, None, 2.0, 50.0) for k in range(500)])
    return old


def test_record_archives_the_finished_days_before_thinning_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log, db = tmp_path / "log.csv", tmp_path / "s.db"
    write_log(log, 100)
    text = REPLAY.format(path=log, speed=10.0, period=0.02) + (
        f'[store]\nurl = "sqlite:///{db}"\nretention_days = 1\nthin_to_s = 1.0\n'
        '[archive]\ndir = "archive"\n'  # relative: taken from the site file's folder
    )
    site_file = tmp_path / "site.toml"
    site_file.write_text(text, encoding="utf-8")
    old = _old_samples(db, text)
    assert main(["record", "--config", str(site_file), "--duration", "20"]) == 0
    capsys.readouterr()
    data, events, _ = rows(db)
    older = data.time < old + 60.0
    assert np.count_nonzero(older) == 10  # thinned to one per second, after archiving
    assert np.count_nonzero(~older) > 0
    root = tmp_path / "archive"
    (day,) = list_loop_days(root)
    assert read_day_table(root, "samples", day.loop_id, day.date).num_rows == 500  # raw
    assert archived_rows(db) == {day.date: 500}
    assert kinds(events, "prune")


def test_without_an_archive_job_retention_keeps_what_is_not_archived(tmp_path: Path) -> None:
    log, db = tmp_path / "log.csv", tmp_path / "s.db"
    write_log(log, 100)
    text = REPLAY.format(path=log, speed=10.0, period=0.02) + (
        f'[store]\nurl = "sqlite:///{db}"\nretention_days = 1\nthin_to_s = 1.0\n'
        f'[archive]\ndir = "{tmp_path / "archive"}"\nauto = false\n'
    )
    old = _old_samples(db, text)
    record_site(load(text), duration_s=20.0)
    data, events, _ = rows(db)
    assert np.count_nonzero(data.time < old + 60.0) == 500  # not archived: kept whole
    assert "500 of them not archived" in kinds(events, "prune")[-1].detail
    assert not (tmp_path / "archive").exists()


def test_the_services_housekeeping_archives_then_prunes_archived_days_only(
    tmp_path: Path,
) -> None:
    """The service's hourly task, run once on a store of four whole days (as a replay site).

    Expected: the three finished days archived (8,640 rows each) and thinned to one per 60 s
    (1,440); the fourth, the newest sample's day, kept whole; no archive failure logged.
    """
    import asyncio
    from types import SimpleNamespace

    from fuelid.online import OnlineService
    from support.archive import DATES, days_store, rows_per_day

    db = days_store(tmp_path / "loop.db")
    said: list[dict[str, object]] = []
    site = SimpleNamespace(
        archive=SimpleNamespace(dir=str(tmp_path / "archive"), auto=True),
        plc=SimpleNamespace(protocol="replay"),  # retention counts back from the newest sample
        store=SimpleNamespace(retention_days=0.5, thin_to_s=60.0),
    )

    async def once() -> None:
        service = SimpleNamespace(
            site=site,
            store=SQLiteStore(db, site_name="site line-x", tag_map_hash="ab12", loop_id="line-x"),
            _stopping=asyncio.Event(),
            context=SimpleNamespace(say=lambda event, **kw: said.append({"event": event, **kw})),
        )
        task = asyncio.create_task(OnlineService._housekeeping(service))  # type: ignore[arg-type]
        try:
            await await_until(
                lambda: service.store.last_event(["prune"]) is not None,
                60.0,
                "the housekeeping's first round to prune",
                every=0.1,
            )
        finally:
            service._stopping.set()
            await task
            service.store.close()

    asyncio.run(once())
    assert said == []
    assert archived_rows(db) == dict.fromkeys(DATES[:3], 8640)
    counts = rows_per_day(db)
    assert [counts[d] for d in DATES[:3]] == [1440] * 3
    assert counts[DATES[3]] == 8640
