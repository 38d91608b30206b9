"""The central store on a real PostgreSQL: the sync of two loops' stores, through an outage.

The two ``fleet_loops`` stores (3 h each, simulated; copied before any change) are sent by
:class:`~fuelid.central._sender.Sender`; the central tables must then hold exactly the union of
the site rows: the same ids, the same values, the same JSON (compared row by row), nothing
lost and nothing twice. The server is killed (``pg_ctl stop -m immediate``) mid-sync and
restarted; a crash between the central commit and the local delete is simulated; the backfill
happens once; a newer schema and a store UUID under another loop id are refused; retention drops
only the old months.
"""

from __future__ import annotations

import contextlib
import json
import sqlite3
import time
from pathlib import Path
from typing import Any

import pytest

from fuelid.central import (
    SCHEMA_VERSION,
    CentralError,
    Sender,
    check_schema,
    connect,
    drop_old_partitions,
    enable_outbox,
    migrate,
    open_store_file,
    sync_status,
)
from fuelid.central._schema import SITE_TABLES, ensure_partitions
from fuelid.store import Event, OnlineHistory, SQLiteStore
from support.fleet import copy_loop


def site_rows(path: Path, table: str) -> list[tuple[Any, ...]]:
    """A site table's rows in the central column order, JSON parsed, by id."""
    spec = SITE_TABLES[table]
    cols = ", ".join(c for c, _ in spec.columns)
    con = sqlite3.connect(path)
    try:
        rows = con.execute(f"SELECT {cols} FROM {table} ORDER BY id").fetchall()
    finally:
        con.close()
    json_at = [i for i, (_, kind) in enumerate(spec.columns) if kind == "jsonb"]
    return [tuple(json.loads(v) if i in json_at else v for i, v in enumerate(row)) for row in rows]


def central_rows(url: str, table: str, store_uuid: str) -> list[tuple[Any, ...]]:
    """The central copy of a site table's rows of one store, by id."""
    spec = SITE_TABLES[table]
    with connect(url) as con:
        return [
            tuple(r)
            for r in con.execute(
                f"SELECT {', '.join(spec.names)} FROM {spec.central} WHERE store_uuid = %s "
                "ORDER BY id",
                (store_uuid,),
            ).fetchall()
        ]


def writable(loop: Any) -> SQLiteStore:
    """A simulated loop's store opened to write (with the identity support.fleet gave it)."""
    return SQLiteStore(
        loop.path, site_name=loop.site_name, tag_map_hash=f"hash-{loop.loop_id}",
        loop_id=loop.loop_id,
    )  # fmt: skip


def uuid_of(path: Path) -> str:
    con = sqlite3.connect(path)
    try:
        return str(con.execute("SELECT value FROM meta WHERE key = 'store_uuid'").fetchone()[0])
    finally:
        con.close()


def assert_same(url: str, path: Path) -> None:
    """The central store holds exactly the site's rows of every table (ids, values, JSON)."""
    uuid = uuid_of(path)
    for table in SITE_TABLES:
        assert central_rows(url, table, uuid) == site_rows(path, table), table


def counts(url: str) -> dict[str, int]:
    with connect(url) as con:
        return {
            t.central: int(con.execute(f"SELECT count(*) FROM {t.central}").fetchone()[0])
            for t in SITE_TABLES.values()
        } | {"kpis": int(con.execute("SELECT count(*) FROM kpis").fetchone()[0])}


def assert_liveness(url: str, path: Path, before: float, after: float) -> None:
    """The schema-2 liveness columns are the site's own values (a sync by hand: no interval)."""
    with contextlib.closing(sqlite3.connect(path)) as lite:
        newest = lite.execute(
            "SELECT time, wall_time FROM samples ORDER BY time DESC LIMIT 1"
        ).fetchone()
        first = lite.execute("SELECT min(time) FROM samples").fetchone()[0]
        meta = dict(lite.execute("SELECT key, value FROM meta").fetchall())
    with connect(url) as con:
        row = con.execute(
            "SELECT site_wall, send_every_s, newest_sample_time, newest_sample_wall, "
            "first_sample_time, period_s, schema_version, site_state FROM liveness "
            "WHERE store_uuid = %s",
            (meta["store_uuid"],),
        ).fetchone()
    assert row is not None
    site_wall, every, t_new, wall_new, t_first, period, version, state = row
    assert before <= site_wall <= after
    assert every is None
    assert (t_new, wall_new, t_first) == (newest[0], newest[1], first)
    assert period == float(meta["period_s"])
    assert version == int(meta["schema_version"])
    assert state == {}  # no service ever wrote gains into these stores


