"""A service killed and started again, watched on the loop page in a real browser (issue 39).

A held-out trial saw the mode, limits and oscillation chips turn green within 3 s of the
service's restart, from the health of the window judged before the kill. The rule
(``fuelid.dashboard._fleet``): the chips about the running loop stay unknown, "unknown since
the restart at …", until the service has judged a window of its own (opened at or after the
plant time of its first sample, the record's ``started_plant``). Slow: a virtual run at 20x,
a kill -9, the stop read on the page, the restart on the same store, until its first window.
"""

from __future__ import annotations

import json
import signal
import sqlite3
import time
from contextlib import ExitStack, closing
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("fastapi")
pytest.importorskip("pymodbus")

from fuelid.dashboard._fleet import LIVE_CHIPS
from fuelid.dashboard._stream import STATUS_EVERY_S
from support.browser import browser_page, dashboard, page_chips, virtual_service, wait_ready

# xdist: one worker runs the dashboard's modules (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("dashboard")

ONLINE = '[online]\nidentify_every_s = 120\nwindow_s = 120\nwrite_back = "approve"\n'
"""A window every 2 min of plant time: 6 s of wall time at 20x."""
LOOK_EVERY_S = 0.5
"""Wall time between two looks at the chips [s]."""
STOP_BAND_S = 25.0
"""The kill is read on the page within [s] (the slow browser test's bound, and room)."""
FIRST_WINDOW_BAND_S = 60.0
"""The restarted service judges its first window within [s of wall time]."""
COLOUR_BAND_S = 2 * STATUS_EVERY_S + LOOK_EVERY_S
"""The chips are coloured again within [s] of that window's commit: the next status event."""


def _one(store: Path, sql: str, args: tuple[Any, ...] = ()) -> Any:
    """One row of a query on the store the service is writing (read only)."""
    with closing(sqlite3.connect(f"file:{store}?mode=ro", uri=True, timeout=10.0)) as con:
        return con.execute(sql, args).fetchone()


def _judged_since(store: Path) -> tuple[float | None, int]:
    """The record's ``started_plant`` and the windows opened at or after it."""
    (value,) = _one(store, "SELECT value FROM online_state WHERE key = 'service'")
    started = json.loads(value).get("started_plant")
    if started is None:
        return None, 0
    (count,) = _one(store, "SELECT count(*) FROM windows WHERE t_from >= ?", (started,))
    return float(started), int(count)


def _windows(store: Path) -> int:
    (count,) = _one(store, "SELECT count(*) FROM windows")
    return int(count)


def _coloured(chips: dict[str, tuple[str, str]], name: str) -> bool:
    return chips.get(name, ("", ""))[0] not in ("", "unknown")


def _watch(page: Any, until: Any, band_s: float) -> dict[str, tuple[str, str]]:
    """Look at the chips every LOOK_EVERY_S until ``until(chips)``; the chips then."""
    deadline = time.monotonic() + band_s
    while True:
        chips = page_chips(page)
        if until(chips) or time.monotonic() > deadline:
            return chips
        page.wait_for_timeout(1000 * LOOK_EVERY_S)


def _watch_restart(page: Any, store: Path) -> list[tuple[float, int, dict[str, Any]]]:
    """Looks at the chips after the restart until its first window is on the page.

    Each: seconds since the first look, the windows the restarted service had judged before
    the look (read first: the status behind the chips is no newer), the chips.
    """
    looks: list[tuple[float, int, dict[str, Any]]] = []
    began = time.monotonic()
    judged_at = None
    while time.monotonic() - began < FIRST_WINDOW_BAND_S:
        _, judged = _judged_since(store)
        looks.append((time.monotonic() - began, judged, page_chips(page)))
        if judged and judged_at is None:
            judged_at = time.monotonic()
        if judged_at is not None and time.monotonic() - judged_at > COLOUR_BAND_S:
            break
        page.wait_for_timeout(1000 * LOOK_EVERY_S)
    return looks


@pytest.mark.slow  # two virtual runs of about half a minute each, a browser: the slow set
@pytest.mark.timeout(600)
def test_after_a_restart_the_live_chips_wait_for_the_services_own_window(tmp_path: Path) -> None:
    store = tmp_path / "loop.db"
    config = tmp_path / "online.toml"
    config.write_text(ONLINE)
    args = ("--speed", "20", "--hours", "2", "--config", str(config))
    with ExitStack() as running:  # the dashboard and the page outlive the first service
        first = running.enter_context(virtual_service(tmp_path, store, *args))
        first.wait_for(lambda line: "link up" in line)
        _, base = running.enter_context(dashboard(tmp_path, "--store", str(store)))
        page, errors = running.enter_context(browser_page())
        deadline = time.monotonic() + FIRST_WINDOW_BAND_S
        while _windows(store) < 2 and time.monotonic() < deadline:
            page.wait_for_timeout(500)
        page.goto(f"{base}/loops/virtual-fuel-loop")
        wait_ready(page)
        live = _watch(page, lambda c: _coloured(c, "mode"), 10.0)
        first.stop(signal.SIGKILL)
        stopped = _watch(page, lambda c: c.get("service", ("",))[0] == "alarm", STOP_BAND_S)
        again = running.enter_context(virtual_service(tmp_path, store, *args))
        again.wait_for(lambda line: "link up" in line)
        looks = _watch_restart(page, store)
        started_plant, _ = _judged_since(store)
    assert _coloured(live, "mode"), live  # the window judged before the kill
    assert stopped["mode"][1].startswith("unknown since the stop at"), stopped
    before = [(t, chips) for t, judged, chips in looks if judged == 0]
    assert before, "the restarted service judged a window before the first look"
    for t, chips in before:  # never coloured by the window judged before the kill
        for name in LIVE_CHIPS:
            assert chips[name][0] == "unknown", (f"{t:.1f} s after the restart", name, chips[name])
    assert started_plant is not None
    assert looks[-1][1] > 0, f"no window judged by the restarted service: {looks[-1]}"
    said = [chips["mode"][1] for _, chips in before]
    assert any(t.startswith("unknown since the restart at ") for t in said), said
    # its own window (and the next status event): coloured again
    last = looks[-1][2]
    assert _coloured(last, "mode"), last
    assert not last["mode"][1].startswith("unknown since"), last
    assert [e for e in errors if "ERR_" not in e] == []
