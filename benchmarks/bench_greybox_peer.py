"""Gray-box fit against a hand-written peer: ``fuelid greybox`` and least_squares over odeint.

Run as ``python benchmarks/bench_greybox_peer.py [--repeats 5] [--keep DIR]``. For each model the
script writes a model file (as a user writes it: scalars, ``math.sqrt``, ``max``; no ``x0``, so
the initial states are estimated) and a 1,000-sample log (1 s samples, the pump voltage in random
steps held 40 to 120 s, white noise 0.01 dm on the lower level, simulated per sample with
``solve_ivp`` at rtol 1e-10 and a short longest step) into a temporary folder, and writes the
peer: about 25 lines an engineer writes, pandas to read, ``odeint`` piece by piece between input
changes (the input held), ``least_squares`` with its default 2-point Jacobian and bounds ≥ 0 on
the same free parameters and every initial state, the covariance inv(JᵀJ)·s² from the returned
Jacobian. Both load the same model file. The models:

- smooth: two cascaded Torricelli tanks (examples/two_tanks.py with scalars), k4 fixed;
- kinked (pipe): the upper tank spills through an overflow pipe above its rim H = 2 dm,
  ``dx1 -= k_ov·max(x1 − H, 0)``, k_ov estimated with k1…k3;
- kinked (if): the rim as a clamp, ``if x1 >= H and dx1 > 0: dx1 = 0``, k1…k3 estimated;
- stiff: the pump's flow q follows the command with a 0.01 s lag (a third state, 100 times
  faster than the sample interval), k1…k3 estimated, k4 and the lag fixed. The pump's initial
  flow cannot be told from the data (it settles in hundredths of a second): fuelid holds it at
  the steady state of the first input and says so (``not_determined``), the peer estimates it;
- stiff (x0): the same with the file's ``x0(p, u0, y0)``: the levels' initial values are two
  free parameters, the pump's initial flow its command's (the peer uses the file's x0 too).
- real-like (``--only real-like``, its own page greybox_peer_real): the record a user brings,
  not one the model made: examples/cascaded_tanks_data.py (seed 42; 1,024 samples at 4 s, a
  multisine pump voltage, a plant richer than the model: power-law outflows with a leak, an
  overflow, a drifting pump, a 10 V clip) fitted with the smooth model
  examples/cascaded_tanks_smooth.py (Torricelli tanks and an offset, k4 fixed) from its guessed
  start values. The model error leaves residuals far above the noise: the case where
  ``--segments auto`` must tell a model error from a local minimum. It has no truth: its
  f−true and p−true columns are blank.

Measured in one process: (a) the whole command, ``fuelid greybox MODEL.py DATA.csv --json``
(default solver and segments) against ``python peer.py MODEL.py DATA.csv``, each a subprocess,
interleaved, median (and min) of the repeats; (b) the fit with its covariance in-process, from
the files: ``read_model_file`` + ``read_record`` + ``GreyBoxEstimator(model).fit(record)`` against
the peer's ``fit(model_path, csv_path)`` (which reads its files too), interleaved, median of the
repeats; (c) agreement: |θ_fuelid − θ_peer| / se_fuelid per parameter, and each estimate against
the truth in its own standard errors. The ratios fuelid/peer are the headline; the targets of
the issue are whole command ≤ 1.5×, fit + covariance ≤ 1.0×, parameters within 0.1 se. A peer
whose residual RMS is above fuelid's by more than 1 % stopped in a local minimum (or at a
worse point), and the table says so.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

from _docs_table import run_to_docs

N_SAMPLES = 1000
NOISE = 0.01  # white noise on the measured lower level [dm]
H_RIM = 2.0  # the upper tank's rim in the kinked models [dm] (--rim)
TAU = 0.01  # the pump's lag in the stiff model [s]: 100 times faster than the 1 s samples

_HEAD = """\
import math

states = {states}
inputs = ["u_V"]
outputs = ["h2_dm"]
"""

SMOOTH = (
    _HEAD.format(states='["x1", "x2"]')
    + """
# k1..k3 start about 30 % above the truth (0.05, 0.04, 0.05); k4 is known (a bucket test)
parameters = {
    "k1": (0.065, 0.0),
    "k2": (0.052, 0.0),
    "k3": (0.065, 0.0),
    "k4": {"value": 0.06, "lower": 0.0, "fixed": True},
}


