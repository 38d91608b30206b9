"""Benchmark: ``fuelid identify`` and ``fuelid report`` on a day at 50 Hz, against read-and-solve.

Targets (issue 38, part 3): on a day of 50 Hz samples (4.32 M rows, an 89 MB CSV)
``fuelid identify`` within 5× (goal 2×) the wall time of ``benchmarks/read_and_solve.py``
(``pandas.read_csv`` of the file and one least-squares ARX problem on every sample) in the same
run, and under 1 GB (goal 0.5 GB) peak memory; ``fuelid report`` within 2× ``fuelid identify``.
The log is simulated into a temporary folder as the issue made it (``fuelid simulate day.csv
-p random --duration 86400 --hold 30 --levels 1.0,1.5,2.0,2.5 --control-period 0.2``; nothing
is kept). Each command runs as a fresh process, ``--runs`` times in turns (the page cache warm
after the first); the table gives the fastest run's wall time and that process's peak resident
memory (``getrusage`` of the child), and each time over read-and-solve's. Run on demand:

    .venv/bin/python benchmarks/bench_day_log.py [--runs 3] [--log day.csv]
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from _docs_table import run_to_docs

HERE = Path(__file__).resolve().parent
SIMULATE = (
    "-p",
    "random",
    "--duration",
    "86400",
    "--hold",
    "30",
    "--levels",
    "1.0,1.5,2.0,2.5",
    "--control-period",
    "0.2",
    "--quiet",
    "--force",
)
"""``fuelid simulate``'s arguments after the file: the issue's day."""

PEAK_OF_CHILD = """\
import resource, subprocess, sys
done = subprocess.run(sys.argv[1:], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
sys.stdout.buffer.write(done.stdout)
sys.stderr.buffer.write(done.stderr)
peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
# kilobytes on Linux, bytes on macOS
print(peak * (1 if sys.platform == "darwin" else 1024), file=sys.stderr)
sys.exit(done.returncode)
"""
"""Runs a command and prints its peak resident memory [bytes] last on stderr."""
READ_AND_SOLVE = "read-and-solve (pandas + lstsq)"


@dataclass
class Run:
    """One command's fastest run."""

    name: str
    seconds: float
    peak_bytes: int
    stdout: str


def timed(name: str, command: list[str]) -> Run:
    """Wall time and peak memory of ``command`` as a fresh process (through a small wrapper)."""
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", PEAK_OF_CHILD, *command], capture_output=True, text=True
    )
    seconds = time.perf_counter() - started
    if done.returncode != 0:
        raise SystemExit(f"{name} failed ({done.returncode}): {done.stderr.strip()[-2000:]}")
    *_, peak = done.stderr.strip().splitlines()
    return Run(name, seconds, int(peak), done.stdout)


def fuelid() -> str:
    """The ``fuelid`` script of the interpreter running this benchmark."""
    beside = Path(sys.executable).with_name("fuelid")
    return str(beside) if beside.exists() else (shutil.which("fuelid") or "fuelid")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=3, help="runs of each command")
    parser.add_argument("--log", type=Path, help="an existing day's CSV (else simulated)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        log = args.log
        if log is None:
            log = Path(tmp) / "day.csv"
            simulated = timed("simulate", [fuelid(), "simulate", str(log), *SIMULATE])
            print(f"simulated the day in {simulated.seconds:.0f} s")
        period = ["--control-period", "0.2", "--quiet"]
        report = ["--force", "--out", str(Path(tmp) / "report.html")]
        commands = {
            READ_AND_SOLVE: [sys.executable, str(HERE / "read_and_solve.py"), str(log)],
            "fuelid identify": [fuelid(), "identify", str(log), *period, "--json"],
            # every sample fitted (the copy only searches): the numbers before the copy fit
            "fuelid identify --full-record": [
                fuelid(),
                "identify",
                str(log),
                *period,
                "--json",
                "--full-record",
            ],
            "fuelid report": [fuelid(), "report", str(log), *period, *report],
        }
        best: dict[str, Run] = {}
        for _ in range(args.runs):
            for name, command in commands.items():
                run = timed(name, command)
                if name not in best or run.seconds < best[name].seconds:
                    best[name] = run
        rows = sum(1 for _ in log.open(encoding="utf-8")) - 1
        size = log.stat().st_size
    base = best[READ_AND_SOLVE].seconds
    identify_s = best["fuelid identify"].seconds
    print(f"a day at 50 Hz: {rows:,} rows, {size / 1e6:.0f} MB CSV; fastest of {args.runs} runs")
    header = f"{'rows':>10s} {'seconds':>8s} {'peak GB':>8s} {'× read-and-solve':>17s}"
    print(f"{'command':34s} {header}")
    for name, run in best.items():
        print(
            f"{name:34s} {rows:>10,d} {run.seconds:8.1f} {run.peak_bytes / 1e9:8.2f} "
            f"{run.seconds / base:17.1f}"
        )
    print(
        f"targets: identify ≤ 5× read-and-solve (goal 2×): {identify_s / base:.1f}×; peak < 1 GB "
        f"(goal 0.5 GB): {best['fuelid identify'].peak_bytes / 1e9:.2f} GB; report ≤ 2× "
        f"identify: {best['fuelid report'].seconds / identify_s:.1f}×"
    )
    print(
        f"identify --full-record: {best['fuelid identify --full-record'].seconds / base:.1f}× "
        "read-and-solve"
    )
    for name in ("fuelid identify", "fuelid identify --full-record"):
        _estimates(name, json.loads(best[name].stdout))


def _estimates(name: str, result: dict[str, Any]) -> None:
    """The estimates, their standard errors and how the long record was fitted."""
    model, stderr = result["model"], result["stderr"]
    estimates = ", ".join(
        f"{key} {model[key]:.6g} ± {stderr[key]:.2g}"
        for key in ("K", "T", "T2", "delay")
        if stderr.get(key) is not None
    )
    print(f"{name}: {estimates}; fit {result['fit_percent']:.2f} %")
    info = result.get("long_record")
    if info is None:
        return
    if info.get("fitted_on") == "copy":
        print(
            f"  fitted on a copy of {info['copy_samples']:,} samples in {info['stretches']} "
            f"stretches of the {info['samples']:,}"
        )
    else:
        print(
            f"  searched on {info['copy_samples']:,} samples in {info['stretches']} stretches, "
            f"polished on all {info['samples']:,} (Gauss–Newton steps by order: "
            f"{info['polish_steps']}, converged: {info['converged']})"
        )


if __name__ == "__main__":
    run_to_docs("day_log", main, __doc__)  # the printed table, also in docs/benchmarks
