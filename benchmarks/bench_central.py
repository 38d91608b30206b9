"""Benchmark: central ingest, rows per second from 20 concurrent senders into one PostgreSQL.

Each sender is a process of its own (a site's service) with its own SQLite store whose outbox
holds a history to backfill: ``--windows`` windows (each with the detail JSON of a real
window of the simulated loop, ~7 KB), one event per window and a model per second window;
the central store derives a KPI row per window. Every sender runs :meth:`Sender.sync
<fuelid.central.Sender.sync>` (COPY into staging, upsert, commit, delete locally, in
batches of ``batch_rows``) from the same instant; the rate is the site rows committed centrally
by all senders over the wall time from the first start to the last end. The cluster is a
temporary one on loopback (``initdb``/``pg_ctl`` as the tests use, fsync on: durable commits),
on the same machine as the senders, so the senders' CPU and the server's share its cores.
Run on demand:

    .venv/bin/python benchmarks/bench_central.py [--windows 2000] [--senders 20]
"""

from __future__ import annotations

import argparse
import json
import shutil
import sqlite3
import sys
import tempfile
import time
import uuid
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from _docs_table import run_to_docs

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from fuelid.central import Sender, connect, migrate
from fuelid.store import Event, OnlineHistory, SQLiteStore
from support.fleet import analyse_loop, simulate_loop
from support.postgres import PgCluster, find_pg_bin

T0 = 1_767_225_600.0  # 2026-01-01 UTC


def _template(folder: Path, windows: int) -> Path:
    """A store with ``windows`` real-sized windows, as many events, a model per two windows."""
    real = simulate_loop(folder / "real.db", "real", hours=0.4, seed=1)
    analyse_loop(real)
    con = sqlite3.connect(real.path)
    detail = json.loads(con.execute("SELECT detail FROM windows LIMIT 1").fetchone()[0])
    model = json.loads(con.execute("SELECT model FROM models LIMIT 1").fetchone()[0])
    con.close()
    path = folder / "template.db"
    with SQLiteStore(path, site_name="bench", tag_map_hash="bench") as store:
        store.append_events([Event(T0 + 300.0 * k, "gap", "bench") for k in range(windows)])
        with OnlineHistory(store) as history:
            for k in range(windows):
                end = T0 + 300.0 * (k + 2)
                history.add_window(
                    t_from=end - 600.0, t_to=end, accepted=k % 2 == 0, reason="ok",
                    T_fuel=20.0, u_mean=3.0, detail=detail,
                    model=model if k % 2 == 0 else None, time=end,
                )  # fmt: skip
    return path


def _copies(template: Path, folder: Path, n: int) -> list[Path]:
    """``n`` stores: the template under a new UUID and loop id each."""
    paths = []
    for i in range(n):
        path = folder / f"site-{i:02d}.db"
        shutil.copyfile(template, path)
        con = sqlite3.connect(path)
        con.execute("UPDATE meta SET value = ? WHERE key = 'store_uuid'", (uuid.uuid4().hex,))
        con.execute("UPDATE meta SET value = ? WHERE key = 'loop_id'", (f"site-{i:02d}",))
        con.execute("UPDATE meta SET value = ? WHERE key = 'tag_map_hash'", (f"hash-{i}",))
        con.commit()
        con.close()
        with Sender(path, "postgresql://unused") as sender:
            sender.enable()  # the backfill queued before the clock starts
        paths.append(path)
    return paths


def _send(args: tuple[str, str, int, float]) -> tuple[int, float, float]:
    path, url, batch_rows, start_at = args
    with Sender(path, url, batch_rows=batch_rows) as sender:
        sender.connection()  # connected before the start: the rate is the ingest's
        time.sleep(max(0.0, start_at - time.time()))
        began = time.time()
        result = sender.sync()
        ended = time.time()
    if result.error is not None:
        raise RuntimeError(result.error)
    return result.sent_rows, began, ended


def _case(
    cluster: PgCluster, template: Path, work: Path, senders: int, batch_rows: int, name: str
) -> tuple[int, float]:
    url = cluster.create_database(name)
    with connect(url) as con:
        migrate(con)
    folder = work / name
    folder.mkdir()
    paths = _copies(template, folder, senders)
    start_at = time.time() + 2.0 + 0.1 * senders
    with ProcessPoolExecutor(max_workers=senders) as pool:
        done = list(pool.map(_send, [(str(p), url, batch_rows, start_at) for p in paths]))
    rows = sum(d[0] for d in done)
    seconds = max(d[2] for d in done) - min(d[1] for d in done)
    return rows, seconds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--windows", type=int, default=2000, help="windows per store")
    parser.add_argument("--senders", type=int, default=20)
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="fuelid-bench-central-"))
    cluster = PgCluster(find_pg_bin(), {"fsync": "on", "max_connections": "100"})
    try:
        cluster.start()
        template = _template(work, args.windows)
        per_store = args.windows * 2 + args.windows // 2 + (args.windows % 2)
        print(
            f"{args.windows} windows per store (~7 KB detail JSON each), {args.windows} events, "
            f"{(args.windows + 1) // 2} models: {per_store} site rows per store"
        )
        print(f"{'senders':>8} {'batch_rows':>10} {'rows':>8} {'seconds':>8} {'rows/s':>8}")
        cases = [(1, 5000), (args.senders, 5000), (args.senders, 500)]
        for k, (senders, batch) in enumerate(cases):
            rows, seconds = _case(cluster, template, work, senders, batch, f"bench_{k}")
            print(f"{senders:>8} {batch:>10} {rows:>8} {seconds:>8.2f} {rows / seconds:>8.0f}")
        need = 10e6 / (365.25 * 86400.0)
        day = 100 * 288 * 2.5  # 100 loops, a window every 5 min, its KPI row, models, events
        print(
            f"the fleet's need: ten million window and KPI rows a fleet-year = {need:.2f} rows/s "
            f"on average; a day's backlog of 100 loops ({day:,.0f} rows) drains in "
            f"{day / (rows / seconds):.0f} s at the last rate"
        )
    finally:
        cluster.close()
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(run_to_docs("central", main, __doc__))
