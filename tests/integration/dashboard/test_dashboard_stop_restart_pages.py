"""The pages and the commands after the service stopped or restarted (issue 39, a held-out trial).

Over a copy of the session's ``dashboard_store`` (a virtual run that ended: its service is
stopped), as served by the dashboard and printed by ``fuelid online status`` and ``history``:

- a stopped service's write-back is said as of its last run, and an out-of-date proposal does
  not promise new windows while nothing runs to judge them;
- a service running again (its record as a restart leaves it) keeps the live chips unknown
  until it judged a window of its own, then colours them again;
- a revert's two instants (issued, verified) are the same on the command and on the page.
"""

from __future__ import annotations

import html
import shutil
import sqlite3
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("fastapi")

from fastapi.testclient import TestClient

from fuelid.cli import main as cli_main
from fuelid.dashboard import Loops, Security, UsersFile, create_app
from fuelid.dashboard._fleet import LIVE_CHIPS
from fuelid.io import format_time
from fuelid.online import RECENT_WINDOWS_SPAN
from fuelid.store import SERVICE_KEY, OnlineHistory, SQLiteStore

# xdist: one worker runs the dashboard's modules, which share one store made once
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("dashboard")


@pytest.fixture
def loop_db(dashboard_store: Path, tmp_path: Path) -> Path:
    return Path(shutil.copy(dashboard_store, tmp_path / "loop.db"))


@pytest.fixture
def served(loop_db: Path, tmp_path: Path) -> Iterator[tuple[TestClient, str]]:
    """The dashboard over the store, an engineer logged in (the actions and their questions)."""
    users = UsersFile(tmp_path / "users.json")
    token = users.add("eve", "engineer")
    loops = Loops([loop_db])
    try:
        (loop_id,) = loops.ids()
        client = TestClient(create_app(loops, Security(users, require_login=False)))
        client.post("/login", data={"name": "eve", "token": token, "next": "/"})
        yield client, loop_id
    finally:
        loops.close()


