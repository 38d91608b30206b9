"""The dashboard's security layer: where it listens, who is logged in, what they may do.

- :func:`check_bind`: the dashboard listens on the loopback address unless told otherwise, and a
  non-loopback address needs ``--allow-remote`` (every page then needs a login) and a users file.
- :class:`Sessions` (in :mod:`fuelid.dashboard._sessions`): logged-in browsers, in memory (a
  restart logs everybody out). A session ends after :data:`SESSION_IDLE_S` without a request,
  and at the latest :data:`SESSION_MAX_S` after the login.
- :class:`LoginLimiter` (there too): at most :data:`LOGIN_MAX_FAILURES` failed logins in
  :data:`LOGIN_WINDOW_S` per client address and name together, and :data:`LOGIN_MAX_SHARED` per
  address and per name alone, then HTTP 429 with ``Retry-After``.
- :class:`Security`: the FastAPI dependencies :meth:`~Security.require_viewer` (pages and data)
  and :meth:`~Security.require_engineer` (actions: approve, reject, revert), which also checks the
  session's CSRF token (header :data:`CSRF_HEADER` or form field :data:`CSRF_FIELD`).
- :func:`auth_router`: ``GET``/``POST /login``, ``POST /logout`` and ``GET /api/whoami``.
- :func:`add_security_headers`: the Content-Security-Policy and the other headers on every
  response.

The session cookie :data:`SESSION_COOKIE` is HttpOnly and SameSite=Strict, and Secure when the
request came over HTTPS (directly or through a proxy that sets ``X-Forwarded-Proto: https``).
"""

from __future__ import annotations

import hmac
import ipaddress
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, quote, urlsplit

import jinja2

try:
    from fastapi import APIRouter, HTTPException, Request, status
    from fastapi.responses import HTMLResponse, JSONResponse, RedirectResponse, Response
    from starlette.datastructures import MutableHeaders
    from starlette.types import ASGIApp, Message, Receive, Scope, Send
except ImportError as exc:  # pragma: no cover - the dashboard extra is installed for the tests
    raise ImportError(
        "the dashboard needs fastapi and uvicorn: pip install 'fuelid[dashboard]'"
    ) from exc

# the sessions' names, where the security layer's users found them before they moved
from fuelid.dashboard._sessions import (
    LOGIN_MAX_FAILURES,
    LOGIN_MAX_SHARED,
    LOGIN_WINDOW_S,
    SESSION_IDLE_S,
    SESSION_MAX_S,
    LoginLimiter,
    Session,
    Sessions,
)
from fuelid.dashboard._users import User, UsersFile
from fuelid.errors import ConfigError

__all__ = [
    "CONTENT_SECURITY_POLICY",
    "CSRF_FIELD",
    "CSRF_HEADER",
    "FORM_MAX_BYTES",
    "LOGIN_MAX_FAILURES",
    "LOGIN_MAX_SHARED",
    "LOGIN_WINDOW_S",
    "NOT_ACCEPTED",
    "SECURITY_HEADERS",
    "SESSION_COOKIE",
    "SESSION_IDLE_S",
    "SESSION_MAX_S",
    "LoginLimiter",
    "Security",
    "SecurityHeadersMiddleware",
    "Session",
    "Sessions",
    "add_security_headers",
    "auth_router",
    "check_bind",
    "form_fields",
    "is_https",
    "is_loopback",
    "login_page",
    "safe_next",
]

SESSION_COOKIE = "fuelid_session"
"""The name of the session cookie (HttpOnly, SameSite=Strict, path ``/``)."""

CSRF_HEADER = "X-CSRF-Token"
"""The request header that carries the session's CSRF token on an action."""

CSRF_FIELD = "csrf"
"""The form field that carries the session's CSRF token on an action posted by a form."""


CONTENT_SECURITY_POLICY = (
    "default-src 'self'; img-src 'self' data:; style-src 'self' 'unsafe-inline'; "
    "script-src 'self'; connect-src 'self'; frame-ancestors 'none'"
)
"""The Content-Security-Policy of every response: no inline script, nothing from elsewhere."""

SECURITY_HEADERS = {
    "Content-Security-Policy": CONTENT_SECURITY_POLICY,
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "same-origin",
    "X-Frame-Options": "DENY",
}
"""The headers :func:`add_security_headers` puts on every response (unless already set)."""

FORM_MAX_BYTES = 64 * 1024
"""The largest form body read for its fields (login, CSRF) [bytes]; a larger one has none."""

NOT_ACCEPTED = "name or token not accepted"
"""The one message of a failed login: it never says whether the name exists."""

