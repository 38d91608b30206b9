"""Benchmark: the raw archive's write and read rates, and its size against the SQLite store.

One loop-day at 50 Hz (4.32 M samples: a command and a flow with noise around setpoint steps, a
slowly warming fuel, 0.1 % of the samples with missing u and y) is written into an SQLite store
through its ordinary append, then archived with ``fuelid.archive.archive_store`` and read
back whole with pyarrow, DuckDB and fuelid's own ``ArchiveLoop``. Rates are in MB of Parquet per
second and in samples per second; sizes in bytes per sample (the store after a checkpoint, with
its indexes and level-of-detail rows). The issue's question: what an archived day costs to write
and read, and how much smaller it is than the store. Run on demand:

    .venv/bin/python benchmarks/bench_archive.py [--hours 24] [--dir /tmp]

``--dir`` chooses the disk measured; ``--hours`` shortens the day for a quick look.
"""

from __future__ import annotations

import argparse
import sqlite3
import tempfile
import time
from pathlib import Path

import numpy as np

from _docs_table import run_to_docs
from fuelid.archive import ArchiveLoop, archive_store
from fuelid.store import Quality, Sample, SQLiteStore, tag_map_hash

RATE_HZ = 50.0
T0 = 1_767_225_600.0  # 2026-01-01 00:00 UTC
SITE = {"site_name": "bench loop", "tag_map_hash": tag_map_hash({"flow": "ir:20"})}


def _write_store(path: Path, hours: float, seed: int = 1) -> int:
    """Write ``hours`` at 50 Hz from midnight into a new store; the samples written."""
    rng = np.random.default_rng(seed)
    n = round(hours * 3600.0 * RATE_HZ)
    batch = 50_000
    with SQLiteStore(path, period_s=1.0 / RATE_HZ, loop_id="bench", **SITE) as store:
        for k0 in range(0, n, batch):
            k = np.arange(k0, min(k0 + batch, n))
            t = T0 + k / RATE_HZ
            setpoint = 40.0 + 2.0 * np.sign(np.sin(2.0 * np.pi * k / (RATE_HZ * 600.0)))
            u = 2.9 + 0.05 * (setpoint - 40.0) + rng.normal(0.0, 0.01, k.size)
            y = setpoint + rng.normal(0.0, 0.15, k.size)
            temperature = 15.0 + 10.0 * k / max(n, 1) + rng.normal(0.0, 0.02, k.size)
            bad = rng.random(k.size) < 1e-3
            u[bad] = y[bad] = np.nan
            store.append_samples(
                Sample(
                    float(t[i]),
                    int(k[i]),
                    float(u[i]),
                    float(y[i]),
                    float(setpoint[i]),
                    float(temperature[i]),
                    1,
                    int(Quality.BAD_VALUE if bad[i] else Quality.OK),
                )
                for i in range(k.size)
            )
    con = sqlite3.connect(path)
    try:
        con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    finally:
        con.close()
    return n


def _timed(work: object) -> float:
    start = time.perf_counter()
    assert callable(work)
    work()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=24.0, help="hours at 50 Hz (a day: 24)")
    parser.add_argument("--dir", type=Path, default=None, help="directory on the disk to test")
    args = parser.parse_args()
    import duckdb
    import pyarrow.dataset as ds

    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        db, root = Path(tmp) / "loop.db", Path(tmp) / "archive"
        start = time.perf_counter()
        n = _write_store(db, args.hours)
        fill_s = time.perf_counter() - start
        store_bytes = db.stat().st_size
        with SQLiteStore(db) as store:
            report = archive_store(store, root, before="2026-01-02")
            read_store_s = _timed(lambda: store.read())
        parquet = report.parquet_bytes
        mb = parquet / 1e6
        samples = root / "samples"
        pattern = str(samples / "**" / "*.parquet")
        pyarrow_s = _timed(
            lambda: ds.dataset(samples, format="parquet", partitioning="hive").to_table()
        )
        con = duckdb.connect()
        columns = "time, wall_time, seq, u, y, setpoint, fuel_temperature, mode, quality"
        sums = ", ".join(f"sum({c})" for c in columns.split(", "))
        duck_s = _timed(
            lambda: con.execute(
                f"SELECT {sums} FROM read_parquet('{pattern}', hive_partitioning = true)"
            ).fetchall()
        )
        con.close()
        fuelid_s = _timed(lambda: ArchiveLoop(root, "bench").read())
        assert report.rows == n, (report.rows, n)

        print(f"one loop-day at {RATE_HZ:.0f} Hz: {n} samples ({args.hours:g} h), store written in "
              f"{fill_s:.1f} s")  # fmt: skip
        print(f"{'step':44s} {'s':>7s} {'MB/s':>8s} {'Msamples/s':>11s}")
        rows = [
            ("archive write (SQLite -> Parquet, re-read)", report.seconds),
            ("read: pyarrow dataset, whole table", pyarrow_s),
            ("read: DuckDB, every column summed", duck_s),
            ("read: fuelid ArchiveLoop.read (arrays)", fuelid_s),
            ("for comparison: SQLiteStore.read (arrays)", read_store_s),
        ]
        for name, seconds in rows:
            print(f"{name:44s} {seconds:7.2f} {mb / seconds:8.1f} {n / seconds / 1e6:11.2f}")
        print("(MB/s: MB of Parquet per second, for every row, the store's read too)")
        print(f"{'size':44s} {'MB':>7s} {'B/sample':>8s}")
        print(f"{'SQLite store (after checkpoint)':44s} {store_bytes / 1e6:7.1f} "
              f"{store_bytes / n:8.1f}")  # fmt: skip
        print(f"{'Parquet (zstd), samples and events':44s} {mb:7.1f} {parquet / n:8.1f}")
        print(f"the archive is {store_bytes / parquet:.1f}x smaller than the store")


if __name__ == "__main__":
    run_to_docs("archive", main, __doc__)  # the printed tables, also in docs/benchmarks
