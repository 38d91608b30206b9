"""Benchmark: the default `fuelid identify` path against the Cramér–Rao bound (Monte Carlo).

What a user gets with no option (the order chosen by the rule of identify/_order.py, the dead
time estimated, no meter prior), with the meter's known lag and delay given (the order still
chosen), and with the structure fixed, all through :func:`fuelid.identify.identify`,
the library call `fuelid identify` makes. Two true plants, both simulated from the model family
with exact ZOH:

- **first order**: K = 13.12 (L/min)/V, T = 1.268 s, delay 0.2 s, no meter lag (the issue's case);
- **with meter**: the same and a meter lag T_f = 0.3 s (the reference plant at 3 V).

Open loop: 30 command steps uniform in 1.5–4.5 V, 10 s each (300 s at 50 Hz). Closed loop: a PI
(SIMC, 1 s period) following flow setpoint steps, reading the noisy samples it logs
(:func:`bench_identify_accuracy.closed_loop_log`, 140 s). Noise: white, σ = 0.3 L/min, or AR(1)
with pole 0.9 and the same variance.

Per case and path, over M runs: the share of runs keeping each order; for K and T, RMSE/√CRB
and bias/√CRB, with the CRB for exactly the free parameters of the true structure (K, T, T2 when
the truth has a second lag the path must find, the delay when estimated, the offset, the initial
state) on each run's input, averaged over the runs (for AR(1) noise the Box–Jenkins bound, the
best any estimator can do knowing the noise model); and the coverage of the printed 95 %
intervals, with the two-sided binomial band that a correct 95 % interval stays inside with
probability 99.9 %. A Monte Carlo RMSE from M runs has a relative spread of about 1/√(2M).

Targets (issue 23): RMSE/CRB ≤ 1.1 where the structure is identifiable and the noise white (with
AR(1) noise the default oe is consistent, not efficient: `--method auto` is the efficient path,
shown beside it), coverage inside the band.

    .venv/bin/python benchmarks/bench_default_path.py [--runs 500] [--jobs 2] [--out FILE.md]

``--out`` (default ``docs/benchmarks/default_path.md``) writes the tables as a page with the
machine, the date, the commit and the command that produced them; ``--out -`` writes none.
"""

from __future__ import annotations

import argparse
import math
import subprocess
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import scipy.signal
import scipy.stats

from _docs_table import provenance, write_index
from bench_identify_accuracy import closed_loop_log
from fuelid.identify import IdentifyOptions, cramer_rao_bound, identify
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel, simulate_model

H = 0.02
SIGMA = 0.3
POLE = 0.9
FIRST_ORDER = ProcessModel(K=13.12, T=1.268, delay=0.2)
WITH_METER = ProcessModel(K=13.12, T=1.268, T_f=0.3, delay=0.2)


@dataclass(frozen=True)
class CallPath:
    """One way of calling identify: its options and the structure its bound assumes."""

    name: str
    options: IdentifyOptions
    bound_model: Callable[[ProcessModel], ProcessModel]
    delay_free: bool


def _as_two_lags(m: ProcessModel) -> ProcessModel:
    """The truth as the default fit must find it: the meter lag as the second process lag."""
    return replace(m, T2=m.T_f, T_f=0.0) if m.T_f > 0.0 else m


PATHS: dict[str, list[CallPath]] = {
    "first order": [
        CallPath("default (nothing given)", IdentifyOptions(), lambda m: m, True),
        CallPath("fixed: order 1, delay free", IdentifyOptions(order=1), lambda m: m, True),
    ],
    "with meter": [
        CallPath("default (nothing given)", IdentifyOptions(), _as_two_lags, True),
        CallPath(
            "default + meter priors",
            IdentifyOptions(flowmeter_T=0.3, flowmeter_delay=0.2),
            lambda m: m,
            False,
        ),
        CallPath(
            "fixed: order 1 + priors",
            IdentifyOptions(order=1, flowmeter_T=0.3, flowmeter_delay=0.2),
            lambda m: m,
            False,
        ),
        CallPath(
            "method auto + meter priors",
            IdentifyOptions(method="auto", flowmeter_T=0.3, flowmeter_delay=0.2),
            lambda m: m,
            False,
        ),
    ],
}
TRUTHS = {"first order": FIRST_ORDER, "with meter": WITH_METER}