def f(t, x, u, p):
    x1 = max(x[0], 0.0)
    x2 = max(x[1], 0.0)
    dx1 = -p["k1"] * math.sqrt(x1) + p["k4"] * u[0]
    dx2 = p["k2"] * math.sqrt(x1) - p["k3"] * math.sqrt(x2)
    return [dx1, dx2]


def h(x, u, p):
    return x[1]
"""
)

KINK_PIPE = (
    _HEAD.format(states='["x1", "x2"]')
    + """
H_MAX = __RIM__  # rim of the upper tank [dm]: above it an overflow pipe drains it

parameters = {
    "k1": (0.065, 0.0),
    "k2": (0.052, 0.0),
    "k3": (0.065, 0.0),
    "k4": {"value": 0.06, "lower": 0.0, "fixed": True},
    "k_ov": (0.13, 0.0),  # overflow pipe [1/s], truth 0.1
}


def f(t, x, u, p):
    x1 = max(x[0], 0.0)
    x2 = max(x[1], 0.0)
    dx1 = -p["k1"] * math.sqrt(x1) + p["k4"] * u[0]
    dx1 -= p["k_ov"] * max(x[0] - H_MAX, 0.0)  # the overflow pipe above the rim
    dx2 = p["k2"] * math.sqrt(x1) - p["k3"] * math.sqrt(x2)
    return [dx1, dx2]


def h(x, u, p):
    return x[1]
"""
)

KINK_IF = (
    _HEAD.format(states='["x1", "x2"]')
    + """
H_MAX = __RIM__  # rim of the upper tank [dm]: a full tank spills, its level stays at the rim

parameters = {
    "k1": (0.065, 0.0),
    "k2": (0.052, 0.0),
    "k3": (0.065, 0.0),
    "k4": {"value": 0.06, "lower": 0.0, "fixed": True},
}


def f(t, x, u, p):
    x1 = max(x[0], 0.0)
    x2 = max(x[1], 0.0)
    dx1 = -p["k1"] * math.sqrt(x1) + p["k4"] * u[0]
    if x[0] >= H_MAX and dx1 > 0:
        dx1 = 0.0
    dx2 = p["k2"] * math.sqrt(x1) - p["k3"] * math.sqrt(x2)
    return [dx1, dx2]


def h(x, u, p):
    return x[1]
"""
)

STIFF_X0 = (
    _HEAD.format(states='["x1", "x2", "q"]')
    + f"""
TAU = {TAU}  # the pump's flow follows the command with this lag [s]

parameters = {{
    "k1": (0.065, 0.0),
    "k2": (0.052, 0.0),
    "k3": (0.065, 0.0),
    "k4": {{"value": 0.06, "lower": 0.0, "fixed": True}},
    "x1_0": (1.0, 0.0),  # the levels at the start [dm], estimated
    "x2_0": (1.0, 0.0),
}}


def f(t, x, u, p):
    x1 = max(x[0], 0.0)
    x2 = max(x[1], 0.0)
    dx1 = -p["k1"] * math.sqrt(x1) + x[2]
    dx2 = p["k2"] * math.sqrt(x1) - p["k3"] * math.sqrt(x2)
    dq = (p["k4"] * u[0] - x[2]) / TAU
    return [dx1, dx2, dq]


def h(x, u, p):
    return x[1]


def x0(p, u0, y0):
    # the pump's flow settles in a few hundredths of a second: it starts at the command's
    return [p["x1_0"], p["x2_0"], p["k4"] * u0[0]]
"""
)

STIFF = (
    _HEAD.format(states='["x1", "x2", "q"]')
    + f"""
TAU = {TAU}  # the pump's flow follows the command with this lag [s]

parameters = {{
    "k1": (0.065, 0.0),
    "k2": (0.052, 0.0),
    "k3": (0.065, 0.0),
    "k4": {{"value": 0.06, "lower": 0.0, "fixed": True}},
}}


def f(t, x, u, p):
    x1 = max(x[0], 0.0)
    x2 = max(x[1], 0.0)
    dx1 = -p["k1"] * math.sqrt(x1) + x[2]
    dx2 = p["k2"] * math.sqrt(x1) - p["k3"] * math.sqrt(x2)
    dq = (p["k4"] * u[0] - x[2]) / TAU
    return [dx1, dx2, dq]


