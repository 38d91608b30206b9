"""Benchmark: the online service's cost, one identification window and the running service.

Targets (issue 15): one identification window (10 min at 50 Hz, 30,000 samples) end to end in
under 0.2 s; the service's CPU at 50 Hz with a window every 5 minutes under 5 % of one core.

(a) One window end to end: :meth:`fuelid.online.WindowAnalyser.analyse` (pre-fit gates,
    the fit, the post-fit gates, the loop's health, and with ``step_ls`` the article's step-ls
    alongside) on 10 minutes of samples from the virtual PLC's engine
    (:class:`fuelid.plc.virtual.VirtualPLC`, reference plant, 50 Hz, PI at 1 s):

    - MAN, local: open loop, command steps of 0.1–0.4 V around 3 V held 15 s (output error);
    - MAN, 1.5–4.5 V: the engine's own command steps (``command_profile="steps"``), which span
      the drive's range: the linear model's error over the nonlinear range makes the residual
      correlation gate reject them (a window must be local), but the cost is the same;
    - AUTO, local: closed loop, setpoint steps of 1–4 L/min around 40 L/min held 30 s
      (prediction error with its noise model, unless it falls back to output error);
    - AUTO, runs: the demo's wind-tunnel runs (``setpoint_profile=demo_run_profile()``, steps of
      up to 20 L/min: not local, the residual correlation gate's case again);

    each cold (a fresh analyser: the estimator's own start) and warm-started (the analyser has
    accepted the previous 10 minutes' model, as the service does), with and without step-ls.
    The timed window is the same in all four rows of a mode (the second 10 minutes of the run);
    the median of ``--repeat`` runs, wall time and this process's CPU time (on a shared machine
    the CPU time is the steadier number). BLAS runs on one thread, as in every fuelid command.

(b) The running service: :class:`fuelid.online.OnlineService` records the virtual PLC
    over Modbus TCP on 127.0.0.1 at real time (50 Hz, ring buffer) for ``--minutes`` and
    analyses a window every ``--every`` seconds of data time (``--window`` long; the short
    default run uses 60 s windows every 60 s so that windows fall in two minutes). The virtual
    PLC runs in a child process, so its CPU is not counted; counted is this process and every
    process it starts (a window worker process, if the service uses one), read from /proc
    (Linux), this process (recorder, store, schedule, heartbeat) and the processes it started
    (the window worker: its start-up once, then the windows) apart. The CPU at a 10-minute
    window every 5 minutes is then *extrapolated*: this process's measured share plus the CPU
    time of (a)'s local AUTO warm-started window with step-ls once per 300 s (the worker's
    start-up, paid once per service start, left out).

Run on demand (``make bench`` runs it with the defaults):

    .venv/bin/python benchmarks/bench_online.py [--minutes 2] [--repeat 3] [--every 60]
        [--window 60] [--skip-service]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from importlib import resources
from pathlib import Path

from _docs_table import run_to_docs
from fuelid.online import Online, WindowAnalyser, WindowResult, window_priors
from fuelid.plc.site import SiteConfig
from fuelid.plc.virtual import VirtualPLC
from fuelid.profiles.runs import demo_run_profile
from fuelid.store import Quality, SampleArrays

PERIOD_S = 0.02
WINDOW_S = 600.0
SAMPLES = round(WINDOW_S / PERIOD_S)  # 30,000
T0 = 1.8e9  # an epoch for the sample times [s UTC]
WINDOW_TARGET_S = 0.2
CPU_TARGET = 0.05
EVERY_TARGET_S = 300.0

CHILD = """
import json, sys
from fuelid.profiles.runs import demo_run_profile
from fuelid.plc.virtual import VirtualPlcThread, site_text
plant = sys.argv[1]
with VirtualPlcThread("modbus", speed=1.0, seed=1, setpoint_profile=demo_run_profile()) as v:
    text = site_text(v.protocol, v.host, v.port, period_s=v.plc.period_s,
                     control_period_s=v.plc.control_period_s, word_order=v.word_order,
                     byte_swap=v.byte_swap, ring_size=v.plc.ring_size,
                     kc=v.plc.kc0, ti=v.plc.ti0, plant=plant)
    print(json.dumps(text), flush=True)
    sys.stdin.read()  # until the parent closes it