def _cli(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    capsys.readouterr()
    assert cli_main(list(args)) == 0
    return capsys.readouterr().out


def _page(client: TestClient, loop_id: str) -> str:
    answer = client.get(f"/loops/{loop_id}")
    assert answer.status_code == 200
    return html.unescape(answer.text)


def _chips(client: TestClient) -> dict[str, dict[str, str]]:
    (row,) = client.get("/api/loops").json()["loops"]
    return {c["name"]: c for c in row["chips"]}


def _out_of_date_proposal(loop_db: Path) -> int:
    """A pending proposal whose window ended long before the newest sample (the age rule)."""
    with SQLiteStore(loop_db) as store, OnlineHistory(store) as history:
        (model,) = history.accepted_models(limit=1)
        settings = (history.state(SERVICE_KEY) or {}).get("settings") or {}
        pid = history.add_proposal(
            model_id=model["id"],
            old={"Kc": 0.04, "Ti": 1.4},
            new={"Kc": 0.045, "Ti": 1.4},
            detail={"reason": "test: evidence from long ago"},
        )
    shift = 2.0 * RECENT_WINDOWS_SPAN * float(settings["window_s"])
    with sqlite3.connect(loop_db) as con:
        con.execute(
            "UPDATE models SET t_from = t_from - ?1, t_to = t_to - ?1 WHERE id = ?2",
            (shift, model["id"]),
        )
    return pid


def test_a_stopped_service_is_said_as_of_its_last_run(
    loop_db: Path, served: tuple[TestClient, str], capsys: pytest.CaptureFixture[str]
) -> None:
    pid = _out_of_date_proposal(loop_db)
    with SQLiteStore(loop_db) as store, OnlineHistory(store) as history:  # one the age rule spares
        fresh = history.add_proposal(
            model_id=None, old={"Kc": 0.04, "Ti": 1.4}, new={"Kc": 0.042, "Ti": 1.4},
            detail={"reason": "test: no window to judge"},
        )  # fmt: skip
    client, loop_id = served
    status = client.get(f"/api/loops/{loop_id}/status").json()
    assert status["link"]["state"] == "stopped"
    stop = format_time(status["link"]["newest_sample"], status["timezone"]).split(" ", 1)[1]
    page = _page(client, loop_id)
    assert (
        f"Write-back: approve when the service last ran (stopped at {stop}); nothing is written "
        "while it is stopped." in page
    )
    assert "Write-back: approve." not in page
    # the "Now" table too
    assert "approve when the service last ran (stopped at " in page.split('id="now"', 1)[1]
    # an approval's question says when it would be written
    card = page.split(f'data-proposal="{fresh}"', 1)[1].split("</form>", 1)[0]
    assert "(the service is stopped: written when it runs again, at its first write check" in card
    # the out-of-date proposal: its reason, without a promise no running service backs
    (stale,) = [p["stale"] for p in status["pending_proposals"] if p["id"] == pid]
    assert stale.endswith("; new windows will propose afresh when the service runs again")
    assert stale in page
    assert "propose afresh<" not in page
    assert "propose afresh." not in page
    # the command says the same of it
    assert stale in _cli(capsys, "online", "status", "--store", str(loop_db))


def _judge_like(
    history: OnlineHistory, last: dict[str, Any], t_from: float, t_to: float, judged: float
) -> None:
    """A window over ``t_from``…``t_to`` judged at plant time ``judged``, else like ``last``."""
    history.add_window(
        t_from=t_from,
        t_to=t_to,
        accepted=False,
        reason="test: judged after the restart",
        detail=dict(last.get("detail") or {}),
        T_fuel=last.get("T_fuel"),
        u_mean=last.get("u_mean"),
        time=judged,
    )
    history.beat()


def test_a_restarted_service_greys_the_live_chips_until_its_first_window(
    loop_db: Path, served: tuple[TestClient, str]
) -> None:
    client, _ = served
    assert {_chips(client)[name]["level"] for name in LIVE_CHIPS} == {"unknown"}  # stopped
    with SQLiteStore(loop_db) as store, OnlineHistory(store) as history:
        newest = history.plant_now()
        assert newest is not None
        last = history.last_window()
        assert last is not None
        record = history.state(SERVICE_KEY)
        # restarted: beating, its first sample 1 s of plant time after the previous run's last
        now = time.time()
        restart = newest + 1.0
        history.set_state(
            SERVICE_KEY,
            {**record, "started": now, "beat": now, "stopped": None, "started_plant": restart},
        )
        chips = _chips(client)
        tz = client.get("/api/loops").json()["loops"][0]["timezone"]
        since = f"unknown since the restart at {format_time(restart, tz).split(' ', 1)[1]}"
        for name in LIVE_CHIPS:
            assert chips[name]["level"] == "unknown", chips[name]
            assert chips[name]["text"].startswith(
                f"{since}: no window of its own yet (last before: "
            )
        # a window judged after the restart but opened before it: the previous run's samples
        # and the outage (the held-out trial's #102): still not the restarted service's health
        _judge_like(history, last, newest - 60.0, newest, restart + 1.0)
        chips = _chips(client)
        for name in LIVE_CHIPS:
            assert chips[name]["level"] == "unknown", chips[name]
            assert chips[name]["text"].startswith(f"{since}: no window of its own yet"), chips
        # its first window of its own: opened at the restart, on its own samples
        _judge_like(history, last, restart, restart + 60.0, restart + 61.0)
        chips = _chips(client)
    for name in LIVE_CHIPS:
        assert "since the restart" not in chips[name]["text"], chips[name]
    assert chips["mode"]["level"] != "unknown"


def test_a_revert_has_the_same_two_instants_on_the_command_and_the_page(
    loop_db: Path, served: tuple[TestClient, str], capsys: pytest.CaptureFixture[str]
) -> None:
    with SQLiteStore(loop_db) as store, OnlineHistory(store) as history:
        newest = history.plant_now()
        assert newest is not None
        write_id = history.begin_write(
            kind="revert", kc=0.04, ti=1.4, apply_seq=(history.last_apply_seq() or 0) + 1,
            who="eve", why="too lively", time=newest - 100.0,
        )  # fmt: skip
        history.finish_write(write_id, "verified", {}, time=newest - 96.0)
        tz = str((history.state(SERVICE_KEY) or {})["settings"]["timezone"])
    issued = format_time(newest - 100.0, tz)
    verified = format_time(newest - 96.0, tz)
    assert issued.split(" ")[0] == verified.split(" ")[0]  # one day: the second without it
    both = f"issued at {issued}, verified at {verified.split(' ', 1)[1]}"
    status = _cli(capsys, "online", "status", "--store", str(loop_db))
    assert f"last write #{write_id} revert verified (Kc 0.04, Ti 1.4): {both}" in status
    history_out = _cli(capsys, "online", "history", "--store", str(loop_db))
    assert f"#{write_id} revert verified Kc 0.04 Ti 1.4 by eve: {both}" in history_out
    client, loop_id = served
    now_table = _page(client, loop_id).split('id="now"', 1)[1]
    assert f"#{write_id} revert verified: {both}" in now_table
