"""The dashboard's actions: the requests an engineer files, and what happens to each next.

``POST /api/loops/{loop}/proposals/{id}/approve`` and ``…/reject``, ``POST /api/loops/{loop}/
revert`` and the test signal's ``POST /api/loops/{loop}/excitation/start`` and ``…/stop``
(issue 40) each file a request in the loop's store (or, for a central loop, a central request
the site fetches) with the engineer's name and reason, exactly as ``fuelid online approve|
reject|revert|excite`` do; the running service carries it out (:mod:`fuelid.online._requests`).
Every one needs an engineer's session and its CSRF token (``Security.require_engineer``); a
viewer gets 403. ``GET /api/loops/{loop}/requests`` lists them with their outcome.
"""

from __future__ import annotations

import asyncio
from typing import Any

from fastapi import HTTPException, Request
from fastapi.responses import JSONResponse

from fuelid.dashboard._board import Dashboard
from fuelid.dashboard._security import form_fields
from fuelid.dashboard._source import LoopReader
from fuelid.dashboard._views import site_warning
from fuelid.errors import FuelidError
from fuelid.io import format_time

__all__ = ["EXCITE_ACTIONS", "action_routes", "next_step", "seen_of"]

EXCITE_ACTIONS = ("excite_start", "excite_stop")
"""The test signal's requests (``fuelid.online._requests.EXCITE_KINDS``); on a central loop
relayed like a revert (central schema version 4)."""


def action_routes(board: Dashboard) -> None:
    """The actions (requests an engineer files: approve, reject, revert, the test signal)."""
    app, viewer, engineer, get_loop = board.app, board.viewer, board.engineer, board.get_loop
    security = board.security

    async def _request(
        loop_id: str,
        kind: str,
        proposal_id: int | None,
        request: Request,
        *,
        why_required: bool = False,
    ) -> JSONResponse:
        user = security.current_user(request)
        if user is None:  # require_engineer let it through: cannot happen
            raise HTTPException(401, "an engineer's login is required")
        loop = get_loop(loop_id)
        fields = await form_fields(request)
        why = fields.get("why", "").strip()[:500]
        if why_required and not why:
            raise HTTPException(422, f"a reason (form field why) is required for {kind}")
        seen = seen_of(fields)
        try:  # waits up to two of the service's beats for it: off the event loop
            row = await asyncio.to_thread(
                loop.file_request, kind, proposal_id, user.name, why or "(no reason given)", seen
            )
        except FuelidError as error:
            return JSONResponse({"error": " ".join(str(error).split())}, status_code=409)
        if row.get("status") == "refused":
            return JSONResponse({"request": row, "error": row.get("outcome")}, status_code=409)
        return JSONResponse({"request": row, "next": next_step(loop, row)})

    @app.post("/api/loops/{loop_id}/proposals/{proposal_id}/approve", dependencies=[engineer])
    async def api_approve(loop_id: str, proposal_id: int, request: Request) -> JSONResponse:
        """An engineer approves a pending proposal (form field ``why``): a request."""
        return await _request(loop_id, "approve", proposal_id, request)

    @app.post("/api/loops/{loop_id}/proposals/{proposal_id}/reject", dependencies=[engineer])
    async def api_reject(loop_id: str, proposal_id: int, request: Request) -> JSONResponse:
        """An engineer rejects a pending or approved proposal (form field ``why``)."""
        return await _request(loop_id, "reject", proposal_id, request)

    @app.post("/api/loops/{loop_id}/revert", dependencies=[engineer])
    async def api_revert(loop_id: str, request: Request) -> JSONResponse:
        """An engineer asks the service to write the last-known-good gains back (``why``)."""
        return await _request(loop_id, "revert", None, request)

    @app.post("/api/loops/{loop_id}/excitation/start", dependencies=[engineer])
    async def api_excite_start(loop_id: str, request: Request) -> JSONResponse:
        """An engineer asks the service to start a test signal now (``why`` required).

        Refused (409, one line) when the site has no ``[write.excitation]`` register or no
        amplitude, or no service runs; the service may still hold it off (the loop not in
        AUTO, a run on, …): the loop page's test-signal line says so. On a central loop it is
        relayed like a revert: the site's service fetches it at its next sync and starts the
        signal or refuses it with the reason (the loop's central requests say which).
        """
        return await _request(loop_id, "excite_start", None, request, why_required=True)

    @app.post("/api/loops/{loop_id}/excitation/stop", dependencies=[engineer])
    async def api_excite_stop(loop_id: str, request: Request) -> JSONResponse:
        """An engineer asks the service to stop the test signal at once (``why`` optional).

        A stop is never held up for want of a reason: the register goes to 0 at the service's
        next look (with no service running, the PLC already holds it at 0). On a central loop
        it is relayed like a revert, at the site's next sync.
        """
        return await _request(loop_id, "excite_stop", None, request)

    @app.get("/api/loops/{loop_id}/requests", dependencies=[viewer])
    def api_requests(loop_id: str) -> dict[str, Any]:
        """The requests people filed, newest last, with their outcome."""
        return {"requests": get_loop(loop_id).requests()}


def seen_of(fields: dict[str, str]) -> dict[str, Any] | None:
    """The proposal as the page showed it (``seen_status``, ``seen_history_len`` form fields).

    >>> seen_of({"seen_status": "pending", "seen_history_len": "1"})
    {'status': 'pending', 'history_len': 1}
    >>> seen_of({"why": "x"}) is None
    True
    """
    status = fields.get("seen_status", "").strip()[:32] or None
    length = fields.get("seen_history_len", "").strip()
    history_len = int(length) if length.isdigit() and len(length) < 7 else None
    if status is None and history_len is None:
        return None
    return {"status": status, "history_len": history_len}


def next_step(loop: LoopReader, request: dict[str, Any]) -> str:
    """What happens to a request next, in one sentence."""
    status = loop.status()
    if request.get("relayed"):
        text = (
            "relayed through the central store: the site's service fetches it at its next sync "
            "and carries it out (or refuses it if the proposal changed meanwhile); it expires "
            f"unapplied at {format_time(request.get('expires'), 'UTC')} (wall clock) if the site "
            "does not fetch it by then"
        )
        warning = site_warning(status, request.get("expires"), "UTC")
        return text if warning is None else f"{text}. Warning: {warning}"
    state = (status.get("link") or {}).get("state")
    if request.get("status") == "done":
        done = str(request.get("outcome") or "done")
        if state == "stopped" and request.get("kind") == "approve":
            return done + "; the service is stopped: written when it runs again"
        return done
    return "filed; the service carries it out at its next beat (a few seconds)"
