"""The dashboard's web application: the pages, the JSON API and the live stream.

Pages (HTML, rendered by Jinja2 with autoescape: every stored string is escaped):

- ``/``: the fleet, one row per loop with its status chips, sorted by severity
  (:mod:`fuelid.dashboard._fleet`);
- ``/loops/{loop_id}``: one loop (live trend, model history, K against fuel temperature, gains
  over time, proposals with their actions, health, windows, events);
- ``/loops/{loop_id}/windows/{window_id}``: one window (data against the model, residuals and
  their autocorrelation, every gate against its threshold, the article's step-ls model, the
  robustness checks behind its proposal) and ``…/report``: the HTML report of that window.

A loop is a store file or a loop of the central store (``--central``): both are read through
:class:`~fuelid.dashboard._source.LoopReader`, so every page is the same; a central store that
cannot be read answers 503 with the reason on its loops' pages, and the fleet page says so while
serving the local loops.

The API under ``/api/`` returns the same data as JSON, built by the functions ``fuelid online
status --json`` and ``history --json`` use (one shape, not two); FastAPI's OpenAPI page is
``/api/docs`` (Swagger UI). The live trend is drawn by uPlot, the analysis charts by plotly.js's
basic bundle (scatter traces), loaded only when they are scrolled into view; uPlot, plotly.js and
Swagger UI are vendored in ``static/vendor/`` (:func:`~fuelid.dashboard._static_files.vendored`):
nothing comes from the internet, and no WebGL trace is used. Static files are compressed once
and cached (:mod:`fuelid.dashboard._static_files`); pages and JSON answers are gzip-compressed
when large; the event stream is not. The actions (approve, reject, revert, the test signal's
start and stop) are :mod:`fuelid.dashboard._actions`.
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path
from typing import Any

from fastapi import FastAPI, HTTPException, Request
from fastapi.responses import HTMLResponse, JSONResponse, Response
from fastapi.sse import EventSourceResponse, ServerSentEvent
from starlette.middleware.gzip import GZipMiddleware

from fuelid import __version__
from fuelid.central import CentralError
from fuelid.dashboard._actions import action_routes
from fuelid.dashboard._board import Dashboard, loop_summary
from fuelid.dashboard._loop_page import PARTS, loop_context
from fuelid.dashboard._registry import Loops
from fuelid.dashboard._security import Security, add_security_headers, auth_router
from fuelid.dashboard._source import LoopReader
from fuelid.dashboard._static_files import StaticFiles
from fuelid.dashboard._trend import trend
from fuelid.dashboard._views import fmt_num
from fuelid.io import format_time

__all__ = ["GZIP_MIN_BYTES", "TREND_MINUTES", "create_app"]

STATIC = "static"
TREND_MINUTES = 10
"""The live trend's span by default [min] (``fuelid dashboard --trend-minutes``)."""
GZIP_MIN_BYTES = 2048
"""Pages and JSON answers larger than this are gzip-compressed [bytes]."""
TEMPLATES = "templates"


def create_app(
    loops: Loops,
    security: Security,
    *,
    title: str = "fuelid",
    trend_minutes: float = TREND_MINUTES,
) -> Any:
    """The FastAPI application over ``loops`` (see the module docstring).

    ``trend_minutes``: the span the loop page's live trend follows [min].
    """
    import jinja2

    from fuelid.dashboard._not_found import install_not_found  # a page's 404: an HTML page

    package = resources.files("fuelid.dashboard")
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(package / TEMPLATES)),
        autoescape=jinja2.select_autoescape(default=True, default_for_string=True),
        undefined=jinja2.ChainableUndefined,  # a key a store lacks shows as nothing
    )
    app = FastAPI(
        title=f"{title} dashboard",
        version=__version__,
        docs_url=None,  # FastAPI's own page loads Swagger UI from a CDN: served locally below
        openapi_url="/api/openapi.json",
        redoc_url=None,
    )
    env.filters["when"] = format_time
    env.filters["num"] = fmt_num
    # the vendored Swagger UI (4.x) reads OpenAPI 3.0 documents
    app.openapi_version = "3.0.3"
    app.state.loops = loops
    app.state.security = security
    static_files = StaticFiles(Path(str(package / STATIC)))
    env.globals["static"] = static_files.url
    # the event stream is never compressed (Starlette leaves text/event-stream alone)
    app.add_middleware(GZipMiddleware, minimum_size=GZIP_MIN_BYTES)
    add_security_headers(app)
    app.include_router(auth_router(security))
    board = Dashboard(app, loops, security, env, title, trend_minutes, static_files)

    @app.exception_handler(CentralError)
    def central_unreachable(request: Request, error: CentralError) -> JSONResponse:
        """A central loop whose store cannot be read now: 503 with the reason."""
        return JSONResponse({"detail": " ".join(str(error).split())}, status_code=503)

    install_not_found(app, board.render)
    _static_routes(board)
    _page_routes(board)
    _data_routes(board)
    action_routes(board)
    return app


