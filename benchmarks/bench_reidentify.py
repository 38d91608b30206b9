"""Benchmark: re-identification throughput on Dask, and how it differs from the live decisions.

(a) Per-task overhead of Dask distributed on a local cluster (2 single-threaded worker
    processes, 127.0.0.1): the round trip of one empty task submitted and awaited alone
    (latency), and the cost per task of ``--tasks`` empty tasks mapped at once (throughput).

(b) Throughput of :func:`fuelid.fleet.reidentify` on an archive of ``--loops`` loop-days at
    50 Hz, each holding ``--hours`` of a virtual loop (reference plant, AUTO and MAN alternating,
    the default ``[online]`` schedule: 10-minute windows every 5 minutes), on a local cluster of
    1 and of 2 workers (cluster start-up excluded: the run is timed from submission to the last
    result). Windows/s per worker, the scaling efficiency (rate with 2 workers / (2 × rate with
    1)), and the workers' time outside the windows' analyses per loop-day (reading the day's
    Parquet, building the analyser, writing the result; with 2 workers also the idle time of
    a worker waiting for the other's last loop-day).

    Projection: a loop-year at 50 Hz with the default schedule is 365 × 288 = 105,120 windows;
    its time on one worker is that over (a)'s windows/s per worker. A 100-loop fleet-year on N
    cores: 100 loop-years / (N × rate per worker × efficiency), with the 2-worker efficiency
    assumed for N cores (a scheduler with one task per loop-day has 36,500 tasks a fleet-year,
    whose ~ms overhead is nothing beside the windows). Days with runs only part of the time
    have fewer windows (a window without samples is skipped): the projection is for loops
    recording around the clock, an upper bound.

(c) Re-identification against the live decisions: two loops (AUTO with the fuel warming
    15 → 25 °C, MAN at 20 °C; 10 Hz) recorded for ``--live-hours`` across a UTC midnight, run
    through the live-like analysis (``tests/support/fleet.analyse_loop``: the service's
    analyser, warm from its own start and across midnight), archived, and re-identified. The
    windows are matched by their end; reported: the share whose accepted/refused decision
    agrees, and among windows both accepted the difference in K in the live window's standard
    errors, |ΔK|/se_K; split into each day's first hour (where the re-identification starts
    cold) and the rest.

Run on demand (``make bench`` runs it with the defaults):

    .venv/bin/python benchmarks/bench_reidentify.py [--loops 4] [--hours 2] [--tasks 200]
        [--live-hours 6]
"""

from __future__ import annotations

import argparse
import json
import math
import sqlite3
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from _docs_table import run_to_docs

LOOP_YEAR_WINDOWS = 365 * 288
"""Windows in a loop-year with the default schedule (a window every 300 s)."""
FLEET_LOOPS = 100
CORES = (2, 8, 32, 128)


def _noop(x: int) -> int:
    return x


def _cluster(n: int) -> tuple[Any, Any]:
    from distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=n,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
    )
    return cluster, Client(cluster)


def overhead(tasks: int) -> tuple[float, float]:
    """(latency of one empty task [s], cost per task of ``tasks`` mapped at once [s])."""
    cluster, client = _cluster(2)
    with cluster, client:
        client.submit(_noop, -1, pure=False).result()  # warm the connection
        started = time.perf_counter()
        for i in range(50):
            client.submit(_noop, i, pure=False).result()
        latency = (time.perf_counter() - started) / 50
        started = time.perf_counter()
        client.gather(client.map(_noop, range(tasks), pure=False))
        per_task = (time.perf_counter() - started) / tasks
    return latency, per_task


def make_archive(folder: Path, loops: int, hours: float, period_s: float) -> Path:
    from support.archive_fixture import archive_store
    from support.fleet import T0, simulate_loop

    root = folder / "archive"
    for k in range(loops):
        loop = simulate_loop(
            folder / f"bench-{k}.db",
            f"bench-{k}",
            hours=hours,
            seed=k,
            period_s=period_s,
            start=T0 + 3600.0,
            mode="AUTO" if k % 2 == 0 else "MAN",
        )
        archive_store(loop.path, root)
    return root


def throughput(root: Path, folder: Path, workers: int) -> dict[str, float]:
    from fuelid.fleet import reidentify

    cluster, client = _cluster(workers)
    with cluster, client:
        client.submit(_noop, 0, pure=False).result()
        started = time.perf_counter()
        run = reidentify(root, folder / f"out-{workers}", client=client)
        wall = time.perf_counter() - started
    days = run.computed
    return {
        "wall": wall,
        "windows": run.windows,
        "days": days,
        "rate": run.windows / wall / workers,
        "fit": run.fit_seconds,
    }


def _live_windows(store: Path) -> dict[float, dict[str, Any]]:
    con = sqlite3.connect(store)
    try:
        rows = con.execute("SELECT t_to, accepted, detail FROM windows").fetchall()
    finally:
        con.close()
    out = {}
    for t_to, accepted, detail in rows:
        d = json.loads(detail)
        out[float(t_to)] = {
            "accepted": bool(accepted),
            "K": (d.get("model") or {}).get("K"),
            "se_K": (d.get("stderr") or {}).get("K"),
        }
    return out


