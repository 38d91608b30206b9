"""The central loops a dashboard lists, on one connection to the central store.

The connection is a :class:`fuelid.central.CentralDB`, shared by every central loop of a
dashboard: one lock, a failure drops it and the next read reconnects, at most every
``retry_s`` (a dead server must not cost every page a connect timeout); several reads run in
one read-only snapshot, so that a loop's status is one moment of the central store.

:class:`CentralLoops` lists the loops of the central database (``loops``), polled every
:data:`~fuelid.dashboard._registry.WATCH_EVERY_S` for new ones, each a
:class:`~fuelid.dashboard.CentralLoop`. When the database is lost, ``error`` says
why (the fleet page's banner) and the loops are listed as not shown until it is back.
"""

from __future__ import annotations

import threading
import time as _time
from pathlib import Path
from typing import TYPE_CHECKING

from fuelid.central import CentralDB, CentralError, central_loop_ids
from fuelid.store import default_loop_id

if TYPE_CHECKING:
    from fuelid.dashboard._central_source import CentralLoop

__all__ = ["CentralLoops"]


class CentralLoops:
    """The loops of the central store, by id (see the module docstring).

    Parameters
    ----------
    url : str
        The central store's libpq URL.
    archive : Path, optional
        The raw archive (the folder ``fuelid archive`` writes) the central loops' trends read.
    every_s : float
        How often the list of loops is read again [s].

    Raises
    ------
    CentralError
        The central store cannot be reached or used at start (one line).
    """

    def __init__(self, url: str, archive: Path | None = None, every_s: float = 5.0) -> None:
        self.db = CentralDB(url)
        self.archive = archive
        self.every_s = float(every_s)
        self._loops: dict[str, CentralLoop] = {}
        self.skipped: dict[str, str] = {}
        self._polled = -float("inf")
        self._lock = threading.Lock()
        self.db.check()
        self.refresh(force=True)

    @property
    def error(self) -> str | None:
        """Why the central store cannot be read now; None while it can."""
        return self.db.error

    def refresh(self, force: bool = False) -> None:
        """Read the list of loops again (at most every ``every_s``); a failure sets ``error``."""
        from fuelid.dashboard._central_source import CentralLoop

        now = _time.monotonic()
        with self._lock:
            if not force and now - self._polled < self.every_s:
                return
            self._polled = now
            try:
                listed = central_loop_ids(self.db)
            except CentralError:
                return  # error set: the fleet page says so
            for loop_id in listed:
                if loop_id in self._loops or loop_id in self.skipped:
                    continue
                if default_loop_id(loop_id) != loop_id:  # a loop id is part of URLs
                    self.skipped[loop_id] = "not a loop id of [a-z0-9-] (it is part of URLs)"
                    continue
                self._loops[loop_id] = CentralLoop(self.db, loop_id, archive=self.archive)

    def ids(self) -> list[str]:
        """The central loop ids, sorted (every loop known, reachable or not)."""
        self.refresh()
        return sorted(self._loops)

    def get(self, loop_id: str) -> CentralLoop | None:
        """The central loop with this id; None when there is none."""
        return self._loops.get(loop_id)

    def close(self) -> None:
        """Close the connection."""
        self.db.close()