def _static_routes(board: Dashboard) -> None:
    """The favicon, the OpenAPI page and the static files (compressed, cached)."""
    app, viewer, page = board.app, board.viewer, board.page
    static_files = board.static_files

    @app.get("/favicon.ico", include_in_schema=False)
    def favicon() -> Response:
        return Response(status_code=204)  # no icon (a 404 would be a console error)

    @app.get(
        "/api/docs", response_class=HTMLResponse, include_in_schema=False, dependencies=[viewer]
    )
    def api_docs(request: Request) -> HTMLResponse:
        """The OpenAPI page: the vendored Swagger UI, no CDN."""
        return page("api_docs.html.j2", request, page_title="API", page="api", tz="UTC")

    @app.get("/static/{name:path}", include_in_schema=False)
    def static(name: str, request: Request) -> Response:
        """A static file, gzipped when the browser takes it, with its ETag; cached a week."""
        return static_files.response(  # type: ignore[no-any-return]
            name, request.headers.get("accept-encoding", ""), request.headers.get("if-none-match")
        )


def _page_routes(board: Dashboard) -> None:
    """The fleet, loop and window pages, the loop page's live parts, the window's report."""
    app, viewer, page, part = board.app, board.viewer, board.page, board.render
    get_loop, is_engineer, window_json = board.get_loop, board.is_engineer, board.window_json
    fleet_rows, central_state = board.fleet_rows, board.central_state
    trend_minutes = board.trend_minutes

    @app.get("/", response_class=HTMLResponse, include_in_schema=False, dependencies=[viewer])
    def fleet_page(request: Request) -> HTMLResponse:
        rows, not_shown = fleet_rows()
        zones = {row["timezone"] for row in rows}
        tz = zones.pop() if len(zones) == 1 else None  # several zones: each loop its own
        return page(
            "fleet.html.j2",
            request,
            page_title="Loops",
            page="fleet",
            tz=tz,
            rows=rows,
            refused=not_shown,
            central=central_state(),
        )

    @app.get(
        "/loops/{loop_id}",
        response_class=HTMLResponse,
        include_in_schema=False,
        dependencies=[viewer],
    )
    def loop_page(request: Request, loop_id: str) -> HTMLResponse:
        loop = get_loop(loop_id)
        context = loop_context(loop, engineer=is_engineer(request))
        identity = context["lp"]
        return page(
            "loop.html.j2",
            request,
            page_title=loop.loop_id,
            page="loop",
            # a central loop without its raw samples: a one-line hint instead of an empty chart
            no_samples=identity.get("source") == "central" and loop.span() is None,
            summary=loop_summary(loop, context["status"]),
            relayed=central_request_rows(context["status"], context["tz"]),
            trend_minutes=f"{trend_minutes:g}",
            **context,
        )

    @app.get("/loops/{loop_id}/parts", include_in_schema=False, dependencies=[viewer])
    def loop_parts(request: Request, loop_id: str) -> dict[str, Any]:
        """The loop page's live parts as HTML, rendered as on the first view (loop_page)."""
        loop = get_loop(loop_id)
        context = loop_context(loop, engineer=is_engineer(request))
        context["relayed"] = central_request_rows(context["status"], context["tz"])
        html = {name: part(f"part_{name}.html.j2", request, context) for name in PARTS}
        # the chips from the same snapshot: after an action the page shows one state at once
        status = loop_summary(loop, context["status"])
        return {"html": html, "link_bands": context["link_bands"], "status": status}

    @app.get(
        "/loops/{loop_id}/windows/{window_id}",
        response_class=HTMLResponse,
        include_in_schema=False,
        dependencies=[viewer],
    )
    def window_page(request: Request, loop_id: str, window_id: int) -> HTMLResponse:
        loop = get_loop(loop_id)
        evidence = window_json(loop, window_id)
        units = evidence.get("gain_units") or {}
        return page(
            "window.html.j2",
            request,
            page_title=f"window {window_id}",
            page="window",
            tz=evidence["timezone"],
            lp=loop.identity(),
            w=evidence,
            units={"Kc": units.get("Kc", ""), "Ti": units.get("Ti", "")},
        )

    @app.get(
        "/loops/{loop_id}/windows/{window_id}/report",
        response_class=HTMLResponse,
        include_in_schema=False,
        dependencies=[viewer],
    )
    def window_report(loop_id: str, window_id: int) -> HTMLResponse:
        from fuelid.dashboard._window_report import window_report_html

        loop = get_loop(loop_id)
        row = loop.window(window_id)
        if row is None:
            raise HTTPException(404, f"no window {window_id} in loop {loop_id!r}")
        return HTMLResponse(window_report_html(loop, row))