_LOCAL_HOSTNAMES = frozenset({"localhost", "localhost."})


# ------------------------------------------------------------------------------------------------
# where the dashboard listens


def is_loopback(host: str) -> bool:
    """True for ``localhost``, 127.0.0.0/8 and ::1 (also written ``[::1]``).

    >>> [is_loopback(h) for h in ("127.0.0.1", "127.1.2.3", "::1", "localhost", "0.0.0.0")]
    [True, True, True, True, False]
    """
    text = host.strip()
    if text.lower() in _LOCAL_HOSTNAMES:
        return True
    try:
        address = ipaddress.ip_address(text.removeprefix("[").removesuffix("]"))
    except ValueError:
        return False  # a name other than localhost: it may resolve to anything
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
        return address.ipv4_mapped.is_loopback
    return address.is_loopback


def check_bind(host: str, allow_remote: bool, users_file: Path | None = None) -> None:
    """Refuse an address the dashboard must not listen on.

    Parameters
    ----------
    host
        The address or host name of ``--host``.
    allow_remote
        ``--allow-remote``: listening on a non-loopback address is wanted (every page then needs
        a login).
    users_file
        The users file; with ``allow_remote`` it must exist, or nobody could log in.

    The dashboard's ``require_login`` is ``allow_remote``: every page then needs a login.

    Raises
    ------
    ConfigError
        A non-loopback address without ``allow_remote``, or ``allow_remote`` without a users file
        (on any address: behind a reverse proxy the dashboard listens on the loopback address
        with ``--allow-remote``).
    """
    if not allow_remote:
        if is_loopback(host):
            return
        raise ConfigError(
            f"--host {host} is not a loopback address: the dashboard would be reachable from the "
            "network; give --allow-remote (every page then needs a login; put TLS in front, see "
            "the docs)"
        )
    # --allow-remote, on any address (also the loopback one behind a reverse proxy): logins
    if users_file is None or not Path(users_file).is_file():
        where = "none given" if users_file is None else f"{users_file} does not exist"
        raise ConfigError(
            f"--allow-remote needs a users file ({where}): nobody could log in; create one with "
            "`fuelid dashboard user add NAME --role engineer`"
        )


# ------------------------------------------------------------------------------------------------
# the dependencies


