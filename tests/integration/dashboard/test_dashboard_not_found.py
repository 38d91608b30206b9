"""A page that does not exist answers an HTML page with a way back (issue 39, item 5).

An unknown loop's page, a window the loop does not have and a path no route serves answered raw
JSON; the pages now answer the dashboard's own page (status 404) with a link to the fleet, the
reason escaped, while the API keeps its JSON 404. The store is an empty one made here: no
window, so any window number is unknown.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("fastapi")

from fastapi.testclient import TestClient

from fuelid.dashboard import Loops, Security, create_app
from fuelid.store import SQLiteStore


@pytest.fixture
def client(tmp_path: Path) -> Iterator[TestClient]:
    store = tmp_path / "loop.db"
    SQLiteStore(store, site_name="tunnel 2", tag_map_hash="ab12", period_s=0.02).close()
    loops = Loops([store])
    try:
        yield TestClient(create_app(loops, Security(None, require_login=False)))
    finally:
        loops.close()


@pytest.mark.parametrize(
    ("path", "reason"),
    [
        ("/loops/nope", "no loop &#39;nope&#39;"),
        ("/loops/tunnel-2/windows/9", "no window 9 in loop &#39;tunnel-2&#39;"),
        ("/loops/tunnel-2/windows/9/report", "no window 9"),
        ("/loops/tunnel-2/windows/nine", "There is no such page."),
        ("/no/such/page", "There is no such page."),
    ],
)
def test_a_missing_page_is_an_html_404_with_a_link_to_the_fleet(
    client: TestClient, path: str, reason: str
) -> None:
    response = client.get(path)
    assert response.status_code == 404
    assert response.headers["content-type"].startswith("text/html")
    page = response.text
    assert page.lstrip().lower().startswith("<!doctype html>")
    assert reason in page
    assert '<a href="/" id="back-to-fleet">' in page
    assert 'href="/static/' in page or "/static/" in page  # the dashboard's own look


def test_the_reason_is_escaped(client: TestClient) -> None:
    response = client.get("/loops/%3Cimg%20src%3Dx%20onerror%3Dalert(1)%3E")
    assert response.status_code == 404
    assert "<img src=x" not in response.text
    assert "&lt;img src=x onerror=alert(1)&gt;" in response.text


@pytest.mark.parametrize(
    "path", ["/api/loops/nope/status", "/api/loops/tunnel-2/windows/9", "/api/no/such/route"]
)
def test_the_api_keeps_its_json_404(client: TestClient, path: str) -> None:
    response = client.get(path)
    assert response.status_code == 404
    assert response.headers["content-type"] == "application/json"
    assert "detail" in response.json()


def test_other_statuses_keep_fastapi_s_answer(client: TestClient) -> None:
    response = client.get("/api/loops/tunnel-2/windows/nine")  # the API's validation: 422 JSON
    assert response.status_code == 422
    assert response.headers["content-type"] == "application/json"
