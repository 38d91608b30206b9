"""The dashboard's security layer in a real FastAPI app: logins, roles, CSRF, limits, headers.

Each expectation comes from the dashboard issue: loopback by default and a non-loopback address
only with --allow-remote; under it every page needs a login; an HttpOnly, SameSite=Strict session
cookie; a CSRF token on every action; only engineers act; failed logins rate-limited; every
string a user can put into a page escaped.
"""

# no `from __future__ import annotations`: FastAPI reads the routes' annotations, which name
# dependencies local to make_app
import warnings
from pathlib import Path
from typing import Annotated

import pytest

pytest.importorskip("fastapi", reason="needs the dashboard extra")

from fastapi import Depends, FastAPI

with warnings.catch_warnings():
    # starlette 1.x's test client runs on httpx2 (the dev extra) and warns when it finds only
    # httpx; the dashboard itself needs neither: only the tests use a client
    warnings.filterwarnings("ignore", message=".*install `httpx2` instead", category=Warning)
    from fastapi.testclient import TestClient

from fuelid.dashboard import CSRF_HEADER, Security, UsersFile
from fuelid.dashboard._security import (
    CONTENT_SECURITY_POLICY,
    FORM_MAX_BYTES,
    LOGIN_MAX_FAILURES,
    LOGIN_MAX_SHARED,
    LOGIN_WINDOW_S,
    SESSION_COOKIE,
    SESSION_IDLE_S,
    SESSION_MAX_S,
    add_security_headers,
    auth_router,
    check_bind,
)
from fuelid.dashboard._users import User
from fuelid.errors import ConfigError


