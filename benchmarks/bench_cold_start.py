"""Benchmark: cold-process wall time of the CLI, against a SysIdentPy script and the import floor.

Targets: ``fuelid --help`` and ``fuelid --version`` in at most 0.3 s; ``fuelid identify`` of one
hour of 50 Hz data (180,000 samples, CSV, made by ``fuelid simulate``) with the dead time and the
flowmeter lag given (the reference plant's meter, as in ``make demo``: nothing searched), JSON
out, in at most 1.3 s for the whole process. Each number is the median of ``--runs`` fresh
processes (wall clock around ``subprocess.run``), after one untimed warm-up run of each command
(bytecode and page cache). The runs are interleaved, one of each command per round, so a change
of load on a shared machine falls on all rows alike. Run on demand:

    .venv/bin/python benchmarks/bench_cold_start.py [--runs 5]

Beside the CLI, in the same run and on the same file: a small script that reads the CSV with
pandas and fits a linear ARX model with SysIdentPy (FROLS, polynomial degree 1), the peer
reference (install with ``pip install -e '.[bench]'``; the row is skipped if absent), and the
bare cost of importing the scientific stack and python-control, the floor below which no
process that needs them can start.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib.util import find_spec
from pathlib import Path

from _docs_table import run_to_docs

N_SAMPLES = 180_000
"""One hour at 50 Hz."""
COLUMNS = ("t_s", "u_V", "q_Lpm")
DELAY_S = 0.2
"""The reference plant's flowmeter dead time, given to identify (not searched)."""
FLOWMETER_T_S = 0.3
"""The reference plant's flowmeter time constant, given to identify as the prior it is."""
SKIPPED = "skipped (pip install -e '.[bench]')"
PEER_NAME = "SysIdentPy ARX script (peer)"

PEER_SCRIPT = '''\
"""Read the log with pandas and fit a linear ARX(3, 3) model with SysIdentPy."""

import sys

import pandas as pd
from sysidentpy.basis_function import Polynomial
from sysidentpy.model_structure_selection import FROLS
from sysidentpy.parameter_estimation import LeastSquares

frame = pd.read_csv(sys.argv[1])
x = frame["u_V"].to_numpy().reshape(-1, 1)
y = frame["q_Lpm"].to_numpy().reshape(-1, 1)
model = FROLS(
    order_selection=False,
    n_terms=6,
    ylag=3,
    xlag=3,
    estimator=LeastSquares(),
    basis_function=Polynomial(degree=1),
)
model.fit(X=x, y=y)
print(len(frame), model.theta.ravel().tolist())
'''


@dataclass
class Case:
    """One command timed as a fresh process.

    Parameters
    ----------
    name : str
        Row label.
    argv : list of str
        Command line; ``None`` when the case cannot run here (the row shows ``skip_reason``).
    target : str
        Target or role shown beside the numbers.
    check : callable, optional
        Called with the stdout of the warm-up run; raises if the output is not what the command
        should print, so a fast failure is never taken for a fast run.
    skip_reason : str
        Shown instead of the numbers when ``argv`` is ``None``.
    seconds : list of float
        Wall time of each timed run [s], filled by the benchmark.
    last_stdout : str
        What the last run printed.
    """

    name: str
    argv: list[str] | None
    target: str
    check: Callable[[str], object] | None = None
    skip_reason: str = ""
    seconds: list[float] = field(default_factory=list)
    last_stdout: str = ""

    def run(self) -> float:
        """Run the command once as a fresh process.

        Returns
        -------
        float
            Wall time of the whole process [s].

        Raises
        ------
        RuntimeError
            The case cannot run here, or the command exited with a non-zero status.
        """
        if self.argv is None:
            raise RuntimeError(f"{self.name}: {self.skip_reason}")
        start = time.perf_counter()
        done = subprocess.run(self.argv, capture_output=True, text=True, check=False)
        seconds = time.perf_counter() - start
        if done.returncode != 0:
            raise RuntimeError(
                f"{self.name}: {' '.join(self.argv)} exited with {done.returncode}:\n"
                f"{done.stderr[-2000:]}"
            )
        self.last_stdout = done.stdout
        return seconds

    def warm_up(self) -> None:
        """One untimed run, its output checked."""
        self.run()
        if self.check is not None:
            self.check(self.last_stdout)


