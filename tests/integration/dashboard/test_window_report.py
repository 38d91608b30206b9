"""The dashboard's HTML report of a window (issue 39, item 1).

(a) No server path: the plant file is named by its base name and SHA-256 prefix. (b) One name
for the gated model: the report tunes from the estimator the service's gate judged the window
with, as the window page says. (c) Ready at once: the newest window's report is made ahead, in
the background, and a request for a report being made waits for it rather than making it twice;
a report made ahead gives way, between its steps, to a request's. (d) Ready after a restart: a
report made is kept beside the store (with its plant's linearisations) and a restarted
dashboard serves it without making it again; a kept file from other inputs or other code is
not served, a corrupt one is made again, a folder others may write in is not read.

The fast tests give the report a loop of their own and stand in for the analysis (what it is
given is what they check); the end-to-end test reads the store a virtual run wrote (the session
fixture ``dashboard_store``).
"""

from __future__ import annotations

import os
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
from fuelid.dashboard import _report_files as report_files
from fuelid.dashboard import _window_report as window_report
from fuelid.dashboard._window_report import (
    PREFETCH_MAX,
    PREFETCH_NEWEST,
    ReportPrefetcher,
    window_report_html,
)
from fuelid.errors import FuelidError
from fuelid.htmlreport import ReportFigure
from fuelid.online import plant_hash
from fuelid.workflow import LogAnalysis


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
    """Each test starts with no report nor linearisation kept in memory."""
    monkeypatch.setattr(window_report, "_cache", OrderedDict())
    monkeypatch.setattr(window_report, "_plant_caches", OrderedDict())
    monkeypatch.setattr(window_report, "_plant_read", {})


def restart(monkeypatch: pytest.MonkeyPatch) -> None:
    """What a dashboard's restart forgets: every report and linearisation in memory."""
    monkeypatch.setattr(window_report, "_cache", OrderedDict())
    monkeypatch.setattr(window_report, "_plant_caches", OrderedDict())
    monkeypatch.setattr(window_report, "_plant_read", {})


class StoreLoop(FakeLoop):
    """A loop of a store file: its reports are kept beside it."""

    def __init__(self, path: Path, settings: dict[str, Any] | None = None) -> None:
        super().__init__(settings or {"rule": "simc"}, [])
        self.path = path


