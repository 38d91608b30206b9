"""The live trend's following and the pages' reconnection, in a real headless browser.

Slow (issue 39, "a dashboard the control room can leave open"):

- a loop page on a running virtual PLC: a drag across the trend or a range button stops
  following (``data-following`` "0", "follow live" shown, the axis' end no longer moving with the
  newest sample); "follow live" resumes it; the PLC's link then blips (back-filled) and drops
  longer than its ring holds (a gap): the trend keeps following with its axis the
  ``--trend-minutes`` span, and so does the page loaded afresh after them;
- a loop page and the fleet page open when the dashboard is killed (kill -9) say
  "disconnected", greyed; the dashboard started again on the same port, both say
  "reconnected at …" and un-grey by themselves.
"""

from __future__ import annotations

import collections
import json
import math
import re
import shutil
import signal
import sqlite3
import time
import urllib.request
from collections.abc import Iterator
from contextlib import closing, contextmanager
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("fastapi")
pytest.importorskip("pymodbus")

from fuelid.dashboard._stream import STATUS_EVERY_S
from fuelid.plc.virtual import VirtualPlcThread
from support.browser import (
    NETWORK_FAILURES,
    Process,
    TrendLook,
    browser_page,
    browser_pages,
    dashboard,
    following_faults,
    look_at_trend,
    port_of,
    wait_ready,
    wait_until,
)

# xdist: one worker runs the dashboard's modules (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("dashboard")


def _get(url: str) -> Any:
    with urllib.request.urlopen(url, timeout=10) as response:
        return json.loads(response.read())


# --- following, zooming, a blip and a gap --------------------------------------------------------

SPEED = 20.0
"""Plant time per wall time of the virtual PLC."""
TREND_MINUTES = 3.0
"""``fuelid dashboard --trend-minutes``: the span a following trend shows [min of plant time]."""
SPAN_TOLERANCE_S = 0.002
"""The axis' span against ``--trend-minutes`` [s] (the scale is set from the same numbers)."""
FOLLOW_ONLINE = "identify_every_s = 3600\nwindow_s = 3600\n"
"""The service records; no window in the run (the trend is what is looked at)."""
BLIP_S = 0.3
"""A link blip [s of wall time]: back at the recorder's first reconnect, back-filled."""
GAP_S = 4.0
"""A drop [s of wall time]: 80 s of plant time at 20x, more than the ring's 41 s (a gap)."""
LINK_BACK_S = 30.0
"""Wall time the recorder may take to be back on the link after a drop [s]."""
STILL_S = 3.0
"""Wall time a stopped trend is watched: 60 s of plant time arrive meanwhile [s]."""
FOLLOW_LOOKS = 3
"""Looks at a trend that must follow, :data:`FOLLOW_EVERY_S` apart."""
FOLLOW_EVERY_S = 2.0
"""Wall time between two looks at a following trend [s]: each must be newer than the one before,
and the service commits once a second."""

_SPANS = "trend.plots.map(({ plot }) => [plot.scales.x.min, plot.scales.x.max])"
"""The x scale of each of the trend's uPlot panels (``trend``: loop.js's LiveTrend)."""


@contextmanager
def _plc_and_service(cwd: Path, store: Path) -> Iterator[tuple[VirtualPlcThread, Process]]:
    """A virtual PLC in this process (its link can be dropped) and ``fuelid online`` on it.

    The PLC's heartbeat timeout is lifted: the service beats once a wall second, 20 s of
    plant time here (nothing is written in this run).
    """
    with VirtualPlcThread(
        speed=SPEED, setpoint_profile="run", heartbeat_timeout_s=1e6, seed=4
    ) as virtual:
        site = cwd / "site.toml"
        text = virtual.site_text(store_url=f"sqlite:///{store}")
        site.write_text(text + "\n[online]\n" + FOLLOW_ONLINE, encoding="utf-8")
        service = Process(["online", "--config", str(site), "--store", str(store)], cwd)
        try:
            yield virtual, service
        finally:
            service.stop(signal.SIGINT)


def _link_ups(store: Path) -> list[str]:
    """The details of the store's ``link_up`` events, oldest first."""
    with closing(sqlite3.connect(f"file:{store}?mode=ro", uri=True, timeout=10.0)) as con:
        rows = con.execute("SELECT detail FROM events WHERE kind = 'link_up' ORDER BY id")
        return [str(detail) for (detail,) in rows]


