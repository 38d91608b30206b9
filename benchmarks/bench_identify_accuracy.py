"""Benchmark: accuracy of the estimators against the Cramér–Rao bound (Monte Carlo).

For each case the truth is simulated from the fitted model structure (exact ZOH), white noise of
known σ is added, and each estimator is fitted M times with seeded noise. The table shows, per
parameter, RMSE/√CRB, where the CRB is computed for the same data and the same free parameters
(K, T, the offset, the initial-state amplitudes, and the delay when it is estimated). A Monte
Carlo RMSE from M runs has a relative spread of about 1/√(2M), printed as ±.

Target (issue 3): at most 1.1 for `oe`.

    .venv/bin/python benchmarks/bench_identify_accuracy.py [--runs 300]
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.signal

from _docs_table import run_to_docs
from fuelid.identify import OutputError, StepResponseLS, cramer_rao_bound
from fuelid.io.timeseries import IOData
from fuelid.lti import discretise
from fuelid.model import ProcessModel, simulate_model

FloatArray = np.ndarray


@dataclass
class Case:
    """One Monte Carlo case: a true model, an input, a sample time, a noise level."""

    name: str
    truth: ProcessModel
    u: FloatArray
    h: float
    sigma: float
    delay_free: bool = False


def reference_case(delay_free: bool) -> Case:
    rng = np.random.default_rng(100)
    u = np.repeat(np.r_[3.0, rng.uniform(2.5, 3.5, 11)], 500)  # 12 steps, 10 s each at 50 Hz
    truth = ProcessModel(K=13.12, T=1.268, T_f=0.3, delay=0.2)  # `fuelid plant info` at 3 V
    label = "delay free" if delay_free else "delay = meter prior"
    return Case(f"reference plant, 50 Hz, {label}", truth, u, 0.02, 0.1, delay_free)


def article_case(T: float, sigma: float) -> Case:
    # the article's kind: 1 s control period, step strength 25, noise std 0.05 (or 10x)
    rng = np.random.default_rng(200)
    u = np.repeat(rng.choice([-25.0, 25.0], 60), 4)  # 240 samples, a change every 4 s at most
    u[:8] = 0.0
    truth = ProcessModel(K=2.0, T=T, T_f=0.3, delay=0.2)
    settled = truth.settling_time() <= 5.0
    return Case(
        f"article kind, 1 s, T={T:g} s ({'settles' if settled else 'not settled'} in N=5), "
        f"σ={sigma:g}",
        truth,
        u,
        1.0,
        sigma,
    )


def fit_oe(case: Case, y: FloatArray) -> dict[str, float]:
    est = OutputError(
        order=1, T_f=case.truth.T_f, delay=None if case.delay_free else case.truth.delay
    ).fit(IOData(u=case.u, y=y, sample_time=case.h))
    return {"K": est.K_, "T": est.T_, "delay": est.delay_}


def fit_step_ls(case: Case, y: FloatArray) -> dict[str, float] | None:
    if case.h != 1.0 or case.delay_free:
        return None  # the article's method runs at the 1 s control period with τ known
    est = StepResponseLS(N=5, T_f=case.truth.T_f, delay=case.truth.delay).fit(
        IOData(u=case.u, y=y, sample_time=case.h)
    )
    return {"K": est.K_, "T": est.T_, "delay": est.delay_}


ESTIMATORS: dict[str, Callable[[Case, FloatArray], dict[str, float] | None]] = {
    "oe": fit_oe,
    "step-ls": fit_step_ls,
}


def run(case: Case, runs: int, seed: int) -> None:
    names, crb = cramer_rao_bound(
        case.truth, case.u, case.h, case.sigma, delay_free=case.delay_free, initial="estimate"
    )
    bound = dict(zip(names, np.sqrt(np.diag(crb)), strict=True))
    params = ["K", "T", "delay"] if case.delay_free else ["K", "T"]
    clean = simulate_model(case.truth, case.u, case.h)
    truth = {"K": case.truth.K, "T": case.truth.T, "delay": case.truth.delay}
    spread = 1.0 / math.sqrt(2 * runs)
    print(f"\n{case.name}: {case.u.size} samples, {runs} runs (Monte Carlo spread ±{spread:.2f})")
    print(
        f"  {'method':8s} "
        + " ".join(f"{p + ' RMSE/CRB':>14s} {p + ' bias/CRB':>14s}" for p in params)
        + f" {'ms/fit':>8s}"
    )
    for method, fit in ESTIMATORS.items():
        rng = np.random.default_rng(seed)
        errors: dict[str, list[float]] = {p: [] for p in params}
        start = time.perf_counter()
        skipped = False
        for _ in range(runs):
            estimate = fit(case, clean + rng.normal(0.0, case.sigma, clean.size))
            if estimate is None:
                skipped = True
                break
            for p in params:
                errors[p].append(estimate[p] - truth[p])
        if skipped:
            continue
        per_fit = 1e3 * (time.perf_counter() - start) / runs
        cells = []
        for p in params:
            e = np.asarray(errors[p])
            cells.append(f"{math.sqrt(np.mean(e**2)) / bound[p]:14.3f}")
            cells.append(f"{np.mean(e) / bound[p]:14.3f}")
        print(f"  {method:8s} " + " ".join(cells) + f" {per_fit:8.1f}")


def closed_loop_log(
    truth: ProcessModel, sigma: float, rng: np.random.Generator, pole: float = 0.0
) -> tuple[FloatArray, FloatArray]:
    """A routine closed-loop log with a discrete PI following flow setpoint steps.

    PI: 1 s period, SIMC tuning, 1–5 V limits; the PLC samples at 50 Hz; the controller reads the
    same noisy samples that are logged, so the noise feeds back into u.
    """
    h, period = 0.02, 1.0
    per = round(period / h)
    setpoints = np.repeat([40.0, 46.0, 36.0, 44.0, 38.0, 47.0, 40.0], 20)  # one per period
    theta = truth.delay + truth.T_f + period / 2  # SIMC with the half rule and h/2
    Kc = truth.T / (truth.K * 2 * theta)
    Ti = min(truth.T, 8 * theta)
    model = discretise(truth.time_constants, truth.delay, h)
    n = setpoints.size * per
    u = np.full(n, 3.0)
    y = np.empty(n)
    v = np.zeros(n + model.shift)  # input deviation from 3 V, delayed by the integer delay
    zi = np.zeros(max(model.a.size, model.b.size) - 1)
    noise = rng.normal(0.0, sigma, n)
    if pole:
        # coloured (AR(1)) noise of the same variance: slow flow disturbances
        noise = scipy.signal.lfilter([math.sqrt(1 - pole**2)], [1.0, -pole], noise)
    u_prev, e_prev = 3.0, 0.0
    for j, r in enumerate(setpoints):
        k0 = j * per
        y_meas = (y[k0 - 1] + noise[k0 - 1]) if k0 else 40.0 + noise[0]
        e = r - y_meas
        u_j = float(np.clip(u_prev + Kc * (e - e_prev + period / Ti * e), 1.0, 5.0))
        u[k0 : k0 + per] = u_j
        v[k0 + model.shift : k0 + per + model.shift] = u_j - 3.0
        out, zi = scipy.signal.lfilter(model.b, model.a, v[k0 : k0 + per], zi=zi)
        y[k0 : k0 + per] = 40.0 + truth.K * out
        u_prev, e_prev = u_j, e
    return u, y + noise


def run_closed_loop(runs: int, seed: int, pole: float = 0.0) -> None:
    truth = ProcessModel(K=13.12, T=1.268, T_f=0.3, delay=0.2)
    sigma = 0.1
    rng = np.random.default_rng(seed)
    sq = {"K": 0.0, "T": 0.0}
    bias = {"K": 0.0, "T": 0.0}
    bound = {"K": 0.0, "T": 0.0}
    for _ in range(runs):
        u, y = closed_loop_log(truth, sigma, rng, pole)
        est = OutputError(T_f=0.3, delay=0.2).fit(IOData(u=u, y=y, sample_time=0.02))
        names, crb = cramer_rao_bound(truth, u, 0.02, sigma, initial="estimate")
        for p, value in (("K", est.K_), ("T", est.T_)):
            err = value - getattr(truth, p)
            sq[p] += err**2
            bias[p] += err
            bound[p] += crb[names.index(p), names.index(p)]
    spread = 1.0 / math.sqrt(2 * runs)
    noise = f"AR(1) noise, pole {pole:g}" if pole else "white noise"
    print(
        f"\nclosed loop: PI (SIMC, 1 s) following flow setpoint steps, 50 Hz, σ = {sigma:g} L/min,"
        f" {noise}; {runs} runs (Monte Carlo spread ±{spread:.2f}); CRB (white) given each run's u"
    )
    print(
        f"  {'method':8s} {'K RMSE/CRB':>14s} {'K bias/CRB':>14s} {'T RMSE/CRB':>14s} "
        f"{'T bias/CRB':>14s}"
    )
    cells = []
    for p in ("K", "T"):
        rms_bound = math.sqrt(bound[p] / runs)
        cells += [
            f"{math.sqrt(sq[p] / runs) / rms_bound:14.3f}",
            f"{bias[p] / runs / rms_bound:14.3f}",
        ]
    print(f"  {'oe':8s} " + " ".join(cells))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=300)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    cases = [
        reference_case(delay_free=False),
        reference_case(delay_free=True),
        article_case(T=0.8, sigma=0.05),
        article_case(T=0.8, sigma=0.5),
        article_case(T=3.0, sigma=0.05),
    ]
    for case in cases:
        run(case, args.runs, args.seed)
    run_closed_loop(max(args.runs // 3, 50), args.seed)
    # coloured noise in closed loop: output error is no longer maximum likelihood and the noise
    # fed back through the controller biases it (the bound shown is the white-noise one)
    run_closed_loop(max(args.runs // 3, 50), args.seed, pole=0.99)
    print(
        "\ntarget: RMSE/CRB <= 1.1 for oe (the Monte Carlo spread is the ± above).\n"
        "step-ls (N = 5 at 1 s) is not efficient, and on the slow plant its truncated step\n"
        "response has not settled after N periods: a_N and hence K and T are biased whatever\n"
        "the noise (docs/explanation/identification.md); the bias/CRB column shows it."
    )


if __name__ == "__main__":
    run_to_docs("identify_accuracy", main, __doc__)  # the printed tables, also in docs/benchmarks