def write_hour_log(fuelid: Path, path: Path) -> None:
    """Simulate one hour of the reference plant at 50 Hz with ``fuelid simulate``, as CSV.

    A random multilevel command over 2.5…3.5 V with a minimum hold of 30 s (fixed seed), the
    meter's noise and resolution from the reference plant. The simulator's log (which also has
    the fuel temperature and the sample at t = 3600 s) is cut to the columns ``t_s``, ``u_V``,
    ``q_Lpm`` and the first 180,000 samples, the text of each cell kept as written.

    Parameters
    ----------
    fuelid : Path
        The console script.
    path : Path
        CSV file to write.
    """
    raw = path.with_name("simulated.csv")
    done = subprocess.run(
        [
            str(fuelid),
            "simulate",
            str(raw),
            "--profile",
            "random",
            "--levels",
            "2.5,2.75,3.0,3.25,3.5",
            "--hold",
            "30",
            "--duration",
            "3600",
            "--sample-time",
            "0.02",
            "--seed",
            "1",
            "--quiet",
            "--force",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode != 0:
        raise RuntimeError(f"fuelid simulate exited with {done.returncode}:\n{done.stderr[-2000:]}")
    with raw.open(encoding="utf-8") as source, path.open("w", encoding="utf-8") as out:
        header = source.readline().rstrip("\n").split(",")
        keep = [header.index(name) for name in COLUMNS]
        out.write(",".join(COLUMNS) + "\n")
        for _, line in zip(range(N_SAMPLES), source, strict=False):
            cells = line.rstrip("\n").split(",")
            out.write(",".join(cells[i] for i in keep) + "\n")
    raw.unlink()
    with path.open(encoding="utf-8") as written:
        n_rows = sum(1 for _ in written) - 1
    if n_rows != N_SAMPLES:
        raise RuntimeError(f"the simulated log has {n_rows} samples, not {N_SAMPLES}")


def check_version(stdout: str) -> None:
    """Raise unless ``stdout`` names fuelid and a version."""
    if not stdout.startswith("fuelid "):
        raise RuntimeError(f"fuelid --version printed {stdout!r}")


def check_help(stdout: str) -> None:
    """Raise unless ``stdout`` is the CLI's usage text."""
    if "Usage:" not in stdout or "identify" not in stdout:
        raise RuntimeError(f"fuelid --help printed {stdout[:200]!r}")


def check_json(stdout: str) -> None:
    """Raise unless ``stdout`` is one JSON object."""
    if not isinstance(json.loads(stdout), dict):
        raise RuntimeError(f"fuelid identify --json printed {stdout[:200]!r}")


def check_peer(stdout: str) -> None:
    """Raise unless the peer script saw every sample."""
    if not stdout.startswith(f"{N_SAMPLES} "):
        raise RuntimeError(f"the SysIdentPy script printed {stdout[:200]!r}")


def cpu_line() -> str:
    """CPU count, the CPUs this process may use and the load average, as one line."""
    parts = [f"CPU count {os.cpu_count()}"]
    if hasattr(os, "sched_getaffinity"):
        parts.append(f"usable {len(os.sched_getaffinity(0))}")
    if hasattr(os, "getloadavg"):
        load = ", ".join(f"{value:.2f}" for value in os.getloadavg())
        parts.append(f"load average {load}")
    return "; ".join(parts)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="fresh processes per command")
    args = parser.parse_args()
    if args.runs < 1:
        parser.error("--runs must be at least 1")

    python = sys.executable
    fuelid = Path(python).parent / ("fuelid.exe" if os.name == "nt" else "fuelid")
    if not fuelid.exists():
        sys.exit(f"no console script {fuelid}: install fuelid in this venv first (make install)")

    with tempfile.TemporaryDirectory(prefix="fuelid-cold-") as tmp:
        csv = Path(tmp) / "hour.csv"
        write_hour_log(fuelid, csv)
        peer = Path(tmp) / "sysidentpy_arx.py"
        peer.write_text(PEER_SCRIPT, encoding="utf-8")
        has_sysidentpy = find_spec("sysidentpy") is not None
        identify = [str(fuelid), "identify", str(csv), "--delay", f"{DELAY_S:g}"]
        identify += ["--flowmeter-T", f"{FLOWMETER_T_S:g}", "--json"]
        cases = [
            Case("fuelid --help", [str(fuelid), "--help"], "≤ 0.3 s", check_help),
            Case("fuelid --version", [str(fuelid), "--version"], "≤ 0.3 s", check_version),
            Case("fuelid identify 1 h CSV --json", identify, "≤ 1.3 s", check_json),
            Case(
                PEER_NAME,
                [python, str(peer), str(csv)] if has_sysidentpy else None,
                "peer reference",
                check_peer,
                SKIPPED,
            ),
            Case(
                "python -c 'import numpy, pandas, scipy…'",
                [
                    python,
                    "-c",
                    "import numpy, pandas, scipy.linalg, scipy.optimize, scipy.signal",
                ],
                "floor (reference)",
            ),
            Case("python -c 'import control'", [python, "-c", "import control"], "reference"),
        ]
        runnable = [case for case in cases if case.argv is not None]
        for case in runnable:
            case.warm_up()
        for _ in range(args.runs):
            for case in runnable:
                case.seconds.append(case.run())

    print(f"cold start: median and min of {args.runs} fresh processes each (wall clock)")
    print(cpu_line())
    print(
        "the machine is shared: compare the ratios within one run, not absolute seconds "
        "between runs"
    )
    print(f"python {sys.version.split()[0]} at {python}")
    print(f"log: {N_SAMPLES} samples (1 h at 50 Hz), columns t_s,u_V,q_Lpm, CSV")
    print(f"identify: fuelid identify FILE.csv {' '.join(identify[3:])}")
    print()
    peer_median = next(
        (
            statistics.median(case.seconds)
            for case in cases
            if case.name == PEER_NAME and case.seconds
        ),
        None,
    )
    header = f"{'command':42s} {'median s':>9s} {'min s':>7s}  {'target':18s} {'× peer':>7s}"
    print(header)
    print("-" * len(header))
    for case in cases:
        if not case.seconds:
            print(f"{case.name:42s} {case.skip_reason}")
            continue
        median = statistics.median(case.seconds)
        ratio = f"{median / peer_median:7.2f}" if peer_median else f"{'':7s}"
        print(f"{case.name:42s} {median:9.3f} {min(case.seconds):7.3f}  {case.target:18s} {ratio}")


if __name__ == "__main__":
    run_to_docs("cold_start", main, __doc__)  # the printed tables, also in docs/benchmarks
