"""The test signal's start and stop relayed by the central store (issue 40), on PostgreSQL.

Central schema version 4 widens ``requests.kind`` to ``excite_start`` and ``excite_stop``: a
database of version 3 must migrate keeping its rows and then take the new kinds. A start filed
centrally is fetched by the loop's link, filed in the site's store (origin ``central:<id>``, who
and why kept) and carried out by the service's beat as a start from the site's own dashboard;
with no service running, ``fuelid central sync`` refuses a start with the reason (nothing would
carry the signal) and does a stop (the PLC holds the signal at 0: its heartbeat rule), and
reports both back. A central loop's page offers the start when the site's service record says
the site can carry a signal and the service runs; the route relays it like a revert.

The stores are small ones made here with the store's API (no simulated fleet): the file runs in
a few seconds.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from fuelid.central import (
    KINDS,
    SCHEMA_VERSION,
    CentralError,
    central_requests,
    connect,
    file_central_request,
    migrate,
    schema_version,
)
from fuelid.cli import main
from fuelid.online import CentralLink, consume_requests
from fuelid.online.excitation import REQUEST_KEY
from fuelid.plc import Central
from fuelid.store import REQUEST_KINDS, SERVICE_KEY, Event, OnlineHistory, Sample, SQLiteStore

T0 = 1_767_225_600.0  # 2026-01-01T00:00:00Z, plant time
PERIOD_S = 0.1
LOOP = "line-x"
START_REFUSED = "no service runs at the site to carry a signal: start it first"
STOP_DONE = "no service runs: the PLC holds the signal at 0 (its heartbeat rule)"


def _service_record(*, running: bool) -> dict[str, Any]:
    """The service's record: a fresh beat (running), or an hour-old one.

    The old one is a service that died without a clean stop (``stopped`` unset: only the beat's
    age says it is not running).
    """
    now = time.time()
    beat = now if running else now - 3600.0
    return {
        "pid": 1,
        "host": "site-x",
        "started": beat - 60.0,
        "beat": beat,
        "beat_every_s": 2.0,
        "stopped": None,
        "settings": {
            "write_back": "approve",
            "timezone": "UTC",
            "window_s": 600.0,
            "excitation": {"mode": "on_request", "amplitude": 0.2, "possible": True},
        },
    }


def make_store(path: Path, *, running: bool) -> Path:
    """A store a service ran on: a minute of samples, its restart, its record (_service_record).

    The event gives the first sync a row to send: a store is registered centrally with its
    first batch.
    """
    samples = [
        Sample(T0 + PERIOD_S * k, k, 2.0, 40.0, 40.0, 20.0, 1, excitation=0.0) for k in range(600)
    ]
    with SQLiteStore(
        path, site_name="tunnel 3 fuel loop", tag_map_hash="cd34", period_s=PERIOD_S, loop_id=LOOP
    ) as store:
        store.append(samples, [Event(T0, "restart", "tunnel 3 fuel loop")])
        with OnlineHistory(store) as history:
            history.set_state(SERVICE_KEY, _service_record(running=running))
    return path


class Site:
    """A loop's store, its history and its link (closed at the end of the test)."""

    def __init__(self, path: Path, url: str) -> None:
        self.store = SQLiteStore(path)
        self.history = OnlineHistory(self.store)
        self.link = CentralLink(path, Central(url=url, batch_rows=1000), self.history)

    def sync(self) -> Any:
        result = self.link.cycle()
        assert result.error is None, result.error
        return result

    def close(self) -> None:
        self.link.close()
        self.history.close()
        self.store.close()


@pytest.fixture
def site(tmp_path: Path, central_url: str) -> Iterator[Site]:
    """A store whose service runs, synced once (its loop and store are central)."""
    opened = Site(make_store(tmp_path / "x.db", running=True), central_url)
    try:
        opened.sync()
        yield opened
    finally:
        opened.close()


