"""The loops a dashboard shows: one store per loop, known by its loop id, a folder watched.

``--store`` names store files or folders. A file is opened at start; a store that cannot be
opened (not a fuelid store, written by a newer fuelid) or whose loop id another store already has
is refused then, with the reason (:class:`~fuelid.errors.ConfigError`: the command exits 2). A
folder is scanned at start and every :data:`WATCH_EVERY_S` seconds for new ``*.db`` files; one
found there that cannot be shown is listed among the refusals (the fleet page shows them) and not
tried again until its file changes.

``--central URL`` adds the loops of the central store (:class:`~fuelid.dashboard._central_loops.
CentralLoops`, polled as often for new loops). A loop id both in a local store and centrally is
shown from the local store (read live: its samples stream, an action is applied at once rather
than relayed at the site's next sync); the central copy is listed among the loops not shown,
with that reason. A central store lost while serving hides nothing local: its loops are listed
as not shown with the reason until it is back.

``prefetch_reports=True`` (what the server asks for) makes the newest windows' HTML reports of
every local store ahead, in a background thread
(:class:`~fuelid.dashboard._window_report.ReportPrefetcher`), stopped by :meth:`Loops.close`.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from fuelid.dashboard._source import LoopReader, SQLiteLoop
from fuelid.errors import ConfigError, FuelidError

if TYPE_CHECKING:
    from fuelid.dashboard._central_loops import CentralLoops
    from fuelid.dashboard._window_report import ReportPrefetcher

__all__ = ["WATCH_EVERY_S", "Loops"]

WATCH_EVERY_S = 5.0
"""How often the watched folders are scanned for new stores [s]."""


def named_by_file(reason: str, path: Path) -> str:
    """``reason`` on one line, the store named by its file's name: a page names no folder.

    The fleet page lists it under the file's name, so a leading "<the file>: " goes.

    >>> named_by_file("/srv/stores/a.db: not a fuelid store", Path("/srv/stores/a.db"))
    'not a fuelid store'
    >>> named_by_file("cannot read /srv/stores/a.db", Path("/srv/stores/a.db"))
    'cannot read a.db'
    """
    for full in sorted({str(path.resolve()), str(path)}, key=len, reverse=True):  # longest first
        reason = reason.replace(full, path.name)
    return " ".join(reason.split()).removeprefix(f"{path.name}: ")


class Loops:
    """The loops by id (see the module docstring).

    Parameters
    ----------
    paths : iterable of path
        Store files and folders of stores.
    opener : callable, optional
        Opens one store file as a :class:`LoopReader` (the SQLite reader by default).
    central : CentralLoops, optional
        The loops of a central store, shown beside the local ones.
    prefetch_reports : bool
        Make each local store's newest windows' reports ahead (the module docstring).
    """

    def __init__(
        self,
        paths: Iterable[str | Path],
        opener: Callable[[Path], LoopReader] = SQLiteLoop,
        central: CentralLoops | None = None,
        prefetch_reports: bool = False,
    ) -> None:
        self._opener = opener
        self.central = central
        self._lock = threading.Lock()
        self._loops: dict[str, LoopReader] = {}
        self._files: dict[Path, str] = {}
        self.refused: dict[str, str] = {}  # file name -> reason
        self._tried: dict[Path, float] = {}
        self.folders: list[Path] = []
        self._scanned = 0.0
        self._prefetch: ReportPrefetcher | None = None
        files = []
        for raw in paths:
            path = Path(raw)
            if path.is_dir():
                self.folders.append(path)
            elif path.is_file():
                files.append(path)
            else:
                raise ConfigError(f"--store {path}: no such file or folder")
        try:
            for path in files:
                self._add(path)
        except FuelidError as error:
            self.close()
            raise ConfigError(str(error)) from None
        self.scan(force=True)
        if prefetch_reports:
            from fuelid.dashboard._window_report import ReportPrefetcher

            self._prefetch = ReportPrefetcher(self.local_loops).start()

    def _add(self, path: Path) -> None:
        key = path.resolve()
        if key in self._files:
            return
        loop = self._opener(path)
        other = self._loops.get(loop.loop_id)
        if other is not None:
            loop.close()
            raise ConfigError(
                f"{path.name}: loop id {loop.loop_id!r} is already shown (another store has "
                "it); give each loop its own [site] loop_id"
            )
        self._loops[loop.loop_id] = loop
        self._files[key] = loop.loop_id

    def scan(self, force: bool = False) -> None:
        """Open the stores that appeared in the watched folders (at most every few seconds)."""
        now = time.monotonic()
        if not force and now - self._scanned < WATCH_EVERY_S:
            return
        self._scanned = now
        for folder in self.folders:
            for path in sorted(folder.glob("*.db")):
                key = path.resolve()
                try:
                    mtime = path.stat().st_mtime
                except OSError:
                    continue
                if key in self._files or self._tried.get(key) == mtime:
                    continue
                with self._lock:
                    try:
                        self._add(path)
                        self.refused.pop(path.name, None)
                    except FuelidError as error:
                        self._tried[key] = mtime
                        self.refused[path.name] = named_by_file(str(error), path)

    def local_loops(self) -> list[LoopReader]:
        """The loops of the local stores now (not the central store's)."""
        with self._lock:
            return list(self._loops.values())

    def _central_ids(self) -> list[str]:
        """The central loops shown: reachable, and not shadowed by a local store."""
        if self.central is None:
            return []
        ids = self.central.ids()  # polls (and so notices a store that is back)
        if self.central.error is not None:
            return []
        return [i for i in ids if i not in self._loops]

    def ids(self) -> list[str]:
        """The loop ids shown, sorted (local stores and the central store's loops)."""
        self.scan()
        return sorted([*self._loops, *self._central_ids()])

    def get(self, loop_id: str) -> LoopReader | None:
        """The loop with this id (a local store first); None when there is none."""
        self.scan()
        loop = self._loops.get(loop_id)
        if loop is None and self.central is not None:
            return self.central.get(loop_id)
        return loop

    def not_shown(self) -> dict[str, str]:
        """What is not shown, and why: stores refused, central loops shadowed or unreachable."""
        out = dict(self.refused)
        if self.central is None:
            return out
        ids = self.central.ids()
        for loop_id in ids:
            name = f"central loop {loop_id}"
            if loop_id in self._loops:
                out[name] = (
                    "a local store has this loop id: shown from the local store (read live; "
                    "an action there is applied at once, not relayed)"
                )
            elif self.central.error is not None:
                out[name] = f"the central store is unreachable: {self.central.error}"
        for loop_id, reason in self.central.skipped.items():
            out[f"central loop {loop_id}"] = reason
        return out

    def close(self) -> None:
        """Close every store (and the central connection); the prefetch stops first."""
        prefetch, self._prefetch = self._prefetch, None
        if prefetch is not None:
            prefetch.stop()
        for loop in self._loops.values():
            loop.close()
        self._loops.clear()
        self._files.clear()
        if self.central is not None:
            self.central.close()
