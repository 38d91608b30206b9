"""The dashboard's static files: vendored as the manifest says, compressed once, cached.

Whatever runs in the browser is served by the dashboard itself (the Content-Security-Policy
allows scripts from 'self' only): fuelid's own files and the vendored ones (uPlot, plotly.js's
basic bundle, Swagger UI: their version, licence and SHA-256 in ``static/vendor/MANIFEST.json``),
nothing from an installed Python package.
"""

from __future__ import annotations

import gzip
import hashlib
import re
import shutil
from importlib import resources
from pathlib import Path

import pytest

pytest.importorskip("fastapi")

from fastapi.testclient import TestClient

from fuelid.dashboard import Loops, Security, create_app
from fuelid.dashboard._static_files import CACHE_MAX_AGE_S, vendored

STATIC = Path(str(resources.files("fuelid.dashboard") / "static"))


@pytest.fixture
def loop_db(dashboard_store: Path, tmp_path: Path) -> Path:
    return Path(shutil.copy(dashboard_store, tmp_path / "loop.db"))


def _client() -> TestClient:
    return TestClient(create_app(Loops([]), Security(None, require_login=False)))


def test_every_vendored_file_is_the_one_its_manifest_names() -> None:
    libraries = vendored()
    assert {lib["name"] for lib in libraries} == {"uPlot", "plotly.js basic", "Swagger UI"}
    for lib in libraries:
        for key in ("version", "licence", "source"):
            assert lib[key], key
        # the licence names a file that is vendored with the library
        licence_files = [name for name in lib["files"] if f"static/{name}" in lib["licence"]]
        assert licence_files, lib["name"]
        for name, sha256 in lib["files"].items():
            assert hashlib.sha256((STATIC / name).read_bytes()).hexdigest() == sha256, name
    listed = {name for lib in libraries for name in lib["files"]}
    on_disk = {
        str(p.relative_to(STATIC)) for p in (STATIC / "vendor").rglob("*") if p.is_file()
    } - {"vendor/MANIFEST.json"}
    assert on_disk == listed  # nothing vendored without its entry


def test_the_dashboard_serves_each_vendored_file_with_its_manifests_hash() -> None:
    client = _client()
    for lib in vendored():
        for name, sha256 in lib["files"].items():
            answer = client.get(f"/static/{name}")
            assert answer.status_code == 200, name
            assert hashlib.sha256(answer.content).hexdigest() == sha256, name


@pytest.mark.xdist_group("dashboard")  # the shared store (tests/conftest.py says why)
def test_every_script_and_style_of_a_page_is_fuelids_own_or_vendored(loop_db: Path) -> None:
    loops = Loops([loop_db])
    client = TestClient(create_app(loops, Security(None, require_login=False)))
    (loop_id,) = loops.ids()
    hashes = {name: sha for lib in vendored() for name, sha in lib["files"].items()}
    try:
        window_id = client.get(f"/api/loops/{loop_id}/history").json()["windows"][0]["id"]
        urls = ["/", f"/loops/{loop_id}", f"/loops/{loop_id}/windows/{window_id}", "/api/docs"]
        loaded: set[str] = set()
        for url in urls:
            page = client.get(url)
            assert page.status_code == 200, url
            # <script src>, <link href> and the analysis charts' lazily loaded scripts
            found = re.findall(r'(?:src|href|data-plotly|data-script)="(/static/[^"]+)"', page.text)
            loaded |= set(found)
            assert not re.search(r'(?:src|href)="(?:https?:)?//', page.text), url
    finally:
        loops.close()
    names = {url.removeprefix("/static/").split("?")[0] for url in loaded}
    assert {
        "vendor/uplot/uPlot.iife.min.js",
        "vendor/plotly/plotly-basic.min.js",
        "vendor/swagger-ui/swagger-ui-bundle.js",
        "vendor/swagger-ui/swagger-ui.css",
    } <= names
    for name in names:
        assert name in hashes or "/" not in name, name  # a vendored file or fuelid's own
        assert (STATIC / name).is_file(), name


def test_a_static_file_is_sent_gzipped_with_its_etag_and_then_not_sent_again() -> None:
    name = "vendor/uplot/uPlot.iife.min.js"
    plain = (STATIC / name).read_bytes()
    client = _client()
    first = client.get(f"/static/{name}", headers={"Accept-Encoding": "gzip"})
    assert first.status_code == 200
    assert first.headers["content-encoding"] == "gzip"
    assert first.content == plain  # httpx decodes it: the bytes are the file's
    sent = int(first.headers["content-length"])
    assert sent == len(gzip.compress(plain, compresslevel=9, mtime=0))
    assert sent < 0.5 * len(plain)
    assert first.headers["cache-control"] == f"public, max-age={CACHE_MAX_AGE_S}"
    again = client.get(f"/static/{name}", headers={"If-None-Match": first.headers["etag"]})
    assert again.status_code == 304
    assert again.content == b""
    identity = client.get(f"/static/{name}", headers={"Accept-Encoding": "identity"})
    assert "content-encoding" not in identity.headers
    assert identity.content == plain


def test_nothing_is_served_from_outside_the_static_folder() -> None:
    client = _client()
    for name in (
        "../app.py",
        "..%2Fapp.py",
        "/etc/passwd",
        "vendor/../../_app.py",
        "nope.js",
        "plotly.min.js",  # once plotly's package file: gone with the vendored basic bundle
        "swagger/swagger-ui-bundle.js",  # once swagger-ui-bundle's folder, mounted whole
        "swagger/index.html",
    ):
        assert client.get(f"/static/{name}").status_code == 404, name