def test_two_loops_sync_to_their_union(fleet_loops: Any, tmp_path: Path, central_url: str) -> None:
    """Both stores sent: every site row centrally, once; KPIs one per window, from its detail."""
    paths = [copy_loop(fleet_loops[name], tmp_path / name).path for name in ("line-a", "line-b")]
    for path in paths:
        before = time.time()
        with Sender(path, central_url, batch_rows=500) as sender:
            result = sender.sync()
        assert result.error is None
        assert result.backlog_rows == 0
        assert_liveness(central_url, path, before, time.time())
    for path in paths:
        assert_same(central_url, path)
    expected = {
        t.central: sum(len(site_rows(p, t.site)) for p in paths) for t in SITE_TABLES.values()
    }
    got = counts(central_url)
    assert {k: got[k] for k in expected} == expected
    assert got["kpis"] == expected["windows"]
    assert expected["windows"] > 30
    assert expected["events"] >= 2
    # a KPI row carries its window's health numbers; line-b ran in MAN
    with connect(central_url) as con:
        rows = con.execute(
            "SELECT k.loop_id, k.mode, k.time_in_auto, w.detail FROM kpis k JOIN windows w "
            "USING (store_uuid, id, time)"
        ).fetchall()
    for loop_id, mode, auto, detail in rows:
        assert mode == detail.get("mode")
        assert auto == (detail.get("health") or {}).get("time_in_auto")
        if loop_id == "line-b" and mode is not None:
            assert mode == "MAN"


def write_during_outage(loop: Any) -> int:
    """Write what a site writes while the central store is away; the new proposal's id.

    An event, a window and a proposal that changes status (two history entries).
    """
    with writable(loop) as store, OnlineHistory(store) as history:
        store.append_events([Event(loop.t_last, "link_down", "during the outage")])
        history.add_window(
            t_from=loop.t_last - 600.0, t_to=loop.t_last, accepted=False,
            reason="outage test", T_fuel=20.0, u_mean=3.0, detail={"mode": "AUTO"},
        )  # fmt: skip
        models = history.accepted_models(limit=1)
        pid = history.add_proposal(
            model_id=models[0]["id"] if models else None, old={"Kc": 0.1, "Ti": 2.0},
            new={"Kc": 0.12, "Ti": 2.1}, detail={"rule": "test"},
        )  # fmt: skip
        history.set_proposal_status(pid, "rejected", who="op", why="outage test")
    return pid


def test_outage_mid_sync_loses_and_doubles_nothing(
    fleet_loops: Any, tmp_path: Path, central_url: str, pg_cluster: Any
) -> None:
    """Two loops: kill the server after their first batch, write on, restart: the union again.

    Nothing lost (every site row is there with its newest value), nothing doubled (the
    counts equal the sites' and the keys are unique).
    """
    loops = [copy_loop(fleet_loops[n], tmp_path / n) for n in ("line-a", "line-b")]
    senders = [Sender(loop.path, central_url, batch_rows=10) for loop in loops]
    try:
        for sender in senders:
            sender.enable()
            assert sender.send_once()[0] == 10
        pg_cluster.stop("immediate")
        try:
            for sender in senders:
                failed = sender.sync()
                assert failed.error is not None
                assert "\n" not in failed.error
                assert failed.backlog_rows > 0
                state = sync_status(sender.lite)
                assert state["failing_since"] is not None
                assert state["last_error"] == failed.error
            pids = [write_during_outage(loop) for loop in loops]
            assert all(sender.sync().error is not None for sender in senders)  # still down
        finally:
            pg_cluster.restart_after_crash()
        for sender in senders:
            done = sender.sync()
            assert done.error is None
            assert done.backlog_rows == 0
    finally:
        for sender in senders:
            sender.close()
    for loop in loops:
        assert_same(central_url, loop.path)
    expected = {
        t.central: sum(len(site_rows(loop.path, t.site)) for loop in loops)
        for t in SITE_TABLES.values()
    }
    got = counts(central_url)
    assert {k: got[k] for k in expected} == expected
    with connect(central_url) as con:
        status = con.execute(
            "SELECT loop_id, status, history_len FROM proposals WHERE id = ANY(%s) "
            "ORDER BY loop_id",
            (pids,),
        ).fetchall()
    assert status == [("line-a", "rejected", 2), ("line-b", "rejected", 2)]


