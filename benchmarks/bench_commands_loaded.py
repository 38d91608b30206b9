"""Benchmark: ``fuelid report`` and ``fuelid tune --model`` as cold processes, quiet and loaded.

Targets (issue 12, item 4), with the other core of a two-core machine busy: ``fuelid report`` of
the README quick start's log in at most 8 s, ``fuelid tune --model ident.json`` in at most 2 s.
The inputs are made as the quick start makes them, in a temporary folder:

    fuelid simulate seq.parquet --profile steps --levels 1,2,1.5,3 --dwell 30
    fuelid identify seq.parquet --json > ident.json

Each number is the median wall time (around ``subprocess.run``) of ``--runs`` fresh processes,
after one untimed warm-up of each command (bytecode and page cache); the commands take turns, one
of each per round. The whole set runs twice: on the machine as it is, then with a competing load,
one child process multiplying 200×200 matrices with numpy on one BLAS thread (one core's worth of
work), started before the round and killed after it; it also stops by itself after
``--load-limit`` seconds, so an interrupted benchmark leaves nothing spinning. Run on demand:

    .venv/bin/python benchmarks/bench_commands_loaded.py [--runs 3]

``tune --model --simulate --config`` (what ``make demo`` runs) is timed too, without a target.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from _docs_table import run_to_docs

LOAD_SCRIPT = """\
import sys, time
import numpy as np
a = np.random.default_rng(0).random((200, 200))
end = time.monotonic() + float(sys.argv[1])
while time.monotonic() < end:
    a = a @ a
    a /= np.abs(a).max()
"""
"""One core's worth of numpy work, for at most ``argv[1]`` seconds."""


@dataclass(frozen=True)
class Case:
    """One command, timed as a fresh process."""

    name: str
    args: tuple[str, ...]
    """Arguments of ``fuelid``."""
    target: float | None
    """Largest acceptable median under load [s] (None: no target)."""


# the quick start's logs are of the reference plant: its plant file is theirs (runs need one)
REFERENCE_PLANT = str(Path(__file__).resolve().parents[1] / "src/fuelid/data/reference_plant.toml")

CASES = (
    Case("report seq.parquet", ("report", "seq.parquet", "--out", "seq.html", "--force"), 8.0),
    Case("tune --model ident.json", ("tune", "--model", "ident.json"), 2.0),
    Case(
        "tune --model ident.json --simulate",
        ("tune", "--model", "ident.json", "--simulate", "--config", REFERENCE_PLANT),
        None,
    ),
)


def fuelid(*args: str, cwd: Path, stdout: int | None = subprocess.DEVNULL) -> None:
    """Run ``python -m fuelid ARGS`` in ``cwd`` (this interpreter, so this environment)."""
    subprocess.run(
        [sys.executable, "-m", "fuelid", *args],
        cwd=cwd,
        stdout=stdout,
        stderr=subprocess.DEVNULL,
        check=True,
    )


def make_inputs(folder: Path) -> None:
    """The quick start's step-sequence log and its identification as JSON."""
    fuelid(
        "simulate", "seq.parquet", "--profile", "steps", "--levels", "1,2,1.5,3", "--dwell", "30",
        cwd=folder,
    )  # fmt: skip
    with (folder / "ident.json").open("w") as out:
        subprocess.run(
            [sys.executable, "-m", "fuelid", "identify", "seq.parquet", "--json"],
            cwd=folder,
            stdout=out,
            stderr=subprocess.DEVNULL,
            check=True,
        )


@contextmanager
def competing_load(limit: float) -> Iterator[None]:
    """A child process busy with numpy on one thread while the block runs (``limit`` s at most)."""
    env = os.environ | {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    child = subprocess.Popen([sys.executable, "-c", LOAD_SCRIPT, str(limit)], env=env)
    try:
        time.sleep(1.0)  # numpy imported and spinning before the first timed run
        yield
    finally:
        child.kill()
        child.wait()


def median_times(folder: Path, runs: int) -> dict[str, float]:
    """Median wall time [s] of each case over ``runs`` rounds, after one warm-up of each."""
    for case in CASES:
        fuelid(*case.args, cwd=folder)
    times: dict[str, list[float]] = {case.name: [] for case in CASES}
    for _ in range(runs):
        for case in CASES:
            start = time.perf_counter()
            fuelid(*case.args, cwd=folder)
            times[case.name].append(time.perf_counter() - start)
    return {name: statistics.median(values) for name, values in times.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="timed runs per command (median)")
    parser.add_argument(
        "--load-limit", type=float, default=300.0, help="the load stops itself after this [s]"
    )
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="fuelid-bench-") as tmp:
        folder = Path(tmp)
        make_inputs(folder)
        quiet = median_times(folder, args.runs)
        with competing_load(args.load_limit):
            loaded = median_times(folder, args.runs)
    print(f"{os.cpu_count()} CPUs, median of {args.runs} cold processes [s]")
    print(f"{'command':<36} {'quiet':>7} {'loaded':>7} {'target (loaded)':>16}  met")
    met_all = True
    for case in CASES:
        target = "-" if case.target is None else f"≤ {case.target:g} s"
        met = "-" if case.target is None else ("yes" if loaded[case.name] <= case.target else "NO")
        met_all &= met != "NO"
        q, lo = quiet[case.name], loaded[case.name]
        print(f"{case.name:<36} {q:>7.2f} {lo:>7.2f} {target:>16}  {met}")
    return 0 if met_all else 1


if __name__ == "__main__":
    sys.exit(run_to_docs("commands_loaded", main, __doc__))  # the tables also in the docs
