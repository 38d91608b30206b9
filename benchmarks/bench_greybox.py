"""Gray-box ODE estimation: speed of a two-tank fit, and the linear model against the CRB.

Run as ``python benchmarks/bench_greybox.py [--runs 500]``. Prints two tables:

1. the 1,000-sample two-state Torricelli tank fit (k4 fixed; k1, k2, k3 and the initial state
   estimated): wall time (median of 3), simulations, right-hand-side evaluations, iterations,
   and the sensitivities' largest relative error against central differences of simulations;
2. the segmented start: the 1,500-sample ringing oscillator of the tests (ω = 1, ζ = 0.01)
   from ω = 1.6: single shooting (which does not converge) against ``segments="auto"``, wall
   time, simulations and the estimate;
3. y' = (K·u − y)/T with white noise, Monte Carlo: RMSE over the Cramér–Rao bound
   σ·√diag((JᵀJ)⁻¹) at the truth, and the 95 % interval coverage (which should be 0.95 ± 2σ of
   a binomial, i.e. about ±0.02 at 500 runs).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from _docs_table import run_to_docs

# the Monte Carlo models of tests/unit/greybox/test_greybox.py (tests/ on the path: support.bands)
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from fuelid.greybox import ConvergenceError, GreyBoxEstimator
from fuelid.greybox._parameters import ParameterMap
from fuelid.greybox._sensitivity import simulate_record
from unit.greybox.test_greybox import (
    TANK_X0,
    central_difference,
    linear_monte_carlo,
    oscillator_model,
    tank_model,
    tank_record,
)


def tank_fit() -> None:
    record, _ = tank_record()
    times, est = [], None
    for _ in range(3):
        start = time.perf_counter()
        est = GreyBoxEstimator(tank_model()).fit(record)
        times.append(time.perf_counter() - start)
    assert est is not None
    model = tank_model()
    pmap = ParameterMap(model.parameters)
    p = len(pmap.free_names)
    phi = np.concatenate(
        [pmap.to_phi(np.array([est.params_[k] for k in pmap.free_names])), TANK_X0]
    )

    def simulate(phi_: np.ndarray, sens: bool = False) -> np.ndarray:
        system = model.bind(pmap.values(phi_[:p]), pmap.free_names, record)
        if not sens:
            return simulate_record(system, record, phi_[p:], rtol=1e-11).outputs[:, 0]
        s0 = np.hstack([np.zeros((2, p)), np.eye(2)])
        out = simulate_record(system, record, phi_[p:], s0, pmap.dtheta_dphi(phi_[:p]))
        assert out.output_sensitivity is not None
        return out.output_sensitivity[:, 0, :]

    reference = central_difference(simulate, phi)
    error = np.abs(simulate(phi, sens=True) - reference).max(axis=0) / np.abs(reference).max(axis=0)
    print("two-tank fit, 1000 samples, 20 input levels, 3 parameters + 2 initial states")
    print(
        f"{'wall [s] median/3':>18} {'min':>6} {'sims':>5} {'rhs evals':>10} {'iters':>6}"
        f" {'sens err':>9}"
    )
    print(
        f"{statistics.median(times):18.3f} {min(times):6.3f} {est.n_simulations_:5d} "
        f"{est.n_evaluations_:10d} {est.n_iterations_:6d} {error.max():9.1e}"
    )
    print(
        "estimate:",
        {k: round(v, 5) for k, v in est.params_.items()},
        "fit %:",
        np.round(est.fit_percent_[0], 2),
    )


def segmented_start() -> None:
    import inspect

    import test_greybox

    # the tests' fixture, called as a function
    record = inspect.unwrap(test_greybox.ringing_record)()
    print("\nringing oscillator, 1500 samples, from w = 1.6 (truth 1.0), z = 0.01")
    print(f"{'start':>8} {'wall [s]':>9} {'sims':>6} {'result':<60}")
    for segments in (None, "auto"):
        started = time.perf_counter()
        est = GreyBoxEstimator(oscillator_model(1.6, 0.01), "estimate", segments=segments)
        try:
            est.fit(record)
            result = f"{est.start_}: w = {est.params_['w']:.5f} ± {est.stderr_['w']:.1e}"
        except ConvergenceError:
            result = "did not converge"
        elapsed = time.perf_counter() - started
        sims = getattr(est, "n_simulations_", float("nan"))
        print(f"{segments!s:>8} {elapsed:9.2f} {sims:6} {result:<60}")


def monte_carlo(runs: int) -> None:
    start = time.perf_counter()
    result = linear_monte_carlo(runs)
    elapsed = time.perf_counter() - start
    print(f"\nlinear first-order model, {runs} Monte Carlo runs ({elapsed:.1f} s)")
    print(f"{'param':>5} {'RMSE/CRB':>9} {'bias/CRB':>9} {'coverage':>9}")
    for i, name in enumerate(("K", "T")):
        print(
            f"{name:>5} {result['rmse'][i] / result['crb'][i]:9.3f} "
            f"{result['bias'][i] / result['crb'][i]:9.3f} {result['coverage'][i]:9.3f}"
        )
    print(
        f"(RMSE/CRB spread ≈ ±{1 / np.sqrt(2 * runs):.3f}; coverage spread ≈ "
        f"±{np.sqrt(0.95 * 0.05 / runs):.3f})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--runs", type=int, default=500, help="Monte Carlo runs")
    args = parser.parse_args()
    tank_fit()
    segmented_start()
    monte_carlo(args.runs)


if __name__ == "__main__":
    run_to_docs("greybox", main, __doc__)  # the printed tables, also in docs/benchmarks
