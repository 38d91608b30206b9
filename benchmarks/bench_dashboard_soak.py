"""Benchmark: a loop page left open for half an hour on a running loop, its heap minute by minute.

Targets (issue 39, item 6): one loop page in headless Chromium stays open on a virtual loop at
20x real time for 30 minutes of wall time (10 h of plant time); the live trend follows at every
look (its axis ends at its newest sample, at most 10 s of plant time behind the samples committed
half a second before, and it advances); the tab's JavaScript heap, read after a garbage
collection, grows by less than 50 MB from minute 2 to the end; no console error. The run is
tests/system/test_dashboard_soak.py (``make dashboard-soak``); this script runs it and keeps its
table: per minute the heap used and reserved, the DOM nodes and listeners, the trend's points,
whether it follows, its lag [s of plant time], the plant hours drawn, the console errors and the
dashboard process' resident memory.

Run on demand:

    .venv/bin/python benchmarks/bench_dashboard_soak.py [--minutes 30] [--from-output FILE]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

from _docs_table import run_to_docs

ROOT = Path(__file__).resolve().parent.parent
SOAK = "tests/system/test_dashboard_soak.py"
HEADER = ["min", "heap"]
"""The soak's table starts with its header line, whose first words these are."""


def _soak_output(minutes: float) -> str:
    """Run the soak for ``minutes``; what it printed (its table), or exit when it failed."""
    env = {**os.environ, "FUELID_DASHBOARD_SOAK_MINUTES": f"{minutes:g}"}
    command = [sys.executable, "-m", "pytest", "-q", "-s", "-p", "no:xdist"]
    command += ["-p", "no:cacheprovider", SOAK]
    done = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        sys.stderr.write(done.stdout[-4000:] + done.stderr[-2000:])
        raise SystemExit(f"the soak failed (exit {done.returncode}): no page written")
    return done.stdout


def _table(output: str) -> list[str]:
    """The soak's table: from its header line to its summary line."""
    lines = output.splitlines()
    start = next((i for i, line in enumerate(lines) if line.split()[:2] == HEADER), None)
    end = next((i for i, line in enumerate(lines) if "looks at the trend" in line), None)
    if start is None or end is None or end < start:
        raise SystemExit("no soak table in the output: no page written")
    return lines[start : end + 1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=30.0, help="wall time the page is open")
    parser.add_argument(
        "--from-output",
        type=Path,
        help="the saved output of a soak run (make dashboard-soak) instead of a new run",
    )
    args = parser.parse_args()
    if args.from_output is not None:
        output = args.from_output.read_text(encoding="utf-8")
        print(f"from the saved output of a soak run ({args.from_output.name})")
    else:
        output = _soak_output(args.minutes)
    table = _table(output)
    minutes = table[-2].split()[0]
    print(f"page open {minutes} min of wall time, virtual loop at 20x")
    print("\n".join(table))
    print("bands met: follows at every look, heap growth < 50 MB, no console error")
    return 0


if __name__ == "__main__":
    sys.exit(run_to_docs("dashboard_soak", main, __doc__))  # the table also in the docs