def _noise(rng: np.random.Generator, n: int, pole: float) -> np.ndarray:
    e = rng.normal(0.0, SIGMA, n)
    if not pole:
        return e
    return np.asarray(scipy.signal.lfilter([math.sqrt(1 - pole**2)], [1.0, -pole], e))


def _log(truth: ProcessModel, loop: str, pole: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    if loop == "closed":
        return closed_loop_log(truth, SIGMA, rng, pole)
    u = np.repeat(rng.uniform(1.5, 4.5, 30), round(10.0 / H))
    y = 40.0 + simulate_model(truth, u, H) + _noise(rng, u.size, pole)
    return u, y


def _lags(model: dict[str, float]) -> tuple[float, str]:
    """The main (larger) process lag and its key."""
    return (model["T"], "T") if model["T"] >= model["T2"] else (model["T2"], "T2")


def one_run(args: tuple[str, str, float, int]) -> list[dict[str, Any]]:
    """Every path of one truth on one simulated log."""
    truth_name, loop, pole, seed = args
    truth = TRUTHS[truth_name]
    u, y = _log(truth, loop, pole, seed)
    data = IOData(u=u, y=y, sample_time=H)
    out = []
    for path in PATHS[truth_name]:
        if path.options.method == "auto" and not pole:
            continue  # auto is oe on white noise: nothing to add
        bound_model = path.bound_model(truth)
        # the bound of the true structure; AR(1): the Box–Jenkins one (innovation σ_e)
        sigma_e = SIGMA * math.sqrt(1 - pole**2) if pole else SIGMA
        names, crb = cramer_rao_bound(
            bound_model,
            u,
            H,
            sigma_e,
            delay_free=path.delay_free,
            initial="estimate",
            noise_ar=np.array([1.0, -pole]) if pole else None,
        )
        try:
            result = identify(data, path.options)
        except Exception as error:  # a refusal is a result too: counted, not hidden
            out.append({"path": path.name, "failed": str(error)})
            continue
        fitted = result.model.to_json()
        T_hat, key = _lags(fitted)
        ci = result.ci95()
        out.append(
            {
                "path": path.name,
                "order": 2 if fitted["T2"] > 0.0 else 1,
                "K": fitted["K"] - truth.K,
                "T": T_hat - truth.T,
                "K_cover": _covers(ci["K"], truth.K),
                "T_cover": _covers(ci[key], truth.T),
                "crb_K": float(crb[names.index("K"), names.index("K")]),
                "crb_T": float(crb[names.index("T"), names.index("T")]),
                "conditional": bool(result.extra.get("structure", {}).get("conditional")),
            }
        )
    return out


def _covers(ci: list[float] | None, value: float) -> bool | None:
    return None if ci is None else bool(ci[0] <= value <= ci[1])


def coverage_band(runs: int, level: float = 0.95, alarm: float = 1e-3) -> tuple[int, int]:
    """Covering counts a correct ``level`` interval stays within with probability 1 − alarm."""
    dist = scipy.stats.binom(runs, level)
    return int(dist.ppf(alarm / 2)), int(dist.isf(alarm / 2))


def summarise(rows: list[dict[str, Any]], runs: int) -> list[str]:
    lines = []
    low, high = coverage_band(runs)
    by_path: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        by_path.setdefault(row["path"], []).append(row)
    for path, items in by_path.items():
        ok = [r for r in items if "failed" not in r]
        if not ok:
            lines.append(f"  {path:28s} every run refused: {items[0]['failed'][:60]}")
            continue
        cells = [f"{100 * np.mean([r['order'] == 2 for r in ok]):6.1f}"]
        for p in ("K", "T"):
            e = np.array([r[p] for r in ok])
            bound = math.sqrt(np.mean([r[f"crb_{p}"] for r in ok]))
            covered = [r[f"{p}_cover"] for r in ok]
            hits = sum(1 for c in covered if c)
            mark = "" if low <= hits <= high else " !"
            cells += [
                f"{math.sqrt(np.mean(e**2)) / bound:7.3f}",
                f"{np.mean(e) / bound:7.3f}",
                f"{100 * hits / len(ok):6.1f}{mark:2s}",
            ]
        cells.append(f"{100 * np.mean([r['conditional'] for r in ok]):6.1f}")
        refused = len(items) - len(ok)
        lines.append(
            f"  {path:28s} " + " ".join(cells) + (f"  ({refused} refused)" if refused else "")
        )
    return lines


def _commit() -> str:
    """The checkout's commit (read when the run starts: the code the numbers come from)."""
    here = Path(__file__).resolve().parent
    head = subprocess.run(
        ["git", "rev-parse", "--short=12", "HEAD"], cwd=here, capture_output=True, text=True
    ).stdout.strip()
    dirty = subprocess.run(
        ["git", "status", "--porcelain", "--untracked-files=no"],
        cwd=here,
        capture_output=True,
        text=True,
    ).stdout.strip()
    return (head or "unknown") + (" with uncommitted changes" if dirty else "")


def _provenance(args: argparse.Namespace, seconds: float, commit: str) -> str:
    # the header every benchmark page carries (benchmarks/_docs_table.py), and the commit
    return f"{provenance(seconds)} Commit {commit}, {args.jobs} processes."


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=500)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", default=str(Path(__file__).resolve().parent.parent / "docs" /
                                           "benchmarks" / "default_path.md"))  # fmt: skip
    args = parser.parse_args()
    low, high = coverage_band(args.runs)
    intro = (
        f"{args.runs} runs per case (RMSE spread ±{1 / math.sqrt(2 * args.runs):.3f}); a 95 % "
        f"interval's coverage band (two-sided, 0.1 %): {low}–{high} of {args.runs} "
        f"({100 * low / args.runs:.1f}–{100 * high / args.runs:.1f} %); ! marks a coverage "
        "outside it"
    )
    print(intro)
    header = (
        f"  {'path':28s} {'ord2 %':>6s} {'K r/CRB':>7s} {'K b/CRB':>7s} {'K cov%':>8s} "
        f"{'T r/CRB':>7s} {'T b/CRB':>7s} {'T cov%':>8s} {'cond %':>6s}"
    )
    page = [intro, ""]
    commit = _commit()
    started = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for truth_name in TRUTHS:
            for loop in ("open", "closed"):
                for pole in (0.0, POLE):
                    tasks = [
                        (truth_name, loop, pole, args.seed * 100_000 + k) for k in range(args.runs)
                    ]
                    rows = [r for batch in pool.map(one_run, tasks, chunksize=8) for r in batch]
                    noise = f"AR(1) pole {pole:g}" if pole else "white"
                    title = f"{truth_name} plant, {loop} loop, {noise} noise, σ = {SIGMA} L/min"
                    lines = summarise(rows, args.runs)
                    print(f"\n{title}\n{header}\n" + "\n".join(lines), flush=True)
                    page += [f"**{title}**", "", "```", header, *lines, "```", ""]
    seconds = time.perf_counter() - started
    print(f"\n{seconds:.0f} s wall time, {args.jobs} processes")
    if args.out != "-":
        text = "\n".join(
            [
                "# The default identify path against the Cramér–Rao bound",
                "",
                (__doc__ or "").split("\n\n    .venv")[0].strip(),
                "",
                "Columns: share of runs keeping two lags; for K and T, RMSE and bias over the "
                "bound's root, and the share of 95 % intervals covering the truth; the share of "
                "runs whose intervals were said to be conditional on the structure.",
                "",
                *page,
                _provenance(args, seconds, commit),
                "",
            ]
        )
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text, encoding="utf-8")
        write_index(Path(args.out).parent)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
