"""The dashboard's soak: a loop page left open on a running loop (issue 39, on demand).

``fuelid online --virtual`` runs a loop at 20x real time and ``fuelid dashboard`` serves it, each
a process of its own; one page in headless Chromium stays open on the loop for
``FUELID_DASHBOARD_SOAK_MINUTES`` of wall time (30 by default: 10 h of plant time). Every
:data:`LOOK_EVERY_S` the live trend must still follow the store (``support.browser.
following_faults``: following, its axis ending at its newest sample, at most 10 s of plant time
behind the samples committed half a second before the look, and advancing); every minute the
tab's JavaScript heap is read after a garbage collection (the DevTools protocol:
``HeapProfiler.collectGarbage``, then ``Runtime.getHeapUsage``), with its DOM counters, the
trend's points, the console errors and the dashboard's resident memory.

Bands, stated before the run: the heap grows by less than :data:`HEAP_GROWTH_MB` (50 MB) from
minute 2 (the page warmed up: the trend's ring full, plotly not loaded) to the end; the trend
follows at every look; no console error. The table of the figures is printed (``-rP``).

Not in ``make test`` nor in the slow set: the module is collected only when
``FUELID_DASHBOARD_SOAK_MINUTES`` is set::

    make dashboard-soak                                    # 30 min
    make dashboard-soak DASHBOARD_SOAK_MINUTES=6           # a short run
"""

from __future__ import annotations

import json
import os
import time
import urllib.request
from pathlib import Path
from typing import Any

import pytest

MINUTES_VARIABLE = "FUELID_DASHBOARD_SOAK_MINUTES"
if MINUTES_VARIABLE not in os.environ:
    pytest.skip(
        f"the dashboard soak runs on demand: make dashboard-soak (or set {MINUTES_VARIABLE})",
        allow_module_level=True,
    )

pytest.importorskip("fastapi")
pytest.importorskip("pymodbus")

from support.browser import (  # noqa: E402  after the skip: only a soak run needs them
    LAG_BAND_S,
    STREAM_ALLOWANCE_S,
    TrendLook,
    browser_page,
    dashboard,
    following_faults,
    heap_used,
    look_at_trend,
    virtual_service,
    wait_ready,
    wait_until,
)

MINUTES = float(os.environ.get(MINUTES_VARIABLE) or "30")
"""Wall time the page stays open [min]."""
SPEED = 20.0
"""Plant time per wall time of the virtual loop [-]."""
LOOK_EVERY_S = 10.0
"""Wall time between two looks at the trend [s]."""
HEAP_FROM_MINUTE = 2
"""The heap's growth is counted from this minute (the page warmed up) to the end."""
HEAP_GROWTH_MB = 50.0
"""The tab's heap grows by less than this from :data:`HEAP_FROM_MINUTE` to the end [MB]."""


def _get(url: str) -> Any:
    with urllib.request.urlopen(url, timeout=10) as response:
        return json.loads(response.read())


def _rss_mb(pid: int) -> float:
    """A process' resident memory [MB] (``VmRSS``); NaN when it cannot be read."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


@pytest.mark.timeout(600 + 60 * MINUTES)
def test_a_page_left_open_for_half_an_hour_keeps_following_in_bounded_memory(
    tmp_path: Path,
) -> None:
    store = tmp_path / "loop.db"
    hours = MINUTES * SPEED / 60.0 + 0.5  # longer than the page is open: the start's margin
    rows: list[dict[str, Any]] = []
    looks: list[TrendLook] = []
    with virtual_service(tmp_path, store, "--speed", f"{SPEED:g}", "--hours", f"{hours:g}") as svc:
        svc.wait_for(lambda line: "link up" in line)
        with dashboard(tmp_path, "--store", str(store)) as (board, base):
            (row,) = _get(f"{base}/api/loops")["loops"]
            with browser_page() as (page, errors):
                page.goto(f"{base}/loops/{row['loop_id']}")
                wait_ready(page)
                wait_until(page, "document.getElementById('trend').dataset.newest")
                cdp = page.context.new_cdp_session(page)
                opened = time.monotonic()
                minute = 0
                while True:
                    looks.append(look_at_trend(page, store))
                    elapsed = time.monotonic() - opened
                    end = elapsed >= 60.0 * MINUTES
                    if elapsed >= 60.0 * minute or end:  # a minute's row (minute 0's, the end's)
                        look = looks[-1]
                        rows.append(
                            {
                                "minute": minute,
                                **heap_used(cdp),
                                "points": look.points,
                                "following": not following_faults(
                                    look, looks[-2] if len(looks) > 1 else None
                                ),
                                "lag_s": look.lag_s,
                                "plant_h": (look.newest - looks[0].newest) / 3600.0
                                if look.newest and looks[0].newest
                                else float("nan"),
                                "errors": len(errors),
                                "board_MB": _rss_mb(board.proc.pid),
                            }
                        )
                        minute += 1
                    if end:
                        break
                    until_row = 60.0 * minute - elapsed
                    page.wait_for_timeout(1000 * max(0.1, min(LOOK_EVERY_S, until_row)))
                console = list(errors)

    print(
        f"{'min':>4} {'heap MB':>8} {'of MB':>7} {'DOM nodes':>9} {'listeners':>9} "
        f"{'points':>7} {'follows':>7} {'lag s':>6} {'plant h':>7} {'errors':>6} {'board MB':>8}"
    )
    for r in rows:
        print(
            f"{r['minute']:>4} {r['used_MB']:8.2f} {r['total_MB']:7.2f} {r['nodes']:9.0f} "
            f"{r['listeners']:9.0f} {r['points']:7d} {r['following']!s:>7} {r['lag_s']:6.2f} "
            f"{r['plant_h']:7.2f} {r['errors']:6d} {r['board_MB']:8.1f}"
        )
    start = next(r for r in rows if r["minute"] == HEAP_FROM_MINUTE)
    growth = rows[-1]["used_MB"] - start["used_MB"]
    lags = [look.lag_s for look in looks]
    print(
        f"{len(looks)} looks at the trend; lag behind the samples committed "
        f"{STREAM_ALLOWANCE_S} s before a look: max {max(lags):.2f} s of plant time "
        f"(band {LAG_BAND_S}); heap from minute {HEAP_FROM_MINUTE} to {rows[-1]['minute']}: "
        f"{growth:+.2f} MB (band < {HEAP_GROWTH_MB})"
    )
    faults = [
        (i, look, fault)
        for i, look in enumerate(looks)
        for fault in following_faults(look, looks[i - 1] if i else None)
    ]
    assert faults == []
    assert console == []
    assert growth < HEAP_GROWTH_MB
