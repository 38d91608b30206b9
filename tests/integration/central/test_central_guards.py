"""The central store's guards on a real PostgreSQL (the review of issue 26).

Retention drops nothing recent whatever the caller's clock; a central request is claimed
before the site files it (one that expired meanwhile is never applied, one claimed and then
lost is refused with the reason) and is carried out only by the store it is for; two senders
of one store never commit an older value over a newer one; the manual sync refuses a store
whose service runs; the connection carries keepalives and a statement timeout; a month's last
instant lands in that month's partition as PostgreSQL routes it; the fleet status shows the
backlog of the loop's current store.
"""

from __future__ import annotations

import json
import math
import sqlite3
import threading
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import psycopg
import pytest

from fuelid.central import (
    SCHEMA_VERSION,
    Sender,
    central_requests,
    claim,
    connect,
    drop_old_partitions,
    file_central_request,
    fleet_status,
    migrate,
    schema_version,
)
from fuelid.central._ingest import months_of, register_store, upsert_liveness
from fuelid.central._outbox import Identity
from fuelid.central._schema import ensure_partitions, month_start
from fuelid.cli import main
from fuelid.online import CentralLink, origin_of
from fuelid.plc import Central
from fuelid.store import SERVICE_KEY, OnlineHistory, SQLiteStore, StoreError
from support.fleet import copy_loop, with_proposal

MONTH_S = 31 * 86400.0


class Site:
    """A loop's store, its history and its link (closed at the end of the test)."""

    def __init__(self, path: Path, url: str) -> None:
        self.store = SQLiteStore(path)
        self.history = OnlineHistory(self.store)
        self.link = CentralLink(path, Central(url=url, batch_rows=1000), self.history)

    def close(self) -> None:
        self.link.close()
        self.history.close()
        self.store.close()


@pytest.fixture
def site(fleet_loops: Any, tmp_path: Path, central_url: str) -> Iterator[tuple[Site, int]]:
    """line-a with a pending proposal, its history sent; (the site, the proposal's id)."""
    loop = copy_loop(fleet_loops["line-a"], tmp_path)
    pid = with_proposal(loop)
    opened = Site(loop.path, central_url)
    assert opened.link.cycle().error is None
    yield opened, pid
    opened.close()


def local_of(s: Site, central_id: int) -> list[dict[str, Any]]:
    """The site's local requests filed for a central one."""
    return [r for r in s.history.requests() if r["origin"] == origin_of(central_id)]


