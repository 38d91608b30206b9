"""The dashboard's one read interface to a loop's data, and its SQLite implementation.

Every page and every ``/api/`` answer reads a loop through :class:`LoopReader`: its identity,
its state now (the shape ``fuelid online status --json`` prints), its history (the shape of
``fuelid online history --json``), one window's record and samples, the trend of its samples at a
level of detail, the samples committed after a point (for the live stream) and the requests
people file. The central store implements the same protocol
(:class:`fuelid.dashboard.CentralLoop`: one reader per loop of it); nothing above
these modules knows where the rows come from.

:class:`SQLiteLoop` reads one store file (one loop). It opens the store once as fuelid opens any
store (a store of an older schema is migrated then, as ``fuelid store info`` would; a store of a
newer fuelid is refused with both versions) and reads it through the store's own API
(:class:`~fuelid.store.SQLiteStore`, :class:`~fuelid.store.OnlineHistory`): the only rows the
dashboard writes are the requests it files, through the store's history. Both readers build
their status and history with :func:`loop_status` and :func:`loop_history`, over a
:class:`~fuelid.store.LoopHistory` and a :class:`~fuelid.store.LoopStore`.

Times are plant time (the samples' time base) [s UTC] unless a key says ``wall``; flows in
L/min, the command in V, fuel temperature in °C, the gains in the PLC block's units.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from fuelid.store import (
    SERVICE_KEY,
    LoopHistory,
    LoopStore,
    SampleArrays,
    StoreError,
    default_loop_id,
)

__all__ = [
    "TREND_COLUMNS",
    "LoopReader",
    "SQLiteLoop",
    "Trend",
    "loop_history",
    "loop_status",
    "service_plant_file",
]

TREND_COLUMNS = ("y", "setpoint", "u", "fuel_temperature")
"""The trend's series: flow and setpoint [L/min], VFD command [V], fuel temperature [°C]."""


def service_plant_file(history: LoopHistory) -> str | None:
    """The plant file the loop's service record names (its ``settings.plant_file``), or None."""
    record = history.state(SERVICE_KEY)
    path = ((record or {}).get("settings") or {}).get("plant_file")
    return str(path) if path else None


def without_folders(status: dict[str, Any]) -> dict[str, Any]:
    """``status`` with the service's plant file named without its folder (no page shows a path).

    >>> without_folders({"service": {"settings": {"plant_file": "/srv/p/line2.toml"}}})
    {'service': {'settings': {'plant_file': 'line2.toml'}}}
    """
    service = status.get("service") or {}
    settings = service.get("settings") or {}
    path = settings.get("plant_file")
    if not path:
        return status
    name = str(path).replace("\\", "/").rsplit("/", 1)[-1]  # a Windows service's path too
    return {**status, "service": {**service, "settings": {**settings, "plant_file": name}}}


def loop_status(
    history: LoopHistory, store: LoopStore, loop_id: str, now_wall: float | None = None
) -> dict[str, Any]:
    """The loop now, by :func:`fuelid.online.status_json` (one shape with the CLI).

    As the pages show it: the site names the loop by its id, no file path (nor the plant
    file's folder).
    """
    from fuelid.online import status_json

    out = status_json(history, store, now_wall)
    out["site"] = {**out["site"], "store": None, "loop_id": loop_id}
    return without_folders(out)


def loop_history(
    history: LoopHistory, store: LoopStore, loop_id: str, windows: int | None = None
) -> dict[str, Any]:
    """Everything the service did, by :func:`fuelid.online.history_json` (no file path)."""
    from fuelid.online import history_json

    out = history_json(history, store, windows=windows)
    out["site"] = {**out["site"], "store": None, "loop_id": loop_id}
    return out


class Trend(dict[str, Any]):
    """One trend answer (a plain dict, JSON as it is).

    Keys: ``source`` ("raw" or "lod"), ``level_s`` (bucket width [s], None for raw), ``start``,
    ``end`` [plant s], ``t`` (times [plant s]), one list per :data:`TREND_COLUMNS` (None for a
    missing value), ``bad`` (times of samples not ok, or of buckets that hold one) and ``points``
    (the number of points before thinning).
    """