def live_comparison(folder: Path, hours: float) -> list[str]:
    import pyarrow.parquet as pq

    from fuelid.fleet import reidentify
    from support.archive_fixture import archive_store
    from support.fleet import T0, analyse_loop, simulate_loop

    start = T0 + 86400.0 - hours / 2 * 3600.0  # centred on a UTC midnight
    root = folder / "live-archive"
    live: dict[str, dict[float, dict[str, Any]]] = {}
    for loop_id, mode, profile, seed in (
        ("live-auto", "AUTO", ([0.0, hours * 3600.0], [15.0, 25.0]), 11),
        ("live-man", "MAN", None, 12),
    ):
        loop = simulate_loop(
            folder / f"{loop_id}.db", loop_id, hours=hours, seed=seed, start=start, mode=mode,
            fuel_temp_profile=profile,
        )  # fmt: skip
        analyse_loop(loop)
        live[loop_id] = _live_windows(loop.path)
        archive_store(loop.path, root)
    cluster, client = _cluster(2)
    with cluster, client:
        reidentify(root, folder / "live-out", client=client)
    lines = []
    for part in ("first hour of a day", "rest of the day", "all"):
        agree = total = reid_only = 0
        z: list[float] = []
        for loop_id, windows in live.items():
            table = pq.read_table(folder / "live-out" / "windows" / f"loop={loop_id}")
            for row in table.select(["t_to", "accepted", "K"]).to_pylist():
                early = (row["t_to"] - 1e-6) % 86400.0 < 3600.0
                if part != "all" and early != (part == "first hour of a day"):
                    continue
                lw = windows.get(row["t_to"])
                if lw is None:  # a window the live schedule (from the first sample) has not
                    reid_only += 1
                    continue
                total += 1
                agree += lw["accepted"] == row["accepted"]
                if lw["accepted"] and row["accepted"] and lw["se_K"]:
                    z.append(abs(row["K"] - lw["K"]) / lw["se_K"])
        zs = sorted(z)
        p95 = zs[int(0.95 * (len(zs) - 1))] if zs else math.nan
        lines.append(
            f"{part:20s} {total:8d} {reid_only:9d} {100 * agree / max(total, 1):8.1f} "
            f"{len(z):9d} {(statistics.median(zs) if zs else math.nan):12.2e} "
            f"{p95:10.2e} {(zs[-1] if zs else math.nan):10.2e}"
        )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--loops", type=int, default=4, help="loop-days in the archive")
    parser.add_argument("--hours", type=float, default=2.0, help="plant hours per loop-day")
    parser.add_argument("--tasks", type=int, default=200, help="empty tasks for the overhead")
    parser.add_argument("--live-hours", type=float, default=6.0, help="hours across midnight")
    args = parser.parse_args()

    latency, per_task = overhead(args.tasks)
    print("(a) Dask per-task overhead, local cluster of 2 workers on 127.0.0.1")
    print(f"{'one empty task, submitted and awaited alone [ms]':52s} {1e3 * latency:8.2f}")
    print(f"{f'{args.tasks} empty tasks mapped at once, per task [ms]':52s} {1e3 * per_task:8.2f}")

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        started = time.perf_counter()
        root = make_archive(folder, args.loops, args.hours, 0.02)
        print(
            f"\n(b) throughput: {args.loops} loop-days of {args.hours:g} h at 50 Hz "
            f"(archive written in {time.perf_counter() - started:.0f} s), default schedule"
        )
        print(
            f"{'workers':>7} {'windows':>8} {'wall s':>8} {'windows/s/worker':>17} "
            f"{'s/window':>9} {'worker s outside windows/loop-day (idle too)':>40}"
        )
        rates = {}
        for workers in (1, 2):
            r = throughput(root, folder, workers)
            rates[workers] = r["rate"]
            outside = max(0.0, (r["wall"] * workers - r["fit"]) / max(r["days"], 1))
            print(
                f"{workers:7d} {r['windows']:8.0f} {r['wall']:8.2f} {r['rate']:17.2f} "
                f"{1 / r['rate']:9.3f} {outside:40.2f}"
            )
        efficiency = rates[2] / rates[1]
        print(f"scaling efficiency, 2 workers: {100 * efficiency:.0f} %")
        year_h = LOOP_YEAR_WINDOWS / rates[1] / 3600.0
        print(
            f"\nprojection: a loop-year (50 Hz, {LOOP_YEAR_WINDOWS} windows) on one worker: "
            f"{year_h:.1f} h"
        )
        print(f"{'cores':>7} {f'{FLEET_LOOPS}-loop fleet-year [h]':>28}")
        for n in CORES:
            fleet_h = FLEET_LOOPS * LOOP_YEAR_WINDOWS / (n * rates[1] * efficiency) / 3600.0
            print(f"{n:7d} {fleet_h:28.1f}")

        print(
            f"\n(c) re-identification vs the live decisions: 2 loops, {args.live_hours:g} h at "
            "10 Hz across a UTC midnight"
        )
        print(
            f"{'windows ending in':20s} {'matched':>8} {'reid only':>9} {'agree %':>8} "
            f"{'both acc':>9} {'med |dK|/se':>12} {'p95':>10} {'max':>10}"
        )
        for line in live_comparison(folder, args.live_hours):
            print(line)


if __name__ == "__main__":
    from fuelid.blas import single_threaded_blas

    with single_threaded_blas():  # as every fuelid command runs (fuelid.cli._common.guarded)
        run_to_docs("reidentify", main, __doc__)
