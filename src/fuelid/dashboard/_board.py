"""What the dashboard's routes share: :class:`Dashboard`, and a loop's fleet row.

:class:`Dashboard` holds the loops, the logins, the templates, the static files and the live
feeds; :func:`loop_summary` is a loop's row of the fleet page (and the stream's status event).

:func:`fuelid.dashboard._app.create_app` builds one :class:`Dashboard` and hands it to each group
of routes (the pages and the data in :mod:`fuelid.dashboard._app`, the actions in
:mod:`fuelid.dashboard._actions`); they all import it from here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from fastapi import Depends, FastAPI, HTTPException, Request
from fastapi.responses import HTMLResponse

from fuelid.central import CentralError
from fuelid.dashboard._fleet import fleet_row
from fuelid.dashboard._registry import Loops
from fuelid.dashboard._security import Security
from fuelid.dashboard._source import LoopReader
from fuelid.dashboard._static_files import StaticFiles
from fuelid.dashboard._stream import Feeds
from fuelid.dashboard._views import link_line_state, link_text

__all__ = ["RECENT_HEALTH", "Dashboard", "loop_summary"]

RECENT_HEALTH = 30
"""Windows whose IAE per unit step form a loop's own median (fleet chip)."""


def _recent_iae(windows: list[dict[str, Any]]) -> list[float]:
    out = []
    for row in windows:
        health = (row.get("detail") or {}).get("health") or {}
        value = health.get("iae_per_unit_step_s")
        if isinstance(value, int | float) and math.isfinite(value):
            out.append(float(value))
    return out


def loop_summary(loop: LoopReader, status: dict[str, Any] | None = None) -> dict[str, Any]:
    """A loop's fleet row: identity, status chips, severity (``status`` when already read)."""
    status = loop.status() if status is None else status
    identity = loop.identity()
    windows = loop.recent_windows(RECENT_HEALTH)
    # the windows also date the proposals (the out-of-date rule: views.proposal_state)
    row = fleet_row(loop.loop_id, identity["site_name"], status, _recent_iae(windows), windows)
    row["link"] = status.get("link")
    row["timezone"] = status.get("timezone", "UTC")
    row["link_text"] = link_text(status, row["timezone"])
    row["link_state"] = link_line_state(status)  # the line's colour: grey once it is not fresh
    # the stream's typed events compare these and the row's excitation note between two status
    # events (stream.changed_topics)
    row["counts"] = status.get("counts")
    newest = loop.recent_events(1)
    row["newest_event"] = [newest[0]["time"], newest[0]["kind"]] if newest else None
    return row


@dataclass
class Dashboard:
    """What the routes share: the loops, the logins, the templates, the static files, the feeds."""

    app: FastAPI
    loops: Loops
    security: Security
    env: Any
    title: str
    trend_minutes: float
    static_files: StaticFiles
    feeds: Feeds = field(default_factory=Feeds)

    @property
    def viewer(self) -> Any:
        """The dependency of every page and data route (a login where one is required)."""
        return Depends(self.security.require_viewer)

    @property
    def engineer(self) -> Any:
        """The dependency of every action (an engineer's session with its CSRF token)."""
        return Depends(self.security.require_engineer)

    def get_loop(self, loop_id: str) -> LoopReader:
        """The loop ``loop_id``; HTTP 404 when there is none."""
        loop = self.loops.get(loop_id)
        if loop is None:
            raise HTTPException(404, f"no loop {loop_id!r}")
        return loop

    def fleet_rows(self) -> tuple[list[dict[str, Any]], dict[str, str]]:
        """The rows, most severe first, and the loops not shown with the reason."""
        rows = []
        not_shown = self.loops.not_shown()
        for loop_id in self.loops.ids():
            loop = self.loops.get(loop_id)
            if loop is None:
                continue
            try:
                rows.append(loop_summary(loop))
            except CentralError as error:  # lost while listing: the local loops still show
                not_shown[f"central loop {loop_id}"] = " ".join(str(error).split())
        return sorted(rows, key=lambda r: r["sort_key"]), not_shown

    def central_state(self) -> dict[str, Any] | None:
        """The central store as the fleet page shows it (None without ``--central``)."""
        if self.loops.central is None:
            return None
        url, error = self.loops.central.db.shown_url, self.loops.central.error
        if error is not None:  # the banner names the store once
            error = error.removeprefix(f"central store {url}: ")
        return {"url": url, "error": error}

    def is_engineer(self, request: Request) -> bool:
        """The actions are offered to an engineer's session only (the others cannot act)."""
        user = self.security.current_user(request)
        return user is not None and user.role == "engineer"

    def render(self, name: str, request: Request, context: dict[str, Any]) -> str:
        """A template (a page or a part of one) for the request's session."""
        session = self.security.session(request)
        return str(
            self.env.get_template(name).render(
                title=self.title,
                user=self.security.current_user(request),
                csrf=None if session is None else session.csrf,
                login_required=self.security.require_login,
                here=request.url.path,  # "log in" comes back here
                **context,
            )
        )

    def page(self, name: str, request: Request, **context: Any) -> HTMLResponse:
        """The page of template ``name`` for the request's session."""
        return HTMLResponse(self.render(name, request, context))

    def window_json(self, loop: LoopReader, window_id: int) -> dict[str, Any]:
        """A window's page data: the stored window, its gates, evidence and proposals."""
        from fuelid.dashboard._window_view import window_evidence
        from fuelid.online import window_json as stored_window

        row = loop.window(window_id)
        if row is None:
            raise HTTPException(404, f"no window {window_id} in loop {loop.loop_id!r}")
        samples = loop.samples(float(row["t_from"]), float(row["t_to"]))
        status = loop.status()
        settings = ((status.get("service") or {}).get("settings")) or None
        proposals = [
            p
            for p in loop.history()["proposals"]
            if p.get("model_id") is not None and p["model_id"] == row.get("model_id")
        ]
        return {
            "window": stored_window(row),
            "gates_verdict": (row.get("detail") or {}).get("gates"),
            "evidence": window_evidence(row, samples, loop.identity().get("period_s"), settings),
            "proposals": proposals,
            "timezone": status.get("timezone", "UTC"),
            "gain_units": status.get("gain_units") or status.get("gains_units"),
        }