class Security:
    """The dashboard's users, sessions and login limiter, and its FastAPI dependencies.

    Use the dependencies as ``Depends(security.require_viewer)`` on pages and data, and
    ``Depends(security.require_engineer)`` on every action.

    Parameters
    ----------
    users
        The users file, or None when there is none (then nobody can log in: pages may still be
        viewed on the loopback address, no action is possible).
    require_login
        Every page needs a login (``--allow-remote``); otherwise pages are open and only actions
        need an engineer's login.
    clock
        A monotonic clock [s] for sessions and the login limiter (tests give their own).
    """

    def __init__(
        self,
        users: UsersFile | None,
        require_login: bool,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if require_login and users is None:
            raise ConfigError("a login is required but there is no users file: nobody could log in")
        self.users = users
        self.require_login = require_login
        self.sessions = Sessions(clock)
        self.limiter = LoginLimiter(clock)

    def session(self, request: Request) -> Session | None:
        """The live session of the request's cookie, or None.

        A session whose user was removed, or whose token was rotated, since the login ends here.
        """
        sid = request.cookies.get(SESSION_COOKIE)
        session = self.sessions.get(sid)
        if session is None:
            return None
        if not self._still_valid(session):
            self.sessions.drop(session.sid)
            return None
        return session

    def _still_valid(self, session: Session) -> bool:
        if self.users is None:
            return False
        try:
            record = self.users.lookup(session.user)
        except ConfigError:
            return False  # a broken users file lets nobody in
        return (
            record is not None
            and record.role == session.role
            and hmac.compare_digest(record.sha256, session.token_sha256)
        )

    def current_user(self, request: Request) -> User | None:
        """The logged-in user of the request, or None."""
        session = self.session(request)
        return session.as_user() if session is not None else None

    def require_viewer(self, request: Request) -> User | None:
        """Dependency of every page and data route: a user, or None when no login is required.

        Without a login where one is required: a page (HTML) redirects to ``/login?next=…``, a
        route under ``/api/`` answers 401.
        """
        user = self.current_user(request)
        if user is None and self.require_login:
            if request.url.path.startswith("/api/"):
                raise HTTPException(status.HTTP_401_UNAUTHORIZED, "login required")
            target = request.url.path + (f"?{request.url.query}" if request.url.query else "")
            raise HTTPException(
                status.HTTP_303_SEE_OTHER,
                "login required",
                headers={"Location": "/login?next=" + quote(target, safe="")},
            )
        return user

    async def require_engineer(self, request: Request) -> User:
        """Dependency of every action: an engineer's session with its CSRF token.

        401 without a login, 403 for a viewer, 403 without the session's CSRF token (header
        ``X-CSRF-Token`` or form field ``csrf``).
        """
        session = self.session(request)
        if session is None:
            raise HTTPException(status.HTTP_401_UNAUTHORIZED, "an engineer's login is required")
        if session.role != "engineer":
            raise HTTPException(status.HTTP_403_FORBIDDEN, "only an engineer may do this")
        await self._check_csrf(request, session)
        return session.as_user()

    async def require_session(self, request: Request) -> Session:
        """Dependency of an action any logged-in user may take (log out): session and CSRF."""
        session = self.session(request)
        if session is None:
            raise HTTPException(status.HTTP_401_UNAUTHORIZED, "not logged in")
        await self._check_csrf(request, session)
        return session

    async def _check_csrf(self, request: Request, session: Session) -> None:
        given = request.headers.get(CSRF_HEADER)
        if given is None:
            given = (await form_fields(request)).get(CSRF_FIELD)
        if not given or not hmac.compare_digest(given.encode(), session.csrf.encode()):
            raise HTTPException(status.HTTP_403_FORBIDDEN, "missing or wrong CSRF token")


async def form_fields(request: Request) -> dict[str, str]:
    """The fields of a URL-encoded form body (the first value of each); {} for any other body.

    A body over :data:`FORM_MAX_BYTES` is not read (its fields count as missing).

    Parsed here with the standard library, so the dashboard needs no multipart parser: the
    dashboard's forms post ``application/x-www-form-urlencoded`` (an HTML form's default).
    """
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind != "application/x-www-form-urlencoded":
        return {}
    length = request.headers.get("content-length", "")
    if not length.isdigit() or int(length) > FORM_MAX_BYTES:
        return {}  # a browser's form always says its length; a huge body is not read here
    body = (await request.body()).decode("utf-8", "replace")
    return {key: values[0] for key, values in parse_qs(body, keep_blank_values=True).items()}


def safe_next(target: str | None) -> str:
    """Where to go after a login: a local path, never another site (else ``/``).

    >>> safe_next("/loops/a?x=1"), safe_next("//evil.example"), safe_next("https://evil.example")
    ('/loops/a?x=1', '/', '/')
    """
    if not target or not target.startswith("/") or target.startswith(("//", "/\\")):
        return "/"
    if any(ord(c) < 0x20 or c == "\\" for c in target):
        return "/"
    parts = urlsplit(target)
    if parts.scheme or parts.netloc:
        return "/"
    return target


def is_https(request: Request) -> bool:
    """The request came over HTTPS, directly or through a proxy saying so."""
    forwarded = request.headers.get("x-forwarded-proto", "").split(",")[0].strip().lower()
    return request.url.scheme == "https" or forwarded == "https"


# ------------------------------------------------------------------------------------------------
# the login routes

_LOGIN_TEMPLATE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>fuelid dashboard: log in</title>
<style>
body { font-family: system-ui, sans-serif; margin: 0; background: #f4f5f7; color: #1b1f24; }
main { max-width: 22rem; margin: 12vh auto; background: #fff; padding: 1.5rem 2rem;
       border: 1px solid #d0d4da; border-radius: 6px; }
h1 { font-size: 1.2rem; margin-top: 0; }
label { display: block; margin: 0.8rem 0 0.2rem; }
input[type=text], input[type=password] { width: 100%; box-sizing: border-box; padding: 0.4rem; }
button { margin-top: 1.2rem; padding: 0.45rem 1.2rem; }
.message { color: #a4161a; margin: 0.6rem 0; }
</style>
</head>
<body>
<main>
<h1>fuelid dashboard</h1>
{% if message %}<p class="message" role="alert">{{ message }}</p>{% endif %}
<form method="post" action="/login">
<input type="hidden" name="next" value="{{ next }}">
<label for="name">Name</label>
<input type="text" id="name" name="name" value="{{ name }}" autocomplete="username"
       maxlength="64" required autofocus>
<label for="token">Token</label>
<input type="password" id="token" name="token" autocomplete="current-password" required>
<button type="submit">Log in</button>
</form>
</main>
</body>
</html>
"""

_TEMPLATES = jinja2.Environment(autoescape=True, undefined=jinja2.StrictUndefined)
_LOGIN_PAGE = _TEMPLATES.from_string(_LOGIN_TEMPLATE)

_NO_STORE = {"Cache-Control": "no-store"}


def login_page(
    next_path: str, name: str = "", message: str = "", status_code: int = 200
) -> HTMLResponse:
    """The login form (self-contained: no script, no external asset); every value escaped."""
    html = _LOGIN_PAGE.render(next=next_path, name=name, message=message)
    return HTMLResponse(html, status_code=status_code, headers=_NO_STORE)


def auth_router(security: Security) -> APIRouter:
    """The routes ``GET /login``, ``POST /login``, ``POST /logout`` and ``GET /api/whoami``."""
    router = APIRouter()

    @router.get("/login", response_class=HTMLResponse, include_in_schema=False)
    def get_login(request: Request) -> Response:
        return login_page(safe_next(request.query_params.get("next")))

    @router.post("/login", response_class=HTMLResponse, include_in_schema=False)
    async def post_login(request: Request) -> Response:
        fields = await form_fields(request)
        name = fields.get("name", "")[:64]
        token = fields.get("token", "")[:256]
        next_path = safe_next(fields.get("next"))
        address = request.client.host if request.client is not None else "unknown"
        wait = security.limiter.retry_after(address, name)
        if wait is not None:
            seconds = math.ceil(wait)
            page = login_page(
                next_path,
                name,
                f"too many failed logins: try again in {seconds} s",
                status.HTTP_429_TOO_MANY_REQUESTS,
            )
            page.headers["Retry-After"] = str(seconds)
            return page
        user = None
        if security.users is not None:
            try:
                user = security.users.verify(name, token)
            except ConfigError:
                user = None  # a broken users file lets nobody in
        if user is None:
            security.limiter.failure(address, name)
            return login_page(next_path, name, NOT_ACCEPTED, status.HTTP_401_UNAUTHORIZED)
        security.limiter.success(address, name)
        record = security.users.lookup(user.name) if security.users is not None else None
        session = security.sessions.create(user, record.sha256 if record is not None else "")
        old = request.cookies.get(SESSION_COOKIE)
        if old:
            security.sessions.drop(old)
        response = RedirectResponse(next_path, status_code=status.HTTP_303_SEE_OTHER)
        response.set_cookie(
            SESSION_COOKIE,
            session.sid,
            httponly=True,
            samesite="strict",
            secure=is_https(request),
            path="/",
        )
        return response

    @router.post("/logout", include_in_schema=False)
    async def post_logout(request: Request) -> Response:
        session = await security.require_session(request)
        security.sessions.drop(session.sid)
        response = RedirectResponse("/login", status_code=status.HTTP_303_SEE_OTHER)
        response.delete_cookie(
            SESSION_COOKIE, path="/", httponly=True, samesite="strict", secure=is_https(request)
        )
        return response

    @router.get("/api/whoami")
    def whoami(request: Request) -> JSONResponse:
        """Who is logged in, their role, the CSRF token actions must carry, and the login rule."""
        session = security.session(request)
        return JSONResponse(
            {
                "user": session.user if session is not None else None,
                "role": session.role if session is not None else None,
                "csrf": session.csrf if session is not None else None,
                "login_required": security.require_login,
            },
            headers=_NO_STORE,
        )

    return router


# ------------------------------------------------------------------------------------------------
# the headers of every response


class SecurityHeadersMiddleware:
    """ASGI middleware: :data:`SECURITY_HEADERS` on every HTTP response (a route's own win).

    Written at the ASGI level, not with ``BaseHTTPMiddleware``, so streamed responses (the
    server-sent events of a loop's live view) pass through untouched.
    """

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Pass the request on; add the headers to the response's start."""
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = MutableHeaders(scope=message)
                for key, value in SECURITY_HEADERS.items():
                    if key not in headers:
                        headers[key] = value
            await send(message)

        await self.app(scope, receive, send_with_headers)


def add_security_headers(app: Any) -> None:
    """Put the security headers on every response of ``app`` (a FastAPI or Starlette app).

    The Content-Security-Policy allows scripts, styles, images and connections from the
    dashboard itself only (``'self'``; images also as ``data:`` URLs), and no framing. Inline
    ``<script>`` blocks and ``on…=`` attributes are **not** allowed (``script-src 'self'``): pages
    put their scripts in static files served by the dashboard (the vendored libraries
    included, never from a CDN). Inline ``style`` attributes and ``<style>`` blocks are allowed.
    """
    app.add_middleware(SecurityHeadersMiddleware)