def h(x, u, p):
    return x[1]
"""
)

PEER = '''\
"""A hand-written fit: least_squares over odeint, the input held between its changes."""
import importlib.util, json, sys
import numpy as np, pandas as pd
from scipy.integrate import odeint
from scipy.optimize import least_squares

def fit(model_path, csv_path):
    spec = importlib.util.spec_from_file_location("model", model_path)
    m = importlib.util.module_from_spec(spec); spec.loader.exec_module(m)
    d = pd.read_csv(csv_path); t = d["t_s"].to_numpy(float)
    u = d[m.inputs[0]].to_numpy(float); y = d[m.outputs[0]].to_numpy(float)
    p = {k: (v[0] if isinstance(v, tuple) else v["value"]) for k, v in m.parameters.items()}
    free = [k for k, v in m.parameters.items() if not (isinstance(v, dict) and v.get("fixed"))]
    n, nx = len(free), 0 if hasattr(m, "x0") else len(m.states)  # x0 in the file: its own
    starts = np.flatnonzero(np.r_[True, u[1:] != u[:-1]]); ends = np.r_[starts[1:], len(t)]
    def simulate(theta):
        q = dict(p, **dict(zip(free, theta[:n]))); out = np.empty(len(t))
        x = m.x0(q, [u[0]], [y[0]]) if nx == 0 else theta[n:]
        for a, b in zip(starts, ends):  # the input is held from sample a to the next change
            xs = odeint(lambda x, s: m.f(s, x, [u[a]], q), x, t[a:b + 1])
            out[a:b] = [m.h(xk, [u[a]], q) for xk in xs[: b - a]]; x = xs[-1]
        return out
    theta0 = np.r_[[p[k] for k in free], np.full(nx, y[0])]
    res = least_squares(lambda th: simulate(th) - y, theta0, bounds=(0.0, np.inf))
    s2 = res.fun @ res.fun / (len(y) - len(theta0))
    se = np.sqrt(np.diag(np.linalg.inv(res.jac.T @ res.jac) * s2))
    return {"parameters": dict(zip(free, res.x[:n].tolist())),
            "stderr": dict(zip(free, se[:n].tolist())), "x0": res.x[n:].tolist(),
            "sigma": float(np.sqrt(s2)), "nfev": int(res.nfev)}

if __name__ == "__main__":
    print(json.dumps(fit(sys.argv[1], sys.argv[2])))
'''

TRUE = {"k1": 0.05, "k2": 0.04, "k3": 0.05, "k4": 0.06, "k_ov": 0.1, "x1_0": 1.0, "x2_0": 0.8}


@dataclass(frozen=True)
class Case:
    """One model: its file's text, the true initial state, the seed, the reference method."""

    name: str
    text: str
    x0: tuple[float, ...]
    seed: int
    method: str  # the reference integration's method
    max_step: float  # and its longest step [s]


CASES = (
    Case("smooth", SMOOTH, (1.0, 0.8), 11, "RK45", 0.05),
    Case("kinked (pipe)", KINK_PIPE, (1.0, 0.8), 12, "RK45", 0.01),
    Case("kinked (if)", KINK_IF, (1.0, 0.8), 13, "RK45", 0.01),
    Case("stiff", STIFF, (1.0, 0.8, 0.06), 14, "Radau", 0.05),
    Case("stiff (x0)", STIFF_X0, (1.0, 0.8, 0.06), 14, "Radau", 0.05),
    Case("real-like", "", (), 42, "", 0.0),  # the example's model and record (write_real_like)
)
EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
REAL_LIKE = "real-like"
"""The case fitted on examples/cascaded_tanks_data.py's record: run alone, its own page."""


def load(path: Path) -> Any:
    spec = importlib.util.spec_from_file_location(f"bench_{path.stem}", path)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def input_steps(rng: np.random.Generator, n: int) -> np.ndarray:
    """Pump voltages 0.4…2 V, each held 40 to 120 samples (as examples/two_tanks_data.py)."""
    u = np.empty(n)
    k = 0
    while k < n:
        hold = int(rng.integers(40, 121))
        u[k : k + hold] = rng.uniform(0.4, 2.0)
        k += hold
    return u


