"""Benchmark: one PI evaluated over many plant variants, against the clock.

Target (issue 4): one PI over 1,000 plant variants (fuel temperature drawn over −20…50 °C and the
identified parameters drawn from the identification's covariance) in under 10 s on this machine.
The sweep uses the linear models (exact ZOH, exact dead time in the frequency response); the
nonlinear plant is kept for the few cases the report shows, and its cost per run is printed here
to show why. Run on demand:

    .venv/bin/python benchmarks/bench_tuning_sweep.py [--quick]

The covariance is the one a real identification gives: a 10-minute simulated PLC log of the
reference plant (a step every 30 s around 3 V) fitted by ``oe`` with the meter's lag as a prior.
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from _docs_table import run_to_docs
from _timing import best_of
from fuelid.identify import OutputError
from fuelid.io.timeseries import IOData
from fuelid.model import model_covariance
from fuelid.plant import load_plant_config
from fuelid.plant.simulate import simulate
from fuelid.profiles import step_sequence
from fuelid.tuning import (
    DEFAULT_T_RANGE,
    Anchor,
    band_edges,
    evaluate_fixed,
    plant_cases,
    tune,
    uncertainty_sweep,
)
from fuelid.tuning.closedloop import flow_at, standard_runs
from fuelid.units import LPM_PER_M3S, celsius_to_kelvin

TARGET_SECONDS = 10.0
TARGET_VARIANTS = 1000
T_FUEL = celsius_to_kelvin(20.0)
"""Fuel temperature of the simulated log [K]."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one repeat, no 3000-variant run")
    args = parser.parse_args()
    repeat = 1 if args.quick else 3
    config = load_plant_config()
    meter = config.flowmeter

    rng = np.random.default_rng(0)
    profile = step_sequence(rng.uniform(2.5, 3.5, 20).round(2).tolist(), 30.0)
    log = simulate(config, profile, T_fuel=T_FUEL, seed=1)
    data = IOData(u=log.u, y=log.q_measured * LPM_PER_M3S, sample_time=log.time[1] - log.time[0])
    fit = OutputError(T_f=meter.time_constant_s).fit(data)
    anchor = Anchor(fit.model_, T_FUEL, float(np.mean(data.u)))
    pi = tune(fit.model_, "simc", control_period=1.0)
    names, block = model_covariance(fit.param_names_, fit.cov_)
    relative = ", ".join(
        f"{name} {np.sqrt(block[i, i]) / abs(getattr(fit.model_, name)):.2%}"
        for i, name in enumerate(names)
    )
    print(
        f"identified: {fit.model_}  (fit {fit.fit_percent_:.1f} %)\n"
        f"relative standard deviations: {relative}\n"
        f"PI (SIMC, h = 1 s): Kc = {pi.Kc:.4g} V/(L/min), Ti = {pi.Ti:.3g} s\n"
    )

    rows: list[tuple[str, int, float, str]] = []
    sizes = (100, TARGET_VARIANTS) if args.quick else (100, TARGET_VARIANTS, 3000)
    summary: dict[str, float] = {}
    for n in sizes:
        seconds, sweep = best_of(
            repeat,
            lambda n=n: uncertainty_sweep(pi, anchor, fit.param_names_, fit.cov_, config, n=n),
        )
        verdict = ""
        if n == TARGET_VARIANTS:
            verdict = "PASS" if seconds < TARGET_SECONDS else "FAIL"
            verdict += f" (< {TARGET_SECONDS:g} s)"
            summary = sweep.summary()
        rows.append((f"uncertainty sweep, {n} variants", n, seconds, verdict))

    temps = tuple(float(T) for T in band_edges(*DEFAULT_T_RANGE, 5.0))
    commands = (config.vfd.u_min_V, anchor.u, config.vfd.u_max_V)

    def fixed_check() -> Any:
        return evaluate_fixed(pi, plant_cases(config, temps, commands, anchor))

    seconds, check = best_of(repeat, fixed_check)
    rows.append(
        (
            f"fixed PI on the physics grid ({len(temps)} temps x 3 commands)",
            len(check.cases),
            seconds,
            "",
        )
    )

    start_flow = flow_at(config, anchor.u, T_FUEL)
    seconds, _ = best_of(repeat, lambda: standard_runs(config, pi, (T_FUEL,), start_flow, 8.0))
    rows.append(("nonlinear closed loop, one 90 s standard run", 1, seconds, ""))
    nonlinear_1000 = seconds * TARGET_VARIANTS

    print(f"{'task':62s} {'cases':>6s} {'best s':>8s} {'ms/case':>8s}  verdict")
    for name, n, seconds, verdict in rows:
        print(f"{name:62s} {n:6d} {seconds:8.3f} {1000 * seconds / n:8.2f}  {verdict}")
    print(
        f"\n{TARGET_VARIANTS} nonlinear runs would take about {nonlinear_1000:.0f} s; "
        "hence the linear models for the sweep."
    )
    print(
        f"sweep of {TARGET_VARIANTS}: worst Ms {summary['worst_Ms']:.2f}, "
        f"95th percentile Ms {summary['Ms_p95']:.2f}, "
        f"min gain margin {summary['min_gain_margin']:.2f}, "
        f"min phase margin {summary['min_phase_margin_deg']:.1f}°, "
        f"unstable {summary['unstable_fraction']:.1%}"
    )
    print(
        f"physics grid: worst Ms {check.worst_Ms:.2f}, "
        f"worst overshoot {check.worst_overshoot:.1f} % (linear, reduced model)"
    )


if __name__ == "__main__":
    run_to_docs("tuning_sweep", main, __doc__)  # the printed tables, also in docs/benchmarks
