"""Benchmark: sustained 50 Hz acquisition of 8 tags from the virtual PLC over Modbus TCP.

The virtual PLC (reference plant, MAN command steps, real time) runs in a child process, so the
CPU time measured here is the recorder's alone: the asyncio poll loop, the adapter, the quality
checks and the store's writer thread (SQLite, WAL, ``synchronous=FULL``, one commit per second).
The site is the one the virtual PLC prints, without its ring buffer: 8 tags (command, flow,
setpoint, fuel temperature, mode, Kc, Ti, seq) in one input-register request per sample, polled
on an absolute deadline (``t_next += period``).

Reported: the interval between successive reads (mean, sd, worst, 99th percentile), the missed
deadlines (the recorder's own timing: an interval over 1.5 periods), the samples lost and the
stale reads as the PLC's sequence counter shows them (polling two free-running 20 ms clocks
against each other aliases: a read may land twice in one PLC sample and skip the next; only a
ring buffer makes that zero), and the CPU use (process CPU time / wall time; target < 5 % of one
core). With ``--mode ring`` (or ``both``, the default) the same site keeps its ring buffer: the
recorder reads the new records in blocks every 0.2 s and every PLC sample must be stored once
(lost = the PLC's sequence span minus the stored rows). Run on demand:

    .venv/bin/python benchmarks/bench_acquisition.py [--minutes 10] [--mode poll|ring|both]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import subprocess
import sys
import tempfile
import time
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from _docs_table import run_to_docs
from fuelid.plc import Recorder, site_identity
from fuelid.plc.adapters import PlcSource, Reading, RingRecord, open_source
from fuelid.plc.site import SiteConfig
from fuelid.store import SampleWriter, SQLiteStore

CHILD = """
import json, sys
from fuelid.plc.virtual import VirtualPlcThread
with VirtualPlcThread("modbus", speed=1.0, seed=1, command_profile="steps") as server:
    print(json.dumps(server.site_text()), flush=True)
    sys.stdin.read()  # until the parent closes it
"""
CPU_TARGET = 0.05


class Timed(PlcSource):
    """A source that notes when each read returns [s, perf_counter]."""

    def __init__(self, inner: PlcSource) -> None:
        super().__init__(inner.site)
        self.inner = inner
        self.stamps: list[float] = []

    async def connect(self) -> None:
        """Connect the inner source."""
        await self.inner.connect()

    async def close(self) -> None:
        """Close the inner source."""
        await self.inner.close()

    async def read(self) -> Reading:
        """Read, noting when the answer came."""
        reading = await self.inner.read()
        self.stamps.append(time.perf_counter())
        return reading

    async def read_ring_head(self) -> int:
        """The inner source's ring head."""
        return await self.inner.read_ring_head()

    async def read_ring(self, first_slot: int, count: int) -> list[RingRecord]:
        """The inner source's ring records."""
        return await self.inner.read_ring(first_slot, count)

    async def write(self, values: Mapping[str, float]) -> None:
        """Write through the inner source."""
        await self.inner.write(values)

    async def read_write_side(self, roles: Sequence[str]) -> dict[str, float]:
        """Read the write side back through the inner source."""
        return await self.inner.read_write_side(roles)


def run_once(text: str, duration: float, ring: bool) -> list[tuple[str, str]]:
    """Record ``duration`` seconds from the virtual PLC; the table rows of one mode."""
    data = tomllib.loads(text)
    if not ring:
        data.pop("ring")  # polling, not the ring buffer
    site = SiteConfig.model_validate(data)
    period = site.sampling.period_s
    source = Timed(open_source(site))
    with tempfile.TemporaryDirectory() as folder:
        db = Path(folder) / "bench.db"
        store = SQLiteStore(db, period_s=period, **site_identity(site))
        writer = SampleWriter(store)
        recorder = Recorder(source, writer)
        cpu0, wall0 = time.process_time(), time.perf_counter()
        stats = asyncio.run(recorder.run(duration))
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
        writer.close()
        rows = store.info().rows
        seq = store.read().seq
        store.close()
    cpu_row = ("recorder CPU [% of one core]", f"{100 * cpu / wall:.2f} (target < 5)")
    if ring:
        expected = int(seq.max() - seq.min() + 1) if len(seq) else 0
        return [
            ("polls (tags + ring head and blocks)", f"{len(source.stamps)} in {wall:.1f} s"),
            ("PLC samples in the recorded span", f"{expected}"),
            ("samples stored", f"{rows}"),
            ("lost (span - stored)", f"{expected - rows}"),
            ("duplicates (stored seq not unique)", f"{len(seq) - len(np.unique(seq))}"),
            cpu_row,
        ]
    dt = np.diff(np.asarray(source.stamps)) * 1e3  # ms
    missed = int(np.count_nonzero(dt > 1.5 * period * 1e3))
    return [
        ("tags per read (one request)", f"{len(site.tags)}"),
        ("reads", f"{len(source.stamps)} in {wall:.1f} s"),
        ("period mean [ms]", f"{dt.mean():.3f} (target {period * 1e3:g})"),
        ("period sd [ms]", f"{dt.std():.3f}"),
        ("period worst [ms]", f"{dt.max():.2f}"),
        ("period 99th percentile [ms]", f"{np.percentile(dt, 99):.2f}"),
        ("missed deadlines (> 1.5 periods)", f"{missed}"),
        ("samples stored", f"{rows}"),
        ("lost (PLC sequence gaps)", f"{stats.lost}"),
        ("stale reads (repeated sequence)", f"{stats.stale}"),
        cpu_row,
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0, help="recording time [min]")
    parser.add_argument("--mode", choices=("poll", "ring", "both"), default="both")
    args = parser.parse_args()
    duration = 60.0 * args.minutes
    modes = {"poll": [False], "ring": [True], "both": [False, True]}[args.mode]

    child = subprocess.Popen(
        [sys.executable, "-c", CHILD], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout is not None
        text = json.loads(child.stdout.readline())
        for ring in modes:
            table = run_once(text, duration, ring)
            width = max(len(name) for name, _ in table)
            how = "ring buffer read in blocks" if ring else "8 tags polled every 20 ms"
            print(f"50 Hz acquisition, virtual PLC over Modbus TCP, {args.minutes:g} min, {how}")
            for name, value in table:
                print(f"  {name:<{width}}  {value}")
    finally:
        if child.stdin is not None:
            child.stdin.close()
        child.wait(30.0)


if __name__ == "__main__":
    run_to_docs("acquisition", main, __doc__)  # the printed tables, also in docs/benchmarks