def _drop_link(page: Any, virtual: VirtualPlcThread, store: Path, seconds: float) -> str:
    """Drop the PLC's link for ``seconds`` of wall time; the ``link_up`` that ends it."""
    before = len(_link_ups(store))
    virtual.stop_link()
    page.wait_for_timeout(1000 * seconds)
    virtual.start_link()
    deadline = time.monotonic() + LINK_BACK_S
    while len(ups := _link_ups(store)) <= before:
        assert time.monotonic() < deadline, f"no link_up within {LINK_BACK_S} s of the drop"
        page.wait_for_timeout(200)
    return ups[-1]


def _spans(page: Any) -> list[float]:
    """The span of each trend panel's time axis [s]."""
    return [float(b) - float(a) for a, b in page.evaluate(_SPANS)]


def _follow_looks(page: Any, store: Path, what: str) -> list[tuple[str, TrendLook, list[str]]]:
    """FOLLOW_LOOKS looks at a trend that must follow: each with its faults.

    A fault: :func:`following_faults`, "follow live" shown, or an axis span other than
    ``--trend-minutes`` (on any panel).
    """
    looks: list[tuple[str, TrendLook, list[str]]] = []
    for _ in range(FOLLOW_LOOKS):
        look = look_at_trend(page, store)
        faults = following_faults(look, looks[-1][1] if looks else None)
        if page.locator("#live").is_visible():
            faults.append('"follow live" shown')
        spans = _spans(page)
        if any(abs(s - 60 * TREND_MINUTES) > SPAN_TOLERANCE_S for s in spans):
            faults.append(f"axis spans {spans} s")
        looks.append((what, look, faults))
        page.wait_for_timeout(1000 * FOLLOW_EVERY_S)
    return looks


def _still_looks(page: Any, store: Path, what: str) -> list[tuple[str, TrendLook, list[str]]]:
    """Two looks STILL_S apart at a trend that must not follow: each with its faults.

    Not following, "follow live" shown, the axis' end the same while the newest sample moves on.
    """
    first = look_at_trend(page, store)
    page.wait_for_timeout(1000 * STILL_S)
    second = look_at_trend(page, store)
    shown = page.locator("#live").is_visible()
    looks = []
    for look in (first, second):
        faults = []
        if look.following:
            faults.append("following")
        if not shown:
            faults.append('"follow live" hidden')
        if look.range_end is None or look.range_end != first.range_end:
            faults.append(f"the axis' end moved: {first.range_end} -> {look.range_end}")
        looks.append((what, look, faults))
    if not (second.newest or 0) > (first.newest or 0) + 0.5 * SPEED * STILL_S:
        looks[-1][2].append(f"no new samples drawn: {first.newest} -> {second.newest}")
    return looks


def _drag_across_trend(page: Any) -> None:
    """Drag across the flow panel from 30 % to 60 % of its width (a zoom into stored history)."""
    box = page.locator("#trend-flow .u-over").bounding_box()
    assert box is not None
    y = box["y"] + box["height"] / 2
    page.mouse.move(box["x"] + 0.3 * box["width"], y)
    page.mouse.down()
    page.mouse.move(box["x"] + 0.45 * box["width"], y, steps=5)
    page.mouse.move(box["x"] + 0.6 * box["width"], y, steps=5)
    page.mouse.up()