def test_a_future_clock_drops_no_recent_month(
    central_url: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """A caller's clock ten years ahead: only what the server's clock would drop goes.

    Months of the last ~100 days exist; keeping 1 month on the server's clock keeps the
    current and the previous month, whatever ``now`` the caller gives. The owner's
    ``fuelid central retention`` (the server's clock) drops the older ones.
    """
    now = time.time()
    with connect(central_url) as con, con.transaction():
        for table in ("windows", "kpis"):
            ensure_partitions(con, table, now - 100 * 86400.0, now)
    assert main(["central", "retention", "--url", central_url, "--months", "1", "--json"]) == 0
    dropped = json.loads(capsys.readouterr().out)["dropped"]
    with connect(central_url) as con:
        assert drop_old_partitions(con, 1, now=now + 10 * 365.25 * 86400.0) == []
        kept = [
            r[0]
            for r in con.execute(
                "SELECT c.relname FROM pg_inherits i JOIN pg_class c ON c.oid = i.inhrelid "
                "JOIN pg_class p ON p.oid = i.inhparent WHERE p.relname = 'windows' ORDER BY 1"
            ).fetchall()
        ]
    made, m = [], month_start(now - 100 * 86400.0)
    while m <= now:  # the months made: 4 or 5
        made.append(m)
        m = month_start(m + MONTH_S)
    previous = month_start(month_start(now) - 1.0)

    def name(table: str, t: float) -> str:
        return time.strftime(f"{table}_p%Y%m", time.gmtime(t))

    assert kept == [name("windows", t) for t in made if t >= previous]
    assert len(kept) == 2  # the current month and the one before
    assert sorted(dropped) == sorted(
        name(table, t) for table in ("kpis", "windows") for t in made if t < previous
    )


def test_the_last_instant_of_a_month_is_in_its_partition(central_url: str) -> None:
    """The double just below 2026-02-01 00:00 UTC is January's, for fuelid and PostgreSQL."""
    t = math.nextafter(1_769_904_000.0, 0.0)
    assert month_start(t) == 1_767_225_600.0  # 2026-01-01
    (month,) = months_of([(1, t)])
    with connect(central_url) as con:
        with con.transaction():  # as the sender does: the partitions of the rows' months
            ensure_partitions(con, "windows", month, month)
            con.execute(
                "INSERT INTO windows(store_uuid, loop_id, id, time, detail) "
                "VALUES ('u', 'l', 1, %s, '{}')",
                (t,),
            )
        where = con.execute("SELECT tableoid::regclass::text, time FROM windows").fetchone()
    assert where == ("windows_p202601", t)


def test_a_request_that_expires_between_fetch_and_claim_is_never_applied(
    site: tuple[Site, int], central_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The request expires after the site fetched it: the claim fails, nothing is filed."""
    import fuelid.central as central  # the service takes claim from the package at each cycle

    s, pid = site
    with connect(central_url) as con:
        request = file_central_request(con, "line-a", "reject", pid, "alice", "race")
    real = central.claim

    def expiring_claim(con: psycopg.Connection, request_id: int, store: str | None = None) -> bool:
        with connect(central_url, autocommit=True) as other:
            other.execute(
                "UPDATE requests SET expires = now() - interval '1 second' WHERE id = %s",
                (request_id,),
            )
        return real(con, request_id, store)

    with monkeypatch.context() as patch:
        patch.setattr(central, "claim", expiring_claim)
        cycle = s.link.cycle(apply_now=True)
    assert cycle.error is None
    assert cycle.filed == []
    assert local_of(s, request["id"]) == []
    assert s.history.proposal(pid)["status"] == "pending"
    assert s.link.cycle(apply_now=True).error is None
    with connect(central_url) as con:
        (row,) = central_requests(con, "line-a")
    assert (row["status"], row["fetched"], row["local_id"]) == ("expired", None, None)
    assert s.history.proposal(pid)["status"] == "pending"


def test_a_claimed_request_the_site_lost_is_refused(
    site: tuple[Site, int], central_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Claimed, then the site died (or failed to file it): refused, with the reason, not run."""
    s, pid = site
    with connect(central_url) as con:
        died = file_central_request(con, "line-a", "reject", pid, "alice", "died")
        assert claim(con, died["id"], s.link.sender.ident.store_uuid)  # then the site died
    assert s.link.cycle(apply_now=True).error is None
    with connect(central_url) as con:
        failed = file_central_request(con, "line-a", "reject", pid, "bob", "disk")

    def full(*args: Any) -> dict[str, Any]:
        raise StoreError("database or disk is full")

    with monkeypatch.context() as patch:
        patch.setattr(s.history, "add_request", full)  # filing the local request fails
        assert s.link.cycle(apply_now=True).error is None
    with connect(central_url) as con:
        rows = {r["id"]: r for r in central_requests(con, "line-a")}
    assert (rows[died["id"]]["status"], rows[died["id"]]["outcome"]) == (
        "refused",
        "claimed but the site has no record of it",
    )
    assert (rows[failed["id"]]["status"], rows[failed["id"]]["outcome"]) == (
        "refused",
        "claimed but the site could not file it: database or disk is full",
    )
    assert local_of(s, died["id"]) == []
    assert local_of(s, failed["id"]) == []
    assert s.history.proposal(pid)["status"] == "pending"


def test_a_request_among_many_local_ones_is_reported(
    site: tuple[Site, int], central_url: str
) -> None:
    """The local request of a central one is found by its origin, however many came after."""
    s, pid = site
    with connect(central_url) as con:
        request = file_central_request(con, "line-a", "reject", pid, "alice", "later")
    (local,) = s.link.cycle().filed  # a service runs: filed, left to its beat
    now = time.time()
    con = sqlite3.connect(s.store.path)
    with con:  # one transaction: 501 requests filed later, more than any "newest N" window
        con.executemany(
            "INSERT INTO requests(time, wall_time, kind, who, why, origin, status, outcome) "
            "VALUES (?, ?, 'revert', 'op', 'filler', 'cli', 'waiting', '')",
            [(now, now)] * 501,
        )
    con.close()
    s.history.finish_request(local["id"], "refused", "test: decided at the site")
    assert s.link.cycle().error is None
    with connect(central_url) as con:
        (row,) = central_requests(con, "line-a")
    assert row["id"] == request["id"]
    assert (row["status"], row["outcome"]) == ("refused", "test: decided at the site")
    assert row["local_id"] == local["id"]


def test_a_central_revert_without_a_service_is_refused(
    site: tuple[Site, int], central_url: str
) -> None:
    """No service runs to write it: refused and said so, nothing left to fire at a later start."""
    s, _ = site
    with connect(central_url) as con:
        file_central_request(con, "line-a", "revert", None, "alice", "back")
    cycle = s.link.cycle(apply_now=True)
    assert cycle.error is None
    with connect(central_url) as con:
        (row,) = central_requests(con, "line-a")
    assert (row["status"], row["outcome"]) == (
        "refused",
        "no service runs at the site to write a revert: start it first",
    )
    assert s.history.state("revert_requested") is None


def _as_new_store(path: Path, beat: float) -> str:
    """Give the store a new UUID (a replacement store of its loop) and a service beat."""
    new = uuid.uuid4().hex
    con = sqlite3.connect(path)
    con.execute("UPDATE meta SET value = ? WHERE key = 'store_uuid'", (new,))
    con.commit()
    con.close()
    _beat(path, beat)
    return new


def _beat(path: Path, beat: float) -> None:
    with SQLiteStore(path) as store, OnlineHistory(store) as history:
        history.set_state(SERVICE_KEY, {"beat": beat, "stopped": beat + 1.0, "pid": 1})


def test_requests_are_carried_out_by_the_store_they_are_for(
    fleet_loops: Any, tmp_path: Path, central_url: str
) -> None:
    """line-a's old store, backfilled by hand after its replacement, never takes its requests.

    Both stores have a proposal with the same id (ids restart per store); the request is for
    the store whose service beat last.
    """
    old = copy_loop(fleet_loops["line-a"], tmp_path / "old")
    new = copy_loop(fleet_loops["line-a"], tmp_path / "new")
    pid = with_proposal(old)
    assert with_proposal(new) == pid
    _beat(old.path, time.time() - 30 * 86400.0)
    new_uuid = _as_new_store(new.path, time.time() - 60.0)
    sites = [Site(new.path, central_url), Site(old.path, central_url)]
    try:
        for s in sites:
            assert s.link.cycle(apply_now=True).error is None
        with connect(central_url) as con:
            request = file_central_request(con, "line-a", "reject", pid, "alice", "new only")
        assert request["store_uuid"] == new_uuid
        late = sites[1].link.cycle(apply_now=True)  # the old store, backfilled again
        assert (late.error, late.filed, late.reported) == (None, [], [])
        assert sites[1].history.proposal(pid)["status"] == "pending"
        done = sites[0].link.cycle(apply_now=True)
        assert done.error is None
        assert [r["origin"] for r in done.filed] == [origin_of(request["id"])]
        assert sites[0].history.proposal(pid)["status"] == "rejected"
        assert sites[1].link.cycle(apply_now=True).filed == []
        assert sites[1].history.proposal(pid)["status"] == "pending"
    finally:
        for s in sites:
            s.close()
    with connect(central_url) as con:
        (row,) = central_requests(con, "line-a")
    assert (row["status"], row["outcome"]) == ("done", f"proposal {pid} rejected by alice")


def test_sync_refuses_a_store_whose_service_runs(
    fleet_loops: Any, tmp_path: Path, central_url: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """A live service's store: one line on stderr, exit 2, nothing sent."""
    loop = copy_loop(fleet_loops["line-b"], tmp_path)
    with SQLiteStore(loop.path) as store, OnlineHistory(store) as history:
        now = time.time()
        history.set_state(SERVICE_KEY, {"started": now, "beat": now, "stopped": None, "pid": 1})
    assert main(["central", "sync", "--store", str(loop.path), "--url", central_url]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "a running service sends" in err
    assert "stop it or let it sync" in err
    with connect(central_url) as con:
        assert con.execute("SELECT count(*) FROM stores").fetchone() == (0,)


def test_two_senders_of_one_store_never_send_an_older_value(
    fleet_loops: Any, tmp_path: Path, central_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Sender A reads a request "waiting", the site finishes it, sender B sends "done".

    Under the store's lock B waits for A's commit and reads after it: the centre ends with
    "done". Without it, A's late commit would put "waiting" back for good.
    """
    import fuelid.central._sender as sender_module

    loop = copy_loop(fleet_loops["line-b"], tmp_path)
    a, b = Sender(loop.path, central_url), Sender(loop.path, central_url)
    opened = SQLiteStore(loop.path)
    history = OnlineHistory(opened)
    try:
        assert a.sync().error is None
        b.connection()
        rid = history.add_request("revert", None, "op", "race", "cli")["id"]
        read, go = threading.Event(), threading.Event()
        real = sender_module.read_batch

        def slow_read(*args: Any, **kwargs: Any) -> Any:
            batch = real(*args, **kwargs)
            if threading.current_thread().name == "sender-a" and batch.ids and not read.is_set():
                read.set()
                assert go.wait(30.0)
            return batch

        monkeypatch.setattr(sender_module, "read_batch", slow_read)
        results: dict[str, Any] = {}
        ta = threading.Thread(target=lambda: results.update(a=a.sync()), name="sender-a")
        tb = threading.Thread(target=lambda: results.update(b=b.sync()), name="sender-b")
        ta.start()
        try:
            assert read.wait(30.0)  # A holds the request as "waiting"
            history.finish_request(rid, "done", "applied at the site")
            tb.start()
            tb.join(0.5)
            waited = tb.is_alive()  # B waits for A's lock
        finally:
            go.set()
            ta.join(30.0)
            if tb.ident is not None:
                tb.join(30.0)
        assert waited
        assert results["a"].error is None
        assert results["b"].error is None
        assert results["b"].backlog_rows == 0
    finally:
        history.close()
        opened.close()
        a.close()
        b.close()
    with connect(central_url) as con:
        row = con.execute(
            "SELECT status, outcome FROM site_requests WHERE id = %s", (rid,)
        ).fetchone()
    assert row == ("done", "applied at the site")


def test_the_connection_has_keepalives_and_a_statement_timeout(central_url: str) -> None:
    """The keepalives and the server's statement timeout, unless the URL sets its own."""
    with connect(central_url) as con:
        params = con.info.get_parameters()
        timeout = con.execute("SHOW statement_timeout").fetchone()
    assert {k: params.get(k) for k in ("keepalives_idle", "keepalives_interval")} == {
        "keepalives_idle": "30",
        "keepalives_interval": "10",
    }
    assert (params.get("keepalives_count"), params.get("tcp_user_timeout")) == ("3", "60000")
    assert timeout == ("5min",)
    own = central_url + "&keepalives_idle=5&options=-c%20statement_timeout%3D7s"
    with connect(own) as con:
        params = con.info.get_parameters()
        timeout = con.execute("SHOW statement_timeout").fetchone()
    assert (params.get("keepalives_idle"), timeout) == ("5", ("7s",))


def test_concurrent_migrations_of_an_empty_database(pg_cluster: Any) -> None:
    """Four migrators of one empty database at once: none fails, the schema is made once."""
    url = pg_cluster.create_database("central_race")
    start = threading.Barrier(4)
    errors: list[BaseException | None] = [None] * 4

    def run(k: int) -> None:
        try:
            with connect(url) as con:
                start.wait()
                migrate(con)
        except BaseException as error:  # kept for the assertion below
            errors[k] = error

    threads = [threading.Thread(target=run, args=(k,)) for k in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60.0)
    assert errors == [None] * 4
    with connect(url) as con:
        assert schema_version(con) == SCHEMA_VERSION
        assert con.execute("SELECT count(*) FROM central_schema").fetchone() == (SCHEMA_VERSION,)


def test_status_shows_the_backlog_of_the_loops_current_store(central_url: str) -> None:
    """A replaced store's last backlog (sent after the current one's) is not the loop's."""
    old = Identity(uuid.uuid4().hex, "line-x", "x", "hash-x")
    new = Identity(uuid.uuid4().hex, "line-x", "x", "hash-x")
    with connect(central_url) as con:
        for ident in (new, old):
            with con.transaction():
                register_store(con, ident)
        upsert_liveness(con, new, {"beat": 2000.0, "stopped": None}, 0, None, 1990.0)
        upsert_liveness(con, old, {"beat": 1000.0, "stopped": 1001.0}, 7, 900.0, None)
        (row,) = fleet_status(con, now=2001.0)
    assert (row["stores"], row["backlog_rows"], row["backlog_oldest_wall"]) == (2, 0, None)
    assert (row["service_beat"], row["service_stopped"]) == (2000.0, None)


def test_a_site_file_may_not_set_the_retention() -> None:
    """The centre's retention is its owner's: ``[central] retention_months`` is refused."""
    from pydantic import ValidationError

    with pytest.raises(ValidationError, match=r"fuelid central retention --url URL --months N"):
        Central(url="postgresql://site@db.example/fuelid", retention_months=24)  # type: ignore[call-arg]