def test_resend_after_a_crash_before_the_local_delete_changes_nothing(
    fleet_loops: Any, tmp_path: Path, central_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Central commit, then the site dies before deleting its entries: the resend is a no-op."""
    import fuelid.central._sender as sender_module

    loop = copy_loop(fleet_loops["line-b"], tmp_path)

    def crash(con: sqlite3.Connection, ids: Any) -> None:
        raise sqlite3.OperationalError("disk I/O error (simulated crash before the delete)")

    with Sender(loop.path, central_url, batch_rows=100_000) as sender:
        with monkeypatch.context() as patch:
            patch.setattr(sender_module, "delete_sent", crash)
            first = sender.sync()
        assert first.error is not None
        assert "simulated crash" in first.error
        assert first.backlog_rows > 0

        def snapshot() -> dict[str, list[Any]]:
            with connect(central_url) as con:
                return {
                    t: con.execute(f"SELECT xmin::text, * FROM {t} ORDER BY id").fetchall()
                    for t in ("events", "windows", "kpis", "models", "proposals")
                }

        before = snapshot()
        again = sender.sync()
    assert again.error is None
    assert again.sent_rows == first.backlog_rows
    assert snapshot() == before  # not even a new row version (xmin)
    assert_same(central_url, loop.path)


def test_backfill_happens_once(fleet_loops: Any, tmp_path: Path) -> None:
    """Switching the outbox on queues every existing row once; later only the changes."""
    loop = copy_loop(fleet_loops["line-a"], tmp_path)
    expected = sum(len(site_rows(loop.path, t)) for t in SITE_TABLES)
    con = open_store_file(loop.path)
    try:
        assert enable_outbox(con) == expected
        assert enable_outbox(con) == 0
        con.execute("DELETE FROM outbox")  # as if sent
        assert enable_outbox(con) == 0
        with writable(loop) as store:
            store.append_events([Event(loop.t_last, "restart", "after the backfill")])
        assert con.execute("SELECT tbl, count(*) FROM outbox").fetchone() == ("events", 1)
    finally:
        con.close()


def test_newer_central_schema_is_refused(
    fleet_loops: Any, tmp_path: Path, central_url: str
) -> None:
    """A database migrated by a newer fuelid: refused with both versions, nothing sent."""
    with connect(central_url) as con:
        con.execute(
            "INSERT INTO central_schema(version, summary) VALUES (%s, 'future')",
            (SCHEMA_VERSION + 1,),
        )
    with connect(central_url) as con:
        with pytest.raises(
            CentralError, match=rf"version {SCHEMA_VERSION + 1} is newer.*\({SCHEMA_VERSION}\)"
        ):
            check_schema(con)
        with pytest.raises(CentralError, match="newer"):
            migrate(con)
    loop = copy_loop(fleet_loops["line-b"], tmp_path)
    with Sender(loop.path, central_url) as sender:
        result = sender.sync()
    assert result.error is not None
    assert "newer" in result.error
    assert counts(central_url)["events"] == 0


def test_store_uuid_under_another_loop_id_is_refused(
    fleet_loops: Any, tmp_path: Path, central_url: str
) -> None:
    """The same store UUID arriving as another loop: refused with the reason, nothing sent."""
    loop = copy_loop(fleet_loops["line-b"], tmp_path / "first")
    with Sender(loop.path, central_url) as sender:
        assert sender.sync().error is None
    twin = copy_loop(fleet_loops["line-b"], tmp_path / "twin")
    con = sqlite3.connect(twin.path)
    con.execute("UPDATE meta SET value = 'line-x' WHERE key = 'loop_id'")
    con.commit()
    con.close()
    before = counts(central_url)
    with Sender(twin.path, central_url) as sender:
        result = sender.sync()
    assert result.error is not None
    assert "known to the central store as loop 'line-b'" in result.error
    assert "'line-x'" in result.error
    assert counts(central_url) == before


def test_retention_drops_only_old_months(central_url: str) -> None:
    """Months that ended before the cutoff go with their rows; the others stay whole."""
    oct_15, jan_20 = 1_760_486_400.0, 1_768_867_200.0  # 2025-10-15, 2026-01-20 (UTC)
    with connect(central_url) as con:
        with con.transaction():
            for table in ("windows", "kpis"):
                ensure_partitions(con, table, oct_15, jan_20)
            for t in (oct_15, oct_15 + 40 * 86400.0, jan_20):  # Oct, Nov, Jan
                con.execute(
                    "INSERT INTO windows(store_uuid, loop_id, id, time, t_from, t_to, accepted, "
                    "reason, detail) VALUES ('u', 'l', %s, %s, %s, %s, 1, 'ok', '{}')",
                    (int(t), t, t - 600.0, t),
                )
        # two months kept before January 2026: November and December 2025 stay
        dropped = drop_old_partitions(con, 2, now=jan_20)
        assert sorted(dropped) == ["kpis_p202510", "windows_p202510"]
        left = [r[0] for r in con.execute("SELECT time FROM windows ORDER BY time").fetchall()]
        parts = con.execute(
            "SELECT c.relname FROM pg_inherits i JOIN pg_class c ON c.oid = i.inhrelid "
            "JOIN pg_class p ON p.oid = i.inhparent WHERE p.relname = 'windows' ORDER BY 1"
        ).fetchall()
    assert left == [oct_15 + 40 * 86400.0, jan_20]
    assert [p[0] for p in parts] == ["windows_p202511", "windows_p202512", "windows_p202601"]


def test_a_site_role_with_the_documented_grants_can_sync(
    fleet_loops: Any, tmp_path: Path, central_url: str, pg_cluster: Any
) -> None:
    """The GRANTs of docs/reference/central.md are enough for a sender (partitions included).

    And no more: the role may not drop partitions (the owner's retention), although
    PostgreSQL lets ``PUBLIC`` execute a new function unless the migration revoked it.
    """
    import re

    import psycopg

    page = (Path(__file__).resolve().parents[3] / "docs/reference/central.md").read_text()
    section = page.split("### One database role per site", 1)[1]
    grants = re.search(r"```sql\n(.*?)```", section, re.DOTALL)
    assert grants is not None
    dbname = central_url.rsplit("/", 1)[1].split("?")[0]
    sql = grants.group(1).replace("DATABASE fuelid", f'DATABASE "{dbname}"')
    with connect(central_url, autocommit=True) as con:
        con.execute("DROP ROLE IF EXISTS site_line_a")
        for statement in re.sub(r"--[^\n]*", "", sql).split(";"):
            if statement.strip():
                con.execute(statement.encode())
    loop = copy_loop(fleet_loops["line-a"], tmp_path)
    url = central_url.replace("://fuelid@", "://site_line_a@")
    try:
        with Sender(loop.path, url, batch_rows=200) as sender:
            result = sender.sync()
        assert result.error is None
        assert_same(central_url, loop.path)
        with (
            connect(url, autocommit=True) as con,
            pytest.raises(psycopg.errors.InsufficientPrivilege),
        ):
            con.execute("SELECT central_drop_partitions(1, 0.0)")
        with connect(central_url) as con:
            parts = con.execute(
                "SELECT count(*) FROM pg_inherits i JOIN pg_class p ON p.oid = i.inhparent "
                "WHERE p.relname IN ('windows', 'kpis')"
            ).fetchone()
        assert parts is not None
        assert parts[0] >= 2  # the loop's month(s), both tables
    finally:
        with connect(central_url, autocommit=True) as con:
            con.execute("REASSIGN OWNED BY site_line_a TO fuelid")
            con.execute("DROP OWNED BY site_line_a")
            con.execute("DROP ROLE site_line_a")