@pytest.mark.slow  # a minute of a virtual PLC at 20x with a page open: the slow set
@pytest.mark.timeout(600)
def test_the_trend_stops_following_on_a_zoom_resumes_on_follow_live_and_follows_across_a_gap(
    tmp_path: Path,
) -> None:
    store = tmp_path / "loop.db"
    minutes = f"{TREND_MINUTES:g}"
    looks: list[tuple[str, TrendLook, list[str]]] = []
    with _plc_and_service(tmp_path, store) as (virtual, service):
        service.wait_for(lambda line: "link up" in line)
        with dashboard(tmp_path, "--store", str(store), "--trend-minutes", minutes) as (_, base):
            (row,) = _get(f"{base}/api/loops")["loops"]
            with browser_page() as (page, errors):
                page.goto(f"{base}/loops/{row['loop_id']}")
                wait_ready(page)
                wait_until(page, "document.getElementById('trend').dataset.newest")
                looks += _follow_looks(page, store, "opened")
                # --- a drag across the trend: a stored range, not following
                _drag_across_trend(page)
                wait_until(page, "document.getElementById('trend').dataset.following === '0'", 10)
                looks += _still_looks(page, store, "dragged")
                dragged_end = looks[-1][1].range_end
                # --- the 1 h button: another stored range, ending at the newest sample then
                end = "document.getElementById('trend').dataset.rangeEnd"
                before = page.evaluate(end)  # read before the click: its redraw may come first
                page.click("button[data-range-minutes='60']")
                wait_until(page, f"{end} !== {json.dumps(before)}", 10)
                looks += _still_looks(page, store, "1 h shown")
                hour_spans = _spans(page)
                # --- "follow live": following again, the span of --trend-minutes
                page.click("#live")
                looks += _follow_looks(page, store, "follow live")
                # --- the link blips, then drops for longer than the ring holds
                blip = _drop_link(page, virtual, store, BLIP_S)
                looks += _follow_looks(page, store, "after a blip")
                gap = _drop_link(page, virtual, store, GAP_S)
                looks += _follow_looks(page, store, "after a gap")
                # --- the page loaded afresh after them
                page.reload()
                wait_ready(page)
                wait_until(page, "document.getElementById('trend').dataset.newest")
                looks += _follow_looks(page, store, "reloaded")

    for what, look, faults in looks:
        lag = "" if math.isnan(look.lag_s) else f"{look.lag_s:5.1f}"
        print(
            f"{what:<14} following {look.following!s:<5} newest {look.newest}  range end "
            f"{look.range_end}  lag {lag} s  points {look.points}  {faults or ''}"
        )
    print(f"dragged: the axis ended at {dragged_end}; 1 h shown: spans {hour_spans} s")
    print(f"the blip's link_up: {blip}")
    print(f"the gap's link_up: {gap}")
    assert errors == []
    assert [(what, faults) for what, _, faults in looks if faults] == []
    # the short drop is back-filled whole (whether the recorder's first reconnect or its third
    # found the link back depends on where its backoff fell in the 0.3 s: "blip" or "after …");
    # the long one is not (more than the ring holds)
    assert re.search(r"; [1-9]\d* samples? back-filled$", blip), blip
    assert "blip" not in gap, gap


# --- the dashboard killed, then started again on the same port ----------------------------------

FLEET_EVERY_S = 5.0
"""The fleet page's refresh [s] (``FLEET_EVERY_MS`` in fleet.js)."""
WATCHDOG_TICK_S = 1.0
"""The watchdog looks this often whether arrivals are late [s] (live.js)."""
WATCH_EVERY_S = 0.5
"""Wall time between two looks at a page's banner [s]."""
LOOP_STOP_BAND_S = 10.0
"""A killed dashboard: the loop page says "disconnected" within [s] (issue 39)."""
FLEET_STOP_BAND_S = LOOP_STOP_BAND_S
"""… and the fleet page within the same [s]: its watchdog says so 1.6 refreshes (8 s) after the
last answer, looked at every second, and the last answer came before the kill."""
LOOP_BACK_BAND_S = 5 * STATUS_EVERY_S + 2.0 + WATCHDOG_TICK_S
"""The dashboard back: the loop page says "reconnected" within [s] of its start: live.js
reopens a stream silent for 5 status periods, looked at every 2 s (the browser's own retry,
every 3 s, is usually first); the first status event comes at once."""
FLEET_BACK_BAND_S = FLEET_EVERY_S + WATCHDOG_TICK_S
"""… and the fleet page within [s]: its next refresh."""
RECONNECTED_SHOWN_S = 8.0
"""The "reconnected" banner stays this long, then the page is "live" [s] (live.js)."""

_BANNER_JS = """(() => { const b = document.getElementById('conn');
  return {connection: document.body.dataset.connection, text: b.textContent,
          visible: !b.hidden && b.offsetParent !== null,
          stale: document.body.classList.contains('stale')}; })()"""


