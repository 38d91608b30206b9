"""Benchmark: one online window, today's analysis against the fast one (issue 26, "Speed").

Target: a warm 10-minute window at 50 Hz (30,000 samples) at least 2× faster in MAN and 3× in
AUTO than the analysis before issue 26, measured as ratios in one run on the same windows; the
decisions unchanged.

Both analysers run in this process on the same windows of the virtual PLC's engine
(:class:`fuelid.plc.virtual.VirtualPLC`, reference plant, 50 Hz, PI at 1 s), each
warm-started from its own previous window as the service does (the first window of each run is
the warm-up and is not timed): ``WindowAnalyser(fast=False)`` fits pem on every AUTO window
with the numerics before issue 26 (:data:`fuelid.numerics_mode.REFERENCE_NUMERICS`, the
default search tolerances), ``fast=True`` skips pem when the noise screen says its noise pole
would be nearly integrating (:mod:`fuelid.online._pem_screen`), with the faster numerics
(:data:`fuelid.numerics_mode.WINDOW_NUMERICS`: exact ZOH coefficients
without scipy's conversions, FFT autocorrelations, statistical search tolerances, one SVD per
stored fit, cached settling times; since the second pass: Levenberg–Marquardt searches with
the lags' analytic sensitivities instead of scipy's trf with finite differences, the searches'
last sensitivities reused by the stored fits, (JᵀJ)⁻¹ through the SVD of R, short
autocovariances by dot products, settling times of distinct lags in closed form, step-ls
without its diagnostics). A profile of one warm window of each kind (cProfile, both paths) says
where the time goes.

The runs are the HELD-OUT settings of the noise screen (its threshold was tuned on seeds 1–2,
disturbances 0.1, 0.3, 1.0 L/min, 20 °C, the local and the demo setpoint profiles):

- AUTO: seeds ``--seeds``, fed-back disturbance (AR(1), 60 s) of 0, 0.2 and 0.5 L/min, the
  setpoint steps around 30 L/min and the demo's wind-tunnel runs, fuel at 5 and 35 °C;
- MAN: command steps of 0.1–0.4 V around 3 V, the same disturbances and temperatures.

Printed: per mode, the median and p90 of the warm window's wall time, both paths, and their
ratio (of medians; and the median of per-window ratios); the agreement of the decisions (pem or
oe, accepted or not) and of K (|ΔK| over the larger standard error); the projected cost of a
loop-year at 50 Hz with a window every ``identify_every_s`` (the default ``[online]``) and of a
100-loop fleet-year on ``--cores`` cores.

Run on demand (``make bench`` runs it with the defaults):

    .venv/bin/python benchmarks/bench_window.py [--windows 5] [--seeds 101 102] [--cores 2]
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Iterator
from importlib import resources
from typing import Any

import numpy as np

from _docs_table import run_to_docs
from fuelid.online import Online, WindowAnalyser, WindowResult, window_priors
from fuelid.plc.virtual import VirtualPLC
from fuelid.profiles.runs import demo_run_profile
from fuelid.store import Quality, SampleArrays

PERIOD_S = 0.02
WINDOW_S = 600.0
T0 = 1.8e9
CHUNK = 1000  # samples per engine advance (under the ring's 2048)
YEAR_S = 365.25 * 86400.0
FLEET_LOOPS = 100


def reference_plant() -> str:
    """Path of the packaged reference plant file."""
    return str(resources.files("fuelid.data").joinpath("reference_plant.toml"))


def windows(plc: VirtualPLC, n: int) -> Iterator[tuple[SampleArrays, float, float]]:
    """``n`` consecutive 10-minute windows of the engine (after a minute's run-in)."""
    plc.advance(round(60.0 / PERIOD_S))
    per = round(WINDOW_S / PERIOD_S)
    k = 0
    for _ in range(n):
        blocks, temps, modes = [], [], []
        left = per
        while left:
            m = min(CHUNK, left)
            blocks.append(np.array(list(plc.advance(m).values())))
            p = plc.read_points()
            temps += [p["fuel_temperature"]] * m
            modes += [int(p["mode"])] * m
            left -= m
        rows = np.concatenate(blocks)
        t = T0 + PERIOD_S * (k + np.arange(per))
        yield (
            SampleArrays(
                time=t,
                seq=rows[:, 0].astype(np.int64),
                u=rows[:, 1].copy(),
                y=rows[:, 2].copy(),
                setpoint=rows[:, 3].copy(),
                fuel_temperature=np.asarray(temps),
                mode=np.asarray(modes, dtype=np.int64),
                quality=np.full(per, int(Quality.OK), dtype=np.int64),
            ),
            float(t[0]),
            float(t[0]) + WINDOW_S,
        )
        k += per


def _steps(levels: tuple[float, ...], dwell: float) -> tuple[list[float], list[float]]:
    t: list[float] = []
    v: list[float] = []
    for i, level in enumerate(levels):
        t += [i * dwell, (i + 1) * dwell]
        v += [level, level]
    return t, v


def settings(mode: str, seeds: list[int]) -> Iterator[tuple[str, VirtualPLC]]:
    """The held-out runs of one mode: (label, engine)."""
    for seed in seeds:
        for dist in (0.0, 0.2, 0.5):
            for temp in (5.0, 35.0):
                if mode == "MAN":
                    profile = _steps((3.0, 3.2, 2.9, 3.3, 3.0, 2.8, 3.1, 2.9), 15.0)
                    yield (
                        f"MAN seed {seed} d {dist} {temp:g} °C",
                        VirtualPLC(
                            seed=seed,
                            command_profile=profile,
                            disturbance_sd_Lpm=dist,
                            fuel_temp_C=temp,
                        ),
                    )
                    continue
                for name, sp in (
                    ("steps", _steps((30.0, 28.5, 32.5, 31.0, 27.0, 30.5, 32.0, 29.0), 30.0)),
                    ("runs", demo_run_profile(seed)),
                ):
                    yield (
                        f"AUTO {name} seed {seed} d {dist} {temp:g} °C",
                        VirtualPLC(
                            seed=seed,
                            setpoint_profile=sp,
                            disturbance_sd_Lpm=dist,
                            fuel_temp_C=temp,
                        ),
                    )


def analyser(fast: bool, ti_s: float) -> WindowAnalyser:
    """A fresh analyser for the reference plant, default ``[online]``, step-ls on."""
    priors, k_plant = window_priors(reference_plant(), control_period=1.0)
    return WindowAnalyser(Online(), priors, PERIOD_S, k_plant=k_plant, ti_s=ti_s, fast=fast)


def _warm(a: WindowAnalyser, result: WindowResult) -> None:
    # as the service: the accepted model warm-starts the next window
    if result.accepted:
        a.accept(result)
    elif a.last_model_ is None and result.model is not None:
        a.resume(result.model)


def run_mode(mode: str, seeds: list[int], n: int) -> list[dict[str, Any]]:
    """Every warm window of one mode, analysed by both paths: times and decisions."""
    out = []
    for label, plc in settings(mode, seeds):
        old, new = analyser(False, plc.gains[1]), analyser(True, plc.gains[1])
        for i, (samples, t_from, t_to) in enumerate(windows(plc, n + 1)):
            timed = {}
            for name, a in (("old", old), ("new", new)):
                start = time.perf_counter()
                result = a.analyse(samples, t_from, t_to)
                timed[name] = (time.perf_counter() - start, result)
                _warm(a, result)
            if i == 0:
                continue  # the cold first window of a run: warm-up only
            out.append({"label": label, **_compare(timed["old"], timed["new"])})
    return out


def _compare(old: tuple[float, WindowResult], new: tuple[float, WindowResult]) -> dict[str, Any]:
    (t_old, r_old), (t_new, r_new) = old, new
    dK = se = None
    if r_old.model is not None and r_new.model is not None:
        dK = abs(r_new.model.K - r_old.model.K)
        errors = [s for s in (r_old.stderr.get("K"), r_new.stderr.get("K")) if s is not None]
        se = max(errors) if errors else None
    return {
        "t_old": t_old,
        "t_new": t_new,
        "method_old": r_old.method,
        "method_new": r_new.method,
        "skipped": "pem not fitted" in r_new.method_reason,
        "accepted_old": r_old.accepted,
        "accepted_new": r_new.accepted,
        "dK": dK,
        "se": se,
    }


def _p90(values: list[float]) -> float:
    return float(np.percentile(values, 90))


def report(mode: str, rows: list[dict[str, Any]], cores: int) -> None:
    """Print one mode's timing, agreement and projection."""
    t_old = [r["t_old"] for r in rows]
    t_new = [r["t_new"] for r in rows]
    ratios = [a / b for a, b in zip(t_old, t_new, strict=True)]
    med_old, med_new = statistics.median(t_old), statistics.median(t_new)
    print(f"{mode}: {len(rows)} warm windows")
    print(f"  {'path':22s} {'median s':>9s} {'p90 s':>7s}")
    print(f"  {'today (fast=False)':22s} {med_old:9.3f} {_p90(t_old):7.3f}")
    print(f"  {'fast (fast=True)':22s} {med_new:9.3f} {_p90(t_new):7.3f}")
    print(
        f"  ratio of medians {med_old / med_new:.2f}×, of p90s {_p90(t_old) / _p90(t_new):.2f}×,"
        f" median per-window ratio {statistics.median(ratios):.2f}×"
    )
    decided = sum(r["method_old"] == r["method_new"] for r in rows)
    verdict = sum(r["accepted_old"] == r["accepted_new"] for r in rows)
    compared = [r for r in rows if r["dK"] is not None and r["se"] is not None]
    within = sum(r["dK"] <= r["se"] for r in compared)
    disagree = [r for r in rows if r["method_old"] != r["method_new"]]
    print(
        f"  estimator (oe/pem) same on {decided}/{len(rows)}; verdict same on "
        f"{verdict}/{len(rows)}; |ΔK| ≤ its stderr on {within}/{len(compared)}"
    )
    if mode == "AUTO":
        skipped = sum(r["skipped"] for r in rows)
        pem_kept = sum(r["method_old"] == "pem" for r in rows)
        print(
            f"  pem skipped by the screen on {skipped}/{len(rows)}; today's path kept pem on "
            f"{pem_kept}/{len(rows)}; cheap decision = full decision on "
            f"{len(rows) - len(disagree)}/{len(rows)}"
        )
        for r in disagree:
            why = "pem skipped by the screen" if r["skipped"] else "pem fitted on both paths"
            print(
                f"    disagreement: {r['label']}: {r['method_old']} → {r['method_new']} ({why}),"
                f" |ΔK| {r['dK']:.4g} vs stderr {r['se']:.4g}"
            )
    every = Online().identify_every_s
    per_year = YEAR_S / every
    for name, t in (("today", med_old), ("fast", med_new)):
        loop_h = per_year * t / 3600.0
        fleet_h = FLEET_LOOPS * loop_h
        print(
            f"  {name:5s}: loop-year {per_year:,.0f} windows × {t:.3f} s = {loop_h:.1f} CPU h;"
            f" {FLEET_LOOPS}-loop fleet-year {fleet_h:,.0f} CPU h = {fleet_h / cores:,.0f} h "
            f"wall on {cores} cores ({100.0 * fleet_h / (YEAR_S / 3600.0) / cores:.2f} % of "
            "each core)"
        )


PIECES = (
    ("the whole window", "_window.py", "analyse"),
    ("output-error fit (both orders)", "_oe.py", "fit"),
    ("  its searches", "_oe.py", "_fit_structure"),
    ("  its covariances, colour tests", "_oe.py", "_store"),
    ("noise screen", "pem_screen.py", "noise_screen"),
    ("prediction-error fit", "_pem.py", "fit"),
    ("step-ls alongside", "_window.py", "_step_ls"),
    ("post-fit gates (residual ACF)", "_postfit.py", "postfit_gates"),
    ("pre-fit gates", "_prefit.py", "prefit_samples"),
    ("loop health", "_window.py", "_health"),
)


def profile_split(label: str, plc: VirtualPLC) -> None:
    """Where one warm window's time goes, today's path and the fast one (cProfile, ms)."""
    import cProfile
    import pstats

    pair = [analyser(False, plc.gains[1]), analyser(True, plc.gains[1])]
    data = list(windows(plc, 2))
    columns = []
    for a in pair:
        _warm(a, a.analyse(*data[0]))
        noise = a._last_noise  # the same warm start for the timed run and the profiled one
        profile = cProfile.Profile()
        profile.enable()
        a.analyse(*data[1])
        profile.disable()
        a._last_noise = noise
        stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
        column = {}
        for name, file, function in PIECES:
            column[name] = 1000.0 * sum(
                v[3] for k, v in stats.items() if k[0].endswith(file) and k[2] == function
            )
        columns.append(column)
    print(f"where the time goes, {label} (one warm window, ms under cProfile):")
    print(f"  {'piece':34s} {'today':>7s} {'fast':>7s}")
    for name, _, _ in PIECES:
        print(f"  {name:34s} {columns[0][name]:7.1f} {columns[1][name]:7.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--windows", type=int, default=13, help="warm windows per run")
    parser.add_argument("--seeds", type=int, nargs="+", default=[101, 102])
    parser.add_argument("--cores", type=int, default=2, help="cores of the fleet projection")
    parser.add_argument("--modes", nargs="+", default=["MAN", "AUTO"], choices=["MAN", "AUTO"])
    args = parser.parse_args()
    every = Online().identify_every_s
    print(
        f"one window: {WINDOW_S / 60:g} min at {1 / PERIOD_S:g} Hz; warm; step-ls on; "
        f"window every {every:g} s (default [online] identify_every_s)"
    )
    first = args.seeds[0]
    for mode in args.modes:
        for label, plc in settings(mode, [first]):
            profiled = "MAN" in label or "steps" in label
            if profiled and label.endswith("35 °C") and "d 0.5" not in label:
                profile_split(label, plc)
    for mode in args.modes:
        report(mode, run_mode(mode, args.seeds, args.windows), args.cores)


if __name__ == "__main__":
    from fuelid.blas import single_threaded_blas

    with single_threaded_blas():  # as every fuelid command runs
        run_to_docs("window", main, __doc__)
