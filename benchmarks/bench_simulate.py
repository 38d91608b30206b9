"""Benchmark: one hour of plant time from the nonlinear model, against the clock.

Target (issue 2): 180,000 samples at 0.02 s with a step every 30 s in at most 3.6 s on a 2-core
machine, i.e. at least 1000 times faster than real time. Run on demand:

    .venv/bin/python benchmarks/bench_simulate.py [--repeat 3]

Prints a table with the best wall time of the repeats and the real-time ratio, and writes it to
docs/benchmarks/simulate.md (benchmarks/_docs_table.py). The ratio, not the absolute time, is
what to compare between machines.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from _docs_table import Table, write_page
from fuelid.plant import load_plant_config
from fuelid.plant.simulate import FuelTemperature, simulate
from fuelid.profiles import random_levels, step_sequence

HOUR = 3600.0
TARGET_RATIO = 1000.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    config = load_plant_config()
    rng = np.random.default_rng(0)
    cases = {
        "steps every 30 s, 20 °C": {
            "profile": step_sequence(rng.uniform(1.0, 5.0, 120).round(2).tolist(), 30.0),
            "fuel_temperature": 293.15,
        },
        "steps every 30 s, fuel 0→40 °C": {
            "profile": step_sequence(rng.uniform(1.0, 5.0, 120).round(2).tolist(), 30.0),
            "fuel_temperature": FuelTemperature.ramp(273.15, 313.15, HOUR),
        },
        "random binary 1/2 V, hold 1 s": {
            "profile": random_levels([1.0, 2.0], hold=1.0, duration=HOUR, seed=3),
            "fuel_temperature": 293.15,
        },
    }
    table = Table(
        header=("case", "samples", "best s", "x real time", "target"),
        formats=("s", "d", ".3f", ".0f", "s"),
        widths=(34, 8, 8, 12, 8),
    )
    table.print_header()
    started = time.perf_counter()
    for name, case in cases.items():
        best = float("inf")
        n = 0
        for _ in range(args.repeat):
            start = time.perf_counter()
            result = simulate(config, case["profile"], T_fuel=case["fuel_temperature"], seed=1)
            best = min(best, time.perf_counter() - start)
            n = result.time.size
        ratio = HOUR / best
        verdict = "ok" if ratio >= TARGET_RATIO else "MISSED"
        table.add(name, n, best, ratio, verdict)
    target = f"target: one hour in at most {HOUR / TARGET_RATIO:.1f} s (>= {TARGET_RATIO:.0f}x)"
    print(target)
    intro = (
        f"One hour of plant time (0.02 s samples) from the nonlinear model; the best of "
        f"{args.repeat} runs per case. {target[0].upper()}{target[1:]}."
    )
    write_page("simulate", intro, [table], time.perf_counter() - started)


if __name__ == "__main__":
    main()