def _watch(pages: dict[str, Any], want: str, band: dict[str, float]) -> dict[str, Any]:
    """Look at each page's banner until it says ``want`` or its band (+10 s) is over.

    Per page: ``delay`` [s] (NaN when not seen) and the banner when last looked at.
    """
    started = time.monotonic()
    seen: dict[str, Any] = {name: {"delay": math.nan, "banner": {}} for name in pages}
    while True:
        at = time.monotonic() - started
        for name, page in pages.items():
            if not math.isnan(seen[name]["delay"]):
                continue
            banner = page.evaluate(_BANNER_JS)
            seen[name]["banner"] = banner
            if banner["connection"] == want:
                seen[name]["delay"] = at
        waiting = [n for n in pages if math.isnan(seen[n]["delay"]) and at < band[n] + 10.0]
        if not waiting:
            return seen
        next(iter(pages.values())).wait_for_timeout(1000 * WATCH_EVERY_S)


@pytest.mark.slow  # two dashboard starts, a kill and ~25 s of watching: the slow set
@pytest.mark.timeout(300)
def test_pages_say_disconnected_when_the_dashboard_dies_and_reconnected_when_it_is_back(
    dashboard_store: Path, tmp_path: Path
) -> None:
    store = tmp_path / "loop.db"
    shutil.copy(dashboard_store, store)
    with dashboard(tmp_path, "--store", str(store)) as (board, base):
        (row,) = _get(f"{base}/api/loops")["loops"]
        with browser_pages(2) as ((loop_page, fleet_page), errors):
            loop_page.goto(f"{base}/loops/{row['loop_id']}")
            wait_ready(loop_page)
            fleet_page.goto(f"{base}/")
            wait_ready(fleet_page)
            pages = {"loop": loop_page, "fleet": fleet_page}
            loop_page.wait_for_timeout(1000 * 2 * STATUS_EVERY_S)  # a few status events in
            errors_before = list(errors)
            # --- the dashboard killed
            board.stop(signal.SIGKILL)
            lost = _watch(
                pages, "disconnected", {"loop": LOOP_STOP_BAND_S, "fleet": FLEET_STOP_BAND_S}
            )
            # --- started again on the same port
            with dashboard(tmp_path, "--store", str(store), port=port_of(base)) as (_, again):
                back = _watch(
                    pages, "reconnected", {"loop": LOOP_BACK_BAND_S, "fleet": FLEET_BACK_BAND_S}
                )
                loop_page.evaluate("1")  # the console events so far are in
                errors_back = len(errors)
                opacity = {
                    name: page.evaluate(
                        "Number(getComputedStyle(document.querySelector('.live')).opacity)"
                    )
                    for name, page in pages.items()
                }
                # the banner says so for a while, then goes: the page is live again
                live = _watch(
                    {"loop": loop_page}, "live", {"loop": RECONNECTED_SHOWN_S + WATCHDOG_TICK_S}
                )
                loop_page.evaluate("1")
                errors_away = errors[len(errors_before) : errors_back]
                errors_live = errors[errors_back:]

    for name in pages:
        print(
            f"{name}: disconnected after {lost[name]['delay']:.1f} s: {lost[name]['banner']}; "
            f"reconnected {back[name]['delay']:.1f} s after the restart: {back[name]['banner']}; "
            f"opacity {opacity[name]}"
        )
    print(f"loop page live again {live['loop']['delay']:.1f} s after: {live['loop']['banner']}")
    print(f"console errors while the dashboard was away: {collections.Counter(errors_away)}")
    print(f"console errors once reconnected: {collections.Counter(errors_live)}")
    assert again == base
    assert errors_before == []
    for name, band in (("loop", LOOP_STOP_BAND_S), ("fleet", FLEET_STOP_BAND_S)):
        seen = lost[name]
        assert seen["delay"] <= band, (name, seen)
        assert seen["banner"]["visible"], (name, seen)
        assert seen["banner"]["text"].startswith("disconnected — values as of"), (name, seen)
        assert seen["banner"]["stale"], (name, seen)
    for name, band in (("loop", LOOP_BACK_BAND_S), ("fleet", FLEET_BACK_BAND_S)):
        seen = back[name]
        assert seen["delay"] <= band, (name, seen)
        assert seen["banner"]["visible"], (name, seen)
        assert seen["banner"]["text"].startswith("reconnected at "), (name, seen)
        assert not seen["banner"]["stale"], (name, seen)
        assert opacity[name] == 1.0, (name, opacity)
    assert live["loop"]["delay"] <= RECONNECTED_SHOWN_S + WATCHDOG_TICK_S, live
    assert not live["loop"]["banner"]["visible"], live
    unexpected = [e for e in errors_away if not any(n in e for n in NETWORK_FAILURES)]
    assert unexpected == []
    assert errors_live == []
