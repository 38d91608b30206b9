"""Retention after archiving: a row that arrives between the check and the delete is kept.

Retention checks the archived days, then deletes window by window; the check is patched here
(inside the store) so that a row of an archived day arrives in between.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from fuelid.archive import archive_store
from fuelid.store import Sample, SQLiteStore
from support.archive import DATES, T0, days_store

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


def test_a_row_that_arrives_between_the_check_and_the_delete_is_kept(
    store_path: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # retention checks the archived days, then deletes window by window: a row of an archived
    # day written in between (after the day's archiving) is not in the file and must stay
    import fuelid.store._prune as prune_module

    root = tmp_path / "archive"
    with _writable(store_path) as store:
        archive_store(store, root, before=DATES[1])
        checked = prune_module.prunable_spans

        def check_then_a_late_row(*args: object, **kwargs: object) -> object:
            spans = checked(*args, **kwargs)  # type: ignore[arg-type]
            late = Sample(T0 + 5.0, 20_000_000, 2.0, 41.0, 40.0, 20.0, 1, 0)
            assert store.append_samples([late]) == 1
            return spans

        monkeypatch.setattr(prune_module, "prunable_spans", check_then_a_late_row)
        store.prune(0.0, None, now=NOW, archived_only=True)
        left = store.read(T0, T0 + 86400.0)
    assert left.seq.tolist() == [20_000_000]  # the archived rows deleted, the late one kept
