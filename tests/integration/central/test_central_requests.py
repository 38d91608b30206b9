"""Central requests carried out by the site, and the ``fuelid central`` commands, on PostgreSQL.

The central store never talks to a PLC: an approve filed centrally is fetched by the loop's
link, filed in the site's store (origin ``central:<id>``), applied there (by the service's beat,
or at once by ``fuelid central sync`` when no service runs) and its outcome reported back. A
proposal that changed since the requester saw it is refused with the reason; an expired request
is never applied.
"""

from __future__ import annotations

import contextlib
import json
import os
import sqlite3
from pathlib import Path
from typing import Any

import pytest

from fuelid.central import SCHEMA_VERSION, central_requests, connect, file_central_request
from fuelid.central._ingest import SITE_STATE_KEYS
from fuelid.cli import main
from fuelid.online import CentralLink, consume_requests
from fuelid.plc import Central
from fuelid.store import OnlineHistory, SQLiteStore
from support.fleet import SimulatedLoop, copy_loop, with_proposal
from support.waiting import wait_until


class Site:
    """A loop's store, its history and its link (closed at the end of the test)."""

    def __init__(self, loop: SimulatedLoop, url: str) -> None:
        self.store = SQLiteStore(loop.path)
        self.history = OnlineHistory(self.store)
        self.link = CentralLink(loop.path, Central(url=url, batch_rows=1000), self.history)

    def close(self) -> None:
        self.link.close()
        self.history.close()
        self.store.close()


@pytest.fixture
def site(fleet_loops: Any, tmp_path: Path, central_url: str) -> Any:
    loop = copy_loop(fleet_loops["line-a"], tmp_path)
    pid = with_proposal(loop)
    opened = Site(loop, central_url)
    first = opened.link.cycle()  # the store's history, the proposal included, is central now
    assert first.error is None
    yield opened, pid
    opened.close()


def test_central_approve_is_applied_by_the_site(site: Any, central_url: str) -> None:
    """Approve centrally → filed at the site, applied by its beat, outcome reported back."""
    s, pid = site
    with connect(central_url) as con:
        request = file_central_request(con, "line-a", "approve", pid, "alice", "looks right")
    assert (request["seen_status"], request["seen_history_len"]) == ("pending", 1)
    cycle = s.link.cycle()  # a service runs: the link files it, the beat applies it
    assert cycle.error is None
    assert [r["origin"] for r in cycle.filed] == [f"central:{request['id']}"]
    local = cycle.filed[0]
    assert (local["who"], local["why"], local["status"]) == ("alice", "looks right", "waiting")
    consume_requests(s.history, "approve")  # the service's beat
    assert s.history.proposal(pid)["status"] == "approved"
    assert s.link.cycle().error is None  # reports the outcome, sends the proposal's change
    with connect(central_url) as con:
        (row,) = central_requests(con, "line-a")
        proposal = con.execute(
            "SELECT status, history_len FROM proposals WHERE id = %s", (pid,)
        ).fetchone()
    assert row["status"] == "done"
    assert row["outcome"] == f"proposal {pid} approved by alice"
    assert row["local_id"] == local["id"]
    assert proposal == ("approved", 2)


def test_changed_proposal_is_refused_with_the_reason(site: Any, central_url: str) -> None:
    """Rejected at the site after the requester looked: the central approve is refused."""
    s, pid = site
    with connect(central_url) as con:
        request = file_central_request(con, "line-a", "approve", pid, "alice", "go")
    s.history.set_proposal_status(pid, "rejected", who="bob", why="at the site")
    cycle = s.link.cycle(apply_now=True)
    assert cycle.error is None
    assert cycle.filed == []
    with connect(central_url) as con:
        (row,) = central_requests(con, "line-a")
    assert row["id"] == request["id"]
    assert row["status"] == "refused"
    assert row["outcome"] == f"proposal {pid} is now rejected (was pending)"
    assert s.history.proposal(pid)["status"] == "rejected"
    assert [r for r in s.history.requests() if r["origin"].startswith("central")] == []


def test_expired_request_is_never_applied(site: Any, central_url: str) -> None:
    """A request its site fetched only after its expiry: marked expired, nothing done."""
    s, pid = site
    with connect(central_url) as con:
        filed = file_central_request(con, "line-a", "reject", pid, "alice", "late", expires_s=0.05)

        def expired() -> bool:  # on the central database's clock, which the fetch compares with
            row = con.execute("SELECT extract(epoch FROM clock_timestamp())::float8").fetchone()
            return row is not None and float(row[0]) > filed["expires"]

        wait_until(expired, 10.0, "the request's expiry (0.05 s)")
    cycle = s.link.cycle(apply_now=True)
    assert cycle.error is None
    assert cycle.filed == []
    with connect(central_url) as con:
        (row,) = central_requests(con, "line-a")
    assert row["status"] == "expired"
    assert s.history.proposal(pid)["status"] == "pending"
    assert s.history.requests() == []


