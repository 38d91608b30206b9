"""The dashboard's static files: vendored as the manifest says, compressed once, cached.

Whatever runs in the browser is served by the dashboard itself (the Content-Security-Policy
allows scripts from 'self' only): fuelid's own files, the vendored ones (their SHA-256 in
``static/vendor/MANIFEST.json``) and plotly.js from the installed plotly package.
"""

from __future__ import annotations

import gzip
import hashlib
from importlib import resources
from pathlib import Path

import pytest

pytest.importorskip("fastapi")

from fastapi.testclient import TestClient

from fuelid.dashboard import Loops, Security, create_app
from fuelid.dashboard._static_files import CACHE_MAX_AGE_S, vendored

STATIC = Path(str(resources.files("fuelid.dashboard") / "static"))


def _client() -> TestClient:
    return TestClient(create_app(Loops([]), Security(None, require_login=False)))


def test_every_vendored_file_is_the_one_its_manifest_names() -> None:
    libraries = vendored()
    assert {lib["name"] for lib in libraries} == {"uPlot"}
    for lib in libraries:
        for key in ("version", "licence", "source"):
            assert lib[key], key
        for name, sha256 in lib["files"].items():
            assert hashlib.sha256((STATIC / name).read_bytes()).hexdigest() == sha256, name
    listed = {name for lib in libraries for name in lib["files"]}
    on_disk = {
        str(p.relative_to(STATIC)) for p in (STATIC / "vendor").rglob("*") if p.is_file()
    } - {"vendor/MANIFEST.json"}
    assert on_disk == listed  # nothing vendored without its entry


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


def test_plotly_comes_from_the_installed_package_and_nothing_leaves_the_folder() -> None:
    import plotly

    client = _client()
    answer = client.get("/static/plotly.min.js")
    package_file = Path(plotly.__file__).parent / "package_data" / "plotly.min.js"
    assert answer.status_code == 200
    assert answer.content == package_file.read_bytes()
    assert answer.headers["content-type"].startswith("text/javascript")
    for name in ("../app.py", "..%2Fapp.py", "/etc/passwd", "vendor/../../app.py", "nope.js"):
        assert client.get(f"/static/{name}").status_code == 404, name