def _data_routes(board: Dashboard) -> None:
    """The JSON API's reads: loops, status, history, trend, window, the event stream."""
    app, viewer, get_loop = board.app, board.viewer, board.get_loop
    fleet_rows, central_state, window_json = (
        board.fleet_rows,
        board.central_state,
        board.window_json,
    )
    feeds, trend_minutes = board.feeds, board.trend_minutes

    @app.get("/api/loops", dependencies=[viewer])
    def api_loops() -> dict[str, Any]:
        """Every loop's fleet row, most severe first; what is not shown, with the reason.

        ``central``: the central store's (redacted) URL and why it cannot be read now (None
        while it can); None without ``--central``.
        """
        rows, not_shown = fleet_rows()
        return {"loops": rows, "refused": not_shown, "central": central_state()}

    @app.get("/api/loops/{loop_id}/status", dependencies=[viewer])
    def api_status(loop_id: str) -> dict[str, Any]:
        """The loop now: the object ``fuelid online status --json`` prints."""
        return get_loop(loop_id).status()

    @app.get("/api/loops/{loop_id}/history", dependencies=[viewer])
    def api_history(loop_id: str, windows: int | None = None) -> dict[str, Any]:
        """Everything the service did: the object ``fuelid online history --json`` prints.

        ``windows``: only the newest this many windows (``counts`` still counts them all).
        """
        if windows is not None and windows < 1:
            raise HTTPException(422, "windows must be at least 1")
        return get_loop(loop_id).history(windows)

    @app.get("/api/loops/{loop_id}/trend", dependencies=[viewer])
    def api_trend(
        loop_id: str,
        start: float | None = None,
        end: float | None = None,
        width: int = 1000,
        minutes: float | None = None,
    ) -> dict[str, Any]:
        """Samples in [start, end) [plant s] thinned for a chart ``width`` pixels wide.

        Without ``start``/``end``: the newest ``minutes`` (the dashboard's --trend-minutes).
        """
        loop = get_loop(loop_id)
        span = loop.span()
        if span is None:
            return {
                "source": "none",
                "series": {},
                "bad": [],
                "points": 0,
                "start": None,
                "end": None,
            }
        stop = span[1] + 1e-6 if end is None else end
        back = 60.0 * (trend_minutes if minutes is None else minutes)
        begin = max(span[0], stop - back) if start is None else start
        if not (math.isfinite(begin) and math.isfinite(stop) and stop > begin):
            raise HTTPException(422, "start and end must be finite with end > start")
        return dict(trend(loop, begin, stop, width))

    @app.get("/api/loops/{loop_id}/windows/{window_id}", dependencies=[viewer])
    def api_window(loop_id: str, window_id: int) -> dict[str, Any]:
        """One window: its record, data against the model, residual ACF, gates, proposals."""
        return window_json(get_loop(loop_id), window_id)

    @app.get(
        "/api/loops/{loop_id}/stream", response_class=EventSourceResponse, dependencies=[viewer]
    )
    async def api_stream(loop_id: str, request: Request):  # type: ignore[no-untyped-def]
        """Server-sent events: ``samples``, ``status``, ``history`` (fuelid.dashboard._stream)."""
        loop = get_loop(loop_id)
        async for kind, data in feeds.events(loop, lambda: stream_summary(loop)):
            if await request.is_disconnected():
                break
            yield ServerSentEvent(event=kind, data=data)


def stream_summary(loop: LoopReader) -> dict[str, Any]:
    """The stream's ``status`` event; a central store lost meanwhile is said, not raised."""
    try:
        return loop_summary(loop)
    except CentralError as error:
        text = " ".join(str(error).split())
        return {"chips": [], "link": {"state": "no_contact", "text": text}, "link_text": text}


def central_request_rows(status: dict[str, Any], tz: str) -> list[dict[str, Any]]:
    """The loop's central requests as the loop page lists them (newest first)."""
    out = []
    for r in reversed((status.get("central") or {}).get("requests") or []):
        what = r["kind"] + ("" if r.get("proposal_id") is None else f" #{r['proposal_id']}")
        if r["status"] == "waiting":
            state = (
                "fetched by the site, being carried out"
                if r.get("fetched") is not None
                # the table's header names the clock (the wall clock) and the zone
                else f"waiting for the site's next sync (expires {format_time(r['expires'], tz)})"
            )
        else:
            state = f"{r['status']}: {r.get('outcome') or ''}".rstrip(": ")
        out.append({**r, "what": what, "state": state, "filed": format_time(r["created"], tz)})
    return out