def test_version_3_migrates_to_4_keeping_its_requests_and_taking_the_new_kinds(
    pg_cluster: Any,
) -> None:
    """The CHECK of version 1 is replaced, not doubled: old rows kept, new kinds in, others out."""
    import psycopg

    assert SCHEMA_VERSION == 4
    url = pg_cluster.create_database("central_v3")
    insert = (
        "INSERT INTO requests(loop_id, kind, who, why, origin, expires, store_uuid) "
        "VALUES ('line-x', %s, 'eve', 'w', 'dashboard', now() + interval '1 hour', 'u1')"
    )
    with connect(url) as con:
        assert migrate(con, upto=3) == (0, 3)
        con.execute(
            "INSERT INTO loops(loop_id, site_name, tag_map_hash) VALUES ('line-x', 's', 'h')"
        )
        con.execute(
            "INSERT INTO stores(store_uuid, loop_id, site_name, tag_map_hash) "
            "VALUES ('u1', 'line-x', 's', 'h')"
        )
        old = file_central_request(con, LOOP, "revert", None, "eve", "back")
        with (  # in a savepoint: the rows above stay
            pytest.raises(psycopg.errors.CheckViolation, match="requests_kind_check"),
            con.transaction(),
        ):
            con.execute(insert, ("excite_start",))
        assert migrate(con) == (3, 4)
        assert schema_version(con) == 4
        start = file_central_request(con, LOOP, "excite_start", None, "eve", "K unknown")
        stop = file_central_request(con, LOOP, "excite_stop", None, "eve", "")
        with (
            pytest.raises(psycopg.errors.CheckViolation, match="requests_kind_check"),
            con.transaction(),
        ):
            con.execute(insert, ("excite_forever",))
        checks = con.execute(
            "SELECT conname FROM pg_constraint WHERE conrelid = 'requests'::regclass "
            "AND contype = 'c' AND pg_get_constraintdef(oid) LIKE '%%kind%%'"
        ).fetchall()
        rows = central_requests(con, LOOP)
        summary = con.execute("SELECT summary FROM central_schema WHERE version = 4").fetchone()
    assert checks == [("requests_kind_check",)]
    assert [(r["id"], r["kind"], r["status"]) for r in rows] == [
        (old["id"], "revert", "waiting"),
        (start["id"], "excite_start", "waiting"),
        (stop["id"], "excite_stop", "waiting"),
    ]
    assert summary is not None
    assert "excite_start" in summary[0]


def test_the_kinds_are_the_sites_and_only_approve_and_reject_need_a_proposal(
    site: Site, central_url: str
) -> None:
    assert set(KINDS) == set(REQUEST_KINDS)
    with connect(central_url) as con:
        for kind in ("approve", "reject"):
            with pytest.raises(CentralError, match=f"a request to {kind} needs its proposal"):
                file_central_request(con, LOOP, kind, None, "eve", "x")
        with pytest.raises(CentralError, match="refers to no proposal"):
            file_central_request(con, LOOP, "excite_stop", 3, "eve", "x")
        assert central_requests(con, LOOP) == []


def test_a_central_start_and_stop_are_filed_and_carried_out_by_the_running_site(
    site: Site, central_url: str
) -> None:
    """Filed locally with origin central:<id>, who and why kept; the beat applies; reported."""
    with connect(central_url) as con:
        start = file_central_request(con, LOOP, "excite_start", None, "eve", "K unknown")
    cycle = site.sync()  # the link claims and files it (no proposal to compare)
    (local,) = cycle.filed
    assert (local["kind"], local["origin"]) == ("excite_start", f"central:{start['id']}")
    assert (local["who"], local["why"], local["status"]) == ("eve", "K unknown", "waiting")
    assert local["proposal_id"] is None
    consume_requests(site.history, "approve")  # the service's beat: left for the exciter
    requested = site.history.state(REQUEST_KEY)
    assert (requested["action"], requested["who"], requested["why"]) == (
        "start",
        "eve",
        "K unknown",
    )
    assert requested["request_id"] == local["id"]
    site.sync()  # reports the outcome
    with connect(central_url) as con:
        stop = file_central_request(con, LOOP, "excite_stop", None, "eve", "(no reason given)")
    (local_stop,) = site.sync().filed
    consume_requests(site.history, "approve")
    assert site.history.state(REQUEST_KEY)["action"] == "stop"
    site.sync()
    with connect(central_url) as con:
        rows = central_requests(con, LOOP)
        relayed = con.execute(
            "SELECT origin, kind, status FROM site_requests WHERE loop_id = %s ORDER BY id", (LOOP,)
        ).fetchall()
    assert [(r["id"], r["status"], r["local_id"]) for r in rows] == [
        (start["id"], "done", local["id"]),
        (stop["id"], "done", local_stop["id"]),
    ]
    assert rows[0]["outcome"].startswith(
        "start requested: the service starts the signal where the next window starts"
    )
    assert rows[1]["outcome"] == "stop requested: the service writes 0 to the register"
    assert relayed == [
        (f"central:{start['id']}", "excite_start", "done"),
        (f"central:{stop['id']}", "excite_stop", "done"),
    ]