@runtime_checkable
class LoopReader(Protocol):
    """What the dashboard reads of one loop (a store file, or a loop of the central store)."""

    loop_id: str
    """The loop's id: in URLs, never a file path."""

    def identity(self) -> dict[str, Any]:
        """``loop_id``, ``site_name``, ``schema_version``, ``store_uuid``, ``period_s``."""
        ...

    def status(self, now_wall: float | None = None) -> dict[str, Any]:
        """The loop now, shaped as ``fuelid online status --json``."""
        ...

    def history(self, windows: int | None = None) -> dict[str, Any]:
        """Everything the service did, shaped as ``fuelid online history --json``.

        ``windows``: only the newest this many windows (None: all).
        """
        ...

    def recent_events(self, limit: int) -> list[dict[str, Any]]:
        """The newest ``limit`` events (``time`` [plant s], ``kind``, ``detail``), oldest first."""
        ...

    def plant_file(self) -> str | None:
        """The service's plant file as its host names it; None: the reference plant, no service.

        Only the window's report reads it; no page shows it (``status`` gives its name only).
        """
        ...

    def window(self, window_id: int) -> dict[str, Any] | None:
        """One window's stored row (``detail`` parsed), None when there is no such window."""
        ...

    def recent_windows(self, limit: int) -> list[dict[str, Any]]:
        """The newest ``limit`` windows' stored rows (``detail`` parsed), oldest first."""
        ...

    def windows_of_models(self, model_ids: Sequence[int]) -> list[dict[str, Any]]:
        """The first stored window naming each of ``model_ids`` (a proposal's evidence), by id.

        One bounded read (one row per model at most) however many windows came since.
        """
        ...

    def requests(self) -> list[dict[str, Any]]:
        """The requests people filed (approve, reject, revert), oldest first."""
        ...

    def samples(self, t_from: float, t_to: float) -> SampleArrays:
        """Raw samples with ``t_from <= time < t_to`` [plant s], sorted by time."""
        ...

    def span(self) -> tuple[float, float] | None:
        """First and newest sample time [plant s]; None without samples."""
        ...

    def lod(self, level: int, t_from: float, t_to: float) -> dict[str, np.ndarray[Any, Any]]:
        """Level-of-detail rows of ``level`` seconds in ``[t_from, t_to)`` as arrays."""
        ...

    def samples_after(self, cursor: int, limit: int) -> tuple[int, SampleArrays]:
        """Samples committed after ``cursor`` (an opaque insertion mark), and the new cursor."""
        ...

    def cursor(self) -> int:
        """The insertion mark of the newest committed sample (0 without samples)."""
        ...

    def file_request(
        self,
        kind: str,
        proposal_id: int | None,
        who: str,
        why: str,
        seen: dict[str, Any] | None = None,
    ) -> dict[str, Any]:
        """Record a person's request (approve, reject, revert) for the service to carry out.

        ``seen``: the proposal as the page showed it (``status``, ``history_len``), or None.
        """
        ...

    def close(self) -> None:
        """Release the connections."""
        ...


