"""The dashboard's HTML report of a window (issue 39, item 1).

(a) No server path: the plant file is named by its base name and SHA-256 prefix. (b) One name
for the gated model: the report tunes from the estimator the service's gate judged the window
with, as the window page says. (c) Ready at once: the newest window's report is made ahead, in
the background, and a request for a report being made waits for it rather than making it twice.

The fast tests give the report a loop of their own and stand in for the analysis (what it is
given is what they check); the end-to-end test reads the store a virtual run wrote (the session
fixture ``dashboard_store``).
"""

from __future__ import annotations

import shutil
import sqlite3
import threading
import time
from collections import OrderedDict
from importlib import resources
from pathlib import Path
from typing import Any

import pytest

from fuelid.dashboard import Loops
from fuelid.dashboard import _window_report as window_report
from fuelid.dashboard._window_report import (
    PREFETCH_MAX,
    PREFETCH_NEWEST,
    ReportPrefetcher,
    window_report_html,
)
from fuelid.errors import FuelidError
from fuelid.online import plant_hash


class FakeLoop:
    """A loop with the service's settings and windows, and no samples worth analysing."""

    def __init__(self, settings: dict[str, Any], windows: list[dict[str, Any]]) -> None:
        self.loop_id = "tunnel-2"
        self.settings = settings
        self.windows = windows
        self.closed = False

    def identity(self) -> dict[str, Any]:
        return {"loop_id": self.loop_id, "store_uuid": "uuid-1", "period_s": 0.02}

    def status(self) -> dict[str, Any]:
        return {"service": {"settings": self.settings}}

    def plant_file(self) -> str | None:
        return self.settings.get("plant_file")

    def samples(self, t_from: float, t_to: float) -> Any:
        return None

    def recent_windows(self, limit: int) -> list[dict[str, Any]]:
        return self.windows[-limit:]

    def history(self) -> dict[str, Any]:
        return {"proposals": [], "windows": []}

    def close(self) -> None:
        self.closed = True


def window(window_id: int, method: str = "oe") -> dict[str, Any]:
    return {"id": window_id, "t_from": 0.0, "t_to": 60.0, "model_id": None,
            "detail": {"method": method}}  # fmt: skip


