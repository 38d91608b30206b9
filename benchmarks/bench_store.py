"""Benchmark: ingest rate and size on disk of the SQLite sample store.

Target (issue 14): ingest at least 100 times the 50 Hz need (5,000 rows/s), with every batch a
durable commit (WAL, ``synchronous=FULL``). Batches of 50 rows are the recorder's case (one
commit per second at 50 Hz); 1000 rows a back-fill after a reconnect; 1 row the worst case. The
size per row is measured after a checkpoint, with all indexes, and scaled to a day at 50 Hz.
Run on demand:

    .venv/bin/python benchmarks/bench_store.py [--rows 100000] [--dir /tmp]

``--dir`` chooses the disk measured (the fsync cost is the disk's, not SQLite's).
"""

from __future__ import annotations

import argparse
import math
import sqlite3
import tempfile
import time
from pathlib import Path

from _docs_table import run_to_docs
from fuelid.store import Quality, Sample, SampleWriter, SQLiteStore, tag_map_hash

RATE_HZ = 50.0
TARGET_FACTOR = 100.0
T0 = 1_700_000_000.0
SITE = {"site_name": "bench loop", "tag_map_hash": tag_map_hash({"flow": "ir:20"})}


def _rows(start: int, n: int) -> list[Sample]:
    h = 1.0 / RATE_HZ
    return [
        Sample(
            T0 + h * k,
            k,
            2.5 + 0.5 * math.sin(0.01 * k),
            60.0 + 10.0 * math.sin(0.01 * k),
            60.0,
            18.0 + 1e-5 * k,
            1,
            Quality.OK,
        )
        for k in range(start, start + n)
    ]


def _ingest(path: Path, batch: int, n_rows: int) -> float:
    """Rows per second [1/s] appending ``n_rows`` in committed batches of ``batch``."""
    batches = [_rows(k, batch) for k in range(0, n_rows, batch)]
    with SQLiteStore(path, period_s=1.0 / RATE_HZ, **SITE) as store:
        start = time.perf_counter()
        for rows in batches:
            store.append_samples(rows)
        elapsed = time.perf_counter() - start
    return n_rows / elapsed


def _writer_rate(path: Path, n_rows: int) -> float:
    """Rows per second [1/s] through :class:`SampleWriter` (queue, thread, 1 s commits)."""
    rows = _rows(0, n_rows)
    with SQLiteStore(path, period_s=1.0 / RATE_HZ, **SITE) as store:
        start = time.perf_counter()
        with SampleWriter(store, commit_interval_s=1.0) as writer:
            writer.put_many(rows)
            writer.flush()
        elapsed = time.perf_counter() - start
    return n_rows / elapsed


def _hour_of_data(path: Path) -> tuple[float, float]:
    """Wall time [s] to read one hour at 50 Hz as IOData, then to thin it to one per second."""
    n = int(3600 * RATE_HZ)
    with SQLiteStore(path, period_s=1.0 / RATE_HZ, **SITE) as store:
        for k in range(0, n, 1000):
            store.append_samples(_rows(k, 1000))
        start = time.perf_counter()
        store.to_iodata(sample_time=1.0 / RATE_HZ)
        read_s = time.perf_counter() - start
        start = time.perf_counter()
        store.prune(older_than_days=0.0, thin_to_period_s=1.0, now=T0 + 2 * 3600.0)
        prune_s = time.perf_counter() - start
    return read_s, prune_s


def _bytes_per_row(path: Path) -> float:
    con = sqlite3.connect(path)
    try:
        con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        rows = con.execute("SELECT count(*) FROM samples").fetchone()[0]
    finally:
        con.close()
    return float(path.stat().st_size) / rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=100_000, help="rows per case")
    parser.add_argument("--dir", type=Path, default=None, help="directory on the disk to test")
    args = parser.parse_args()
    need = RATE_HZ
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        cases = {
            "1 row per commit": (1, min(args.rows, 5_000)),
            "50 rows per commit (50 Hz, 1 s)": (50, args.rows),
            "1000 rows per commit (back-fill)": (1000, args.rows),
        }
        print(f"{'case':36s} {'rows':>8s} {'rows/s':>10s} {'x 50 Hz':>9s} {'target':>8s}")
        for name, (batch, n) in cases.items():
            rate = _ingest(Path(tmp) / f"batch{batch}.db", batch, n)
            verdict = "ok" if rate >= TARGET_FACTOR * need else "MISSED"
            verdict = verdict if batch > 1 else "(info)"
            print(f"{name:36s} {n:8d} {rate:10.0f} {rate / need:9.0f} {verdict:>8s}")
        rate = _writer_rate(Path(tmp) / "writer.db", args.rows)
        verdict = "ok" if rate >= TARGET_FACTOR * need else "MISSED"
        name = "SampleWriter (queue + thread)"
        print(f"{name:36s} {args.rows:8d} {rate:10.0f} {rate / need:9.0f} {verdict:>8s}")
        per_row = _bytes_per_row(Path(tmp) / "batch50.db")
        per_day = per_row * RATE_HZ * 86400.0 / 1e6
        print(f"size: {per_row:.1f} B/row (8 columns, 3 indexes) = {per_day:.0f} MB/day at 50 Hz")
        read_s, prune_s = _hour_of_data(Path(tmp) / "hour.db")
        print(
            f"one hour at 50 Hz (180000 rows): read as IOData {read_s:.2f} s, thin {prune_s:.2f} s"
        )
        print(f"target: >= {TARGET_FACTOR:.0f}x the 50 Hz need ({TARGET_FACTOR * need:.0f} rows/s)")


if __name__ == "__main__":
    run_to_docs("store", main, __doc__)  # the printed tables, also in docs/benchmarks
