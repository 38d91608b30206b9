"""The answer to a page that does not exist: an HTML page with a way back, not raw JSON.

A page route (any path outside ``/api/`` and ``/static/``) that raises a 404 (an unknown loop,
a window the loop does not have, a path no route serves), or whose path does not parse (a
window number that is not a number: no such page either), answers the dashboard's own page
(``templates/not_found.html.j2``, which extends ``base.html.j2``; autoescaped, so the reason,
which may repeat the path a browser asked for, is text) with status 404 and a link back to the
fleet. Under ``/api/`` and ``/static/``, and for every other status, the answer is FastAPI's own
(JSON ``{"detail": …}``, the headers kept: a 303 to the login page stays a redirect).
"""

from __future__ import annotations

import html
from collections.abc import Callable
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exception_handlers import (
    http_exception_handler,
    request_validation_exception_handler,
)
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, Response
from starlette.exceptions import HTTPException as StarletteHTTPException

__all__ = ["NOT_FOUND_TEMPLATE", "install_not_found", "is_page_path"]

NOT_FOUND_TEMPLATE = "not_found.html.j2"
"""The page's template, in the dashboard's templates."""

Render = Callable[[str, Request, dict[str, Any]], str]
"""The app's page renderer: template name, request, context → HTML (user and CSRF added)."""


def is_page_path(path: str) -> bool:
    """True for a path a browser shows as a page (not the API, not a static file).

    >>> is_page_path("/loops/nope"), is_page_path("/api/loops/nope/status")
    (True, False)
    >>> is_page_path("/static/common.js")
    False
    """
    return not (path.startswith("/api/") or path.startswith("/static/"))


def _reason(error: StarletteHTTPException) -> str:
    """What was not found, in one line (Starlette's bare "Not Found" said as a sentence)."""
    detail = str(error.detail or "")
    return "There is no such page." if detail in ("", "Not Found") else detail


def _plain_page(reason: str) -> str:
    """The page without the dashboard's look, should the template fail to render."""
    return (
        "<!doctype html><html lang='en'><head><meta charset='utf-8'><title>not found</title>"
        f"</head><body><h1>Not found</h1><p>{html.escape(reason)}</p>"
        "<p><a href='/'>Back to the loops</a></p></body></html>"
    )


def install_not_found(app: FastAPI, render: Render) -> None:
    """Answer a page route's 404 (or unparsable path) with an HTML 404 linking to the fleet.

    Parameters
    ----------
    app : FastAPI
        The dashboard's application.
    render : callable
        The app's page renderer (:data:`Render`).
    """

    def page(request: Request, reason: str) -> HTMLResponse:
        context = {"page_title": "not found", "page": "not-found", "tz": None, "reason": reason}
        try:
            text = render(NOT_FOUND_TEMPLATE, request, context)
        except Exception:  # a 404 must never become a 500: the page without the look
            text = _plain_page(reason)
        return HTMLResponse(text, status_code=404)

    async def on_http(request: Request, error: Exception) -> Response:
        assert isinstance(error, StarletteHTTPException)
        if error.status_code != 404 or not is_page_path(request.url.path):
            return await http_exception_handler(request, error)
        return page(request, _reason(error))

    async def on_invalid(request: Request, error: Exception) -> Response:
        assert isinstance(error, RequestValidationError)
        if not is_page_path(request.url.path) or request.method != "GET":
            return await request_validation_exception_handler(request, error)
        return page(request, "There is no such page.")

    app.add_exception_handler(StarletteHTTPException, on_http)
    app.add_exception_handler(RequestValidationError, on_invalid)
