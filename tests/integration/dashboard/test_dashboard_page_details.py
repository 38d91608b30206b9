"""The dashboard's smaller promises (issue 39, item 5), each against the pages as served.

(a) No page, part or report names a folder of the server: the stores' folder, the plant file's.
(b) Each table with a time column names one clock and its zone in its header; no row of a
    table says "wall clock" (the prune event once read "written before … UTC (wall clock)" in
    an events table dated in plant time in the site's zone).
(c) The charts' toolbar offers no cloud upload: the one plotly config every chart is drawn with
    turns the cloud and Chart Studio buttons off.
(d) Approve through the API keeps ``why`` optional (as documented); the page asks for one.

The store is the session's ``dashboard_store`` (a short virtual run), copied into a folder of
the test's own.
"""

from __future__ import annotations

import html
import re
import shutil
import sqlite3
from collections.abc import Iterator
from html.parser import HTMLParser
from importlib import resources
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("fastapi")

from fastapi.testclient import TestClient

from fuelid.dashboard import CSRF_HEADER, Loops, Security, UsersFile, create_app
from fuelid.dashboard._app import central_request_rows
from fuelid.io import format_time
from fuelid.store import SCHEMA_VERSION, SQLiteStore

# xdist: one worker runs the dashboard's modules, which share one store made once
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("dashboard")

STATIC = Path(str(resources.files("fuelid.dashboard") / "static"))


@pytest.fixture
def site_folder(dashboard_store: Path, tmp_path: Path) -> Path:
    """A folder of stores as a site keeps them: the loop's store (pruned once) and a refused one."""
    folder = tmp_path / "site stores"
    folder.mkdir()
    store = Path(shutil.copy(dashboard_store, folder / "loop.db"))
    with SQLiteStore(store) as reader:
        info = reader.info()
    # a prune that finds nothing to do still leaves its event (the events table shows it)
    with SQLiteStore(store, site_name=info.site_name, tag_map_hash=info.tag_map_hash) as writer:
        writer.prune(older_than_days=3650.0)
    newer = Path(shutil.copy(dashboard_store, folder / "newer.db"))
    with sqlite3.connect(newer) as con:  # refused: the fleet page says why, by the file's name
        con.execute(f"PRAGMA user_version={SCHEMA_VERSION + 1}")
    return folder


@pytest.fixture
def client(site_folder: Path) -> Iterator[tuple[TestClient, Loops]]:
    loops = Loops([site_folder])
    try:
        yield TestClient(create_app(loops, Security(None, require_login=False))), loops
    finally:
        loops.close()


def _loop_and_window(client: TestClient) -> tuple[str, int]:
    (row,) = client.get("/api/loops").json()["loops"]
    history = client.get(f"/api/loops/{row['loop_id']}/history").json()
    accepted = [w for w in history["windows"] if w["accepted"]]
    return row["loop_id"], accepted[-1]["id"]


def test_no_page_part_or_report_names_a_folder_of_the_server(
    client: tuple[TestClient, Loops], site_folder: Path, dashboard_store: Path
) -> None:
    test_client, loops = client
    loop_id, window_id = _loop_and_window(test_client)
    plant_file = loops.get(loop_id).plant_file()  # type: ignore[union-attr]
    folders = {str(site_folder), str(site_folder.resolve()), str(dashboard_store.parent)}
    if plant_file is not None:
        folders.add(str(Path(plant_file).parent))
    window = f"/loops/{loop_id}/windows/{window_id}"
    pages = {
        "fleet": "/",
        "loop": f"/loops/{loop_id}",
        "parts": f"/loops/{loop_id}/parts",
        "window": window,
        "report": f"{window}/report",
        "no loop": "/loops/nope",
        "no window": f"/loops/{loop_id}/windows/999999",
        "no page": "/no/such/page",
        "api docs": "/api/docs",
    }
    seen = {}
    for name, url in pages.items():
        answer = test_client.get(url)
        seen[name] = (answer.status_code, answer.text)
    assert {name: code for name, (code, _) in seen.items()} == {
        name: 404 if name.startswith("no ") else 200 for name in pages
    }
    # the refused store is named by its file's name, once, with the reason
    assert "<b>newer.db</b>: store schema version" in seen["fleet"][1]
    for name, (_, text) in seen.items():
        for folder in folders:
            assert folder not in text, (name, folder)
            assert html.escape(folder) not in text, (name, folder)


