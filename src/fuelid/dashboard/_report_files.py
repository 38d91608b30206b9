"""The window reports a dashboard made, kept in a folder beside the store for its next run.

A restarted dashboard (an upgrade, a reboot) would otherwise make again, a few seconds of CPU
each, the reports it had made when the service judged the windows, while the first requests
wait. Each report made (its analysis and figures; the page itself is rendered afresh, with the
proposals filed since) is written to :func:`report_folder`, ``<store>.reports/`` beside the
store file, under a name digested from what it was made from (the loop, the store's uuid, the
window, its span, the report's settings and plant) and from :func:`code_version` (fuelid's own
files and the versions of the libraries that compute and draw it): a changed input or another
fuelid names another file, never an old report. The plants' linearisations, which every report
on one plant shares, are kept there too.

- The store file is never opened here: the folder is beside it, outside its transactions.
- A file is written whole under a temporary name, then renamed: a reader sees all or nothing.
- A file that does not read back whole (cut short, corrupt, another format) is removed and the
  report made again: the folder is a cache, never the only copy of anything.
- The files are Python pickles, which run code when read: the folder is made private (0700 on
  POSIX) and read only while it is the dashboard user's own and no one else may write in it.
- At most :data:`KEPT_REPORTS` reports and :data:`KEPT_PLANTS` plants per folder, the least
  recently used removed first.
- Where the dashboard may not write (a store of another user's, a read-only disk) nothing is
  kept: its reports stay in memory only.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import os
import pickle
import stat
import sys
import time
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

from fuelid.io.files import atomic_write_bytes

__all__ = [
    "KEPT_PLANTS",
    "KEPT_REPORTS",
    "code_version",
    "file_name",
    "load",
    "report_folder",
    "save",
]

KEPT_REPORTS = 24
"""Reports kept per folder (about 2.6 MB each for a 10-minute window at 50 Hz): twice what
the dashboard keeps in memory, so a restart finds those made ahead and the ones looked at."""
KEPT_PLANTS = 4
"""Plants whose linearisations are kept per folder (a few hundred kB each)."""
STALE_TEMPORARY_S = 600.0
"""A temporary file this old [s] is a write a killed process never finished: removed."""
_MAGIC = b"fuelid window report cache 1\n"
"""A kept file's first line; a SHA-256 of the rest follows, then the pickle."""
_LIBRARIES = ("numpy", "scipy", "matplotlib", "jinja2")
"""The libraries whose version may change a report's numbers or figures."""


def report_folder(store: Path) -> Path:
    """Where the reports of ``store`` are kept: ``<store>.reports/`` beside it.

    >>> report_folder(Path("plant") / "loop.db").name
    'loop.db.reports'
    """
    return store.with_name(f"{store.name}.reports")


@functools.cache
def code_version() -> str:
    """A digest of the code that makes a report: fuelid's files, its libraries, Python.

    Every source file and template of the installed fuelid is read (some 300 files, a few
    milliseconds, once per process): a development checkout changed since a report was kept
    names another file, as an upgrade does.
    """
    import fuelid

    digest = hashlib.sha256(sys.version.encode())
    for name in _LIBRARIES:
        with contextlib.suppress(metadata.PackageNotFoundError):
            digest.update(f"{name} {metadata.version(name)}\n".encode())
    root = Path(fuelid.__file__).parent
    for path in sorted(root.rglob("*")):
        if path.suffix in (".py", ".j2", ".toml", ".json") and path.is_file():
            digest.update(path.relative_to(root).as_posix().encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def file_name(kind: str, inputs: Sequence[Any]) -> str:
    """The file of a ``kind`` ("report" or "plant") made from ``inputs`` by this code.

    ``inputs`` are turned into JSON (anything else by its ``repr``), so equal inputs name the
    same file in every process.
    """
    text = json.dumps([code_version(), *inputs], default=repr, sort_keys=True)
    return f"{kind}-{hashlib.sha256(text.encode()).hexdigest()[:32]}.pickle"


def _private(folder: Path) -> bool:
    """The folder is a real folder of this user's that no one else may write in."""
    try:
        st = folder.lstat()  # a link to someone else's folder is not this folder
    except OSError:
        return False
    if not stat.S_ISDIR(st.st_mode):
        return False
    if not hasattr(os, "getuid"):  # Windows: the store folder's permissions are inherited
        return True
    return st.st_uid == os.getuid() and not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def load(folder: Path, name: str) -> Any | None:
    """What ``name`` in ``folder`` holds; None when it is absent, unreadable or not whole.

    A file that is there but does not read back is removed: it is made again.
    """
    if not _private(folder):
        return None
    path = folder / name
    try:
        blob = path.read_bytes()
    except OSError:
        return None
    head, digest, payload = blob[: len(_MAGIC)], blob[len(_MAGIC) : len(_MAGIC) + 32], b""
    if head == _MAGIC:
        payload = blob[len(_MAGIC) + 32 :]
    try:
        if not payload or hashlib.sha256(payload).digest() != digest:
            raise ValueError("not a whole report file")
        value = pickle.loads(payload)  # a pickle runs code: only from a private folder
    except Exception:  # cut short, corrupt, from another Python: made again
        with contextlib.suppress(OSError):
            path.unlink()
        return None
    with contextlib.suppress(OSError):
        os.utime(path)  # recently used: the last to be removed
    return value


def save(folder: Path, name: str, value: Any) -> bool:
    """Keep ``value`` as ``name`` in ``folder`` (made private); whether it was kept.

    Nothing is raised: a folder the dashboard may not write, a full disk or a value that does not
    pickle only leave the report in memory. The oldest files of the same kind beyond
    :data:`KEPT_REPORTS` (or :data:`KEPT_PLANTS`) are removed.
    """
    try:
        folder.mkdir(mode=0o700, exist_ok=True)
        if not _private(folder):
            return False
        payload = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
        atomic_write_bytes(folder / name, _MAGIC + hashlib.sha256(payload).digest() + payload)
    except Exception:  # only a cache: the report is in memory all the same
        return False
    kind = name.split("-", 1)[0]
    _prune(folder, kind, KEPT_PLANTS if kind == "plant" else KEPT_REPORTS)
    return True


def _prune(folder: Path, kind: str, keep: int) -> None:
    """Remove the least recently used files of ``kind`` beyond ``keep``, and stale temporaries."""
    now = time.time()
    with contextlib.suppress(OSError):
        aged = []
        for path in folder.iterdir():
            with contextlib.suppress(OSError):  # removed meanwhile by another dashboard
                mtime = path.stat().st_mtime
                if path.name.startswith(f"{kind}-") and path.suffix == ".pickle":
                    aged.append((mtime, path))
                elif path.name.endswith(".tmp") and now - mtime > STALE_TEMPORARY_S:
                    path.unlink()
        aged.sort(reverse=True)
        for _, path in aged[keep:]:
            with contextlib.suppress(OSError):
                path.unlink()