"""


def reference_plant() -> str:
    """Path of the packaged reference plant file."""
    return str(resources.files("fuelid.data").joinpath("reference_plant.toml"))


# --- (a) one window ---------------------------------------------------------------------------


def engine_samples(plc: VirtualPLC, n: int, k0: int) -> SampleArrays:
    """``n`` samples of the engine as the recorder would store them (all quality OK)."""
    rows = []
    for k in range(n):
        plc.advance(1)
        p = plc.read_points()
        rows.append(
            (
                T0 + (k0 + k) * PERIOD_S,
                int(p["seq"]),
                p["command"],
                p["flow"],
                p["setpoint"],
                p["fuel_temperature"],
                int(p["mode"]),
                int(Quality.OK),
            )
        )
    return SampleArrays.from_rows(rows)


def analyser(step_ls: bool, ti_s: float) -> WindowAnalyser:
    """A fresh analyser for the reference plant with the default ``[online]`` table."""
    priors, k_plant = window_priors(reference_plant(), control_period=1.0)
    return WindowAnalyser(Online(), priors, PERIOD_S, k_plant=k_plant, step_ls=step_ls, ti_s=ti_s)


LOCAL_STEPS_V = (3.0, 3.2, 2.9, 3.3, 3.0, 2.8, 3.1, 2.9)
"""Command levels of the local MAN profile [V] (each held :data:`LOCAL_DWELL_S`)."""
LOCAL_DWELL_S = 15.0


def local_steps() -> tuple[list[float], list[float]]:
    """Small MAN command steps around one operating point, as (times [s], commands [V])."""
    t: list[float] = []
    v: list[float] = []
    for i, level in enumerate(LOCAL_STEPS_V):
        t += [i * LOCAL_DWELL_S, (i + 1) * LOCAL_DWELL_S]
        v += [level, level]
    return t, v


LOCAL_SETPOINTS_LPM = (40.0, 42.0, 39.0, 43.0, 40.0, 38.0, 41.0, 39.0)
"""Setpoints of the local AUTO profile [L/min] (each held :data:`LOCAL_HOLD_S`)."""
LOCAL_HOLD_S = 30.0


def local_setpoints() -> tuple[list[float], list[float]]:
    """Small setpoint steps around one operating point, as (times [s], setpoints [L/min])."""
    t: list[float] = []
    v: list[float] = []
    for i, level in enumerate(LOCAL_SETPOINTS_LPM):
        t += [i * LOCAL_HOLD_S, (i + 1) * LOCAL_HOLD_S]
        v += [level, level]
    return t, v


def window_rows(mode: str, repeat: int) -> list[tuple[str, float, float, WindowResult]]:
    """(label, median wall s, median CPU s, last result) for cold/warm × step-ls on/off."""
    if mode == "MAN, local":
        plc = VirtualPLC(seed=1, command_profile=local_steps())
    elif mode == "MAN, 1.5–4.5 V":
        plc = VirtualPLC(seed=1, command_profile="steps")
    elif mode == "AUTO, local":
        plc = VirtualPLC(seed=1, setpoint_profile=local_setpoints())
    else:
        plc = VirtualPLC(seed=1, setpoint_profile=demo_run_profile())
    ti_s = plc.gains[1]
    first = engine_samples(plc, SAMPLES, 0)
    second = engine_samples(plc, SAMPLES, SAMPLES)
    t_from, t_to = T0 + SAMPLES * PERIOD_S, T0 + 2 * SAMPLES * PERIOD_S
    rows = []
    for step_ls in (False, True):
        # warm start: the model of the first 10 minutes, as the service keeps it
        warm = analyser(step_ls, ti_s)
        previous = warm.analyse(first, T0, t_from)
        if previous.accepted:
            warm.accept(previous)
        else:
            warm.resume(previous.model)
        for label, make in (
            ("cold", lambda s=step_ls: analyser(s, ti_s)),
            ("warm", lambda w=warm: w),
        ):
            times, cpus = [], []
            result = None
            for _ in range(repeat):
                a = make()
                start, cpu = time.perf_counter(), time.process_time()
                result = a.analyse(second, t_from, t_to)
                times.append(time.perf_counter() - start)
                cpus.append(time.process_time() - cpu)
            assert result is not None
            name = f"{mode}, {label}, step-ls {'on' if step_ls else 'off'}"
            rows.append((name, statistics.median(times), statistics.median(cpus), result))
    return rows


# --- (b) the service --------------------------------------------------------------------------


def _stat(pid: int | str) -> list[str] | None:
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return text[text.rindex(")") + 2 :].split()  # fields from 3 (state) on


def tree_cpu_s(exclude: int) -> tuple[float, float]:
    """CPU seconds of this process, and of the processes it started (live or waited for).

    The subtree of ``exclude`` (the virtual PLC's process) is left out.
    """
    tick = os.sysconf("SC_CLK_TCK")
    parents: dict[int, int] = {}
    cpu: dict[int, float] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        fields = _stat(entry)
        if fields is None:
            continue
        pid = int(entry)
        parents[pid] = int(fields[1])
        cpu[pid] = (int(fields[11]) + int(fields[12])) / tick  # utime, stime
    me = os.getpid()
    own_fields = _stat(me)
    assert own_fields is not None
    own = (int(own_fields[11]) + int(own_fields[12])) / tick
    others = (int(own_fields[13]) + int(own_fields[14])) / tick  # cutime, cstime: waited for
    for pid in cpu:
        p = pid
        while p > 1 and p != me and p != exclude:
            if parents.get(p) == me:
                others += cpu[pid]
                break
            p = parents.get(p, 0)
    return own, others


def service_rows(minutes: float, every_s: float, window_s: float) -> list[tuple[str, str, str]]:
    """Run the service against the virtual PLC; the table rows (measured and extrapolated)."""
    import tomllib

    from fuelid.online import OnlineService

    child = subprocess.Popen(
        [sys.executable, "-c", CHILD, reference_plant()],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    lines: list[str] = []
    try:
        assert child.stdout is not None
        text = json.loads(child.stdout.readline())
        data = tomllib.loads(text)
        data["online"] = {
            "identify_every_s": every_s,
            "window_s": window_s,
            "write_back": "auto",
        }
        with tempfile.TemporaryDirectory() as folder:
            data["store"] = {"url": f"sqlite:///{Path(folder) / 'online.db'}"}
            site = SiteConfig.model_validate(data)
            service = OnlineService(site, on_message=lines.append, heartbeat_s=1.0)
            try:
                (own0, others0), wall0 = tree_cpu_s(child.pid), time.perf_counter()
                stats = asyncio.run(service.run(minutes * 60.0))
                own1, others1 = tree_cpu_s(child.pid)
                wall = time.perf_counter() - wall0
                own, others = own1 - own0, others1 - others0
            finally:
                service.close()
    finally:
        if child.stdin is not None:
            child.stdin.close()
        child.wait(timeout=30)
    windows = [_fields(line) for line in lines if line.startswith("window ")]
    stored = stats.recorder.stored if stats.recorder is not None else 0
    return [
        (
            "service run (virtual PLC in a child process)",
            f"{wall:.0f} s wall, {stored} samples, {len(windows)} windows "
            f"({stats.accepted} accepted) of {window_s:g} s every {every_s:g} s",
            "",
        ),
        (
            "windows' analysis time (their `seconds`)",
            ", ".join(f"{float(w['seconds']):.2f}" for w in windows) or "none",
            "",
        ),
        (
            "CPU of the whole service [% of one core]",
            f"{100.0 * (own + others) / wall:.2f}",
            f"{own + others:.1f} s CPU in {wall:.0f} s",
        ),
        (
            "  of which this process [% of one core]",
            f"{100.0 * own / wall:.2f}",
            "recorder, store, schedule, heartbeat, history",
        ),
        (
            "  of which processes it started [CPU s]",
            f"{others:.2f}",
            "the window worker: its start-up (imports) once, then the windows",
        ),
        ("_extrapolate", f"{own / wall}", ""),
    ]


def _fields(line: str) -> dict[str, str]:
    import shlex

    out = {}
    for part in shlex.split(line)[1:]:
        key, _, value = part.partition("=")
        out[key] = value
    return out


# --- the table --------------------------------------------------------------------------------


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=2.0, help="service run [min of wall]")
    parser.add_argument("--every", type=float, default=60.0, help="identify_every_s of (b) [s]")
    parser.add_argument("--window", type=float, default=60.0, help="window_s of (b) [s]")
    parser.add_argument("--repeat", type=int, default=3, help="runs per window row (median)")
    parser.add_argument("--skip-service", action="store_true", help="only (a)")
    args = parser.parse_args()

    print(f"(a) one window: {WINDOW_S / 60:g} min at {1 / PERIOD_S:g} Hz ({SAMPLES} samples),")
    print(f"    median of {args.repeat}; target < {WINDOW_TARGET_S} s")
    print(
        f"{'window':36s} {'wall s':>7s} {'CPU s':>7s}  {'method':6s} {'K':>7s} {'max|ρ|':>6s}"
        "  verdict"
    )
    reference = None
    reasons = {}
    for mode in ("MAN, local", "MAN, 1.5–4.5 V", "AUTO, local", "AUTO, runs"):
        for name, seconds, cpu, result in window_rows(mode, args.repeat):
            K = f"{result.model.K:7.3f}" if result.model is not None else f"{'-':>7s}"
            rho = result.verdict.measured.get("residual_acf_max")
            rho_s = f"{rho:6.3f}" if isinstance(rho, float) else f"{'-':>6s}"
            verdict = "accepted" if result.accepted else f"rejected: {result.reason}"
            ok = "ok" if seconds < WINDOW_TARGET_S else "OVER"
            print(
                f"{name:36s} {seconds:7.3f} {cpu:7.3f}  {result.method or '-':6s} {K} {rho_s}"
                f"  [{ok}] {verdict}"
            )
            reasons[mode] = result.method_reason
            if name == "AUTO, local, warm, step-ls on":
                reference = cpu
    for mode, why in reasons.items():
        print(f"  {mode}: {why}")
    if args.skip_service:
        return
    print()
    print(
        f"(b) the service at 50 Hz, real time, {args.minutes:g} min; target CPU "
        f"< {100 * CPU_TARGET:g} % of one core with a window every {EVERY_TARGET_S:g} s"
    )
    rows = service_rows(args.minutes, args.every, args.window)
    base = float(rows.pop()[1])
    for name, value, note in rows:
        print(f"{name:48s} {value}" + (f"  ({note})" if note else ""))
    assert reference is not None
    extrapolated = base + reference / EVERY_TARGET_S
    ok = "ok" if extrapolated < CPU_TARGET else "OVER"
    print(
        f"{'service CPU, 10-min window every 300 s [%]':48s} {100 * extrapolated:.2f} [{ok}]  "
        f"(extrapolated: this process + {reference:.3f} CPU s (AUTO, local, warm, step-ls) / 300 s)"
    )


if __name__ == "__main__":
    from fuelid.blas import single_threaded_blas

    with single_threaded_blas():  # as every fuelid command runs (fuelid.cli._common.guarded)
        run_to_docs("online", main, __doc__)  # the printed tables, also in docs/benchmarks
