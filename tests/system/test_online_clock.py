"""One clock (issue "one clock"): plant time in every row, the service's liveness on the wall clock.

An accelerated virtual run (50x) whose windows, proposals and writes come out in plant-time
order, with the service record a reader needs; a service killed with SIGKILL read as stopped
within SERVICE_STALE_S + 2 beats.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from fuelid.cli import main
from fuelid.online import SERVICE_BEAT_S, SERVICE_STALE_S, status_json
from fuelid.store import OnlineHistory, SQLiteStore
from support.waiting import wait_until

SERVICE_KEYS = {
    "pid",
    "host",
    "version",
    "started",
    "beat",
    "beat_every_s",
    "stopped",
    "settings",
}


@pytest.mark.slow  # 15 s of a virtual run at 50x (the fast set's 6-min budget)
def test_an_accelerated_run_files_everything_in_plant_time_order(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("pymodbus", reason="the [plc] extra (pymodbus) is not installed")
    online = tmp_path / "online.toml"
    online.write_text('[online]\nidentify_every_s = 60\nwindow_s = 120\nwrite_back = "auto"\n')
    db = tmp_path / "virtual.db"
    started = time.time()
    code = main(
        ["online", "--virtual", "--speed", "50", "--hours", "0.2", "--store", str(db),
         "--config", str(online)]
    )  # fmt: skip
    ended = time.time()
    capsys.readouterr()
    assert code == 0
    with SQLiteStore(db) as store, OnlineHistory(store) as history:
        windows = history.windows()
        proposals = history.proposals()
        writes = history.writes()
        record = history.state("service")
        newest = store.last_time()
        status = status_json(history, store)
    assert len(windows) >= 5
    # plant time runs ahead of the wall clock (50x): the windows end after the run's wall end
    assert windows[-1]["t_to"] > ended + 60.0
    for w in windows:
        assert w["time"] >= w["t_to"]  # analysed after its data, in plant time
        assert started <= w["wall_time"] <= ended
    assert [w["time"] for w in windows] == sorted(w["time"] for w in windows)
    assert proposals, "the run filed no proposal: its plant-time order is not checked"
    by_model = {w["model_id"]: w for w in windows if w["model_id"] is not None}
    for p in proposals:
        assert p["time"] >= by_model[p["model_id"]]["t_to"]  # never before its window
        assert p["time"] <= newest
        assert started <= p["wall_time"] <= ended
        for entry in p["history"]:
            assert entry["time"] >= p["time"]
            assert started <= entry["wall_time"] <= ended
    proposal_time = {p["id"]: p["time"] for p in proposals}
    for w in writes:
        assert w["time"] >= proposal_time[w["proposal_id"]]
        assert w["finished"] >= w["time"]
        assert started <= w["wall_time"] <= w["finished_wall"] <= ended
    # the service's record: every key, stopped at the clean end, the settings a reader needs
    assert set(record) >= SERVICE_KEYS
    assert started <= record["started"] <= record["beat"] <= record["stopped"] <= ended
    assert record["beat_every_s"] == SERVICE_BEAT_S
    settings = record["settings"]
    assert settings["write_back"] == "auto"
    assert settings["timezone"] == "UTC"
    assert settings["loop_id"] == "virtual-fuel-loop"
    assert len(settings["plant_hash"]) == 64
    assert settings["gain_units"] == {"Kc": "V per L/min", "Ti": "s"}
    assert settings["controller"]["form"] == "ideal"
    # read back without --config: stopped, and the write-back known from the record
    assert status["link"]["state"] == "stopped"
    assert status["service"]["state"] == "stopped"
    assert status["write_back"]["setting"] == "auto"
    assert status["write_back"]["setting_from"] == "service"
    code = main(["online", "status", "--store", str(db)])
    out = capsys.readouterr().out
    assert code == 0
    assert "service stopped (" in out
    # the stop's wall age and the newest sample's plant time, each labelled (issue 39)
    assert " ago in wall time; newest sample at " in out
    assert " plant time)" in out
    assert "write_back auto (from the last service's settings)" in out
    code = main(["online", "history", "--store", str(db)])
    out = capsys.readouterr().out
    assert code == 0
    assert " V per L/min" in out  # the gains in the block's units


# the slow set: 15 s of a virtual run (the fast set's 6-min budget); the dashboard's slow browser
# test kills a service with SIGKILL too and reads the stop on the page
@pytest.mark.slow
def test_a_service_killed_with_sigkill_reads_stopped_within_five_beats_and_two(
    tmp_path: Path,
) -> None:
    pytest.importorskip("pymodbus", reason="the [plc] extra (pymodbus) is not installed")
    db = tmp_path / "killed.db"
    child = subprocess.Popen(
        [sys.executable, "-m", "fuelid", "online", "--virtual", "--speed", "20", "--hours", "1",
         "--store", str(db)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # the service and its worker: one group, killed at once
    )  # fmt: skip
    try:
        assert child.stderr is not None
        for line in child.stderr:  # wait until the service records
            if "connected to" in line:
                break

        def read_status() -> dict[str, Any]:
            with SQLiteStore(db) as store, OnlineHistory(store) as history:
                return status_json(history, store)

        # beats of the service: the status reads it running, the link up
        live = wait_until(
            lambda: (s := read_status())["link"]["state"] == "up" and s, 5 * SERVICE_BEAT_S,
            lambda: f"the link up: {read_status()['link']}",
        )  # fmt: skip
        assert live["service"]["state"] == "running"
        os.killpg(child.pid, signal.SIGKILL)
        child.wait(timeout=10)
        # the behaviour: the status reads stopped within five beats and two (its deadline)
        stopped = wait_until(
            lambda: (s := read_status())["link"]["state"] == "stopped" and s,
            SERVICE_STALE_S + 2 * SERVICE_BEAT_S,
            lambda: f"the status to read stopped: {read_status()['link']}",
            every=0.5,
        )
    finally:
        if child.poll() is None:
            os.killpg(child.pid, signal.SIGKILL)
            child.wait()
        if child.stderr is not None:
            child.stderr.close()
    assert stopped["service"]["stopped"] is None  # killed: never wrote its stop
    assert stopped["service"]["state"] == "stopped"
    assert "no beat for" in stopped["link"]["text"]
    assert " of wall time; newest sample at " in stopped["link"]["text"]
    assert json.dumps(stopped)  # plain JSON
