"""The dashboard over the central store: one read interface, two sources, actions relayed.

Both ``fleet_loops`` stores are synced to a fresh central database (the site's own link, one
cycle, no service). The fleet page must give each loop the same chips whether it reads the two
stores or the central store; a loop's status and history must be the same objects on every key
that does not depend on where they are read; an engineer's approve on a central loop must be a
central request that the site's link files and its beat applies, its outcome shown on the page;
a site not heard from for minutes must show "no contact", never "stopped"; a central store lost
while serving must leave the local loops served and say so.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("fastapi")

from fastapi.testclient import TestClient

from fuelid.central import connect
from fuelid.cli import main as cli_main
from fuelid.dashboard import CSRF_HEADER, CentralLoops, Loops, Security, UsersFile, create_app
from fuelid.online import CentralLink, consume_requests
from fuelid.plc import Central
from fuelid.store import SERVICE_KEY, OnlineHistory, SQLiteStore
from support.fleet import SimulatedLoop, copy_loop

LOCATION_KEYS = {"link", "central"}
"""Status keys that depend on where the loop is read: the link is judged as of the site's last
sync from the centre (with the contact's age), and ``central`` is the site's own sync state
locally but the centre's view of the contact (and its central requests) centrally."""


class Site:
    """A loop's store, its history and its link to the central store."""

    def __init__(self, loop: SimulatedLoop, url: str) -> None:
        self.loop = loop
        self.store = SQLiteStore(loop.path)
        self.history = OnlineHistory(self.store)
        self.link = CentralLink(loop.path, Central(url=url, batch_rows=5000), self.history)

    def sync(self) -> None:
        result = self.link.cycle()
        assert result.error is None, result.error

    def close(self) -> None:
        self.link.close()
        self.history.close()
        self.store.close()


@pytest.fixture
def sites(fleet_loops: Any, tmp_path: Path, central_url: str) -> Iterator[dict[str, Site]]:
    """line-a (with a pending proposal) and line-b, copied and synced once."""
    opened: dict[str, Site] = {}
    try:
        for name in ("line-a", "line-b"):
            opened[name] = Site(copy_loop(fleet_loops[name], tmp_path), central_url)
        history = opened["line-a"].history
        model_id = history.accepted_models(limit=1)[0]["id"]
        history.add_proposal(
            model_id=model_id, old={"Kc": 0.10, "Ti": 2.0}, new={"Kc": 0.12, "Ti": 2.2},
            detail={"rule": "test"}, who="online", why="test proposal",
        )  # fmt: skip
        for site in opened.values():
            site.sync()
        yield opened
    finally:
        for site in opened.values():
            site.close()


@contextlib.contextmanager
def dashboard(
    stores: list[Path],
    url: str | None,
    security: Security | None = None,
    archive: Path | None = None,
) -> Iterator[tuple[TestClient, Loops]]:
    central = None if url is None else CentralLoops(url, archive=archive)
    loops = Loops(stores, central=central)
    try:
        yield TestClient(create_app(loops, security or Security(None, require_login=False))), loops
    finally:
        loops.close()


def _rows(client: TestClient) -> dict[str, dict[str, Any]]:
    answer = client.get("/api/loops")
    assert answer.status_code == 200, answer.text
    return {row["loop_id"]: row for row in answer.json()["loops"]}


def test_the_fleet_rows_are_the_same_from_the_stores_and_from_the_centre(
    sites: dict[str, Site], central_url: str
) -> None:
    paths = [s.loop.path for s in sites.values()]
    with dashboard(paths, None) as (client, _):
        local = _rows(client)
    with dashboard([], central_url) as (client, loops):
        central = _rows(client)
        assert loops.not_shown() == {}
    assert sorted(central) == sorted(local) == ["line-a", "line-b"]
    for loop_id, row in local.items():
        other = central[loop_id]
        assert other["site_name"] == row["site_name"]
        assert other["level"] == row["level"], loop_id
        assert other["sort_key"] == row["sort_key"], loop_id
        chips = {c["name"]: c for c in row["chips"]}
        for chip in other["chips"]:
            mine = chips[chip["name"]]
            assert chip["level"] == mine["level"], (loop_id, chip)
            if chip["name"] == "service":  # the same state, said as of the site's last sync
                assert chip["text"].startswith(mine["text"] + ", as of the site's last sync ")
            else:
                assert chip["text"] == mine["text"], (loop_id, chip)
    # the same chips mean something: line-b ran in MAN (its service is stopped now: the mode is
    # unknown since, the last one said), line-a has a proposal waiting
    mode_b = next(c for c in central["line-b"]["chips"] if c["name"] == "mode")
    assert mode_b["level"] == "unknown"
    assert "(last: MAN" in mode_b["text"]
    waiting = next(c for c in central["line-a"]["chips"] if c["name"] == "proposals")
    assert waiting["text"] == "1 waits for approval"


def test_status_and_history_equal_the_stores_but_where_they_are_read(
    sites: dict[str, Site], central_url: str
) -> None:
    paths = [s.loop.path for s in sites.values()]
    answers: dict[str, dict[str, Any]] = {}
    for name, stores, url in (("local", paths, None), ("central", [], central_url)):
        with dashboard(stores, url) as (client, _):
            for loop_id in ("line-a", "line-b"):
                for what in ("status", "history"):
                    got = client.get(f"/api/loops/{loop_id}/{what}")
                    assert got.status_code == 200, got.text
                    answers[f"{name} {loop_id} {what}"] = got.json()
    for loop_id in ("line-a", "line-b"):
        local, central = answers[f"local {loop_id} status"], answers[f"central {loop_id} status"]
        assert set(local) == set(central)
        for key in set(local) - LOCATION_KEYS:
            assert central[key] == local[key], (loop_id, key)
        for key in ("state", "service", "newest_sample", "newest_sample_wall", "last_event"):
            assert central["link"][key] == local["link"][key], (loop_id, key)
        assert central["central"]["read_from"] == "central store"
        assert local["central"]["outbox"] == "on"
        local, central = answers[f"local {loop_id} history"], answers[f"central {loop_id} history"]
        assert central == local, loop_id  # every key: nothing in a history depends on where
    assert answers["central line-a history"]["counts"]["windows"] >= 30  # 3 h of 5 min steps


def test_a_proposals_window_is_found_by_its_model_from_the_centre_as_from_the_store(
    sites: dict[str, Site], central_url: str
) -> None:
    # the card's evidence row and age rule look the window up by the proposal's model, not
    # among the newest windows: both readers give the same row, one per model
    with dashboard([sites["line-a"].loop.path], None) as (_, loops):
        local = loops.get("line-a")
        assert local is not None
        (proposal,) = local.status()["pending_proposals"]
        model_id = int(proposal["model_id"])
        mine = local.windows_of_models([model_id, model_id, 10**9])
    with dashboard([], central_url) as (_, loops):
        central = loops.get("line-a")
        assert central is not None
        theirs = central.windows_of_models([model_id, 10**9])
    assert [w["model_id"] for w in mine] == [model_id]
    assert [(w["id"], w["t_to"], w["model_id"]) for w in theirs] == [
        (w["id"], w["t_to"], w["model_id"]) for w in mine
    ]


def test_a_window_page_from_the_centre(sites: dict[str, Site], central_url: str) -> None:
    with dashboard([sites["line-a"].loop.path], None) as (client, _):
        history = client.get("/api/loops/line-a/history").json()
        window_id = next(w["id"] for w in reversed(history["windows"]) if w["accepted"])
        local = client.get(f"/api/loops/line-a/windows/{window_id}").json()
    with dashboard([], central_url) as (client, _):
        answer = client.get(f"/api/loops/line-a/windows/{window_id}")
        page = client.get(f"/loops/line-a/windows/{window_id}")
        loop_page = client.get("/loops/line-a")
    assert answer.status_code == 200, answer.text
    central = answer.json()
    assert central["window"] == local["window"]
    assert central["gates_verdict"] == local["gates_verdict"]
    assert central["evidence"]["samples"] == 0 < local["evidence"]["samples"]
    assert page.status_code == 200
    hint = "raw samples stay at the site; start the dashboard with --archive dir to draw them"
    assert hint in page.text.lower()
    # no samples, no empty plots: the charts' containers and the report's link are absent
    for chart in ('id="fit"', 'id="resid"', 'id="acf"', f"/windows/{window_id}/report"):
        assert chart not in page.text, chart
    assert loop_page.status_code == 200
    assert hint in loop_page.text.lower()
    assert 'id="trend"' not in loop_page.text
    assert 'id="live"' not in loop_page.text  # nothing to follow live
    assert 'id="models"' in loop_page.text  # the model history is drawn from the central rows


def test_with_an_archive_the_trend_of_a_central_loop_is_the_stores(
    sites: dict[str, Site], central_url: str, tmp_path: Path
) -> None:
    """Raw and level of detail: the archive's samples give the trend the store gives.

    line-b: its NULL samples (599, quality bad) test the buckets' NaN rule and bad counts.
    """
    from fuelid.archive import archive_store

    site = sites["line-b"]
    day_after = dt.datetime.fromtimestamp(site.loop.t_last, dt.UTC).date() + dt.timedelta(1)
    archive_store(site.store, tmp_path / "archive", day_after.isoformat())
    t0 = site.loop.t_first + 3600.0  # a bad stretch begins here: 30 s of NULL samples
    spans = {"raw": (t0 - 60.0, t0 + 240.0), "lod": (t0 - 1800.0, t0 + 5400.0)}
    answers: dict[str, dict[str, Any]] = {}
    for name, stores, url in (("local", [site.loop.path], None), ("central", [], central_url)):
        with dashboard(stores, url, archive=tmp_path / "archive") as (client, _):
            for kind, (start, end) in spans.items():
                got = client.get(f"/api/loops/line-b/trend?start={start}&end={end}&width=400")
                assert got.status_code == 200, got.text
                answers[f"{name} {kind}"] = got.json()
            if name == "central":
                page = client.get("/loops/line-b").text
    assert answers["local raw"]["source"] == "raw"
    assert answers["local lod"]["source"] == "lod"
    assert answers["local lod"]["level_s"] == 1  # 2 h: 7,200 buckets of 1 s
    for kind in spans:
        assert answers[f"central {kind}"] == answers[f"local {kind}"], kind
    assert len(answers["central raw"]["bad"]) == 299  # the NULL samples of the stretch, 30 s
    assert "Samples from the raw archive" in page
    assert 'id="trend"' in page  # with its samples the chart is drawn


def test_an_approve_on_a_central_loop_is_relayed_and_carried_out_by_the_site(
    sites: dict[str, Site], central_url: str, tmp_path: Path
) -> None:
    users = UsersFile(tmp_path / "users.json")
    engineer = users.add("eve", "engineer")
    viewer = users.add("vic", "viewer")
    site = sites["line-a"]
    with dashboard([], central_url, Security(users, require_login=False)) as (client, _):
        status = client.get("/api/loops/line-a/status").json()
        (pending,) = status["pending_proposals"]
        url = f"/api/loops/line-a/proposals/{pending['id']}/approve"
        seen = {"seen_status": pending["status"], "seen_history_len": len(pending["history"])}
        form = {"why": "checked centrally", **seen}
        assert client.post(url, data=form).status_code == 401
        client.post("/login", data={"name": "vic", "token": viewer, "next": "/"})
        csrf = client.get("/api/whoami").json()["csrf"]
        assert client.post(url, data=form, headers={CSRF_HEADER: csrf}).status_code == 403
        client.post("/logout", headers={CSRF_HEADER: csrf})
        client.post("/login", data={"name": "eve", "token": engineer, "next": "/"})
        csrf = client.get("/api/whoami").json()["csrf"]
        assert client.post(url, data=form).status_code == 403  # no CSRF token
        before = time.time()
        answer = client.post(url, data=form, headers={CSRF_HEADER: csrf})
        assert answer.status_code == 200, answer.text
        request = answer.json()["request"]
        assert "next sync" in answer.json()["next"]
        # nothing happened at the site yet: the request waits centrally, with its expiry
        assert site.history.proposal(pending["id"])["status"] == "pending"
        page = client.get("/loops/line-a").text
        assert "waiting for the site&#39;s next sync (expires" in page
        # the site's link: one cycle files it locally, the beat applies it, the next reports
        cycle = site.link.cycle()
        assert cycle.error is None
        assert [r["origin"] for r in cycle.filed] == [f"central:{request['id']}"]
        consume_requests(site.history, "approve")
        site.sync()
        after = client.get("/api/loops/line-a/status").json()
        page = client.get("/loops/line-a").text
    assert (request["status"], request["who"], request["origin"]) == ("waiting", "eve", "dashboard")
    assert (request["seen_status"], request["seen_history_len"]) == ("pending", 1)
    # the expiry is the default hour from when it was filed (the central clock, same machine)
    assert abs(request["expires"] - request["created"] - 3600.0) < 1e-3
    assert before - 5.0 < request["created"] < time.time() + 5.0
    assert site.history.proposal(pending["id"])["status"] == "approved"
    (row,) = after["central"]["requests"]
    assert (row["status"], row["outcome"]) == ("done", f"proposal {pending['id']} approved by eve")
    assert after["pending_proposals"][0]["status"] == "approved"
    assert f"done: proposal {pending['id']} approved by eve" in page


def test_a_second_request_for_a_waiting_proposal_is_refused_and_a_stopped_site_warned(
    sites: dict[str, Site], central_url: str, tmp_path: Path
) -> None:
    from fuelid.io import format_time

    users = UsersFile(tmp_path / "users.json")
    token = users.add("eve", "engineer")
    site = sites["line-a"]
    stop = time.time() - 60.0
    record = {"pid": 1, "host": "site-a", "beat": stop, "started": stop - 600.0}
    site.history.set_state(SERVICE_KEY, {**record, "stopped": stop, "settings": {}})
    site.sync()
    with dashboard([], central_url, Security(users, require_login=False)) as (client, _):
        client.post("/login", data={"name": "eve", "token": token, "next": "/"})
        csrf = {CSRF_HEADER: client.get("/api/whoami").json()["csrf"]}
        (pending,) = client.get("/api/loops/line-a/status").json()["pending_proposals"]
        url = f"/api/loops/line-a/proposals/{pending['id']}"
        first = client.post(f"{url}/approve", data={"why": "go"}, headers=csrf)
        again = client.post(f"{url}/approve", data={"why": "go again"}, headers=csrf)
        reject = client.post(f"{url}/reject", data={"why": "changed my mind"}, headers=csrf)
        page = client.get("/loops/line-a").text
        requests = client.get("/api/loops/line-a/status").json()["central"]["requests"]
    assert first.status_code == 200, first.text
    request = first.json()["request"]
    expires = format_time(request["expires"], "UTC")
    warning = (
        "the site's service is stopped: the request will expire unless it starts before "
        f"{expires} (wall clock)"
    )
    assert first.json()["next"].endswith(f"Warning: {warning}")
    for answer in (again, reject):  # one request per proposal at a time, whatever its kind
        assert answer.status_code == 409
        assert answer.json()["error"] == (
            f"request {request['id']} (approve by eve) for proposal #{pending['id']} already "
            f"waits for the site (expires {expires}, wall clock): one at a time"
        )
    assert [r["id"] for r in requests] == [request["id"]]  # nothing else was filed
    # the proposal says what waits, warns, and offers no button meanwhile
    assert (
        f"approve filed by eve, waiting for the site&#39;s next sync, expires {expires} "
        "(wall clock)"
    ) in page
    assert warning.replace("'", "&#39;") in page
    card = page.split(f'data-proposal="{pending["id"]}" data-state=', 1)[1]
    card = card.split("</form>", 1)[0]
    assert card.count("disabled") == 2  # approve and reject


def test_a_request_on_a_proposal_changed_since_it_was_seen_is_refused(
    sites: dict[str, Site], central_url: str
) -> None:
    site = sites["line-a"]
    with dashboard([], central_url) as (client, loops):
        (pending,) = client.get("/api/loops/line-a/status").json()["pending_proposals"]
        loop = loops.get("line-a")
        assert loop is not None
        request = loop.file_request(
            "approve", pending["id"], "eve", "go", {"status": "pending", "history_len": 1}
        )
        site.history.set_proposal_status(pending["id"], "rejected", who="bob", why="at the site")
        site.sync()
        (row,) = client.get("/api/loops/line-a/status").json()["central"]["requests"]
    assert row["id"] == request["id"]
    assert row["status"] == "refused"
    assert row["outcome"] == f"proposal {pending['id']} is now rejected (was pending)"


def test_a_site_not_heard_from_shows_no_contact_not_stopped(
    sites: dict[str, Site], central_url: str
) -> None:
    site = sites["line-b"]
    record = {"pid": 1, "host": "site-b", "beat": time.time(), "started": time.time() - 60.0}
    site.history.set_state(SERVICE_KEY, {**record, "stopped": None, "settings": {}})
    site.sync()
    with dashboard([], central_url) as (client, _):
        fresh = client.get("/api/loops/line-b/status").json()["link"]
        with connect(central_url) as con:  # the site's network went down 3 minutes ago
            con.execute("UPDATE liveness SET updated = now() - interval '3 minutes'")
            con.commit()
        old = client.get("/api/loops/line-b/status").json()["link"]
        row = _rows(client)["line-b"]
    # a running service, as of the site's last sync (its link up or down by its samples' age)
    assert fresh["service"] == "running"
    assert fresh["state"] in ("up", "link_down")
    assert fresh["no_contact_after_s"] == 30.0  # 3 sends of 5 s, at least 30 s
    assert old["state"] == "no_contact"
    assert old["state_at_contact"] == fresh["state"]
    assert old["text"].startswith("no contact with the site for 3 min (last sync ")
    assert 179.0 < old["contact_age_s"] < 200.0
    service = next(c for c in row["chips"] if c["name"] == "service")
    assert (service["level"], service["text"]) == ("warn", old["text"])


def test_a_stopped_service_says_when_it_stopped_and_how_long_ago_now(
    sites: dict[str, Site], central_url: str
) -> None:
    """The stop's age runs to now (the centre's clock), not to the site's last sync."""
    site = sites["line-b"]
    stop = time.time() - 60.0  # stopped a minute before the sync below
    record = {"pid": 1, "host": "site-b", "beat": stop, "started": stop - 600.0}
    site.history.set_state(SERVICE_KEY, {**record, "stopped": stop, "settings": {}})
    site.sync()
    with dashboard([], central_url) as (client, _):
        with connect(central_url) as con:  # and that sync was 2 minutes ago
            con.execute("UPDATE liveness SET updated = now() - interval '2 minutes'")
            con.commit()
        link = client.get("/api/loops/line-b/status").json()["link"]
        row = _rows(client)["line-b"]
        page = client.get("/loops/line-b").text
    clock = dt.datetime.fromtimestamp(stop, dt.UTC).strftime("%H:%M:%S")
    # 60 s before the sync + 120 s since: 180 s (3 min) however long the test takes (< 30 s)
    expected = f"service stopped at {clock} UTC (3 min ago, wall clock)"
    assert link["state"] == "stopped"  # a clean stop stays stopped, not "no contact"
    assert link["text"] == expected
    assert 179.0 < link["stopped_age_s"] < 210.0
    service = next(c for c in row["chips"] if c["name"] == "service")
    assert (service["level"], service["text"]) == ("alarm", expected)
    assert expected in page


def test_a_central_store_lost_while_serving_leaves_the_local_loops(
    sites: dict[str, Site], central_url: str, pg_cluster: Any
) -> None:
    """The database goes (its connections cut, then renamed away) and comes back."""
    dbname = central_url.rsplit("/", 1)[1].split("?")[0]
    with dashboard([sites["line-b"].loop.path], central_url) as (client, loops):
        assert loops.central is not None
        loops.central.every_s = 0.0  # the list of loops read at every request
        loops.central.db.retry_s = 0.0  # reconnect at the next read, not in 5 s
        assert sorted(_rows(client)) == ["line-a", "line-b"]
        assert "central loop line-b" in loops.not_shown()  # shadowed by the local store
        with connect(pg_cluster.url()) as admin:
            admin.autocommit = True
            admin.execute(
                "SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE datname = %s",
                (dbname,),
            )
            admin.execute(f'ALTER DATABASE "{dbname}" RENAME TO "{dbname}_gone"')
        try:
            answer = client.get("/api/loops").json()
            page = client.get("/")
            loop_page = client.get("/loops/line-a")
            local_page = client.get("/loops/line-b")
        finally:
            with connect(pg_cluster.url()) as admin:
                admin.autocommit = True
                admin.execute(f'ALTER DATABASE "{dbname}_gone" RENAME TO "{dbname}"')
        back = client.get("/api/loops").json()
    assert [row["loop_id"] for row in answer["loops"]] == ["line-b"]
    assert [row["loop_id"] for row in back["loops"]] == ["line-a", "line-b"]
    assert back["central"]["error"] is None
    assert answer["central"]["error"] is not None
    assert "central loop line-a" in answer["refused"]
    assert page.status_code == 200
    assert "cannot be read now" in page.text
    assert loop_page.status_code == 503
    assert local_page.status_code == 200


def test_the_fleet_page_of_an_unreachable_central_store_alone_says_so(
    sites: dict[str, Site], central_url: str, pg_cluster: Any
) -> None:
    """No local store: not "give --store or --central" but why the central loops are away."""
    dbname = central_url.rsplit("/", 1)[1].split("?")[0]
    with dashboard([], central_url) as (client, loops):
        assert loops.central is not None
        loops.central.every_s = 0.0  # the list of loops read at every request
        loops.central.db.retry_s = 0.0  # reconnect at the next read, not in 5 s
        assert sorted(_rows(client)) == ["line-a", "line-b"]
        with connect(pg_cluster.url()) as admin:
            admin.autocommit = True
            admin.execute(
                "SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE datname = %s",
                (dbname,),
            )
            admin.execute(f'ALTER DATABASE "{dbname}" RENAME TO "{dbname}_gone"')
        try:
            first = client.get("/api/loops").json()["central"]["error"]
            page = client.get("/").text
            latest = client.get("/api/loops").json()["central"]["error"]
        finally:
            with connect(pg_cluster.url()) as admin:
                admin.autocommit = True
                admin.execute(f'ALTER DATABASE "{dbname}_gone" RENAME TO "{dbname}"')
    # the connection was cut, then the database went (renamed): the banner says the latter
    assert first is not None
    assert f'database "{dbname}" does not exist' in latest
    assert "terminating connection" not in page
    banner = page.split('id="central-banner">', 1)[1].split("</p>", 1)[0]
    assert f"database &#34;{dbname}&#34; does not exist" in banner  # the latest error
    assert "the local stores are" not in banner  # there are none
    assert banner.count("central store postgresql://") == 1  # the URL said once
    assert "No loop yet" not in page
    assert "The central store is unreachable: " in page


def test_an_unreachable_central_store_at_start_is_one_line_and_exit_2(
    capsys: pytest.CaptureFixture[str],
) -> None:
    url = "postgresql://fuelid@127.0.0.1:9/none"  # nothing listens on port 9 (discard)
    code = cli_main(["dashboard", "--central", url, "--port", "0"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1
    assert err.startswith("error: --central: central store postgresql://fuelid@127.0.0.1:9/none")


def test_the_fleet_and_a_central_loop_page_load_in_a_browser_without_a_console_error(
    sites: dict[str, Site], central_url: str, tmp_path: Path
) -> None:
    """``fuelid dashboard --central URL`` as a process, Debian's Chromium on its pages."""
    from support.browser import browser_page, wait_ready, wait_until
    from support.browser import dashboard as dashboard_process

    window = sites["line-a"].history.last_window()
    assert window is not None
    with (
        dashboard_process(tmp_path, "--central", central_url) as (_, base),
        browser_page() as (page, errors),
    ):
        for path in ("/", "/loops/line-a", f"/loops/line-a/windows/{window['id']}"):
            page.goto(base + path)
            wait_ready(page)
            assert page.locator("h1").count() == 1, path
        page.goto(base + "/")
        wait_ready(page)
        fleet = page.locator("#fleet tbody tr").count()
        banner = page.locator("#central-banner").inner_text()
        page.goto(base + "/loops/line-a")
        wait_ready(page)
        note = page.locator("#samples-note").inner_text()
        page.locator("#models").scroll_into_view_if_needed()  # plotly loads when shown
        wait_until(page, "document.getElementById('analysis').dataset.drawn")
        models = page.evaluate("document.getElementById('models').data[0].x.length")
    assert errors == []
    assert fleet == 2
    assert "loops of the central store" in banner
    assert note.startswith("Raw samples stay at the site")
    history = sites["line-a"].history
    assert models == sum(w["accepted"] for w in history.windows())  # the model history drawn


def test_the_dashboards_role_needs_only_the_documented_rights(
    sites: dict[str, Site], central_url: str, pg_cluster: Any
) -> None:
    """SELECT on the tables, INSERT on requests, USAGE on its sequence (docs: central.md)."""
    dbname = central_url.rsplit("/", 1)[1].split("?")[0]
    role = f"dash_{dbname}"
    with connect(central_url) as owner:
        owner.autocommit = True
        owner.execute(f"CREATE ROLE {role} LOGIN")
        owner.execute(f"GRANT CONNECT ON DATABASE {dbname} TO {role}")
        owner.execute(f"GRANT USAGE ON SCHEMA public TO {role}")
        owner.execute(f"GRANT SELECT ON ALL TABLES IN SCHEMA public TO {role}")
        owner.execute(f"GRANT INSERT ON requests TO {role}")
        owner.execute(f"GRANT USAGE ON SEQUENCE requests_id_seq TO {role}")
    url = central_url.replace("://fuelid@", f"://{role}@")
    with dashboard([], url) as (client, loops):
        assert sorted(_rows(client)) == ["line-a", "line-b"]
        (pending,) = client.get("/api/loops/line-a/status").json()["pending_proposals"]
        loop = loops.get("line-a")
        assert loop is not None
        request = loop.file_request("approve", pending["id"], "eve", "with the dashboard's role")
    assert request["status"] == "waiting"