@pytest.fixture(autouse=True)
def empty_cache(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test starts with no report kept."""
    monkeypatch.setattr(window_report, "_cache", OrderedDict())


def plant_file(folder: Path) -> Path:
    """A copy of the reference plant in a folder of the server's."""
    path = folder / "plants" / "tunnel2.toml"
    path.parent.mkdir()
    shutil.copy(str(resources.files("fuelid.data").joinpath("reference_plant.toml")), path)
    return path


def test_the_report_tunes_from_the_gates_estimator_and_names_the_plant_file_without_its_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import fuelid.store
    import fuelid.workflow

    path = plant_file(tmp_path)
    digest = plant_hash(path)
    assert digest is not None
    settings = {"plant_file": str(path), "plant_hash": digest, "sampling": {"control_period_s": 1}}
    given: dict[str, Any] = {}

    def analyse_log(data: Any, plant: Any, analysis_settings: Any, cache: Any) -> Any:
        given.update(plant=plant, settings=analysis_settings, cache=cache)
        raise FuelidError("stopped here")

    monkeypatch.setattr(fuelid.workflow, "analyse_log", analyse_log)
    monkeypatch.setattr(fuelid.store, "iodata_from_samples", lambda *a, **k: None)
    page = window_report_html(FakeLoop(settings, []), window(3, "pem"))
    assert "stopped here" in page
    assert given["settings"].tune_from == "pem"  # the window page's name, not "oe"
    assert given["plant"].path == f"tunnel2.toml (SHA-256 {digest[:12]})"
    assert not given["plant"].is_reference  # the file was found and loaded by its full path
    assert str(tmp_path) not in page
    window_report_html(FakeLoop(settings, []), window(4))  # another window, the same plant
    assert given["cache"] is not None
    assert given["cache"] is window_report._linearisations(digest)  # its linearisations shared


def test_the_newest_windows_reports_are_made_ahead_once_and_served_from_memory(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    made: list[int] = []

    def analyse(loop: Any, row: dict[str, Any]) -> str:
        made.append(int(row["id"]))
        return f"<p>report of window {row['id']}</p>"

    monkeypatch.setattr(window_report, "_analyse", analyse)
    loop = FakeLoop({}, [window(i) for i in range(1, 6)])
    prefetcher = ReportPrefetcher(lambda: [loop])
    assert prefetcher.run_once() == PREFETCH_NEWEST
    assert made == [5, 4, 3]  # the newest first
    assert prefetcher.run_once() == 0  # made once
    assert window_report_html(loop, window(5)) == "<p>report of window 5</p>"
    assert made == [5, 4, 3]  # the first request: from memory
    loop.windows.append(window(6))  # the service judged another window
    assert prefetcher.run_once() == 1
    assert made == [5, 4, 3, 6]
    assert window_report_html(loop, window(1)) == "<p>report of window 1</p>"  # on request
    assert made == [5, 4, 3, 6, 1]


def test_the_newest_window_of_every_loop_is_made_before_the_older_ones() -> None:
    loops = [FakeLoop({}, [window(i) for i in range(1, 5)]) for _ in range(PREFETCH_MAX)]
    for number, loop in enumerate(loops):
        loop.loop_id = f"loop-{number}"
    wanted = ReportPrefetcher(lambda: loops).wanted()
    assert len(wanted) == PREFETCH_MAX  # the cache keeps them all
    assert [key[2] for key, _, _ in wanted] == [4] * PREFETCH_MAX
    assert [key[0] for key, _, _ in wanted] == [loop.loop_id for loop in loops]


def test_a_request_for_a_report_being_made_waits_for_it(monkeypatch: pytest.MonkeyPatch) -> None:
    started, release = threading.Event(), threading.Event()
    made: list[int] = []

    def analyse(loop: Any, row: dict[str, Any]) -> str:
        made.append(int(row["id"]))
        started.set()
        assert release.wait(10.0)
        return "<p>made</p>"

    monkeypatch.setattr(window_report, "_analyse", analyse)
    loop = FakeLoop({}, [window(5)])
    pages: list[str] = []
    first = threading.Thread(target=lambda: pages.append(window_report_html(loop, window(5))))
    first.start()
    assert started.wait(10.0)
    second = threading.Thread(target=lambda: pages.append(window_report_html(loop, window(5))))
    second.start()
    time.sleep(0.1)  # a negative check's window: a second analysis would start in it
    assert second.is_alive()  # waiting for the first, not making it again
    assert made == [5]
    release.set()
    first.join(10.0)
    second.join(10.0)
    assert pages == ["<p>made</p>", "<p>made</p>"]
    assert made == [5]


def test_a_requests_analysis_goes_before_the_ones_made_ahead(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    started, release = threading.Event(), threading.Event()
    made: list[int] = []

    def analyse(loop: Any, row: dict[str, Any]) -> str:
        made.append(int(row["id"]))
        if row["id"] == 1:  # the window asked for: a while
            started.set()
            assert release.wait(10.0)
        return "<p>made</p>"

    monkeypatch.setattr(window_report, "_analyse", analyse)
    loop = FakeLoop({}, [window(1), window(7), window(8)])
    asked = threading.Thread(target=window_report_html, args=(loop, window(1)))
    asked.start()
    assert started.wait(10.0)
    prefetcher = ReportPrefetcher(lambda: [loop])
    ahead = threading.Thread(target=prefetcher.run_once)
    ahead.start()
    time.sleep(0.5)  # a negative check's window: an analysis made ahead would start in it
    assert made == [1]  # nothing started ahead while the request's analysis runs
    release.set()
    asked.join(10.0)
    ahead.join(10.0)
    assert made == [1, 8, 7]


def test_the_server_s_loops_make_the_reports_ahead_in_the_background(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    made = threading.Event()

    def analyse(loop: Any, row: dict[str, Any]) -> str:
        made.set()
        return "<p>made</p>"

    monkeypatch.setattr(window_report, "_analyse", analyse)
    store = tmp_path / "a.db"
    store.touch()
    fake = FakeLoop({}, [window(1)])
    quiet = Loops([store], opener=lambda path: fake)  # tests and tools: nothing in background
    assert quiet._prefetch is None
    quiet.close()
    loops = Loops([store], opener=lambda path: fake, prefetch_reports=True)
    try:
        assert made.wait(10.0)
    finally:
        loops.close()
    assert fake.closed


@pytest.mark.slow  # two whole reports of a window of the virtual run: the slow set
def test_the_report_of_a_stored_window_names_no_folder_and_the_gates_model(
    dashboard_store: Path, tmp_path: Path
) -> None:
    from fuelid.dashboard import SQLiteLoop

    target = tmp_path / "loop.db"
    shutil.copy(dashboard_store, target)
    con = sqlite3.connect(target)  # one window judged by pem, as an AUTO window often is
    (window_id,) = con.execute("SELECT max(id) FROM windows WHERE model_id IS NOT NULL").fetchone()
    con.execute(
        "UPDATE windows SET detail = json_set(detail, '$.method', 'pem') WHERE id = ?",
        (window_id,),
    )
    con.commit()
    con.close()
    loop = SQLiteLoop(target)
    try:
        settings = loop.status()["service"]["settings"]
        full_path = loop.plant_file()
        row = loop.window(window_id)
        assert row is not None
        page = window_report_html(loop, row)
    finally:
        loop.close()
    assert full_path is not None
    assert settings["plant_file"] == Path(full_path).name  # the API names no folder either
    folder = str(Path(full_path).parent)
    assert folder not in page
    assert f"{Path(full_path).name} (SHA-256 {settings['plant_hash'][:12]})" in page
    assert "pem (gains)" in page
    assert "oe (gains)" not in page
