"""Gray-box fits of a kinked model: the exact kink against softplus-smoothed versions.

The overflow tank of ``examples/overflow_tank.py`` (the tests' ``support.kinked_models``), dx/dt
= a·u − b·√x − c·max(x − RIM, 0) with a = 0.2, b = 0.1, c = 0.3 and RIM = 2 m, simulated by
DOP853 at rtol 1e-11 (which finds the kink by step rejection) over 600 samples of 1 s, the input
held random steps 0.4…0.95 V (30 to 90 s each), from a known initial level of 1 m, with 0.01 m
of white noise; a new record per run, from seed 1000 on, keeping only records whose level is
above the rim in at least 50 samples (in one that never reaches it c does not act and the exact
model is refused; the header says how many were skipped). Each record is fitted (a, b, c free
from 1.3× the truth, the initial level known) with the exact kink and with the kink replaced by
the softplus w·log(1 + exp((x − RIM)/w)) of width w = 0.02, 0.1 and 0.4 m (1 %, 5 % and 20 % of
the rim's height), which is smooth everywhere and equals the kink far from the rim but not near
it (at the rim it is w·ln 2, not 0).

Per model and parameter: the mean bias in per cent of the true value and in units of the
printed standard error (its spread over the runs is about ±1/√runs for an unbiased estimator),
the share of runs whose printed 95 % interval covers the truth (95 % ± 1.96·√(0.95·0.05/runs)
for a correct one: ±4 points at 100 runs), the median largest linearity discrepancy (above 0.2
fuelid warns), and the median fit time. A run that fails (refused or not converged) is counted
under "failed", one that ends without a standard error for a parameter (undetermined there, or
at a bound) under "no se"; neither enters the other columns.

Run on demand (about 2 minutes at 100 runs on a shared 2-core machine):

    python benchmarks/bench_greybox_smoothing.py [--runs 100]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from _docs_table import run_to_docs

# the records of tests/unit/greybox/test_greybox_kinks.py (tests/ on the path: support)
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from fuelid.errors import FuelidError
from fuelid.greybox import GreyBoxEstimator, OdeModel, ParameterSpec
from support.kinked_models import H_RIM, TRUTH, X0, kinked_record

SAMPLES = 600
NOISE = 0.01  # m
WIDTHS = (0.02, 0.1, 0.4)  # m: 1 %, 5 % and 20 % of the rim's height
NAMES = ("a", "b", "c")
MIN_ABOVE = 50  # samples above the rim a record needs (those with fewer are skipped)


def overflow(width: float | None) -> Callable[..., Any]:
    """The tank's f with the exact kink (width None) or a softplus of that width, numpy style."""

    def f(t: float, x: Any, u: Any, p: Any) -> Any:
        excess = x[0] - H_RIM
        if width is None:
            pipe = np.maximum(excess, 0.0)
        else:  # w·log(1 + exp(excess/w)), written so that it cannot overflow
            pipe = width * np.logaddexp(0.0, excess / width)
        return [p["a"] * u[0] - p["b"] * np.sqrt(np.maximum(x[0], 0.0)) - p["c"] * pipe]

    return f


def model(width: float | None) -> OdeModel:
    truth = TRUTH["overflow"]
    level = X0["overflow"]
    return OdeModel(
        overflow(width),
        [ParameterSpec(name, 1.3 * truth[name], 0.0) for name in NAMES],
        ["level"],
        x0=lambda p, u0, y0: [level],
    )


def label(width: float | None) -> str:
    if width is None:
        return "exact kink"
    return f"softplus w={width:g} m ({100 * width / H_RIM:g} %)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100, help="records (seeds) per model")
    args = parser.parse_args()
    truth = TRUTH["overflow"]
    widths: list[float | None] = [None, *WIDTHS]
    z: dict[str | None, dict[str, list[float]]] = {}
    relative: dict[str | None, dict[str, list[float]]] = {}
    covered: dict[str | None, dict[str, list[bool]]] = {}
    linearity: dict[str | None, list[float]] = {}
    seconds: dict[str | None, list[float]] = {}
    failed: dict[str | None, int] = {}
    unsure: dict[str | None, int] = {}
    for w in widths:
        key = label(w)
        z[key] = {name: [] for name in NAMES}
        relative[key] = {name: [] for name in NAMES}
        covered[key] = {name: [] for name in NAMES}
        linearity[key], seconds[key], failed[key], unsure[key] = [], [], 0, 0
    above: list[int] = []
    seed, skipped = 999, 0
    while len(above) < args.runs:
        seed += 1
        record, clean = kinked_record("overflow", seed=seed, n=SAMPLES, noise=NOISE)
        if np.sum(clean > H_RIM) < MIN_ABOVE:  # c acts too little there: a record for another
            skipped += 1
            continue
        above.append(int(np.sum(clean > H_RIM)))
        for w in widths:
            key = label(w)
            started = time.perf_counter()
            try:
                est = GreyBoxEstimator(model(w)).fit(record)
            except FuelidError:
                failed[key] += 1
                continue
            seconds[key].append(time.perf_counter() - started)
            if any(est.stderr_[name] is None for name in NAMES):  # undetermined or at a bound
                unsure[key] += 1
                print(f"seed {seed}, {key}: {est.params_} without an error", file=sys.stderr)
                continue
            worst = 0.0
            for name in NAMES:
                se, interval = est.stderr_[name], est.ci95_[name]
                z[key][name].append((est.params_[name] - truth[name]) / se)
                relative[key][name].append(est.params_[name] / truth[name] - 1.0)
                covered[key][name].append(interval[0] <= truth[name] <= interval[1])
                discrepancy = est.linearity_[name]
                worst = max(worst, math.nan if discrepancy is None else discrepancy)
            linearity[key].append(worst)
    print(
        f"overflow tank, {args.runs} records of {SAMPLES} s (level above the rim in "
        f"{min(above)}…{max(above)} samples of each; {skipped} records with fewer than "
        f"{MIN_ABOVE} skipped), noise {NOISE} m; truth a = {truth['a']}, b = {truth['b']}, "
        f"c = {truth['c']}"
    )
    print(
        f"{'model':<28} {'param':>5} {'bias %':>7} {'bias/se':>8} {'coverage':>9}"
        f" {'lin. (med)':>10} {'fit s (med)':>11} {'failed':>6} {'no se':>5}"
    )
    for w in widths:
        key = label(w)
        for i, name in enumerate(NAMES):
            values = z[key][name]
            bias = statistics.fmean(values) if values else math.nan
            percent = 100 * statistics.fmean(relative[key][name]) if values else math.nan
            cover = statistics.fmean(covered[key][name]) if values else math.nan
            first = i == 0
            lin = statistics.median(linearity[key]) if first and linearity[key] else math.nan
            secs = statistics.median(seconds[key]) if first and seconds[key] else math.nan
            print(
                f"{key if first else '':<28} {name:>5} {percent:7.2f} {bias:8.2f} {cover:9.2f}"
                + (f" {lin:10.3f} {secs:11.2f} {failed[key]:6d} {unsure[key]:5d}" if first else "")
            )
    print(
        f"(bias/se spread of an unbiased estimator ≈ ±{1 / math.sqrt(args.runs):.2f}; "
        f"coverage of a correct interval 0.95 ± {1.96 * math.sqrt(0.95 * 0.05 / args.runs):.2f})"
    )


if __name__ == "__main__":
    run_to_docs("greybox_smoothing", main, __doc__)  # the printed table, also in docs/benchmarks