def write_data(case: Case, model_path: Path, csv_path: Path, rim: float) -> float:
    """Simulate the model file at the truth, write the log; the upper level's share over the rim."""
    model = load(model_path)
    rng = np.random.default_rng(case.seed)
    u = input_steps(rng, N_SAMPLES)
    x = np.array(case.x0, dtype=float)
    if hasattr(model, "x0"):  # the file's initial state, at the true parameters
        x = np.array(model.x0(TRUE, [u[0]], [math.nan]), dtype=float)
    y = np.empty(N_SAMPLES)
    above = 0
    for k in range(N_SAMPLES):
        y[k] = model.h(x, [u[k]], TRUE)
        above += x[0] > rim
        step = solve_ivp(
            lambda t, s, uk=u[k]: model.f(t, s, [uk], TRUE),
            (0.0, 1.0),
            x,
            method=case.method,
            rtol=1e-10,
            atol=1e-12,
            max_step=case.max_step,
        )
        if not step.success:
            raise RuntimeError(f"{case.name}: reference integration failed: {step.message}")
        x = step.y[:, -1]
    y = y + rng.normal(0.0, NOISE, N_SAMPLES)
    frame = pd.DataFrame({"t_s": np.arange(N_SAMPLES, dtype=float), "u_V": u, "h2_dm": y})
    frame.to_csv(csv_path, index=False, float_format="%.8g")
    return above / N_SAMPLES


def write_real_like(model_path: Path, csv_path: Path, seed: int) -> None:
    """The smooth cascaded-tanks model file and the real-like estimation record, as a user has."""
    shutil.copyfile(EXAMPLES / "cascaded_tanks_smooth.py", model_path)
    folder = csv_path.parent / "real_like_records"
    subprocess.run(
        [
            sys.executable,
            str(EXAMPLES / "cascaded_tanks_data.py"),
            str(folder),
            "--seed",
            str(seed),
        ],
        check=True,
        capture_output=True,
    )
    shutil.copyfile(folder / "cascaded_tanks_estimation.csv", csv_path)


def fuelid_command() -> list[str]:
    script = Path(sys.executable).with_name("fuelid")
    return [str(script)] if script.exists() else [sys.executable, "-m", "fuelid"]


def run(cmd: list[str]) -> tuple[float, dict[str, Any] | None, str]:
    start = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        tail = (done.stderr.strip() or done.stdout.strip()).splitlines()[-1:] or ["?"]
        return elapsed, None, f"exit {done.returncode}: {tail[0]}"
    return elapsed, json.loads(done.stdout), ""


def fuelid_fit(model_path: Path, csv_path: Path) -> dict[str, Any]:
    from fuelid.greybox import GreyBoxEstimator
    from fuelid.greybox.modelfile import read_model_file
    from fuelid.workflow import data_columns, read_record

    mf = read_model_file(model_path)
    inputs, outputs = data_columns(mf, (), ())
    record = read_record(csv_path, "t_s", inputs, outputs, None)
    est = GreyBoxEstimator(mf.model).fit(record)
    return {
        "parameters": dict(est.params_),
        "stderr": dict(est.stderr_),
        "sigma": float(est.sigma_[0]),
        "start": est.start_,
        "solver": est.solver_.solver.to_json().get("method", "?"),
        "sims": est.n_simulations_,
    }


def timed(fn: Callable[[], Any], warned: list[str]) -> tuple[float, Any, str]:
    """Run fn: seconds, its result, the error (empty when none); its warnings into warned."""
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result = fn()
        except Exception as exc:  # a failing fit is a finding, reported in the table
            return time.perf_counter() - start, None, f"{type(exc).__name__}: {exc}"[:200]
        finally:
            warned.extend(
                f"{w.category.__name__}: {str(w.message).split('(')[0].strip()}" for w in caught
            )
    return time.perf_counter() - start, result, ""


def in_se(value: float) -> str:
    """A deviation in standard errors, 7 wide (exponent form when huge; blank without truth)."""
    if not math.isfinite(value):
        return f"{'':7}"
    return f"{value:7.2f}" if abs(value) < 1e4 else f"{value:7.0e}"