class FakeClock:
    """A monotonic clock the test moves by hand [s]."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def make_app(security: Security) -> FastAPI:
    """A tiny dashboard: the auth routes, a page ``GET /x`` and an action ``POST /act``."""
    app = FastAPI()
    add_security_headers(app)
    app.include_router(auth_router(security))

    Viewer = Annotated[User | None, Depends(security.require_viewer)]
    Engineer = Annotated[User, Depends(security.require_engineer)]

    @app.get("/x")
    def page(user: Viewer) -> dict[str, str | None]:
        return {"page": "x", "user": user.name if user else None}

    @app.get("/api/data")
    def data(user: Viewer) -> dict[str, int]:
        return {"value": 1}

    @app.post("/act")
    def act(user: Engineer) -> dict[str, str]:
        return {"done_by": user.name}

    return app


@pytest.fixture
def users(tmp_path: Path) -> UsersFile:
    return UsersFile(tmp_path / "users.json")


@pytest.fixture
def tokens(users: UsersFile) -> dict[str, str]:
    return {"eve": users.add("eve", "engineer"), "vic": users.add("vic", "viewer")}


@pytest.fixture
def clock() -> FakeClock:
    return FakeClock()


def client_for(users: UsersFile | None, require_login: bool, clock: FakeClock) -> TestClient:
    security = Security(users, require_login=require_login, clock=clock)
    return TestClient(make_app(security), follow_redirects=False)


def login(client: TestClient, name: str, token: str, next_path: str = "/x") -> str:
    """Log in; return the CSRF token of the new session."""
    response = client.post("/login", data={"name": name, "token": token, "next": next_path})
    assert response.status_code == 303, response.text
    csrf = client.get("/api/whoami").json()["csrf"]
    assert isinstance(csrf, str)
    return csrf


# -- where it listens -------------------------------------------------------------------------


@pytest.mark.parametrize("host", ["127.0.0.1", "127.0.0.53", "::1", "[::1]", "localhost"])
def test_loopback_addresses_are_fine_without_allow_remote(host: str) -> None:
    check_bind(host, allow_remote=False)


@pytest.mark.parametrize("host", ["0.0.0.0", "::", "192.168.1.5", "tunnel-pc.example"])
def test_other_addresses_are_refused_without_allow_remote(host: str) -> None:
    with pytest.raises(ConfigError) as caught:
        check_bind(host, allow_remote=False)
    assert str(caught.value).startswith(f"--host {host} is not a loopback address")
    assert "--allow-remote" in str(caught.value)


def test_allow_remote_with_a_users_file_is_fine(users: UsersFile, tokens: dict[str, str]) -> None:
    check_bind("0.0.0.0", allow_remote=True, users_file=users.path)


@pytest.mark.parametrize("host", ["0.0.0.0", "127.0.0.1"])
def test_allow_remote_without_a_users_file_is_refused(tmp_path: Path, host: str) -> None:
    # also on the loopback address, where a reverse proxy forwards to a dashboard needing logins
    with pytest.raises(ConfigError, match="nobody could log in"):
        check_bind(host, allow_remote=True, users_file=None)
    with pytest.raises(ConfigError, match="does not exist"):
        check_bind("0.0.0.0", allow_remote=True, users_file=tmp_path / "none.json")


# -- logging in -------------------------------------------------------------------------------


def test_login_sets_an_httponly_samesite_strict_cookie(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    client = client_for(users, True, clock)
    response = client.post("/login", data={"name": "vic", "token": tokens["vic"], "next": "/x"})
    assert response.status_code == 303
    assert response.headers["location"] == "/x"
    cookie = response.headers["set-cookie"]
    assert cookie.startswith(f"{SESSION_COOKIE}=")
    attributes = [part.strip().lower() for part in cookie.split(";")]
    assert "httponly" in attributes
    assert "samesite=strict" in attributes
    assert "path=/" in attributes
    assert "secure" not in attributes  # plain http on the loopback address
    assert client.get("/x").json() == {"page": "x", "user": "vic"}


def test_the_cookie_is_secure_behind_a_tls_proxy(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    client = client_for(users, True, clock)
    response = client.post(
        "/login",
        data={"name": "vic", "token": tokens["vic"]},
        headers={"X-Forwarded-Proto": "https"},
    )
    assert response.status_code == 303
    assert "secure" in [p.strip().lower() for p in response.headers["set-cookie"].split(";")]


def test_a_wrong_token_gets_401_and_a_generic_message(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    client = client_for(users, True, clock)
    wrong = client.post("/login", data={"name": "vic", "token": "guess"})
    unknown = client.post("/login", data={"name": "nobody", "token": "guess"})
    for response in (wrong, unknown):
        assert response.status_code == 401
        assert "name or token not accepted" in response.text
        assert "set-cookie" not in response.headers
    # the same answer whether or not the name exists
    assert wrong.text.replace('value="vic"', "") == unknown.text.replace('value="nobody"', "")


def test_the_sixth_failure_within_the_window_gets_429_with_retry_after(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    client = client_for(users, True, clock)
    for _ in range(LOGIN_MAX_FAILURES):
        assert client.post("/login", data={"name": "vic", "token": "guess"}).status_code == 401
    blocked = client.post("/login", data={"name": "vic", "token": tokens["vic"]})
    assert blocked.status_code == 429
    assert 0 < int(blocked.headers["retry-after"]) <= LOGIN_WINDOW_S
    assert "set-cookie" not in blocked.headers  # even the right token waits
    clock.now += LOGIN_WINDOW_S + 1
    assert client.post("/login", data={"name": "vic", "token": tokens["vic"]}).status_code == 303


def test_failures_for_one_name_from_many_addresses_are_limited(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    security = Security(users, require_login=True, clock=clock)
    for i in range(LOGIN_MAX_SHARED):  # a guess spread over addresses, a few tries from each
        security.limiter.failure(f"10.0.0.{i % 7}", "eve")
    assert security.limiter.retry_after("10.0.0.99", "eve") is not None
    assert security.limiter.retry_after("10.0.0.99", "vic") is None


def test_a_success_does_not_clear_another_addresses_count(clock: FakeClock) -> None:
    security = Security(None, require_login=False, clock=clock)
    limiter = security.limiter
    for _ in range(LOGIN_MAX_FAILURES):
        limiter.failure("10.0.0.1", "a")
    limiter.success("10.0.0.2", "a")
    assert limiter.retry_after("10.0.0.1", "a") is not None


def test_one_persons_typos_do_not_lock_out_the_others_at_the_same_console(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    # issue 39: five typos by one engineer locked every engineer at that console out
    client = client_for(users, True, clock)
    for _ in range(LOGIN_MAX_FAILURES):
        assert client.post("/login", data={"name": "vic", "token": "typo"}).status_code == 401
    assert client.post("/login", data={"name": "vic", "token": tokens["vic"]}).status_code == 429
    other = client.post("/login", data={"name": "eve", "token": tokens["eve"]})
    assert other.status_code == 303  # the same address, another name: let in


def test_an_address_guessing_many_names_is_stopped_at_the_shared_limit(clock: FakeClock) -> None:
    limiter = Security(None, require_login=False, clock=clock).limiter
    assert LOGIN_MAX_SHARED > LOGIN_MAX_FAILURES
    names = [f"user{i}" for i in range(LOGIN_MAX_SHARED)]
    for name in names[:-1]:  # one failure per name: no name reaches its own limit
        limiter.failure("10.0.0.1", name)
        assert limiter.retry_after("10.0.0.1", "nobody-yet") is None
    limiter.failure("10.0.0.1", names[-1])
    wait = limiter.retry_after("10.0.0.1", "nobody-yet")
    assert wait is not None
    assert 0.0 < wait <= LOGIN_WINDOW_S
    assert limiter.retry_after("10.0.0.2", "nobody-yet") is None  # another address is not
    clock.now += LOGIN_WINDOW_S
    assert limiter.retry_after("10.0.0.1", "nobody-yet") is None  # the window slid past


def test_a_success_clears_only_its_own_name_at_its_address(clock: FakeClock) -> None:
    limiter = Security(None, require_login=False, clock=clock).limiter
    for _ in range(LOGIN_MAX_FAILURES):
        limiter.failure("10.0.0.1", "eve")
        limiter.failure("10.0.0.1", "vic")
    limiter.success("10.0.0.1", "eve")
    assert limiter.retry_after("10.0.0.1", "eve") is None
    assert limiter.retry_after("10.0.0.1", "vic") is not None
    # the address's count stays: a guesser's own account does not reset it
    for _ in range(LOGIN_MAX_SHARED - 2 * LOGIN_MAX_FAILURES):
        limiter.failure("10.0.0.1", "mallory")
        limiter.success("10.0.0.1", "mallory")
    assert limiter.retry_after("10.0.0.1", "eve") is not None


def test_next_is_followed_only_to_a_local_path(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    client = client_for(users, True, clock)
    for hostile in ("//evil.example", "https://evil.example/x", "/\\evil.example", "evil"):
        response = client.post(
            "/login", data={"name": "vic", "token": tokens["vic"], "next": hostile}
        )
        assert response.status_code == 303
        assert response.headers["location"] == "/"
    good = client.post("/login", data={"name": "vic", "token": tokens["vic"], "next": "/x?a=1"})
    assert good.headers["location"] == "/x?a=1"


def test_hostile_input_is_escaped_in_the_login_page(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    client = client_for(users, True, clock)
    hostile = "<script>alert(1)</script>"
    page = client.get("/login", params={"next": "/" + hostile})
    assert page.status_code == 200
    assert hostile not in page.text
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page.text
    failed = client.post(
        "/login", data={"name": hostile, "token": "x", "next": '/"><script>alert(1)</script>'}
    )
    assert failed.status_code == 401
    assert hostile not in failed.text
    assert "&lt;script&gt;" in failed.text


# -- pages and actions ------------------------------------------------------------------------


def test_without_require_login_pages_are_open_and_actions_need_an_engineer(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    client = client_for(users, False, clock)
    assert client.get("/x").json() == {"page": "x", "user": None}
    assert client.post("/act").status_code == 401
    assert client.get("/api/whoami").json() == {
        "user": None,
        "role": None,
        "csrf": None,
        "login_required": False,
    }


def test_without_a_users_file_nobody_acts(clock: FakeClock) -> None:
    client = client_for(None, False, clock)
    assert client.get("/x").status_code == 200
    assert client.post("/act").status_code == 401
    assert client.post("/login", data={"name": "a", "token": "b"}).status_code == 401


def test_require_login_without_a_users_file_is_refused(clock: FakeClock) -> None:
    with pytest.raises(ConfigError, match="nobody could log in"):
        Security(None, require_login=True, clock=clock)


def test_with_require_login_a_page_redirects_to_login_and_data_gets_401(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    client = client_for(users, True, clock)
    page = client.get("/x", params={"a": "1"})
    assert page.status_code == 303
    assert page.headers["location"] == "/login?next=%2Fx%3Fa%3D1"
    assert client.get("/api/data").status_code == 401
    assert client.post("/act").status_code == 401
    assert client.get("/api/whoami").json()["login_required"] is True


def test_a_viewer_may_not_act(users: UsersFile, tokens: dict[str, str], clock: FakeClock) -> None:
    client = client_for(users, True, clock)
    csrf = login(client, "vic", tokens["vic"])
    assert client.get("/x").status_code == 200
    assert client.post("/act", headers={CSRF_HEADER: csrf}).status_code == 403


def test_an_engineer_acts_only_with_the_csrf_token(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    client = client_for(users, True, clock)
    csrf = login(client, "eve", tokens["eve"])
    assert client.post("/act").status_code == 403
    assert client.post("/act", headers={CSRF_HEADER: "not-it"}).status_code == 403
    assert client.post("/act", data={"csrf": csrf + "x"}).status_code == 403
    done = client.post("/act", headers={CSRF_HEADER: csrf})
    assert done.status_code == 200
    assert done.json() == {"done_by": "eve"}
    assert client.post("/act", data={"csrf": csrf}).status_code == 200  # a form's field


def test_a_form_too_large_to_read_carries_no_csrf_token(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    client = client_for(users, True, clock)
    csrf = login(client, "eve", tokens["eve"])
    padding = "x" * FORM_MAX_BYTES
    assert client.post("/act", data={"csrf": csrf, "note": padding}).status_code == 403


def test_actions_need_an_engineer_even_on_loopback_without_require_login(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    client = client_for(users, False, clock)
    csrf = login(client, "eve", tokens["eve"])
    assert client.post("/act", headers={CSRF_HEADER: csrf}).status_code == 200


def test_logout_needs_the_csrf_token_and_ends_the_session(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    client = client_for(users, True, clock)
    csrf = login(client, "eve", tokens["eve"])
    assert client.post("/logout").status_code == 403
    assert client.get("/x").status_code == 200
    out = client.post("/logout", headers={CSRF_HEADER: csrf})
    assert out.status_code == 303
    assert out.headers["location"] == "/login"
    assert client.get("/x").status_code == 303


def test_sessions_expire_when_idle_and_at_the_latest_after_seven_days(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    assert SESSION_IDLE_S == 12 * 3600
    assert SESSION_MAX_S == 7 * 24 * 3600
    client = client_for(users, True, clock)
    login(client, "vic", tokens["vic"])
    clock.now += SESSION_IDLE_S - 60
    assert client.get("/x").status_code == 200
    clock.now += SESSION_IDLE_S + 1
    assert client.get("/x").status_code == 303
    login(client, "vic", tokens["vic"])
    for _ in range(15):  # busy all week, never idle for long
        clock.now += SESSION_IDLE_S - 60
        client.get("/x")
    assert client.get("/x").status_code == 303


def test_rotating_or_removing_a_user_ends_their_sessions(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    client = client_for(users, True, clock)
    login(client, "vic", tokens["vic"])
    UsersFile(users.path).rotate("vic")  # an administrator, from another process
    assert client.get("/x").status_code == 303
    client_eve = client_for(users, True, clock)
    login(client_eve, "eve", tokens["eve"])
    UsersFile(users.path).remove("eve")
    assert client_eve.get("/api/data").status_code == 401


# -- headers ----------------------------------------------------------------------------------


def test_every_response_carries_the_security_headers(
    users: UsersFile, tokens: dict[str, str], clock: FakeClock
) -> None:
    client = client_for(users, True, clock)
    for response in (client.get("/login"), client.get("/x"), client.get("/api/data")):
        assert response.headers["content-security-policy"] == CONTENT_SECURITY_POLICY
        assert "script-src 'self'" in response.headers["content-security-policy"]
        assert "frame-ancestors 'none'" in response.headers["content-security-policy"]
        assert response.headers["x-content-type-options"] == "nosniff"
        assert response.headers["referrer-policy"] == "same-origin"
        assert response.headers["x-frame-options"] == "DENY"


def test_the_login_page_has_no_script_and_no_external_asset(clock: FakeClock) -> None:
    page = client_for(None, False, clock).get("/login").text
    assert "<script" not in page
    assert "http://" not in page
    assert "https://" not in page
    assert "<form" in page