def made_counter(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The windows whose report is made, each a stand-in analysis and one figure."""
    made: list[int] = []

    def analyse(loop: Any, row: dict[str, Any]) -> Any:
        made.append(int(row["id"]))
        analysis = object.__new__(LogAnalysis)  # no numbers: what is kept, not what it says
        return (analysis, [ReportFigure("overview", f"window {row['id']}", b"\x89PNG")])

    monkeypatch.setattr(window_report, "_analyse", analyse)
    return made


def kept_reports(store: Path) -> list[Path]:
    return sorted(report_files.report_folder(store).glob("report-*.pickle"))


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


def test_the_prefetcher_loads_what_the_figures_are_drawn_with_before_its_first_look(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    order: list[str] = []
    real_warm_up = window_report.warm_up

    def warm_up() -> None:
        real_warm_up()  # a small figure drawn as the report's are: nothing raised
        order.append("warmed up")

    def analyse(loop: Any, row: dict[str, Any]) -> str:
        order.append(f"window {row['id']}")
        return "<p>made</p>"

    monkeypatch.setattr(window_report, "warm_up", warm_up)
    monkeypatch.setattr(window_report, "_analyse", analyse)
    prefetcher = ReportPrefetcher(lambda: [FakeLoop({}, [window(1)])]).start()
    try:
        deadline = time.monotonic() + 20.0
        while len(order) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        prefetcher.stop()
    assert order == ["warmed up", "window 1"]


def test_a_report_made_ahead_gives_way_to_a_requests_between_its_steps(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import fuelid.htmlreport
    import fuelid.store
    import fuelid.workflow

    ahead_analysed, go_on, request_started, release = (threading.Event() for _ in range(4))
    drawn: list[str] = []

    def analyse_log(data: Any, plant: Any, settings: Any, cache: Any) -> Any:
        if data == "Window 8":  # made ahead: the request comes while it is under way
            ahead_analysed.set()
            assert go_on.wait(10.0)
        else:
            request_started.set()
            assert release.wait(10.0)
        return data

    def report_figures(analysis: Any) -> dict[str, tuple[str, str]]:
        return {key: (f"{analysis}: {key}", "caption") for key in ("overview", "bode")}

    def figure_png(fig: str) -> bytes:
        drawn.append(fig)
        return b"png"

    monkeypatch.setattr(fuelid.store, "iodata_from_samples", lambda s, p, source: source[:8])
    monkeypatch.setattr(fuelid.workflow, "analyse_log", analyse_log)
    monkeypatch.setattr(fuelid.htmlreport, "report_figures", report_figures)
    monkeypatch.setattr(fuelid.htmlreport, "figure_png", figure_png)
    loop = FakeLoop({}, [window(8)])
    ahead = threading.Thread(target=window_report._analysed, args=(loop, window(8), True))
    ahead.start()
    assert ahead_analysed.wait(10.0)
    asked = threading.Thread(target=window_report._analysed, args=(loop, window(1)))
    asked.start()
    assert request_started.wait(10.0)
    go_on.set()  # the report made ahead may go on: it waits at its next step
    time.sleep(0.3)  # a negative check's window: a figure drawn ahead would be drawn in it
    assert drawn == []
    release.set()
    asked.join(10.0)
    ahead.join(10.0)
    assert drawn == [
        "Window 1: overview",
        "Window 1: bode",
        "Window 8: overview",
        "Window 8: bode",
    ]


def test_a_report_made_is_kept_beside_the_store_and_a_restarted_dashboard_serves_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    made = made_counter(monkeypatch)
    store = tmp_path / "loop.db"
    first = window_report._analysed(StoreLoop(store), window(5))
    assert made == [5]
    assert len(kept_reports(store)) == 1
    folder = report_files.report_folder(store)
    if hasattr(os, "getuid"):
        assert folder.stat().st_mode & 0o777 == 0o700  # pickles: no one else's to write
    restart(monkeypatch)
    second = window_report._analysed(StoreLoop(store), window(5))
    assert made == [5]  # read back, not made again
    assert isinstance(second, tuple)
    assert isinstance(first, tuple)
    assert second[1] == first[1]
    assert isinstance(second[0], LogAnalysis)
    window_report._analysed(StoreLoop(store), window(6))  # another window: its own file
    assert made == [5, 6]
    assert len(kept_reports(store)) == 2


def test_a_kept_report_of_other_settings_or_other_code_is_made_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    made = made_counter(monkeypatch)
    store = tmp_path / "loop.db"
    window_report._analysed(StoreLoop(store), window(5))
    restart(monkeypatch)
    window_report._analysed(StoreLoop(store, {"rule": "lambda"}), window(5))  # the service's
    assert made == [5, 5]
    restart(monkeypatch)
    window_report._analysed(StoreLoop(store), window(5, "pem"))  # the gate's estimator
    assert made == [5, 5, 5]
    restart(monkeypatch)
    monkeypatch.setattr(report_files, "code_version", lambda: "another fuelid")
    window_report._analysed(StoreLoop(store), window(5))
    assert made == [5, 5, 5, 5]
    restart(monkeypatch)
    window_report._analysed(StoreLoop(store), window(5))  # each is kept: the last one served
    assert made == [5, 5, 5, 5]


@pytest.mark.parametrize("damage", ["cut short", "a byte changed", "emptied", "not ours"])
def test_a_kept_file_that_does_not_read_back_is_made_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, damage: str
) -> None:
    made = made_counter(monkeypatch)
    store = tmp_path / "loop.db"
    window_report._analysed(StoreLoop(store), window(5))
    (kept,) = kept_reports(store)
    blob = kept.read_bytes()
    if damage == "cut short":
        kept.write_bytes(blob[: len(blob) // 2])
    elif damage == "a byte changed":
        kept.write_bytes(blob[:-10] + bytes([blob[-10] ^ 0xFF]) + blob[-9:])
    elif damage == "emptied":
        kept.write_bytes(b"")
    else:  # a pickle written by whoever may write in the folder would run as the dashboard
        if not hasattr(os, "getuid"):
            pytest.skip("POSIX permissions")
        report_files.report_folder(store).chmod(0o777)
    restart(monkeypatch)
    page = window_report._analysed(StoreLoop(store), window(5))
    assert made == [5, 5]
    assert isinstance(page, tuple)
    if damage != "not ours":  # made again and kept again, whole
        restart(monkeypatch)
        window_report._analysed(StoreLoop(store), window(5))
        assert made == [5, 5]


def test_where_nothing_can_be_kept_the_report_is_served_all_the_same(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    made = made_counter(monkeypatch)
    store = tmp_path / "loop.db"
    report_files.report_folder(store).write_text("a file where the folder would be")
    page = window_report._analysed(StoreLoop(store), window(5))
    assert isinstance(page, tuple)
    assert made == [5]
    assert report_files.report_folder(store).read_text() == "a file where the folder would be"
    assert window_report._analysed(StoreLoop(store), window(5)) is page  # in memory still


def test_the_kept_files_are_bounded_the_least_recently_used_removed_first(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(report_files, "KEPT_REPORTS", 3)
    folder = tmp_path / "loop.db.reports"
    names = [report_files.file_name("report", [n]) for n in range(5)]
    for age, name in enumerate(names[:3]):
        assert report_files.save(folder, name, age)
        os.utime(folder / name, (1000.0 + age, 1000.0 + age))
    assert report_files.load(folder, names[0]) == 0  # used: now the most recent
    stale = folder / ".report-x.pickle.abc.tmp"  # a write a killed dashboard never finished
    stale.write_bytes(b"half")
    os.utime(stale, (1000.0, 1000.0))
    assert report_files.save(folder, names[3], 3)
    assert sorted(p.name for p in folder.iterdir()) == sorted([names[0], names[2], names[3]])
    assert report_files.save(folder, report_files.file_name("plant", ["p"]), {})  # its own count
    assert len(list(folder.glob("report-*"))) == 3


def test_a_plants_linearisations_are_kept_beside_the_store_for_the_next_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from fuelid.plant import linearise, load_plant_config

    config = load_plant_config(None)
    folder = report_files.report_folder(tmp_path / "loop.db")
    cache = window_report._linearisations("plant-a", folder)
    assert cache == {}
    linear = linearise(config, 5.0, 293.15)
    cache[(293.15, 5.0)] = (linear, linear.equivalent_model().model)
    window_report._keep_linearisations(folder, "plant-a", cache)
    restart(monkeypatch)
    again = window_report._linearisations("plant-a", folder)
    assert list(again) == [(293.15, 5.0)]
    assert again[(293.15, 5.0)][1] == cache[(293.15, 5.0)][1]
    restart(monkeypatch)
    assert window_report._linearisations("plant-b", folder) == {}  # another plant's: its own


def test_a_plants_linearisations_stay_bounded_however_many_windows_add_theirs(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # each window's report linearises the plant at its own fuel temperature and command: a
    # dashboard left open adds a few a window; the cache keeps the newest CACHED_CASES
    from fuelid.plant import load_plant_config
    from fuelid.tuning import plant_cases

    config = load_plant_config(None)
    monkeypatch.setattr(window_report, "CACHED_CASES", 8)
    for window_id in range(20):
        cache = window_report._linearisations("plant-a")
        plant_cases(config, (283.15 + 0.1 * window_id,), (3.0,), cache=cache)
    cache = window_report._linearisations("plant-a")
    assert len(cache) == 8
    assert min(T for T, _ in cache) == pytest.approx(283.15 + 0.1 * 12)  # the newest kept


@pytest.mark.slow  # a whole report of a window of the virtual run: the slow set
def test_the_report_of_a_stored_window_names_no_folder_and_the_gates_model(
    dashboard_store: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
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
        restart(monkeypatch)  # the same page from the analysis kept beside the store

        def analyse(loop: Any, row: dict[str, Any]) -> Any:
            raise AssertionError("made again")

        monkeypatch.setattr(window_report, "_analyse", analyse)
        again = window_report_html(loop, row)
    finally:
        loop.close()
    assert again.replace(generated(again), "") == page.replace(generated(page), "")
    assert full_path is not None
    assert settings["plant_file"] == Path(full_path).name  # the API names no folder either
    folder = str(Path(full_path).parent)
    assert folder not in page
    assert f"{Path(full_path).name} (SHA-256 {settings['plant_hash'][:12]})" in page
    assert "pem (gains)" in page
    assert "oe (gains)" not in page


def generated(page: str) -> str:
    """The line that says when a page was rendered (each page is rendered afresh)."""
    (line,) = [line for line in page.splitlines() if line.startswith('<p class="meta">fuelid')]
    return line
