"""The dashboard's API and pages with FastAPI's test client, over a store a virtual run wrote.

The store (the session fixture ``dashboard_store``) holds 6 minutes of plant time of the virtual
PLC with windows, a proposal left pending and events. The API must give the same objects as
``fuelid online status --json`` and ``history --json`` (one shape), the trend must be the store's
samples (raw) or the min/max of its buckets (level of detail), every action must need an
engineer's login with the CSRF token, and every stored string must reach the page escaped.
"""

from __future__ import annotations

import json
import shutil
import sqlite3
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("fastapi")

from fastapi.testclient import TestClient

from fuelid.cli import main as cli_main
from fuelid.dashboard import CSRF_HEADER, Loops, Security, SQLiteLoop, UsersFile, create_app
from fuelid.errors import ConfigError
from fuelid.store import SCHEMA_VERSION, Event, SQLiteStore, StoreError

# xdist: one worker runs the dashboard's modules, which share one store made once
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("dashboard")

PROVENANCE = {"fuelid_version", "input_sha256", "options"}
"""Keys the CLI adds to its JSON (what it ran with), not part of the store's object."""


def _copy(store: Path, folder: Path, name: str = "loop.db") -> Path:
    target = folder / name
    shutil.copy(store, target)
    return target


def _client(paths: list[Path], security: Security | None = None) -> tuple[TestClient, Loops]:
    loops = Loops(paths)
    app = create_app(loops, security or Security(None, require_login=False))
    return TestClient(app), loops


def _cli_json(capsys: pytest.CaptureFixture[str], *args: str) -> dict[str, Any]:
    capsys.readouterr()
    assert cli_main(list(args)) == 0
    return dict(json.loads(capsys.readouterr().out))


@pytest.fixture
def loop_db(dashboard_store: Path, tmp_path: Path) -> Path:
    return _copy(dashboard_store, tmp_path)


