"""Benchmark: the dashboard's speed, against the targets of issue 25.

Targets: the loop page's first full render with a 24-hour store at 50 Hz under 1.5 s (and its
ratio to a static plotly page with the same number of points, measured in the same run); the
server's time for a 24-hour trend query from the level-of-detail table under 150 ms; a
sample's commit to the screen under 0.5 s; the dashboard's CPU with three browsers open on a
running service under 5 % of one core.

(a) A store of ``--hours`` of 50 Hz samples is written the way the recorder writes it
    (:meth:`SQLiteStore.append` in one-second batches of 50 samples grouped by the thousand,
    which fills the level-of-detail table at ingest): setpoint steps every minute, a first-order
    flow response with noise, the fuel temperature drifting; a window every 5 minutes with a
    model, as the service leaves them.
(b) The server's time of the 24-hour trend (:func:`fuelid.dashboard._trend.trend`, 10 s buckets
    thinned to 1,500 px), in this process: the median of ``--repeat`` calls.
(c) ``fuelid dashboard`` on that store, headless Chromium (Playwright, Debian's Chromium): the
    loop page from navigation to drawn (the page's own ``data-ready``), the median of
    ``--repeat`` loads in fresh pages; then a static page with plotly.js (the same file) and one
    chart of as many SVG points as the loop page drew, from navigation to drawn.
(d) ``fuelid online --virtual --speed 1`` (real time, 50 Hz) with the dashboard on its store and
    one browser on the loop page for ``--seconds``: for every batch the trend drew, the time from
    the newest sample's commit (its ``wall_time`` in the store) to the next frame after it was
    drawn; median, 95th percentile, largest.
(e) Then two more browsers (three): the dashboard process's CPU time over ``--seconds`` from
    /proc, as a share of one core, and whether the service lost a sample.

Run on demand (``make bench`` runs it with the defaults):

    .venv/bin/python benchmarks/bench_dashboard.py [--hours 24] [--repeat 5] [--seconds 60]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sqlite3
import statistics
import sys
import tempfile
import time
import urllib.request
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from _docs_table import Table, write_page

PERIOD_S = 0.02
WINDOW_EVERY_S = 300.0
T0 = 1.8e9  # 2027-01-15: any fixed plant time


def build_store(path: Path, hours: float) -> tuple[int, float]:
    """The synthetic 24-hour store; (samples, seconds to write)."""
    from fuelid.store import Event, OnlineHistory, Sample, SQLiteStore

    rng = np.random.default_rng(25)
    n = int(hours * 3600.0 / PERIOD_S)
    started = time.perf_counter()
    with SQLiteStore(
        path, site_name="bench loop", tag_map_hash="bench", period_s=PERIOD_S
    ) as store:
        level = 40.0
        y = level
        a = math.exp(-PERIOD_S / 1.3)
        chunk = 50_000
        for start in range(0, n, chunk):
            k = np.arange(start, min(n, start + chunk))
            t = T0 + k * PERIOD_S
            minute = (k * PERIOD_S // 60.0).astype(np.int64)
            sp = 30.0 + 5.0 * (minute % 5)
            u = sp / 14.0 + rng.normal(0.0, 0.005, k.size)
            out = np.empty(k.size)
            for i in range(k.size):  # a first-order lag, sample by sample
                y = a * y + (1.0 - a) * 14.0 * u[i]
                out[i] = y
            out += rng.normal(0.0, 0.1, k.size)
            tf = 10.0 + 20.0 * np.sin(2.0 * math.pi * (t - T0) / 86_400.0)
            rows = [
                Sample(float(ti), int(ki), float(ui), float(yi), float(si), float(fi), 1, 0)
                for ti, ki, ui, yi, si, fi in zip(t, k, u, out, sp, tf, strict=True)
            ]
            for b in range(0, len(rows), 1000):  # the recorder commits about once a second
                store.append(rows[b : b + 1000])
        store.append([], [Event(T0 + 3600.0, "gain_change", "kc 0.04 → 0.045 V per L/min")])
        with OnlineHistory(store) as history:
            for w in range(1, int(hours * 3600.0 / WINDOW_EVERY_S)):
                t_to = T0 + w * WINDOW_EVERY_S
                model = {"K": 14.0 + rng.normal(0, 0.05), "T": 1.3, "T2": 0.0, "delay": 0.2}
                history.add_window(
                    t_from=t_to - 600.0,
                    t_to=t_to,
                    accepted=True,
                    reason="passed every gate",
                    T_fuel=10.0,
                    u_mean=2.8,
                    detail={"model": model, "stderr": {"K": 0.01, "T": 0.01}, "mode": "AUTO"},
                    model={"model": model, "stderr": {"K": 0.01, "T": 0.01}},
                    time=t_to,
                )
    return n, time.perf_counter() - started


def trend_query(path: Path, repeat: int) -> tuple[float, int, int]:
    """Median server time of the 24-hour trend [s], the points read, the points sent."""
    from fuelid.dashboard import SQLiteLoop
    from fuelid.dashboard._trend import trend

    loop = SQLiteLoop(path)
    try:
        span = loop.span()
        assert span is not None
        times = []
        for _ in range(repeat):
            started = time.perf_counter()
            answer = trend(loop, span[1] - 86_400.0, span[1] + 1.0, width=1500)
            times.append(time.perf_counter() - started)
        sent = sum(len(s["t"]) for s in answer["series"].values())
        return statistics.median(times), int(answer["points"]), sent
    finally:
        loop.close()


PLOTLY_JS = "static/vendor/plotly/plotly-basic.min.js"
"""The plotly.js the dashboard serves (its analysis charts), under the package's folder."""
STATIC_PAGE = """<!doctype html><html><head><meta charset="utf-8">
<script src="{plotly}"></script></head><body><div id="c" style="width:1400px;height:560px"></div>
<script>
const n = {n};
const x = Array.from({{length: n}}, (_, i) => i);
const y = x.map((i) => Math.sin(i / 50));
Plotly.newPlot("c", [{{type: "scatter", mode: "lines", x, y}}]).then(() => {{
  document.body.dataset.ready = "1";
}});
</script></body></html>"""


