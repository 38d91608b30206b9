"""Benchmark: the prediction-error (Box–Jenkins) fit against the output-error fit and the bound.

Issue 13, part 2. The settings are pinned here and printed with the table:

- the model: like the reference plant's, K = 13.5 (L/min)/V, T = 1.26 s, with the meter priors
  T_f = 0.3 s and delay 0.2 s held fixed (K and T estimated, order 1, initial state estimated);
- open loop: 300 s at 50 Hz (15,000 samples) of a step sequence, each level drawn from 1.5–4.5 V
  and held 12–30 s, a new sequence per run; measurement noise white or AR(1) with poles 0.8,
  0.95, 0.99 per 0.02 s sample, stationary standard deviation 0.25 L/min;
- closed loop: a PI flow controller at a 1 s period (Kc = 0.04 V/(L/min), Ti = 1.3 s, the last
  50 Hz sample read each period) following setpoint steps of 30–55 L/min held 12–30 s, 300 s,
  with an AR(1) output disturbance of pole 0.99 and standard deviation 3 L/min that the
  controller feeds back into u;
- oe: ``OutputError`` with its white covariance σ̂²(JᵀJ)⁻¹ (and, where the installed oe has it,
  its printed ``covariance="auto"`` one, the column "cover(auto)"); pem: ``PredictionError``
  with the noise order chosen by BIC among (nc, nd) ∈ {0, 1, 2}², its asymptotic covariance.

Per case, estimator and parameter: RMSE over the bound, with the bound
- white noise: the Cramér–Rao bound σ²(JᵀJ)⁻¹, J = ∂ŷ/∂p at the truth on each run's input;
- AR(1) noise: the Box–Jenkins Cramér–Rao bound σ_e²((D·J)ᵀ(D·J))⁻¹, D = 1 − p·q⁻¹ the true
  noise inverse (open loop the noise parameters' block is asymptotically uncorrelated with the
  process block, so this is the process block of the full bound);
both averaged over runs (RMS); the closed-loop case has no fixed bound (the input depends on
the noise): its RMSE is given over the RMS of pem's printed standard errors. Then the bias in
units of the median printed standard error, and the share of runs whose printed 95 % interval
(± 1.96 se) covers the truth; the acceptance band of the coverage is 95 % ± three binomial
standard deviations for the number of runs. A Monte Carlo RMSE from M runs has a relative
spread of about 1/√(2M).

Speed: pem on one hour of 50 Hz data (180,000 samples, delay given, AR(1) 0.95 noise) from
scratch, and the refit of a 10-minute window warm-started from that fit (best of a few runs).

Real records: the shared DaISy heating plate and hair dryer (skipped when ../shared/ref-data is
absent), oe against pem: validation fit and the whiteness of the residuals.

    .venv/bin/python benchmarks/bench_pem.py [--runs 500] [--seed 13]
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import scipy.signal

from _docs_table import run_to_docs
from _timing import best_of
from fuelid.blas import single_threaded_blas
from fuelid.identify import OutputError, PredictionError, residual_whiteness
from fuelid.identify._variable_projection import Structure, jacobian
from fuelid.io.logs import load_log
from fuelid.io.timeseries import IOData
from fuelid.lti import discretise
from fuelid.model import ProcessModel, nrmse_fit, simulate_model

H = 0.02
DURATION = 300.0
TRUTH = ProcessModel(K=13.5, T=1.26, T_f=0.3, delay=0.2)
SD = 0.25
POLES = (0.0, 0.8, 0.95, 0.99)
CLOSED_LOOP = {"pole": 0.99, "sd": 3.0, "Kc": 0.04, "Ti": 1.3, "period": 1.0}
PRIORS: dict[str, Any] = {"order": 1, "T_f": TRUTH.T_f, "delay": TRUTH.delay}


def _steps(rng: np.random.Generator, lo: float, hi: float) -> np.ndarray:
    n = round(DURATION / H)
    pieces, total = [], 0
    while total < n:
        length = round(rng.uniform(12.0, 30.0) / H)
        pieces.append(np.full(length, rng.uniform(lo, hi)))
        total += length
    return np.concatenate(pieces)[:n]


def _noise(rng: np.random.Generator, pole: float, sd: float, n: int) -> np.ndarray:
    """Stationary AR(1) noise (white for pole 0) with standard deviation ``sd``."""
    innovation = rng.normal(0.0, sd * math.sqrt(1.0 - pole**2), n)
    start = [pole * rng.normal(0.0, sd)]
    return np.asarray(scipy.signal.lfilter([1.0], [1.0, -pole], innovation, zi=start)[0])


def open_loop(rng: np.random.Generator, pole: float) -> IOData:
    u = _steps(rng, 1.5, 4.5)
    return IOData(u, 40.0 + simulate_model(TRUTH, u, H) + _noise(rng, pole, SD, u.size), H)


def closed_loop(rng: np.random.Generator) -> IOData:
    """The PI loop of the module docstring, linear, the plant exact at 50 Hz."""
    n, per = round(DURATION / H), round(CLOSED_LOOP["period"] / H)
    setpoint = _steps(rng, 30.0, 55.0)
    v = _noise(rng, CLOSED_LOOP["pole"], CLOSED_LOOP["sd"], n)
    plant = discretise([TRUTH.T, TRUTH.T_f], TRUTH.delay, H)
    u0, y0 = 2.0, 20.0 + TRUTH.K * 2.0
    du, y = np.zeros(n), np.empty(n)
    state = np.zeros(max(plant.a.size, plant.b.size) - 1)
    u_k, e_prev = u0, 0.0
    for j in range(0, n, per):
        e = setpoint[j] - (y[j - 1] if j else y0 + v[0])
        u_k += CLOSED_LOOP["Kc"] * (e - e_prev + CLOSED_LOOP["period"] / CLOSED_LOOP["Ti"] * e)
        e_prev = e
        du[j : j + per] = u_k - u0
        delayed = np.zeros(per)
        first = max(j - plant.shift, 0)
        delayed[first - (j - plant.shift) :] = du[first : j + per - plant.shift]
        out, state = scipy.signal.lfilter(plant.b, plant.a, delayed, zi=state)
        y[j : j + per] = y0 + TRUTH.K * out + v[j : j + per]
    return IOData(u0 + du, y, H)


def bound(u: np.ndarray, pole: float) -> dict[str, float]:
    """Variance bound of K and T (white: Cramér–Rao; AR(1): Box–Jenkins) on this input."""
    st = Structure(1, TRUTH.T_f, TRUTH.delay, "estimate", None)
    beta = np.r_[TRUTH.K, 0.0, np.zeros(2)]
    values = {"T": TRUTH.T, "T2": 0.0, "delay": TRUTH.delay}
    names, J = jacobian(st, values, beta, u, H, float(u[0]))
    sigma_e = SD * math.sqrt(1.0 - pole**2)
    if pole:
        J = scipy.signal.lfilter([1.0, -pole], [1.0], J, axis=0)[1:]
    cov = sigma_e**2 * np.linalg.inv(J.T @ J)
    return {p: float(cov[names.index(p), names.index(p)]) for p in ("K", "T")}


def fit_both(data: IOData) -> dict[str, dict[str, float]]:
    out: dict[str, dict[str, float]] = {}
    oe = OutputError(**PRIORS).fit(data)
    white = getattr(oe, "cov_white_", oe.cov_)
    out["oe"] = {
        **{p: getattr(oe, f"{p}_") for p in ("K", "T")},
        **{f"se_{p}": math.sqrt(white[i, i]) for i, p in ((0, "K"), (1, "T"))},
        **{f"auto_{p}": oe.stderr_[p] or math.nan for p in ("K", "T")},
    }
    pem = PredictionError(**PRIORS).fit(data)
    out["pem"] = {
        **{p: getattr(pem, f"{p}_") for p in ("K", "T")},
        **{f"se_{p}": pem.stderr_[p] or math.nan for p in ("K", "T")},
        "white_noise_model": float(pem.noise_model_["nc"] + pem.noise_model_["nd"] == 0),
        "pole": float(pem.noise_model_["poles"][0]) if pem.noise_model_["nd"] == 1 else math.nan,
    }
    return out


def run_case(
    make: Callable[[np.random.Generator], IOData], pole: float | None, runs: int, seed: int
) -> tuple[dict[str, dict[str, dict[str, float]]], dict[str, float]]:
    rng = np.random.default_rng(seed)
    rows: dict[str, list[dict[str, float]]] = {"oe": [], "pem": []}
    bounds: dict[str, list[float]] = {"K": [], "T": []}
    extra = {"white_noise_model": 0.0, "pole_mean": 0.0}
    poles = []
    for _ in range(runs):
        data = make(rng)
        fits = fit_both(data)
        for method, row in fits.items():
            rows[method].append(row)
        extra["white_noise_model"] += fits["pem"]["white_noise_model"] / runs
        poles.append(fits["pem"]["pole"])
        if pole is not None:
            for p, var in bound(data.u, pole).items():
                bounds[p].append(var)
    extra["pole_mean"] = float(np.nanmean(poles)) if np.any(np.isfinite(poles)) else math.nan
    table: dict[str, dict[str, dict[str, float]]] = {}
    for method, found in rows.items():
        table[method] = {}
        for p, true in (("K", TRUTH.K), ("T", TRUTH.T)):
            est = np.array([r[p] for r in found])
            se = np.array([r[f"se_{p}"] for r in found])
            err = est - true
            ref = (
                np.mean(bounds[p])
                if pole is not None
                else np.mean([r[f"se_{p}"] ** 2 for r in rows["pem"]])
            )
            row = {
                "rmse_over_bound": float(np.sqrt(np.mean(err**2) / ref)),
                "bias_se": float(np.mean(err) / np.median(se)),
                "bias_z": float(np.mean(err) / (np.std(err, ddof=1) / math.sqrt(runs))),
                "coverage": float(np.mean(np.abs(err) <= 1.96 * se)),
                "se_over_spread": float(np.median(se) / np.std(est, ddof=1)),
            }
            if method == "oe":
                auto = np.array([r[f"auto_{p}"] for r in found])
                row["coverage_auto"] = float(np.mean(np.abs(err) <= 1.96 * auto))
            table[method][p] = row
    return table, extra


def speed(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = round(3600.0 / H)
    u = np.concatenate([_steps(rng, 1.5, 4.5) for _ in range(12)])[:n]
    data = IOData(u, 40.0 + simulate_model(TRUTH, u, H) + _noise(rng, 0.95, SD, n), H)
    window = data.segment(n - round(600.0 / H))
    t_oe, _ = best_of(3, lambda: OutputError(**PRIORS).fit(data))
    t_pem, pem = best_of(3, lambda: PredictionError(**PRIORS).fit(data))
    t_cold, _ = best_of(3, lambda: PredictionError(**PRIORS).fit(window))
    t_warm, _ = best_of(5, lambda: PredictionError(**PRIORS).fit(window, init=pem))
    print(
        f"\nspeed (one BLAS thread, best of 3–5): one hour at 50 Hz ({n:,} samples, delay "
        f"given): oe {t_oe:.3f} s, pem {t_pem:.3f} s (noise order "
        f"nc={pem.noise_model_['nc']}, nd={pem.noise_model_['nd']}); 10-minute window "
        f"({window.n_samples:,} samples): pem from scratch {t_cold:.3f} s, warm-started from "
        f"the hour's fit {t_warm:.3f} s"
    )


REF = Path(__file__).resolve().parents[2] / "shared" / "ref-data"
RECORDS = {
    "heating plate": ("daisy_heating_system.csv", "u_lamp_drive_V", "y_plate_temp_degC"),
    "hair dryer": ("daisy_hair_dryer.csv", "u_heater_V", "y_outlet_temp_thermocouple_V"),
}


def real_records() -> None:
    """The shared DaISy records: fit on the first half, free run scored on the second."""
    if not REF.is_dir():
        print(f"\nreal records skipped: {REF} is absent")
        return
    print(
        "\nreal records (fit on the first half, delay estimated; val = free-run NRMSE fit % on "
        "the second half; white p = whiteness p-value of oe's residuals / pem's prediction "
        "errors):"
    )
    print(
        f"{'record':>14} {'order':>5} {'oe fit':>7} {'oe val':>7} {'oe p':>8} {'pem fit':>7} "
        f"{'pem val':>7} {'pem p':>8} {'1-step':>7} {'noise (nc,nd): poles':>24}"
    )
    for name, (file, u_col, y_col) in RECORDS.items():
        data = load_log(REF / file, input_col=u_col, output_col=y_col)
        half = data.n_samples // 2
        fit = data.segment(0, half)
        for order in (1, 2):
            oe = OutputError(order=order).fit(fit)
            pem = PredictionError(order=order).fit(fit)
            val_oe = nrmse_fit(data.y[half:], oe.simulate(data)[half:])
            val_pem = nrmse_fit(data.y[half:], pem.simulate(data)[half:])
            p_oe = residual_whiteness(fit.y - oe.y_hat_).p_value
            p_pem = residual_whiteness(pem.residuals_).p_value
            noise = pem.noise_model_
            poles = ", ".join(f"{p:.6g}" for p in noise["poles"] if isinstance(p, float))
            label = f"({noise['nc']},{noise['nd']}): {poles}"
            print(
                f"{name:>14} {order:>5} {oe.fit_percent_:7.1f} {val_oe:7.1f} {p_oe:8.2g} "
                f"{pem.fit_percent_:7.1f} {val_pem:7.1f} {p_pem:8.2g} "
                f"{pem.one_step_fit_percent_:7.1f} {label:>24}"
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=500, help="Monte Carlo runs per case")
    parser.add_argument("--seed", type=int, default=13)
    parser.add_argument("--skip-speed", action="store_true")
    args = parser.parse_args()
    band = 3.0 * math.sqrt(0.95 * 0.05 / args.runs)
    print(
        f"oe vs pem on {TRUTH} (T_f, delay fixed; K, T, offset, initial state estimated), "
        f"{DURATION:g} s at {1 / H:g} Hz; open loop: steps 1.5–4.5 V held 12–30 s, noise sd "
        f"{SD} L/min; closed loop: PI Kc={CLOSED_LOOP['Kc']} V/(L/min), Ti={CLOSED_LOOP['Ti']} "
        f"s at {CLOSED_LOOP['period']} s, setpoint steps 30–55 L/min, AR(1) "
        f"{CLOSED_LOOP['pole']} disturbance sd {CLOSED_LOOP['sd']} L/min; {args.runs} runs per "
        f"case (RMSE spread ±{1 / math.sqrt(2 * args.runs):.2f}); coverage band "
        f"{0.95 - band:.3f}…{0.95 + band:.3f}"
    )
    print(
        "bound: white → Cramér–Rao σ²(JᵀJ)⁻¹; AR(1) → Box–Jenkins σ_e²((D·J)ᵀ(D·J))⁻¹; closed "
        "loop → RMS of pem's printed se (no fixed bound)"
    )
    print(
        f"{'case':>16} {'method':>6} {'par':>3} {'RMSE/bound':>10} {'bias/se':>8} "
        f"{'bias z':>7} {'se/spread':>9} {'cover':>6} {'cover(auto)':>11}"
    )
    start = time.perf_counter()
    cases: list[tuple[str, Callable[[np.random.Generator], IOData], float | None]] = [
        (
            "white" if pole == 0.0 else f"AR(1) {pole:g}",
            lambda rng, pole=pole: open_loop(rng, pole),
            pole,
        )
        for pole in POLES
    ]
    cases.append(("closed loop", closed_loop, None))
    with single_threaded_blas():
        for k, (label, make, pole) in enumerate(cases):
            table, extra = run_case(make, pole, args.runs, args.seed + k)
            for method, params in table.items():
                for p, row in params.items():
                    auto = row.get("coverage_auto")
                    auto_cell = f"{auto:11.3f}" if auto is not None else f"{'':>11}"
                    flag = "" if abs(row["coverage"] - 0.95) <= band else " *"
                    print(
                        f"{label:>16} {method:>6} {p:>3} {row['rmse_over_bound']:10.3f} "
                        f"{row['bias_se']:8.2f} {row['bias_z']:7.2f} "
                        f"{row['se_over_spread']:9.2f} {row['coverage']:6.3f}{auto_cell}{flag}"
                    )
            print(
                f"{'':>16} pem noise model: white (nc = nd = 0) in "
                f"{100 * extra['white_noise_model']:.0f} % of runs; mean AR(1) pole "
                f"{extra['pole_mean']:.4f}"
            )
        print(f"({time.perf_counter() - start:.0f} s; * coverage outside the band)")
        if not args.skip_speed:
            speed(args.seed)
        real_records()


if __name__ == "__main__":
    run_to_docs("pem", main, __doc__)  # the printed tables, also in docs/benchmarks
