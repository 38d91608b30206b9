"""Benchmark: the output-error fit's printed uncertainty under white and coloured noise.

Issue 13, part 1. The settings are pinned here and printed with the table:

- the model: like the reference plant's, K = 13.5 (L/min)/V, T = 1.26 s, with the meter priors
  T_f = 0.3 s and delay 0.2 s held fixed (K and T estimated, order 1);
- 300 s at 50 Hz (15,000 samples) of a step sequence, each level drawn from 1.5–4.5 V and held
  12–30 s, a new sequence per run;
- measurement noise: white, or AR(1) with poles 0.8, 0.95 and 0.99 per 0.02 s sample, always
  with a stationary standard deviation of 0.25 L/min.

Per case and parameter: RMSE over the bound (the Cramér–Rao bound: σ²(JᵀJ)⁻¹ for white noise, the
Box–Jenkins bound σ_e²(J_fᵀJ_f)⁻¹ with J_f = A(q)J for AR noise, both at the true parameters on
each run's input, averaged over runs), bias in units of the printed standard error, and the
share of runs whose printed 95 % interval (the JSON's ci95: K ± 1.96 se, T log-transformed)
covers the truth, for the printed covariance (``covariance="auto"``: the sandwich with the
residual spectrum when the whiteness test fails) and for the white one σ²(JᵀJ)⁻¹. The acceptance
band of the coverage is 95 % ± three binomial standard deviations for the number of runs.

Run on demand (about 0.1 s per fit):

    .venv/bin/python benchmarks/bench_oe_coverage.py [--runs 500]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import scipy.signal

from _docs_table import run_to_docs
from fuelid.blas import single_threaded_blas
from fuelid.identify import OutputError, cramer_rao_bound, interval95
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel, simulate_model

H = 0.02
DURATION = 300.0
TRUTH = ProcessModel(K=13.5, T=1.26, T_f=0.3, delay=0.2)
SD = 0.25
POLES = (0.0, 0.8, 0.95, 0.99)


def _input(rng: np.random.Generator) -> np.ndarray:
    n = round(DURATION / H)
    pieces, total = [], 0
    while total < n:
        length = round(rng.uniform(12.0, 30.0) / H)
        pieces.append(np.full(length, rng.uniform(1.5, 4.5)))
        total += length
    return np.concatenate(pieces)[:n]


def _noise(rng: np.random.Generator, pole: float, n: int) -> np.ndarray:
    innovation = rng.normal(0.0, SD * math.sqrt(1.0 - pole**2), n)
    return np.asarray(scipy.signal.lfilter([1.0], [1.0, -pole], innovation))


def run_case(pole: float, runs: int, seed: int) -> dict[str, dict[str, float]]:
    rng = np.random.default_rng(seed)
    found: dict[str, list[tuple[float, float, float, float]]] = {"K": [], "T": []}
    bounds: dict[str, list[float]] = {"K": [], "T": []}
    a = np.array([1.0, -pole])
    for _ in range(runs):
        u = _input(rng)
        y = 40.0 + simulate_model(TRUTH, u, H) + _noise(rng, pole, u.size)
        est = OutputError(order=1, T_f=TRUTH.T_f, delay=TRUTH.delay).fit(IOData(u, y, H))
        names, crb = cramer_rao_bound(
            TRUTH, u, H, SD * math.sqrt(1.0 - pole**2), initial="estimate", noise_ar=a
        )
        for name in ("K", "T"):
            i = est.param_names_.index(name)
            found[name].append(
                (
                    getattr(est, f"{name}_"),
                    math.sqrt(est.cov_[i, i]),
                    math.sqrt(est.cov_white_[i, i]),
                    1.0 if est.covariance_ == "hac" else 0.0,
                )
            )
            bounds[name].append(crb[names.index(name), names.index(name)])
    table: dict[str, dict[str, float]] = {}
    for name, true in (("K", TRUTH.K), ("T", TRUTH.T)):
        values = np.array(found[name])
        estimates, printed, white = values[:, 0], values[:, 1], values[:, 2]
        error = estimates - true
        covered = [
            _covers(v, se, true, positive=name == "T")
            for v, se in zip(estimates, printed, strict=True)
        ]
        covered_white = [
            _covers(v, se, true, positive=name == "T")
            for v, se in zip(estimates, white, strict=True)
        ]
        table[name] = {
            "rmse_over_bound": float(np.sqrt(np.mean(error**2) / np.mean(bounds[name]))),
            "bias_se": float(np.mean(error) / np.median(printed)),
            "coverage": float(np.mean(covered)),
            "coverage_white": float(np.mean(covered_white)),
            "se_over_spread": float(np.median(printed) / np.std(estimates, ddof=1)),
            "hac_share": float(np.mean(values[:, 3])),
        }
    return table


def _covers(value: float, se: float, true: float, positive: bool) -> bool:
    interval = interval95(value, se, positive=positive)
    assert interval is not None
    low, high = interval[0]
    return low <= true <= high


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=500)
    parser.add_argument("--seed", type=int, default=13)
    args = parser.parse_args()
    band = 3.0 * math.sqrt(0.95 * 0.05 / args.runs)
    print(
        f"oe on {TRUTH} (T_f, delay fixed), {DURATION:g} s at {1 / H:g} Hz, steps 1.5–4.5 V "
        f"held 12–30 s, noise sd {SD} L/min; {args.runs} runs per case; coverage band "
        f"{0.95 - band:.3f}…{0.95 + band:.3f}"
    )
    print(
        f"{'noise':>12} {'par':>3} {'RMSE/bound':>10} {'bias/se':>8} {'se/spread':>9} "
        f"{'cover':>6} {'cover(white)':>12} {'hac share':>9}"
    )
    start = time.perf_counter()
    with single_threaded_blas():
        for k, pole in enumerate(POLES):
            table = run_case(pole, args.runs, args.seed + k)
            label = "white" if pole == 0.0 else f"AR(1) {pole:g}"
            for name, row in table.items():
                ok = abs(row["coverage"] - 0.95) <= band
                print(
                    f"{label:>12} {name:>3} {row['rmse_over_bound']:10.2f} {row['bias_se']:8.2f} "
                    f"{row['se_over_spread']:9.2f} {row['coverage']:6.3f}"
                    f"{'' if ok else '*':1} {row['coverage_white']:11.3f} {row['hac_share']:9.2f}"
                )
    print(f"({time.perf_counter() - start:.0f} s; * = coverage outside the band)")


if __name__ == "__main__":
    run_to_docs("oe_coverage", main, __doc__)  # the printed tables, also in docs/benchmarks