class SQLiteLoop:
    """One loop's store file behind :class:`LoopReader`.

    Parameters
    ----------
    path : str or Path
        The store (an SQLite file fuelid wrote).

    Raises
    ------
    StoreError
        Not a fuelid store, or one written by a newer fuelid (the reason names both versions).
    """

    def __init__(self, path: str | Path) -> None:
        from fuelid.store import OnlineHistory, SQLiteStore

        self.path = Path(path)
        self.store = SQLiteStore(self.path)  # migrates an older store; refuses a newer one
        try:
            self.online = OnlineHistory(self.store)
        except StoreError as error:
            self.store.close()
            raise StoreError(f"{self.path}: cannot read the store ({error})") from None
        # a loop id is part of URLs: whatever a store holds, only [a-z0-9-] reaches them
        self.loop_id = default_loop_id(self.store.loop_id)

    def close(self) -> None:
        """Close the history and the store."""
        self.online.close()
        self.store.close()

    # --- identity and the service's view -------------------------------------------------

    def identity(self) -> dict[str, Any]:
        """``loop_id``, ``site_name``, ``schema_version``, ``store_uuid``, ``period_s``."""
        return {
            "loop_id": self.loop_id,
            "site_name": self.store.site_name,
            "schema_version": self.store.schema_version,
            "store_uuid": self.store.store_uuid,
            "period_s": self.store.period_s,
        }

    def status(self, now_wall: float | None = None) -> dict[str, Any]:
        """The loop now (:func:`loop_status`)."""
        return loop_status(self.online, self.store, self.loop_id, now_wall)

    def plant_file(self) -> str | None:
        """The service's plant file as its record names it (None: the reference plant)."""
        return service_plant_file(self.online)

    def history(self, windows: int | None = None) -> dict[str, Any]:
        """Everything the service did (:func:`loop_history`)."""
        return loop_history(self.online, self.store, self.loop_id, windows)

    def recent_events(self, limit: int) -> list[dict[str, Any]]:
        """The newest ``limit`` events, oldest first (read newest first, by the time index)."""
        return self.store.newest_events(limit)

    def window(self, window_id: int) -> dict[str, Any] | None:
        """One window's row with its ``detail`` parsed; None when absent."""
        return self.online.window(window_id)

    def recent_windows(self, limit: int) -> list[dict[str, Any]]:
        """The newest ``limit`` windows' stored rows (``detail`` parsed), oldest first."""
        return self.online.windows(limit=int(limit))

    def windows_of_models(self, model_ids: Sequence[int]) -> list[dict[str, Any]]:
        """The first window naming each of ``model_ids`` (its index on ``model_id``), by id."""
        return self.online.windows_of_models(model_ids)

    def requests(self) -> list[dict[str, Any]]:
        """The requests people filed (approve, reject, revert), oldest first."""
        return list(self.online.requests())

    def file_request(
        self,
        kind: str,
        proposal_id: int | None,
        who: str,
        why: str,
        seen: dict[str, Any] | None = None,
    ) -> dict[str, Any]:
        """File a person's request through the store's history (the only write here).

        As ``fuelid online approve|reject|revert``: the running service applies it within a
        beat; with no live service it is applied here at once (the row comes back "done" or
        "refused" with its outcome, or "waiting"). ``seen`` is not needed here: the request is
        decided within a beat of the page, on the proposal's own transitions.
        """
        from fuelid.online import submit_request

        record = self.online.state(SERVICE_KEY) or {}
        write_back = (record.get("settings") or {}).get("write_back") or record.get("write_back")
        return submit_request(
            self.store, self.online, kind, proposal_id, who, why, "dashboard", write_back
        )

    # --- samples ---------------------------------------------------------------------------

    def span(self) -> tuple[float, float] | None:
        """First and newest sample time [plant s]; None without samples."""
        first, last = self.store.first_time(), self.store.last_time()
        return None if first is None or last is None else (first, last)

    def samples(self, t_from: float, t_to: float) -> SampleArrays:
        """Raw samples with ``t_from <= time < t_to`` [plant s], sorted by time."""
        return self.store.read(t_from, t_to)

    def lod(self, level: int, t_from: float, t_to: float) -> dict[str, np.ndarray[Any, Any]]:
        """Level-of-detail rows (``samples_lod``) of ``level`` s in ``[t_from, t_to)``."""
        return self.store.read_lod(level, t_from, t_to)

    def cursor(self) -> int:
        """The rowid of the newest committed sample (0 without samples)."""
        return self.store.newest_rowid()

    def samples_after(self, cursor: int, limit: int) -> tuple[int, SampleArrays]:
        """Samples inserted after rowid ``cursor`` (at most ``limit``, oldest first)."""
        return self.store.samples_after(cursor, limit)