def render_times(base: str, loop_id: str, repeat: int, work: Path) -> tuple[float, float, int]:
    """Median first render of the loop page [s], of a static page of as many points, points."""
    from support.browser import browser_page, wait_ready

    loads, points = [], 0
    with browser_page() as (page, errors):
        for _ in range(repeat):
            page.goto("about:blank")
            started = time.perf_counter()
            page.goto(f"{base}/loops/{loop_id}")
            wait_ready(page, 60)
            loads.append(time.perf_counter() - started)
            # the live trend's points (uPlot; the analysis charts wait until scrolled to)
            points = 4 * int(page.evaluate("document.getElementById('trend').dataset.points"))
        # the dashboard's own plotly.js (vendored: its basic bundle)
        plotly_js = Path(str(resources.files("fuelid.dashboard"))) / PLOTLY_JS
        static = work / "static.html"
        static.write_text(STATIC_PAGE.format(plotly=plotly_js.as_uri(), n=points))
        statics = []
        for _ in range(repeat):
            page.goto("about:blank")
            started = time.perf_counter()
            page.goto(static.as_uri())
            wait_ready(page, 60)
            statics.append(time.perf_counter() - started)
        if errors:
            print("console errors:", errors)
    return statistics.median(loads), statistics.median(statics), int(points)


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def live(seconds: float, work: Path) -> dict[str, Any]:
    """Latency from commit to screen with one browser, then the CPU with three."""
    from support.browser import browser_pages, dashboard, virtual_service, wait_ready

    store = work / "live.db"
    hours = (3 * seconds + 120.0) / 3600.0
    out: dict[str, Any] = {}
    with virtual_service(work, store, "--speed", "1", "--hours", f"{hours:.4f}") as service:
        service.wait_for(lambda line: "link up" in line)
        with dashboard(work, "--store", str(store)) as (proc, base):
            loop_id = json.loads(urllib.request.urlopen(f"{base}/api/loops").read())["loops"][0][
                "loop_id"
            ]
            with browser_pages(3) as ((one, two, three), _):
                one.goto(f"{base}/loops/{loop_id}")
                wait_ready(one)
                one.wait_for_timeout(seconds * 1000)
                log = one.evaluate("window.fuelidShownLog")
                for page in (two, three):
                    page.goto(f"{base}/loops/{loop_id}")
                    wait_ready(page)
                cpu0, wall0 = _cpu_s(proc.proc.pid), time.monotonic()
                one.wait_for_timeout(seconds * 1000)
                cpu1, wall1 = _cpu_s(proc.proc.pid), time.monotonic()
        out["cpu_share"] = (cpu1 - cpu0) / (wall1 - wall0)
    with sqlite3.connect(store) as con:
        wall = dict(con.execute("SELECT time, wall_time FROM samples").fetchall())
        first, last, n = con.execute("SELECT min(seq), max(seq), count(*) FROM samples").fetchone()
    latencies = [at - wall[t] for t, at in log if wall.get(t) is not None]
    out["latency"] = sorted(latencies)
    out["lost"] = (last - first + 1) - n
    counted = [line for line in service.output if " lost |" in line]
    out["service_line"] = counted[-1] if counted else ""
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--hours", type=float, default=24.0)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument(
        "--store",
        type=Path,
        default=None,
        help="keep the synthetic store here and reuse it when it exists (it takes minutes)",
    )
    args = parser.parse_args()
    started = time.perf_counter()
    work = Path(tempfile.mkdtemp(prefix="fuelid-bench-dashboard-"))
    try:
        store = work / "day.db" if args.store is None else args.store
        if not store.exists():
            n, build_s = build_store(store, args.hours)
            print(f"store: {n} samples ({args.hours:g} h at 50 Hz) written in {build_s:.0f} s")
        query_s, read, sent = trend_query(store, args.repeat)
        from support.browser import dashboard

        with dashboard(work, "--store", str(store)) as (_, base):
            loop_id = json.loads(urllib.request.urlopen(f"{base}/api/loops").read())["loops"][0][
                "loop_id"
            ]
            page_s, static_s, points = render_times(base, loop_id, args.repeat, work)
        result = live(args.seconds, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    lat = result["latency"]
    table = Table(
        header=["measure", "measured", "target", "met"],
        formats=["", "", "", ""],
        widths=[58, 22, 12, 5],
    )
    table.print_header()

    def row(name: str, value: str, target: str, met: bool) -> None:
        table.add(name, value, target, "yes" if met else "NO")

    row(
        f"loop page, first full render ({points} points)",
        f"{page_s:.2f} s",
        "< 1.5 s",
        page_s < 1.5,
    )
    row(
        "  against a static plotly page of as many points",
        f"{page_s / static_s:.2f}x ({static_s:.2f} s)",
        "-",
        True,
    )
    row(
        f"24-hour trend query, server ({read} bucket points, {sent} sent)",
        f"{1000 * query_s:.0f} ms",
        "< 150 ms",
        query_s < 0.150,
    )
    if lat:
        p95 = lat[min(len(lat) - 1, int(0.95 * len(lat)))]
        row(
            f"commit to screen ({len(lat)} batches): median, p95, max",
            f"{statistics.median(lat):.2f}, {p95:.2f}, {lat[-1]:.2f} s",
            "< 0.5 s",
            statistics.median(lat) < 0.5,
        )
    row(
        "dashboard CPU, 3 browsers on a running service",
        f"{100 * result['cpu_share']:.1f} % of a core",
        "< 5 %",
        result["cpu_share"] < 0.05,
    )
    row("samples lost by the service meanwhile", str(result["lost"]), "0", result["lost"] == 0)
    write_page(
        "dashboard",
        __doc__.split("\n\n    ")[0],
        [table],
        time.perf_counter() - started,
    )


if __name__ == "__main__":
    main()
