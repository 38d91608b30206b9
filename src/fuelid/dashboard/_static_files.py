"""The dashboard's static files: compressed once, served with a validator and cached.

A control-room screen reloads its page now and then, and a 2-core machine serves it beside the
service: every static file is gzip-compressed once, when first asked for (not on every request,
as a compressing middleware would), and served with its SHA-256 as the ETag and
``Cache-Control: public, max-age=…``. The pages name each file with ``?v=<hash prefix>``
(:meth:`StaticFiles.url`), so a new fuelid version is fetched at once while an unchanged file
is never asked for again.

What runs in the browser is either fuelid's own (``static/*.js``, ``*.css``) or vendored under
``static/vendor/`` with its version, licence and hash in ``static/vendor/MANIFEST.json``
(:func:`vendored`): uPlot, plotly.js's basic bundle and Swagger UI, each file unchanged from its
npm package, so a Python dependency's update cannot change what the browser runs. Nothing is
loaded from the internet: the Content-Security-Policy allows scripts from the dashboard itself
only.
"""

from __future__ import annotations

import gzip
import hashlib
import json
import threading
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

__all__ = ["CACHE_MAX_AGE_S", "StaticFiles", "vendored"]

CACHE_MAX_AGE_S = 7 * 24 * 3600
"""How long a browser may keep a static file without asking again [s] (the URL changes with it)."""
MEDIA_TYPES = {
    ".js": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".json": "application/json",
}


@dataclass(frozen=True)
class StaticFile:
    """One file as served: its bytes plain and gzipped, its hash and media type."""

    plain: bytes
    gzipped: bytes
    sha256: str
    media_type: str


def _load(path: Path) -> StaticFile:
    data = path.read_bytes()
    return StaticFile(
        plain=data,
        # mtime=0: the same bytes give the same compressed bytes (a stable response)
        gzipped=gzip.compress(data, compresslevel=9, mtime=0),
        sha256=hashlib.sha256(data).hexdigest(),
        media_type=MEDIA_TYPES.get(path.suffix, "application/octet-stream"),
    )


class StaticFiles:
    """The files under the package's ``static/`` folder (and nothing from elsewhere).

    Parameters
    ----------
    root : Path
        The ``static`` folder.
    """

    def __init__(self, root: Path) -> None:
        self.root = root.resolve()
        self._files: dict[str, StaticFile] = {}
        self._lock = threading.Lock()

    def _path(self, name: str) -> Path | None:
        path = (self.root / name).resolve()
        # a name with ".." or an absolute path must not leave the folder
        if self.root not in path.parents or not path.is_file():
            return None
        return path

    def get(self, name: str) -> StaticFile | None:
        """The file ``name`` (relative to ``static/``), loaded once; None when there is none."""
        with self._lock:
            found = self._files.get(name)
        if found is not None:
            return found
        path = self._path(name)
        if path is None:
            return None
        loaded = _load(path)
        with self._lock:
            self._files[name] = loaded
        return loaded

    def url(self, name: str) -> str:
        """``/static/<name>?v=<hash prefix>``: the URL a page names the file by."""
        found = self.get(name)
        version = "" if found is None else f"?v={found.sha256[:12]}"
        return f"/static/{name}{version}"

    def response(self, name: str, accept_encoding: str, if_none_match: str | None) -> Any:
        """The Starlette response for ``GET /static/<name>`` (404 when absent, 304 when known)."""
        from starlette.responses import Response

        found = self.get(name)
        if found is None:
            return Response(status_code=404)
        etag = f'"{found.sha256[:32]}"'
        headers = {
            "ETag": etag,
            "Cache-Control": f"public, max-age={CACHE_MAX_AGE_S}",
            "Vary": "Accept-Encoding",
        }
        if if_none_match is not None and etag in if_none_match:
            return Response(status_code=304, headers=headers)
        if "gzip" in accept_encoding.lower():
            headers["Content-Encoding"] = "gzip"
            return Response(found.gzipped, media_type=found.media_type, headers=headers)
        return Response(found.plain, media_type=found.media_type, headers=headers)


def vendored() -> list[dict[str, Any]]:
    """The vendored browser libraries: ``static/vendor/MANIFEST.json``'s entries.

    Each: ``name``, ``version``, ``licence``, ``source`` (where it was taken from) and
    ``files`` (path under ``static/`` → SHA-256), which the tests check against the files.
    """
    text = (resources.files("fuelid.dashboard") / "static" / "vendor" / "MANIFEST.json").read_text(
        encoding="utf-8"
    )
    return list(json.loads(text)["libraries"])
