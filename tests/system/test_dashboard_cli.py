"""``fuelid dashboard`` and ``fuelid online --dashboard`` as a user runs them.

Refusals exit 2 with one line on stderr (a non-loopback address without --allow-remote, remote
access without a users file, no store, a store of a newer fuelid, two stores with one loop id, a
live trend's span that is not 1 to 1440 minutes); ``--trend-minutes`` reaches the loop page;
``fuelid online --virtual --dashboard`` serves the store's loop from a second process while the
service runs, and that process ends with the service.
"""

from __future__ import annotations

import json
import shutil
import sqlite3
import urllib.error
import urllib.request
from pathlib import Path

import pytest

pytest.importorskip("fastapi")

from fuelid.cli import main
from fuelid.store import SCHEMA_VERSION
from support.browser import Process, dashboard

# xdist: one worker runs the dashboard's modules, which share one store made once
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("dashboard")


def _refused(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    capsys.readouterr()
    assert main(["dashboard", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith("error: ")
    return err


def test_refusals_exit_2_with_one_line(
    dashboard_store: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    store = tmp_path / "loop.db"
    shutil.copy(dashboard_store, store)
    assert "not a loopback address" in _refused(capsys, "--store", str(store), "--host", "0.0.0.0")
    assert "users file" in _refused(
        capsys, "--store", str(store), "--host", "0.0.0.0", "--allow-remote"
    )
    assert "--store" in _refused(capsys)
    assert "no such file" in _refused(capsys, "--store", str(tmp_path / "absent.db"))
    twin = tmp_path / "twin"
    twin.mkdir()
    shutil.copy(store, twin / "loop.db")
    twin_store = str(twin / "loop.db")
    assert "already shown" in _refused(capsys, "--store", str(store), "--store", twin_store)
    with sqlite3.connect(store) as con:
        con.execute(f"PRAGMA user_version={SCHEMA_VERSION + 1}")
    assert "newer" in _refused(capsys, "--store", str(store))


def test_the_trend_minutes_reach_the_page_and_a_bad_span_is_refused(
    dashboard_store: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    store = tmp_path / "loop.db"
    shutil.copy(dashboard_store, store)
    for bad in ("0", "-5", "0.5", "1441", "inf", "nan", "ten"):
        err = _refused(capsys, "--store", str(store), "--trend-minutes", bad)
        assert "--trend-minutes" in err, (bad, err)
        reason = "a valid number" if bad == "ten" else f"from 1 to 1440, got {bad}"
        assert reason in err, (bad, err)
    with dashboard(tmp_path, "--store", str(store), "--trend-minutes", "2.5") as (_, base):
        (row,) = json.loads(urllib.request.urlopen(f"{base}/api/loops").read())["loops"]
        page = urllib.request.urlopen(f"{base}/loops/{row['loop_id']}").read().decode()
        trend = json.loads(
            urllib.request.urlopen(f"{base}/api/loops/{row['loop_id']}/trend").read()
        )
    assert 'data-minutes="2.5"' in page  # the span the page's trend follows
    assert "the newest 2.5 min, following" in page
    assert trend["end"] - trend["start"] == pytest.approx(150.0, abs=1e-3)  # the API's default


@pytest.mark.slow  # a 20 s virtual run: the slow set (CI runs it)
def test_online_dashboard_serves_beside_the_service_and_ends_with_it(tmp_path: Path) -> None:
    store = tmp_path / "loop.db"
    args = ["online", "--virtual", "--speed", "20", "--hours", "0.05", "--store", str(store)]
    proc = Process([*args, "--dashboard", "--dashboard-port", "0"], tmp_path)
    try:
        line = proc.wait_for(lambda s: s.startswith("dashboard: http"))
        base = line.split()[1].rstrip("/")
        with urllib.request.urlopen(f"{base}/api/loops", timeout=10) as answer:
            loops = json.loads(answer.read())["loops"]
        code = proc.wait(timeout=90)
    finally:
        proc.stop()
    assert code == 0, "\n".join(proc.output[-20:])
    assert [row["loop_id"] for row in loops] == ["virtual-fuel-loop"]
    with pytest.raises(urllib.error.URLError):  # the dashboard ended with the service
        urllib.request.urlopen(f"{base}/api/loops", timeout=5)