def test_central_commands(
    fleet_loops: Any, tmp_path: Path, pg_cluster: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    """The commands: migrate, sync, status; one line and exit 2 when the store is unusable.

    sync backfills, then applies a central reject at once (no service runs); an unreachable
    server and a newer schema give one line on stderr, no password, exit code 2.
    """
    url = pg_cluster.create_database("central_cli")
    assert main(["central", "migrate", "--url", url]) == 0
    assert f"from version 0 to {SCHEMA_VERSION}" in capsys.readouterr().out
    assert main(["central", "migrate", "--url", url]) == 0
    assert "nothing to do" in capsys.readouterr().out
    loop = copy_loop(fleet_loops["line-b"], tmp_path)
    pid = with_proposal(loop)
    assert main(["central", "sync", "--store", str(loop.path), "--url", url, "--json"]) == 0
    sent = json.loads(capsys.readouterr().out)
    assert sent["backlog_rows"] == 0
    assert sent["sent_rows"] == sent["backfilled"]
    with connect(url) as con:
        file_central_request(con, "line-b", "reject", pid, "carol", "not now")
    assert main(["central", "sync", "--store", str(loop.path), "--url", url, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["requests_reported"] == 1
    with SQLiteStore(loop.path) as store, OnlineHistory(store) as history:
        assert history.proposal(pid)["status"] == "rejected"
    assert main(["central", "status", "--url", url, "--json"]) == 0
    (row,) = json.loads(capsys.readouterr().out)["loops"]
    assert (row["loop_id"], row["backlog_rows"], row["waiting_requests"]) == ("line-b", 0, 0)
    assert main(["central", "status", "--url", url]) == 0
    header, line = capsys.readouterr().out.splitlines()
    assert header.split()[:3] == ["loop", "service", "last"]
    assert line.split()[:2] == ["line-b", "none"]  # synced by hand: no service ran on it
    assert line.endswith("fuel line line-b")
    assert main(["online", "status", "--store", str(loop.path), "--json"]) == 0
    central = json.loads(capsys.readouterr().out)["central"]
    assert (central["outbox"], central["backlog_rows"]) == ("on", 0)
    assert central["last_ok"] is not None
    assert central["failing_since"] is None

    down = f"postgresql://fuelid:secret@127.0.0.1:{pg_cluster.port + 1}/x?connect_timeout=2"
    assert main(["central", "status", "--url", down]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "secret" not in err
    assert "central store postgresql://fuelid:***@" in err
    with connect(url) as con:
        con.execute("INSERT INTO central_schema(version, summary) VALUES (99, 'future')")
    assert main(["central", "migrate", "--url", url]) == 2
    assert f"version 99 is newer than this fuelid's ({SCHEMA_VERSION})" in capsys.readouterr().err


def test_a_running_service_syncs_and_carries_out_a_central_approve(
    tmp_path: Path, central_url: str
) -> None:
    """The service with [central]: its rows and liveness arrive; a central approve is written.

    About 6 s of wall time (the virtual PLC at 20×): the link's cycle files the request, the
    beat approves, the write-back writes the gains with the echo check, the next cycles report
    the outcome and send the proposal's new status; the last cycle sends the record of the
    clean stop.
    """
    import asyncio

    pytest.importorskip("pymodbus")
    from fuelid.online import OnlineService
    from fuelid.plc.virtual import VirtualPlcThread
    from support.online import online_site, open_history

    store = tmp_path / "s.db"
    online = (
        'identify_every_s = 3600\nwindow_s = 3600\nwrite_back = "approve"\n'
        f'[central]\nurl = "{central_url}"\nsend_every_s = 0.3\n'
    )
    with VirtualPlcThread(speed=20.0, setpoint_profile="run") as virtual:
        site = online_site(virtual, store, online)
        assert site.central is not None
        kc0, ti0 = virtual.plc.gains
        opened, history = open_history(site, store)
        try:
            pid = history.add_proposal(
                model_id=None, old={"Kc": kc0, "Ti": ti0},
                new={"Kc": round(1.1 * kc0, 6), "Ti": ti0}, detail={"reason": "test"},
            )  # fmt: skip
            loop_id = opened.loop_id
            link = CentralLink(store, site.central, history)
            assert link.cycle().error is None
            link.close()
        finally:
            history.close()
            opened.close()
        with connect(central_url) as con:
            file_central_request(con, loop_id, "approve", pid, "dana", "go")
        service = OnlineService(site, heartbeat_s=0.05, isolate=False)
        try:
            asyncio.run(service.run(5.0))
        finally:
            service.close()
    with connect(central_url) as con:
        (request,) = central_requests(con)
        status = con.execute("SELECT status FROM proposals WHERE id = %s", (pid,)).fetchone()
        service_record, every, state = con.execute(
            "SELECT service, send_every_s, site_state FROM liveness"
        ).fetchone()
        writes = con.execute("SELECT id, kind, proposal_id, status FROM writes").fetchall()
    with SQLiteStore(store) as opened, OnlineHistory(opened) as history:
        local_writes = [
            (w["id"], w["kind"], w["proposal_id"], w["status"]) for w in history.writes()
        ]
    assert request["status"] == "done"
    assert request["outcome"] == f"proposal {pid} approved by dana"
    assert status == ("applied",)
    assert service_record["pid"] == os.getpid()
    assert service_record["stopped"] is not None  # the clean stop reached the centre
    # schema 2: the site's send interval and its write-back state (the write set
    # current_gains and tuned_for, here null: the test proposal carries no ideal form) arrive
    assert every == 0.3
    with contextlib.closing(sqlite3.connect(store)) as lite:
        site_state = {
            key: json.loads(value)
            for key, value in lite.execute("SELECT key, value FROM online_state").fetchall()
            if key in SITE_STATE_KEYS
        }
    assert {"current_gains", "tuned_for"} <= set(site_state)
    assert state == site_state
    assert writes == local_writes
    assert (pid, "verified") in [(w[2], w[3]) for w in writes]


def test_a_failure_is_one_event_when_it_starts_and_one_when_it_ends(
    tmp_path: Path, central_url: str, pg_cluster: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    """A dead server: central_error once however many cycles fail, central_ok on recovery.

    ``online status`` says what is failing and since when, then that all was sent.
    """
    from fuelid.store import Event

    path = tmp_path / "loop.db"
    with SQLiteStore(path, site_name="tiny", tag_map_hash="t1") as store:
        # a NUL from a PLC string: PostgreSQL refuses it, the outbox must not stick on it
        store.append_events([Event(1.7e9, "restart", "tiny\x00store")])
    dead = f"postgresql://fuelid@127.0.0.1:{pg_cluster.port + 1}/x?connect_timeout=2"
    events: list[tuple[str, str]] = []
    with SQLiteStore(path) as store, OnlineHistory(store) as history:
        link = CentralLink(
            path, Central(url=dead), history, event=lambda k, d: events.append((k, d))
        )
        try:
            assert link.cycle().error is not None
            assert link.cycle().error is not None
            assert [k for k, _ in events] == ["central_error"]
            assert "Connection refused" in events[0][1]
            assert main(["online", "status", "--store", str(path)]) == 0
            line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("central"))
            assert "backlog 1 rows" in line
            assert "last send never" in line
            assert "failing since" in line
            link.sender.url = central_url
            assert link.cycle().error is None
            assert [k for k, _ in events] == ["central_error", "central_ok"]
        finally:
            link.close()
    with connect(central_url) as con:
        details = [r[0] for r in con.execute("SELECT detail FROM events").fetchall()]
    assert details == ["tiny\ufffdstore"]
    assert main(["online", "status", "--store", str(path)]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("central"))
    assert line.startswith("central    backlog 0 rows, last send ")
    assert "failing" not in line


def test_concurrent_senders_of_a_new_month_create_its_partitions_once(
    fleet_loops: Any, tmp_path: Path, central_url: str
) -> None:
    """Six stores sending windows of the same new month at once: no sender fails."""
    import sqlite3
    import threading
    import uuid

    paths = []
    for i in range(6):
        loop = copy_loop(fleet_loops["line-b"], tmp_path / f"s{i}")
        con = sqlite3.connect(loop.path)
        con.execute("UPDATE meta SET value = ? WHERE key = 'store_uuid'", (uuid.uuid4().hex,))
        con.execute("UPDATE meta SET value = ? WHERE key = 'loop_id'", (f"loop-{i}",))
        con.commit()
        con.close()
        paths.append(loop.path)
    from fuelid.central import Sender

    senders = [Sender(p, central_url, batch_rows=50) for p in paths]
    for sender in senders:
        sender.connection()
    start = threading.Barrier(len(senders))
    errors: list[str | None] = [None] * len(senders)

    def send(k: int) -> None:
        start.wait()
        errors[k] = senders[k].sync().error

    threads = [threading.Thread(target=send, args=(k,)) for k in range(len(senders))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60.0)
    for sender in senders:
        sender.close()
    assert errors == [None] * len(senders)
    with connect(central_url) as con:
        loops = con.execute("SELECT count(DISTINCT loop_id) FROM windows").fetchone()
    assert loops == (len(senders),)