def test_without_a_service_central_sync_refuses_a_start_and_does_a_stop(
    tmp_path: Path, central_url: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """A dead service's stale record (no clean stop) is no service: nothing left to fire later."""
    path = make_store(tmp_path / "x.db", running=False)
    sync = ["central", "sync", "--store", str(path), "--url", central_url, "--json"]
    assert main(sync) == 0  # the backfill: the loop and its store are central
    capsys.readouterr()
    with connect(central_url) as con:
        start = file_central_request(con, LOOP, "excite_start", None, "eve", "K unknown")
        stop = file_central_request(con, LOOP, "excite_stop", None, "eve", "(no reason given)")
    assert main(sync) == 0
    sent = json.loads(capsys.readouterr().out)
    assert (sent["requests_filed"], sent["requests_reported"]) == (2, 2)
    with connect(central_url) as con:
        rows = central_requests(con, LOOP)
    assert [(r["id"], r["status"], r["outcome"]) for r in rows] == [
        (start["id"], "refused", START_REFUSED),
        (stop["id"], "done", STOP_DONE),
    ]
    with SQLiteStore(path) as store, OnlineHistory(store) as history:
        local = [(r["origin"], r["status"], r["outcome"]) for r in history.requests()]
        assert history.state(REQUEST_KEY) is None  # no start waits for a later service
    assert local == [
        (f"central:{start['id']}", "refused", START_REFUSED),
        (f"central:{stop['id']}", "done", STOP_DONE),
    ]


def test_a_central_loop_offers_the_start_and_relays_it_like_a_revert(
    site: Site, central_url: str, tmp_path: Path
) -> None:
    """Same rights and CSRF as a revert; a reason required; one start waits at a time."""
    pytest.importorskip("fastapi")
    from fastapi.testclient import TestClient

    from fuelid.dashboard import CSRF_HEADER, CentralLoops, Loops, Security, UsersFile, create_app

    users = UsersFile(tmp_path / "users.json")
    engineer, viewer = users.add("eve", "engineer"), users.add("vic", "viewer")
    url = f"/api/loops/{LOOP}/excitation/start"
    loops = Loops([], central=CentralLoops(central_url))
    try:
        client = TestClient(create_app(loops, Security(users, require_login=False)))
        client.post("/login", data={"name": "vic", "token": viewer, "next": "/"})
        csrf = {CSRF_HEADER: client.get("/api/whoami").json()["csrf"]}
        assert 'data-kind="excite_start"' not in client.get(f"/loops/{LOOP}").text
        assert client.post(url, data={"why": "go"}, headers=csrf).status_code == 403
        client.post("/logout", headers=csrf)
        client.post("/login", data={"name": "eve", "token": engineer, "next": "/"})
        csrf = {CSRF_HEADER: client.get("/api/whoami").json()["csrf"]}
        page = client.get(f"/loops/{LOOP}").text
        assert client.post(url, data={"why": "go"}).status_code == 403  # no CSRF token
        assert client.post(url, data={"why": " "}, headers=csrf).status_code == 422
        answer = client.post(url, data={"why": "K unknown"}, headers=csrf)
        again = client.post(url, data={"why": "K unknown"}, headers=csrf)
        waiting_page = client.get(f"/loops/{LOOP}").text
        cycle = site.sync()
        consume_requests(site.history, "approve")
        site.sync()
        after = client.get(f"/api/loops/{LOOP}/status").json()["central"]["requests"]
    finally:
        loops.close()
    assert 'data-kind="excite_start"' in page
    assert answer.status_code == 200, answer.text
    request = answer.json()["request"]
    assert (request["kind"], request["who"], request["why"]) == ("excite_start", "eve", "K unknown")
    assert (request["status"], request["relayed"]) == ("waiting", True)
    # a start waits 5 minutes at most, not the dashboard's hour (EXCITE_START_EXPIRY_S)
    assert request["expires"] - time.time() <= 300.0 + 1.0
    assert "next sync" in answer.json()["next"]
    assert again.status_code == 409
    assert "a start of the test signal already waits for the site" in again.json()["error"]
    assert 'data-kind="excite_start"' not in waiting_page
    assert "A start of the test signal filed by eve waits for the site" in waiting_page.replace(
        "&#39;", "'"
    )
    assert [r["origin"] for r in cycle.filed] == [f"central:{request['id']}"]
    ((row_id, status),) = [(r["id"], r["status"]) for r in after]
    assert (row_id, status) == (request["id"], "done")