def shown(truth: float) -> str:
    """A true value, 7 wide ('-' where there is none)."""
    return f"{truth:7.4f}" if math.isfinite(truth) else f"{'-':>7}"


def truth_of(case: Case, name: str) -> float:
    """The true value of a parameter (NaN for the real-like record: its plant is not the model)."""
    return math.nan if case.name == REAL_LIKE else TRUE[name]


def median_min(times: list[float]) -> str:
    return f"{statistics.median(times):7.2f} {min(times):6.2f}" if times else f"{'-':>7} {'-':>6}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="runs of each, interleaved")
    parser.add_argument("--keep", type=Path, help="write the files here (default: a temp dir)")
    parser.add_argument("--rim", type=float, default=H_RIM, help="the kinked models' rim [dm]")
    parser.add_argument("--only", help="run only the case of this name (e.g. smooth)")
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="greybox_peer_")) if args.keep is None else args.keep
    folder.mkdir(parents=True, exist_ok=True)
    peer_path = folder / "peer.py"
    peer_path.write_text(PEER, encoding="utf-8")
    peer = load(peer_path)
    record = (
        "the real-like record (examples/cascaded_tanks_data.py, seed 42): 1024 samples at 4 s, "
        "the smooth model examples/cascaded_tanks_smooth.py"
        if args.only == REAL_LIKE
        else f"{N_SAMPLES} samples at 1 s, noise {NOISE} dm"
    )
    print(
        f"{record}; peer: {len(PEER.splitlines())} lines "
        f"(odeint + least_squares 2-point); {args.repeats} interleaved runs of each"
    )
    timing_rows, agreement_rows, notes = [], [], []
    try:
        for case in CASES:
            # the real-like record runs alone (its own page), the models' rows without it
            if (args.only or "") != REAL_LIKE and case.name == REAL_LIKE:
                continue
            if args.only and case.name.split()[0] != args.only:
                continue
            stem = case.name.replace(" ", "_").replace("(", "").replace(")", "")
            model_path, csv_path = folder / f"{stem}.py", folder / f"{stem}.csv"
            share = 0.0
            if case.name == REAL_LIKE:
                write_real_like(model_path, csv_path, case.seed)
            else:
                model_path.write_text(
                    case.text.replace("__RIM__", repr(args.rim)), encoding="utf-8"
                )
                share = write_data(case, model_path, csv_path, args.rim)
            if "kinked" in case.name:
                notes.append(f"{case.name}: upper level above the rim {share:.0%} of the time")
            cmd_f = [*fuelid_command(), "greybox", str(model_path), str(csv_path), "--json"]
            cmd_p = [sys.executable, str(peer_path), str(model_path), str(csv_path)]
            whole_f, whole_p, inproc_f, inproc_p = [], [], [], []
            res: dict[str, Any] = {}
            errors: dict[str, str] = {}
            warned: dict[str, list[str]] = {"fit_f": [], "fit_p": []}
            for _ in range(args.repeats):
                for key, cmd, times in (("cmd_f", cmd_f, whole_f), ("cmd_p", cmd_p, whole_p)):
                    elapsed, out, err = run(cmd)
                    if err:
                        errors[key] = err
                    else:
                        times.append(elapsed)
                        res[key] = out
                for key, fn, times in (
                    ("fit_f", partial(fuelid_fit, model_path, csv_path), inproc_f),
                    ("fit_p", partial(peer.fit, str(model_path), str(csv_path)), inproc_p),
                ):
                    elapsed, out, err = timed(fn, warned[key])
                    if err:
                        errors[key] = err
                    else:
                        times.append(elapsed)
                        res[key] = out
            for key, err in errors.items():
                notes.append(f"{case.name}: {key} failed: {err}")
            for key, caught in warned.items():
                for text in sorted(set(caught)):
                    per_run = caught.count(text) / args.repeats
                    notes.append(f"{case.name}: {key} warned {per_run:g}× per fit: {text}")
            ratio_whole = (
                statistics.median(whole_f) / statistics.median(whole_p)
                if whole_f and whole_p
                else math.nan
            )
            ratio_fit = (
                statistics.median(inproc_f) / statistics.median(inproc_p)
                if inproc_f and inproc_p
                else math.nan
            )
            fit_f, fit_p = res.get("fit_f"), res.get("fit_p")
            local = ""
            if fit_f and fit_p:
                local = (
                    "peer local min"
                    if fit_p["sigma"] > 1.01 * fit_f["sigma"]
                    else "fuelid worse"
                    if fit_f["sigma"] > 1.01 * fit_p["sigma"]
                    else ""
                )
            if fit_f and fit_p and local == "" and case.name == REAL_LIKE:
                apart = [
                    name
                    for name, value_p in fit_p["parameters"].items()
                    # apart: beyond fuelid's standard error (none: undetermined) and 1 %
                    if abs(fit_f["parameters"][name] - value_p)
                    > max(fit_f["stderr"][name] or 0.0, 0.01 * abs(value_p))
                ]
                if apart:
                    notes.append(
                        f"{case.name}: the same residual σ within 1 % at other values of "
                        f"{', '.join(apart)}: a valley the record does not determine "
                        "(fuelid's identifiability report names it), not a local minimum"
                    )
            how = f"{fit_f['solver']}, {fit_f['start']}" if fit_f else "failed"
            timing_rows.append(
                f"{case.name:<14} {median_min(whole_f)} {median_min(whole_p)} {ratio_whole:6.2f}"
                f" {median_min(inproc_f)} {median_min(inproc_p)} {ratio_fit:6.2f}  {how}"
            )
            if fit_p and not fit_f:  # fuelid refused or failed: the peer's estimates alone
                for name, value_p in fit_p["parameters"].items():
                    se_p = fit_p["stderr"][name]
                    agreement_rows.append(
                        f"{case.name:<14} {name:>5} {shown(truth_of(case, name))} {'-':>9} {'-':>8}"
                        f" {value_p:9.5f} {se_p:8.1e} {'-':>8} {'-':>7}"
                        f" {in_se((value_p - truth_of(case, name)) / se_p)} {'-':>8}"
                        f" {fit_p['sigma']:8.5f}"
                    )
            if fit_f and fit_p:
                for name, value_p in fit_p["parameters"].items():
                    value = fit_f["parameters"][name]
                    se_f = fit_f["stderr"][name] or math.nan
                    se_p = fit_p["stderr"][name]
                    truth = truth_of(case, name)
                    agreement_rows.append(
                        f"{case.name:<14} {name:>5} {shown(truth)} {value:9.5f} {se_f:8.1e}"
                        f" {value_p:9.5f} {se_p:8.1e} {abs(value - value_p) / se_f:8.3f}"
                        f" {in_se((value - truth) / se_f)} {in_se((value_p - truth) / se_p)}"
                        f" {fit_f['sigma']:8.5f} {fit_p['sigma']:8.5f} {local}"
                    )
    finally:
        if args.keep is None:
            shutil.rmtree(folder, ignore_errors=True)
    print("\n(a) whole command (subprocess) and (b) fit + covariance in-process [s]")
    print(
        f"{'model':<14} {'(a) fuelid':>7} {'min':>6} {'peer':>7} {'min':>6} {'ratio':>6}"
        f" {'(b) fuelid':>7} {'min':>6} {'peer':>7} {'min':>6} {'ratio':>6}  fuelid solver, start"
    )
    for row in timing_rows:
        print(row)
    print("\n(c) agreement: Δ = |θ_fuelid − θ_peer| / se_fuelid; each against the truth in its se")
    print(
        f"{'model':<14} {'param':>5} {'truth':>7} {'fuelid':>9} {'se':>8} {'peer':>9} {'se':>8}"
        f" {'Δ/se':>8} {'f−true':>7} {'p−true':>7} {'σ fuelid':>8} {'σ peer':>8}"
    )
    for row in agreement_rows:
        print(row)
    for note in notes:
        print(note)
    print(
        "targets: whole command ≤ 1.5×, fit + covariance ≤ 1.0×, parameters within 0.1 se; "
        f"machine load average {os.getloadavg()[0]:.1f} at the end"
    )


if __name__ == "__main__":
    # the printed tables, also in docs/benchmarks (the real-like record's on a page of its own)
    page = "greybox_peer_real" if REAL_LIKE in sys.argv else "greybox_peer"
    run_to_docs(page, main, __doc__)