def test_status_and_history_are_the_objects_the_cli_prints(
    loop_db: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    client, loops = _client([loop_db])
    try:
        (loop_id,) = loops.ids()
        api_status = client.get(f"/api/loops/{loop_id}/status").json()
        api_history = client.get(f"/api/loops/{loop_id}/history").json()
    finally:
        loops.close()
    cli_status = _cli_json(capsys, "online", "status", "--store", str(loop_db), "--json")
    cli_history = _cli_json(capsys, "online", "history", "--store", str(loop_db), "--json")
    assert set(api_status) == set(cli_status) - PROVENANCE
    assert set(api_history) == set(cli_history) - PROVENANCE
    for key in ("current_model", "pending_proposals", "counts", "k_trend", "last_window"):
        assert api_status[key] == cli_status[key], key
    for key in ("windows", "proposals", "writes", "events", "counts"):
        assert api_history[key] == cli_history[key], key
    # the store's path is never shown (loops are known by id)
    assert api_status["site"]["store"] is None
    assert api_status["site"]["loop_id"] == loop_id
    assert api_history["counts"]["windows"] >= 3
    assert any(p["status"] == "pending" for p in api_history["proposals"])


def test_the_raw_trend_is_the_stored_samples_thinned(loop_db: Path) -> None:
    client, loops = _client([loop_db])
    try:
        (loop_id,) = loops.ids()
        answer = client.get(f"/api/loops/{loop_id}/trend?width=300").json()
    finally:
        loops.close()
    with sqlite3.connect(loop_db) as con:
        rows = con.execute("SELECT time, y, u FROM samples ORDER BY time").fetchall()
    t = np.array([r[0] for r in rows])
    y = {r[0]: r[1] for r in rows}
    u = {r[0]: r[2] for r in rows}
    assert answer["source"] == "raw"
    # the newest 10 minutes (here the whole run of 6 min): every stored sample was a candidate
    assert answer["points"] == np.count_nonzero(t >= t[-1] - 600.0)
    flow = answer["series"]["y"]
    assert 0 < len(flow["t"]) <= 2 * 300
    assert all(y[ti] == vi for ti, vi in zip(flow["t"], flow["v"], strict=True))
    command = answer["series"]["u"]
    assert all(u[ti] == vi for ti, vi in zip(command["t"], command["v"], strict=True))


def test_the_level_of_detail_trend_is_the_min_and_max_of_each_bucket(loop_db: Path) -> None:
    loop = SQLiteLoop(loop_db)
    try:
        span = loop.span()
        assert span is not None
        first, last = span
        rows = loop.lod(1, first, last + 1.0)
        samples = loop.samples(first, last + 1.0)
    finally:
        loop.close()
    buckets = np.floor(samples.time)
    expected = {}
    for b in np.unique(buckets):
        sel = buckets == b
        expected[b] = (np.nanmin(samples.y[sel]), np.nanmax(samples.y[sel]), int(sel.sum()))
    assert rows["bucket"].tolist() == sorted(expected)
    for b, lo, hi, n in zip(rows["bucket"], rows["y_min"], rows["y_max"], rows["n"], strict=True):
        assert (lo, hi, int(n)) == expected[b]


def test_a_window_shows_its_gates_against_their_thresholds_and_its_simulation(
    loop_db: Path,
) -> None:
    client, loops = _client([loop_db])
    try:
        (loop_id,) = loops.ids()
        history = client.get(f"/api/loops/{loop_id}/history").json()
        accepted = next(w for w in history["windows"] if w["accepted"])
        data = client.get(f"/api/loops/{loop_id}/windows/{accepted['id']}").json()
        page = client.get(f"/loops/{loop_id}/windows/{accepted['id']}")
        missing = client.get(f"/api/loops/{loop_id}/windows/999999")
    finally:
        loops.close()
    assert page.status_code == 200
    assert f"Window {accepted['id']}" in page.text
    assert missing.status_code == 404
    gates = {g["gate"]: g for g in data["evidence"]["gates"]}
    assert gates["fit_percent"]["measured"] == pytest.approx(accepted["fit_percent"])
    assert all(g["passed"] is not False for g in gates.values() if g["gate"] != "plant_ratio")
    # the stored model simulated from rest: the same model on the same samples, so its fit is
    # the window's own but for the first settling time of each segment (T ≈ 1.2 s, delay
    # 0.2 s: a few seconds of a 120 s window); 5 points of fit cover that start
    assert data["evidence"]["fit_percent"] == pytest.approx(accepted["fit_percent"], abs=5.0)
    assert data["evidence"]["thinned"] is False


def test_pages_load_and_an_unknown_loop_is_404(loop_db: Path) -> None:
    client, loops = _client([loop_db])
    try:
        (loop_id,) = loops.ids()
        plotly_js = "/static/vendor/plotly/plotly-basic.min.js"
        for url in ("/", f"/loops/{loop_id}", "/api/loops", "/api/docs", plotly_js):
            assert client.get(url).status_code == 200, url
        loop_page = client.get(f"/loops/{loop_id}").text
        assert client.get("/loops/no-such-loop").status_code == 404
        assert client.get("/api/loops/no-such-loop/status").status_code == 404
        fleet = client.get("/api/loops").json()
    finally:
        loops.close()
    (row,) = fleet["loops"]
    assert row["loop_id"] == loop_id
    # the pending proposal's evidence link names the loop (Jinja's own `loop` once hid it)
    assert f'href="/loops/{loop_id}/windows/' in loop_page
    assert 'href="/loops//' not in loop_page
    assert {c["name"] for c in row["chips"]} >= {"service", "proposals", "drift"}


HOSTILE = "<script>alert('x')</script>"
HOSTILE_EVENT = '<img src=x onerror="alert(1)">'


def test_stored_strings_reach_the_pages_escaped(tmp_path: Path) -> None:
    db = tmp_path / "hostile.db"
    with SQLiteStore(db, site_name=f"tunnel {HOSTILE}", tag_map_hash="ab") as store:
        store.append([], [Event(1.7e9, "gain_change", HOSTILE_EVENT)])
    client, loops = _client([db])
    try:
        (loop_id,) = loops.ids()
        assert "<" not in loop_id
        assert ">" not in loop_id
        for url in ("/", f"/loops/{loop_id}"):
            text = client.get(url).text
            assert HOSTILE not in text, url
            assert "&lt;script&gt;" in text, url
        history = client.get(f"/api/loops/{loop_id}/history").json()
    finally:
        loops.close()
    # JSON carries the text as it is (a script must put it into the page as text, not HTML)
    assert history["events"][0]["detail"] == HOSTILE_EVENT


def test_actions_need_an_engineers_login_and_the_csrf_token(loop_db: Path, tmp_path: Path) -> None:
    users = UsersFile(tmp_path / "users.json")
    engineer = users.add("eve", "engineer")
    viewer = users.add("vic", "viewer")
    client, loops = _client([loop_db], Security(users, require_login=False))
    try:
        (loop_id,) = loops.ids()
        history = client.get(f"/api/loops/{loop_id}/history").json()
        pending = next(p for p in history["proposals"] if p["status"] == "pending")
        url = f"/api/loops/{loop_id}/proposals/{pending['id']}/approve"
        form = {"why": "checked the window"}
        assert client.post(url, data=form).status_code == 401  # no login
        client.post("/login", data={"name": "vic", "token": viewer, "next": "/"})
        csrf = client.get("/api/whoami").json()["csrf"]
        assert client.post(url, data=form, headers={CSRF_HEADER: csrf}).status_code == 403
        client.post("/logout", headers={CSRF_HEADER: csrf})
        client.post("/login", data={"name": "eve", "token": engineer, "next": "/"})
        csrf = client.get("/api/whoami").json()["csrf"]
        assert client.post(url, data=form).status_code == 403  # no CSRF token
        answer = client.post(url, data=form, headers={CSRF_HEADER: csrf})
        assert answer.status_code == 200, answer.text
        request = answer.json()["request"]
        requests = client.get(f"/api/loops/{loop_id}/requests").json()["requests"]
    finally:
        loops.close()
    assert request["kind"] == "approve"
    assert request["who"] == "eve"
    assert request["why"] == "checked the window"
    assert request["origin"] == "dashboard"
    assert [r["id"] for r in requests] == [request["id"]]


def test_with_allow_remote_every_page_needs_a_login(loop_db: Path, tmp_path: Path) -> None:
    users = UsersFile(tmp_path / "users.json")
    token = users.add("vic", "viewer")
    client, loops = _client([loop_db], Security(users, require_login=True))
    try:
        (loop_id,) = loops.ids()
        page = client.get(f"/loops/{loop_id}", follow_redirects=False)
        api = client.get(f"/api/loops/{loop_id}/status")
        client.post("/login", data={"name": "vic", "token": token, "next": "/"})
        after = client.get(f"/loops/{loop_id}")
    finally:
        loops.close()
    assert page.status_code == 303
    assert page.headers["location"].startswith("/login?next=")
    assert api.status_code == 401
    assert after.status_code == 200


def test_two_stores_with_one_loop_id_are_refused_and_a_watched_folder_picks_up_new_ones(
    loop_db: Path, tmp_path: Path
) -> None:
    twin = tmp_path / "twin"
    twin.mkdir()
    second = _copy(loop_db, twin)
    with pytest.raises(ConfigError, match="already shown"):
        Loops([loop_db, second])
    folder = tmp_path / "watched"
    folder.mkdir()
    loops = Loops([folder])
    try:
        assert loops.ids() == []
        _copy(loop_db, folder, "new.db")
        loops.scan(force=True)
        assert len(loops.ids()) == 1
        _copy(loop_db, folder, "same-id.db")
        loops.scan(force=True)
        assert len(loops.ids()) == 1
        assert "already shown" in loops.refused["same-id.db"]
    finally:
        loops.close()


def test_a_store_of_a_newer_fuelid_is_refused_with_both_versions(loop_db: Path) -> None:
    with sqlite3.connect(loop_db) as con:
        con.execute(f"PRAGMA user_version={SCHEMA_VERSION + 1}")
    with pytest.raises(StoreError, match=f"{SCHEMA_VERSION + 1}.*newer"):
        SQLiteLoop(loop_db)
    with pytest.raises(ConfigError, match="newer"):
        Loops([loop_db])


def test_a_store_of_the_previous_schema_is_migrated_and_shown(tmp_path: Path) -> None:
    # written the v2 way (fuelid 0.2): a virtual run at 20x, windows timed by the wall clock
    # while their data ran ahead in plant time; a proposal filed between two windows
    from fuelid.store import Sample, build_at

    db = tmp_path / "v2.db"
    build_at(str(db), 2, {"site_name": "tunnel 2", "tag_map_hash": "ab12"})
    wall0, plant0 = 1.8e9, 1.8e9 + 50_000.0
    samples = [
        Sample(plant0 - 1_200.0 + 0.02 * k, k, 2.0, 40.0 + (k // 3000) % 2, 40.0, 20.0, 1, 0)
        for k in range(60_000)
    ]
    con = sqlite3.connect(db)
    con.executemany("INSERT INTO samples VALUES (?, ?, ?, ?, ?, ?, ?, ?)", [r[:8] for r in samples])
    model = json.dumps({"model": {"K": 14.0, "T": 1.2, "delay": 0.2}})
    for k in (1, 2):
        wall, plant = wall0 + 30.0 * k, plant0 + 600.0 * (k - 1)
        con.execute(
            "INSERT INTO models VALUES (?, ?, ?, ?, 20.0, ?)",
            (k, wall, plant - 600.0, plant, model),
        )
        con.execute(
            "INSERT INTO windows VALUES (?, ?, ?, ?, 1, 'passed every gate', 20.0, 2.0, ?, ?)",
            (k, wall, plant - 600.0, plant, k, model),
        )
    detail = {
        "old": {"Kc": 0.04, "Ti": 1.4},
        "new": {"Kc": 0.045, "Ti": 1.38},
        "detail": {"reason": "2 independent windows agree", "Ms": {"newest": 1.45}},
        "history": [{"time": wall0 + 45.0, "status": "pending", "who": "online", "why": ""}],
    }
    con.execute(
        "INSERT INTO proposals VALUES (1, ?, 1, 0.045, 1.38, 'pending', ?)",
        (wall0 + 45.0, json.dumps(detail)),
    )
    con.commit()
    con.close()
    client, loops = _client([db])
    try:
        (loop_id,) = loops.ids()
        pages = [client.get(u).status_code for u in ("/", f"/loops/{loop_id}")]
        history = client.get(f"/api/loops/{loop_id}/history").json()
        span = (plant0 - 1_200.0, plant0)
        trend = client.get(
            f"/api/loops/{loop_id}/trend?start={span[0]}&end={span[1]}&width=400"
        ).json()
    finally:
        loops.close()
    assert pages == [200, 200]
    assert loop_id == "tunnel-2"
    (proposal,) = history["proposals"]
    windows = history["windows"]
    # filed halfway between the windows' analyses in wall time: halfway in plant time too
    assert windows[0]["end"] < proposal["time"] < windows[1]["end"]
    assert proposal["time"] == pytest.approx(plant0 + 300.0)
    # the level-of-detail table was built by the migration: 1,200 s of 50 Hz is 60,000 samples
    assert trend["source"] == "lod"
    assert trend["level_s"] == 1
    assert trend["points"] == 2 * 1_200


def test_each_live_part_is_rendered_as_the_first_view_renders_it(loop_db: Path) -> None:
    # one truth on a page: the parts the stream makes the page re-read are the page's own HTML
    client, loops = _client([loop_db])
    try:
        (loop_id,) = loops.ids()
        page = client.get(f"/loops/{loop_id}").text
        parts = client.get(f"/loops/{loop_id}/parts").json()
    finally:
        loops.close()
    assert set(parts["html"]) == {"proposals", "now", "windows", "events"}
    for name, html in parts["html"].items():
        assert html.strip(), name
        assert html in page, name
    assert isinstance(parts["link_bands"], list)


def test_history_pages_its_windows_and_counts_them_all(loop_db: Path) -> None:
    client, loops = _client([loop_db])
    try:
        (loop_id,) = loops.ids()
        whole = client.get(f"/api/loops/{loop_id}/history").json()
        newest = client.get(f"/api/loops/{loop_id}/history?windows=2").json()
        refused = client.get(f"/api/loops/{loop_id}/history?windows=0")
    finally:
        loops.close()
    assert len(whole["windows"]) >= 3
    assert newest["windows"] == whole["windows"][-2:]
    assert newest["counts"] == whole["counts"]
    assert newest["proposals"] == whole["proposals"]
    assert refused.status_code == 422


def test_the_trend_spans_the_minutes_asked_for(loop_db: Path) -> None:
    client, loops = _client([loop_db])
    try:
        (loop_id,) = loops.ids()
        default = client.get(f"/api/loops/{loop_id}/trend").json()
        one = client.get(f"/api/loops/{loop_id}/trend?minutes=1").json()
        five = client.get(f"/api/loops/{loop_id}/trend?minutes=5").json()
    finally:
        loops.close()
    assert one["end"] - one["start"] == pytest.approx(60.0, abs=1e-3)
    assert five["end"] - five["start"] == pytest.approx(300.0, abs=1e-3)
    # 10 min by default, from the first sample when the store holds less (9 min here)
    assert 300.0 < default["end"] - default["start"] <= 600.0 + 1e-3
    assert one["end"] == five["end"] == default["end"]


def test_the_first_view_of_a_loop_page_sends_at_most_300_kb_of_scripts(loop_db: Path) -> None:
    # the goal (at most 500 KB): plotly.js (1.2 MB) waits until the analysis charts show
    import re

    client, loops = _client([loop_db])
    try:
        (loop_id,) = loops.ids()
        page = client.get(f"/loops/{loop_id}").text
        scripts = re.findall(r'<script src="([^"]+)"', page)
        sent = {
            src: int(client.get(src, headers={"Accept-Encoding": "gzip"}).headers["content-length"])
            for src in scripts
        }
    finally:
        loops.close()
    assert not any("plotly" in src for src in scripts)
    assert any("uPlot" in src for src in scripts)
    assert sum(sent.values()) <= 300_000, sent
