"""What a reader of one loop reads: its online history and the few facts of its store.

Two places hold a loop's history: the site's store file (:class:`~fuelid.store._online.
OnlineHistory` and :class:`~fuelid.store._sqlite.SQLiteStore`) and the central database
(:class:`fuelid.central.CentralHistory` and :class:`fuelid.central.CentralStoreView`, the rows
one site sent). The readers — the reports of ``fuelid online status|history``
(:mod:`fuelid.online._report`), the dashboard's loop pages — take either through these two
protocols, so that mypy checks that both sources offer the same methods with the same shapes.
Only reads are here: writing the history is the online service's, on the site's file alone.

Times are plant time [s UTC] unless a key says ``wall``; every row is a dict with the keys
:class:`~fuelid.store._online.OnlineHistory` documents.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any, Protocol

__all__ = ["LoopHistory", "LoopStore"]


class LoopHistory(Protocol):
    """What the readers of a loop's online history call (see the module docstring)."""

    def windows(
        self, t_from: float | None = None, t_to: float | None = None, limit: int | None = None
    ) -> list[dict[str, Any]]:
        """Windows ending in ``[t_from, t_to)`` [plant s], oldest first; the newest ``limit``."""
        ...

    def window(self, window_id: int) -> dict[str, Any] | None:
        """One window as :meth:`windows` gives it; None when absent."""
        ...

    def windows_of_models(self, model_ids: Sequence[int]) -> list[dict[str, Any]]:
        """The first window naming each of ``model_ids``, as :meth:`windows` gives it, by id."""
        ...

    def last_window(self) -> dict[str, Any] | None:
        """The newest window; None when none."""
        ...

    def accepted_models(self, limit: int | None = None) -> list[dict[str, Any]]:
        """The models, oldest first (by their window's end); the newest ``limit``."""
        ...

    def model(self, model_id: int) -> dict[str, Any] | None:
        """One model as :meth:`accepted_models` gives it; None when absent."""
        ...

    def plant_now(self) -> float | None:
        """Plant time now: the newest sample's time [s UTC]; None without one."""
        ...

    def writes(self, limit: int | None = None) -> list[dict[str, Any]]:
        """Writes of gains, oldest first; the newest ``limit``."""
        ...

    def proposals(self, status: str | Sequence[str] | None = None) -> list[dict[str, Any]]:
        """Proposals, oldest first: all, or those of ``status`` (one or several)."""
        ...

    def proposal(self, proposal_id: int) -> dict[str, Any] | None:
        """One proposal; None when absent."""
        ...

    def requests(self, status: str | None = None, limit: int | None = None) -> list[dict[str, Any]]:
        """People's requests, oldest first: all or those of ``status``; the newest ``limit``."""
        ...

    def counts(self) -> dict[str, int]:
        """Windows, accepted, models, and proposals and writes in all and by status."""
        ...

    def state(self, key: str, default: Any = None) -> Any:
        """The ``online_state`` value of ``key`` (decoded); ``default`` when never set."""
        ...


class LoopStore(Protocol):
    """What the readers of a loop read of its store beside the history (module docstring)."""

    @property
    def path(self) -> str | None:
        """The store's file; None when there is none here (a loop of the central database)."""
        ...

    @property
    def site_name(self) -> str:
        """The site's name (``[site] name``)."""
        ...

    @property
    def tag_map_hash(self) -> str:
        """SHA-256 of the site's tag map."""
        ...

    def newest_sample_clocks(self) -> tuple[float, float] | None:
        """The newest sample's plant and wall time [s UTC] (wall NaN when unknown); None."""
        ...

    def last_event(self, kinds: Iterable[str]) -> tuple[float, str, str, float | None] | None:
        """The newest event of one of ``kinds``: (time, kind, detail, wall_time); None."""
        ...

    def read_event_rows(self) -> list[dict[str, object]]:
        """Every event, oldest first: ``time``, ``kind``, ``detail``, ``wall_time``."""
        ...