class _Tables(HTMLParser):
    """Each ``<table>``'s header cells and its body rows' text."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: list[dict[str, Any]] = []
        self._where: str | None = None
        self._cell: list[str] | None = None
        self._row: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "table":
            self.tables.append({"id": dict(attrs).get("id"), "head": [], "rows": []})
        elif tag in ("thead", "tbody"):
            self._where = tag
        elif tag == "tr":
            self._row = []
        elif tag in ("th", "td"):
            self._cell = []

    def handle_endtag(self, tag: str) -> None:
        if tag in ("th", "td") and self._cell is not None:
            self._row.append("".join(self._cell).strip())
            self._cell = None
        elif tag == "tr" and self.tables:
            key = "head" if self._where == "thead" else "rows"
            self.tables[-1][key].append(self._row)
        elif tag in ("thead", "tbody"):
            self._where = None

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data)


def _tables(page: str) -> list[dict[str, Any]]:
    parser = _Tables()
    parser.feed(page)
    return parser.tables


CLOCKS = ("plant time", "wall clock")
TIME_WORDS = re.compile(r"\b(time|end|started|filed|when|at)\b")


def test_each_table_names_one_clock_and_its_zone_and_no_row_says_wall_clock(
    client: tuple[TestClient, Loops],
) -> None:
    test_client, _ = client
    loop_id, window_id = _loop_and_window(test_client)
    tz = test_client.get(f"/api/loops/{loop_id}/status").json()["timezone"]
    parts = test_client.get(f"/loops/{loop_id}/parts").json()
    pages = {
        "fleet": test_client.get("/").text,
        "loop": test_client.get(f"/loops/{loop_id}").text,
        "window": test_client.get(f"/loops/{loop_id}/windows/{window_id}").text,
        **{f"part {name}": text for name, text in parts["html"].items()},
    }
    timed = set()
    for page_name, page in pages.items():
        for table in _tables(page):
            where = (page_name, table["id"])
            head = [cell for row in table["head"] for cell in row]
            time_columns = [cell for cell in head if TIME_WORDS.search(cell)]
            if time_columns:
                timed.add(where)
                assert len(time_columns) == 1, where  # one time column, one clock
                (column,) = time_columns
                assert sum(clock in column for clock in CLOCKS) == 1, (where, column)
                assert tz in column, (where, column)
            for row in table["rows"]:
                assert not any("wall clock" in cell for cell in row), (where, row)
    # the loop page's tables with times: its windows and its events (first view and parts)
    assert {("loop", "windows"), ("loop", "events"), ("part events", "events")} <= timed
    events = next(t for t in _tables(parts["html"]["events"]) if t["id"] == "events")
    prune = [row for row in events["rows"] if row[1] == "prune"]
    assert prune  # the fixture's prune, said as an age in the table of plant times
    assert prune[0][2] == "samples older than 3650 d: 0 deleted, 0 kept (one per 1.0 s)"


def test_the_relayed_requests_rows_leave_the_clock_to_their_header() -> None:
    # a central loop's table of relayed requests: "filed (wall clock, <zone>)" in its header;
    # a waiting request's state names its expiry in that clock and zone without saying it again
    expires = 1_800_000_000.0
    status = {
        "central": {
            "requests": [
                {"id": 1, "kind": "approve", "proposal_id": 4, "status": "waiting",
                 "created": expires - 600.0, "expires": expires, "fetched": None},
                {"id": 2, "kind": "revert", "proposal_id": None, "status": "done",
                 "created": expires - 900.0, "expires": expires - 300.0, "outcome": "written"},
            ]
        }
    }  # fmt: skip
    rows = central_request_rows(status, "Europe/Oslo")
    assert [r["id"] for r in rows] == [2, 1]  # newest first
    waiting = rows[1]["state"]
    assert waiting == (
        f"waiting for the site's next sync (expires {format_time(expires, 'Europe/Oslo')})"
    )
    assert all("wall clock" not in str(value) for row in rows for value in row.values())
    template = (STATIC.parent / "templates" / "part_proposals.html.j2").read_text()
    assert "<th>filed (wall clock, {{ tz }})</th>" in template


def _js_object(source: str, name: str) -> str:
    """The text of ``const NAME = { … };`` in ``source`` (no nested braces in it)."""
    found = re.search(rf"const {name} = (\{{[^{{}}]*\}});", source)
    assert found is not None, name
    return found.group(1)


def test_every_chart_is_drawn_with_a_toolbar_without_cloud_buttons() -> None:
    config = _js_object((STATIC / "common.js").read_text(), "PLOT_CONFIG")
    assert re.search(r"\bshowSendToCloud: false\b", config)
    assert re.search(r"\bshowEditInChartStudio: false\b", config)
    assert re.search(r"\bshowLink: false\b", config)
    assert re.search(r"\bdisplaylogo: false\b", config)
    removed = re.search(r"modeBarButtonsToRemove: \[([^\]]*)\]", config)
    assert removed is not None
    assert {'"sendDataToCloud"', '"editInChartStudio"'} <= {
        name.strip() for name in removed.group(1).split(",")
    }
    # every plotly chart of the pages is drawn with that config, as its last argument
    calls = 0
    for script in STATIC.glob("*.js"):
        text = script.read_text()
        for found in re.finditer(r"Plotly\.(?:newPlot|react|plot)\(", text):
            calls += 1
            end = text.index(";\n", found.end())
            statement = re.sub(r"\)\.then\(.*", ")", text[found.start() : end], flags=re.S)
            assert re.search(r",\s*PLOT_CONFIG\s*\)\s*$", statement), (script.name, statement)
    assert calls >= 6  # model history, K against temperature, gains, fit, residuals, ACF


def test_the_api_approves_without_a_why_and_the_page_asks_for_one(
    site_folder: Path, tmp_path: Path
) -> None:
    users = UsersFile(tmp_path / "users.json")
    token = users.add("eve", "engineer")
    loops = Loops([site_folder])
    client = TestClient(create_app(loops, Security(users, require_login=False)))
    try:
        (loop_id,) = loops.ids()
        client.post("/login", data={"name": "eve", "token": token, "next": "/"})
        csrf = client.get("/api/whoami").json()["csrf"]
        page = client.get(f"/loops/{loop_id}").text
        history = client.get(f"/api/loops/{loop_id}/history").json()
        pending = next(p for p in history["proposals"] if p["status"] == "pending")
        url = f"/api/loops/{loop_id}/proposals/{pending['id']}/approve"
        answer = client.post(url, data={}, headers={CSRF_HEADER: csrf})
    finally:
        loops.close()
    assert answer.status_code == 200, answer.text
    request = answer.json()["request"]
    assert (request["kind"], request["who"]) == ("approve", "eve")
    assert request["why"] == "(no reason given)"
    # the page: the proposal's form asks for a reason and no approve button waives it
    form = page.split(f'data-proposal="{pending["id"]}"', 1)[1].split("</form>", 1)[0]
    why = re.search(r'<input name="why"[^>]*>', form)
    assert why is not None
    assert " required" in why.group(0)
    approve = re.search(r'<button[^>]*data-kind="approve"[^>]*>', form)
    assert approve is not None
    assert "data-why-optional" not in approve.group(0)
    script = (STATIC / "loop.js").read_text()
    assert "if (!why.value.trim() && !button.dataset.whyOptional) {" in script
