"""The online service's soak against the virtual PLC (issue 15, "Tests and evidence", first item).

The service (:class:`~fuelid.online._service.OnlineService`, in this process) records the virtual
PLC over Modbus TCP on 127.0.0.1 into an SQLite store, identifies a 10 min window every 5 min of
data time, tracks K(T), proposes PI gains and writes them itself (``write_back = "auto"`` with
the site's ``[controller]``). The plant runs the wind-tunnel day of ``fuelid online --virtual``
(:func:`~fuelid.profiles.runs.demo_run_profile`: six test points with trims) followed in
each cycle by a 17 min hold at one setpoint (no excitation), while the fuel temperature follows
a sinusoid over −10…+45 °C (:func:`~fuelid.profiles.runs.demo_temperature`).

What is measured, after the run, from the store, the history and the engine (the truth):

- **K error**: every accepted window's K against the plant's linearised static gain at the
  window's mean command and mean fuel temperature (what ``fuelid plant info`` prints); within
  3 % in at least 95 % of the accepted windows (a specification: the error is the model
  structure's on the nonlinear plant, not a sampling statistic);
- **coverage**: over non-overlapping windows (every other one) that were accepted, whether
  K ± 1.96·se covers the K the output-error fit gets from the window's noise-free reading
  (the samples read back from the store with y replaced by the engine's clean reading of the
  same sequence number, fitted with the settings of a
  :class:`~fuelid.online._window.WindowAnalyser` set up as the service's, warm-started from the
  model the service warm-started from, i.e. the previous accepted window's; output error also
  for the few windows the service fitted with pem: on a noise-free reading pem's noise model
  has only the model-structure error to describe and its K wanders, 9 % once). The best
  the model structure can do on the nonlinear plant is the target, not the linearised K.
  Band, pre-registered: the number of misses lies inside the two-sided binomial band of n
  correct 95 % intervals at a false-alarm rate of 0.1 % (:func:`coverage_band`: n = 10:
  0…4 misses; n = 100: 0…13; too many is too narrow, too few too wide), and, since that band's
  lower end is 0 below n ≈ 150, Σz² of z = (K − K_clean)/se inside χ²(n)'s 0.1 % band. Before
  issue 23 the
  intervals covered 99–100 %: the HAC sandwich counted the model's misfit (the same in every
  noise realisation) as noise;
- **no excitation**: every window lying wholly inside a hold (from 30 s after the step into
  it) is rejected with a reason starting "no excitation";
- **K(T) held out**: a :class:`~fuelid.online._tracking.KTracker` fitted on the accepted windows
  except those within ±3 °C of T* (the accepted window temperature nearest the median) predicts
  the ratio K/K_plant at each held-out window's temperature; z = (K/K_plant − r̂)/
  √(se(r̂)² + b·(se_K/K_plant)²), the standard error of a new observation under the tracker's
  own error model (b = max(1, χ²/dof), the Birge inflation the tracker applies to its fit:
  the windows scatter about the line by more than their standard errors, from the plant's
  nonlinearity over a window's operating range), printed; asserted is the issue's check, K at
  the held-out temperature: the held-out windows' mean ratio against r̂(T*), |z| ≤ 3.29 (0.1 %) with
  z = (mean − r̂(T*)) / √(se(r̂(T*))² + v/m), v the larger of their scatter s² and the
  tracker's variance of a new window b·(se_K/K_plant)² (one window has no scatter), m their
  number; and, pre-registered, every held-out window's |z| within the Šidák bound of their
  count at 0.1 % (:func:`z_bound`: 3.29 for one window, 3.89 for ten);
- **Ms on the true plant**: for every gain set that was in the PLC (the commissioning gains and
  every verified write, reverts included), Ms of the sampled loop (``control_period = 1 s``)
  with the plant linearised (full state space, the meter's dead time) at every window's mean
  command and fuel temperature of the whole run (a superset of the moments those gains were
  applied) is at most ``ms_target`` + 0.02 (the proposal rules check Ms on identified
  low-order models; the linearised plant is a slightly different, higher-order model, and
  0.02 covers that difference and the frequency-grid refinement);
- **memory**: VmRSS of this process (the service, the recorder and the store's connections run
  in it; the store is on disk) plus its child processes (the window worker), after 20 % of the
  run and at its end: growth < 50 MB after subtracting the engine's own record of clean
  readings (8 bytes a sample: a test instrument, not the service);
- **windows accepted**: at least 75 % of the windows not wholly inside a hold (a requirement,
  asserted; the residual-correlation gate's default is set on other plants:
  docs/explanation/gate-study.md);
- samples lost by the recorder are reported, not asserted (they depend on the machine's load;
  the checks above stand on what was stored). The virtual PLC's ring holds 6400 records
  (128 s of plant time, 2.56 s of wall time at 50×): the default 2048 records are 0.8 s of wall
  time at 50×, shorter than the recorder's worst stall on a loaded 2-core machine (~3750
  samples, 1 %, were lost in a 2 h soak with it; with 8000, none; 6400 is the largest since
  the ring record grew to 10 registers). At 100× the 24 h soak lost 3 % of its samples on a
  loaded machine (Modbus answers later than the 1 s timeout, the link dropped and the ring
  overran), so it runs at 50× (about 30 min).

How to run: the soak is in the slow set and takes its plant time from ``FUELID_SOAK_HOURS``
(default 6, 50× real time, about 8 min; ``make test-slow``, which CI runs, sets 4 h to keep CI
within its budget); ``make soak`` runs 24 h (about 30 min)::

    .venv/bin/pytest -m slow tests/system/test_online_soak.py -s                     # 6 h
    FUELID_SOAK_HOURS=2 .venv/bin/pytest -m slow tests/system/test_online_soak.py -s  # 2 h
    make soak                                                                          # 24 h

Every band above is computed from the counts of the run (windows, held-out windows), so it holds
at its stated false-alarm rate for any length; fewer hours mean fewer windows (the table prints
the counts), wider relative bands and less power. The run needs at least 5 non-overlapping
accepted windows (asserted), which 2 h already gives.

``-s`` prints a table of the numbers: windows, accepted, within 3 %, coverage, held-out
prediction z, max Ms, RSS growth, samples lost, wall time; and the K error of every fitted
window a gate rejected. ``FUELID_SOAK_KEEP=FOLDER`` keeps a copy of the store there.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import math
import os
import shutil
import threading
import time
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("pymodbus")

from fuelid.online import (
    KTracker,
    OnlineService,
    ServiceSite,
    TrackingError,
    WindowAnalyser,
    observation_of,
)
from fuelid.plant import linearise
from fuelid.plc.virtual import VirtualPlcThread
from fuelid.profiles.runs import Profile, demo_run_profile, demo_temperature
from fuelid.store import SampleArrays
from fuelid.tuning import PISettings, robustness
from fuelid.units import celsius_to_kelvin
from support.bands import coverage_band, rmse_ratio_band, z_bound

HOLD_S = 1020.0
"""The constant-setpoint stretch after each run cycle [s]: ≥ 900 s holds one whole 600 s window
whatever the windows' phase (a window every 300 s), with a 30 s margin to spare."""
HOLD_SETPOINT_LPM = 35.0
"""The hold's setpoint [L/min]: mid-range, far from the command limits at every temperature."""
HOLD_SETTLE_S = 30.0
"""A window starting this long after the step into the hold lies wholly inside it [s]."""
ONLINE = 'identify_every_s = 300\nwindow_s = 600\nwrite_back = "auto"\n'
K_TOLERANCE = 0.03
HELD_OUT_C = 3.0
MS_TOLERANCE = 0.02
RSS_LIMIT_MB = 50.0
Z95 = 1.959963984540054
MIN_ACCEPTED_SHARE = 0.75
"""Accepted windows, as a share of those not wholly inside a hold (the rest have excitation:
the windows that straddle a hold's edge, or a test-point ramp)."""
RING_SIZE = 6400
"""The virtual PLC's ring [records]: 128 s of plant time, 2.56 s of wall time at 50x. The
default 2048 records (41 s of plant time, ample at 1x) are 0.8 s of wall time at 50x, less
than the recorder's worst stall on a loaded 2-core machine (samples were lost)."""


def soak_profile() -> Profile:
    """The demo's run cycle (about 33 min) then a hold of :data:`HOLD_SETPOINT_LPM` for HOLD_S."""
    runs = demo_run_profile()
    end = runs.cycle_s
    times = [*runs.times.tolist(), end, end + HOLD_S]
    values = [*runs.values.tolist(), HOLD_SETPOINT_LPM, HOLD_SETPOINT_LPM]
    return Profile(times, values, repeat=True)


def hold_intervals(duration_s: float) -> list[tuple[float, float]]:
    """The holds of :func:`soak_profile` in plant time [s]: (start, end)."""
    runs_s = demo_run_profile().cycle_s
    cycle = runs_s + HOLD_S
    out, start = [], runs_s
    while start < duration_s:
        out.append((start, start + HOLD_S))
        start += cycle
    return out


def _rss_mb(pid: str) -> float:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return math.nan


def vm_rss_mb() -> float:
    """Resident set size of this process and its children [MB] (Linux /proc; NaN elsewhere)."""
    children: set[str] = set()
    for task in Path("/proc/self/task").glob("*/children"):
        with contextlib.suppress(OSError):
            children.update(task.read_text().split())
    return _rss_mb("self") + sum(_rss_mb(pid) for pid in children)


@dataclass
class SoakResult:
    """What one soak measured (see the module docstring)."""

    hours: float
    speed: float
    wall_s: float = 0.0
    windows: int = 0
    accepted: int = 0
    within: int = 0
    k_errors: list[tuple[float, float, float, float]] = field(default_factory=list)
    """(window end [s plant], T [°C], u [V], K/K_plant − 1) per accepted window."""
    coverage: list[tuple[float, float, float, float, bool]] = field(default_factory=list)
    """(t_from [s plant], K, se, K_clean, covered) per non-overlapping accepted window."""
    no_excitation: list[tuple[float, bool, str]] = field(default_factory=list)
    """(t_from [s plant], accepted, reason) per window wholly inside a hold: its "no excitation"
    reason when the verdict has one (a window with gaps gives that reason first), else its
    first."""
    held_out_T: float = math.nan
    held_out_z: list[float] = field(default_factory=list)
    held_out_n_fit: int = 0
    held_out_inflation: float = math.nan
    held_out_mean_z: float = math.nan
    """(mean held-out ratio − r̂(T*)) / √(se(r̂(T*))² + s²/m): K at the held-out temperature."""
    ms: list[tuple[str, float, float, float, float]] = field(default_factory=list)
    """(gain set, Kc, Ti, max Ms over the grid, at T [°C]) per gain set."""
    ms_target: float = math.nan
    rss_mb: tuple[float, float] = (math.nan, math.nan)
    clean_mb: float = 0.0
    lost: int = 0
    stored: int = 0
    proposals: int = 0
    writes: int = 0
    reasons: dict[str, int] = field(default_factory=dict)
    rejected_fits: list[tuple[float, float, float, str]] = field(default_factory=list)
    """(window start [s plant], T [°C], K/K_plant − 1, reason) per fitted but rejected window."""
    ring_size: int = 0

    @property
    def rss_growth_mb(self) -> float:
        """VmRSS growth from 20 % of the run to its end, the clean-reading record subtracted."""
        return self.rss_mb[1] - self.rss_mb[0] - self.clean_mb

    def table(self) -> str:
        covered = sum(c[4] for c in self.coverage)
        z = max((abs(v) for v in self.held_out_z), default=math.nan)
        max_ms = max((m[3] for m in self.ms), default=math.nan)
        rows = [
            ("plant time / speed", f"{self.hours:g} h at {self.speed:g}x"),
            ("wall time", f"{self.wall_s:.0f} s"),
            ("samples stored / lost", f"{self.stored} / {self.lost} (ring {self.ring_size})"),
            ("windows / accepted", f"{self.windows} / {self.accepted}"),
            ("K within 3 % of plant", f"{self.within} / {self.accepted}"),
            ("max |K/K_plant - 1|", f"{max((abs(e[3]) for e in self.k_errors), default=0):.2%}"),
            ("coverage (non-overlapping)", f"{covered} / {len(self.coverage)}"),
            ("no-excitation windows", f"{len(self.no_excitation)} (all rejected: "
             f"{all(not a and r.startswith('no excitation') for _, a, r in self.no_excitation)})"),
            ("held out T*, fit on", f"{self.held_out_T:.1f} °C, {self.held_out_n_fit} windows"),
            ("held-out z (K at T*)", f"{self.held_out_mean_z:.2f}"),
            ("held-out max |z|", f"{z:.2f} over {len(self.held_out_z)} windows (Birge "
             f"inflation {self.held_out_inflation:.3g})"),
            ("gain sets / max Ms", f"{len(self.ms)} / {max_ms:.3f} (target {self.ms_target:g})"),
            ("proposals / writes", f"{self.proposals} / {self.writes}"),
            ("RSS at 20 % / end", f"{self.rss_mb[0]:.1f} / {self.rss_mb[1]:.1f} MB"),
            ("RSS growth (- clean record)", f"{self.rss_growth_mb:.1f} MB "
             f"(clean record {self.clean_mb:.1f} MB)"),
        ]  # fmt: skip
        width = max(len(r[0]) for r in rows)
        lines = [f"online soak, {self.hours:g} h"] + [f"  {k:<{width}}  {v}" for k, v in rows]
        lines.append("  rejections: " + "; ".join(f"{n}× {r}" for r, n in self.reasons.items()))
        for t, T, err, reason in self.rejected_fits:
            lines.append(f"  rejected fit at {t:.0f} s, {T:.1f} °C: K/K_plant - 1 = {err:+.2%}: "
                         f"{reason[:70]}")  # fmt: skip
        for name, kc, ti, ms, T in self.ms:
            lines.append(f"  Ms {name}: Kc={kc:.4g} Ti={ti:.4g} s -> {ms:.3f} (at {T:.1f} °C)")
        return "\n".join(lines)


def _site(virtual: VirtualPlcThread, store: Path) -> ServiceSite:
    plant = resources.files("fuelid.data").joinpath("reference_plant.toml")
    text = virtual.site_text(store_url=f"sqlite:///{store}", plant=str(plant))
    return ServiceSite.model_validate(tomllib.loads(f"{text}\n[online]\n{ONLINE}"))


def run_soak(
    tmp_path: Path,
    hours: float,
    speed: float,
    temperature_period_s: float,
    ring_size: int = RING_SIZE,
) -> SoakResult:
    """Run the service against the virtual PLC for ``hours`` of plant time; measure everything."""
    plant_s = hours * 3600.0
    wall = (plant_s + 60.0) / speed
    result = SoakResult(hours=hours, speed=speed, ring_size=ring_size)
    times, temperatures = demo_temperature(plant_s + 600.0, period_s=temperature_period_s)
    store = tmp_path / "soak.db"
    rss: dict[str, float] = {}
    with VirtualPlcThread(
        speed=speed,
        seed=1,
        setpoint_profile=soak_profile(),
        fuel_temp_profile=(times, temperatures),
        keep_clean_readings=True,
        ring_size=ring_size,
    ) as virtual:
        site = _site(virtual, store)
        # as `fuelid online --virtual`: heartbeats well inside the PLC's 10 s (plant) timeout
        heartbeat = min(1.0, 0.25 * virtual.plc.heartbeat_timeout_s / speed)
        service = OnlineService(site, on_message=None, heartbeat_s=heartbeat)
        timer = threading.Timer(0.2 * wall, lambda: rss.setdefault("early", vm_rss_mb()))
        timer_k: dict[str, int] = {}
        timer2 = threading.Timer(0.2 * wall, lambda: timer_k.setdefault("k", virtual.plc.seq))
        try:
            started = time.monotonic()
            timer.start()
            timer2.start()
            stats = asyncio.run(service.run(wall))
            result.wall_s = time.monotonic() - started
            rss["end"] = vm_rss_mb()
            n_end = virtual.plc.seq
            clean = virtual.plc.clean_readings()
            engine_config = virtual.plc.config
            kc0, ti0 = virtual.plc.kc0, virtual.plc.ti0
        finally:
            timer.cancel()
            timer2.cancel()
        try:
            assert stats.recorder is not None
            result.lost, result.stored = stats.recorder.lost, stats.recorder.stored
            result.proposals, result.writes = stats.proposals, stats.writes
            result.rss_mb = (rss.get("early", math.nan), rss["end"])
            result.clean_mb = 8.0 * (n_end - timer_k.get("k", n_end)) / 2**20
            _measure(result, service, site, clean, engine_config, (kc0, ti0), plant_s)
        finally:
            service.close()
            keep = os.environ.get("FUELID_SOAK_KEEP")
            if keep:  # the store for a closer look (FUELID_SOAK_KEEP=folder)
                shutil.copy(store, Path(keep) / f"soak-{hours:g}h.db")
    return result


def _plant_time(samples: SampleArrays, period_s: float) -> tuple[float, float]:
    """Plant time of a window's first and last sample [s] (sample k at k·period, seq0 = 0)."""
    return float(samples.seq[0]) * period_s, float(samples.seq[-1]) * period_s


def _measure(
    result: SoakResult,
    service: OnlineService,
    site: ServiceSite,
    clean: np.ndarray[Any, Any],
    config: Any,
    commissioning: tuple[float, float],
    plant_s: float,
) -> None:
    history, store = service.history, service.store
    period = site.sampling.period_s
    k_plant = service.k_plant
    assert k_plant is not None, "the site names the plant file: the service has its K"
    windows = history.windows()
    result.windows = len(windows)
    result.accepted = sum(w["accepted"] for w in windows)
    result.ms_target = service.settings.ms_target
    for w in windows:
        if not w["accepted"]:
            reason = w["reason"].split(":")[0]
            result.reasons[reason] = result.reasons.get(reason, 0) + 1
    models = {m["window_id"]: m for m in history.accepted_models()}
    holds = hold_intervals(plant_s)
    first_t = windows[0]["t_from"] if windows else 0.0
    previous: Any = None
    for w in windows:
        samples = store.read(w["t_from"], w["t_to"])
        if len(samples) == 0:
            continue
        p_from, p_to = _plant_time(samples, period)
        # windows wholly inside a hold
        if any(a + HOLD_SETTLE_S <= p_from and p_to <= b for a, b in holds):
            reasons = (w["detail"].get("gates") or {}).get("reasons") or [w["reason"]]
            excitation = next((r for r in reasons if r.startswith("no excitation")), w["reason"])
            result.no_excitation.append((p_from, w["accepted"], excitation))
        m = models.get(w["id"])
        detail = w["detail"]
        if not w["accepted"] and detail.get("model") and detail.get("plant_K"):
            err = float(detail["model"]["K"]) / float(detail["plant_K"]) - 1.0
            result.rejected_fits.append((p_from, float(w["T_fuel"]), err, w["reason"]))
        if not w["accepted"] or m is None:
            continue
        fitted = m["model"]
        K = float(fitted["model"]["K"])
        se = float(fitted["stderr"]["K"])
        u, T = float(fitted["u_mean"]), float(fitted["T_fuel"])
        err = K / k_plant(u, T) - 1.0
        result.k_errors.append((p_to, T, u, err))
        result.within += int(abs(err) <= K_TOLERANCE)
        # non-overlapping windows: every other one on the 300 s grid (600 s apart)
        index = round((w["t_from"] - first_t) / service.settings.identify_every_s)
        if index % 2 == 0:
            K_clean = _clean_K(service, site, samples, clean, previous, w)
            covered = abs(K_clean - K) <= Z95 * se
            result.coverage.append((p_from, K, se, K_clean, covered))
        previous = fitted
    _held_out(result, history.accepted_models(), k_plant)
    _robustness(result, history, windows, config, commissioning)


def _clean_K(
    service: OnlineService,
    site: ServiceSite,
    samples: SampleArrays,
    clean: np.ndarray[Any, Any],
    warm: dict[str, Any] | None,
    window: dict[str, Any],
) -> float:
    """K the output-error fit gets from the window's noise-free reading.

    With the analyser's settings (:class:`WindowAnalyser` set up as the service's: order from
    the warm start, the meter's lag and dead time fixed), warm-started from the model the
    service warm-started from (the previous accepted window's). The output-error fit also for
    windows the service fitted with pem: on a noise-free reading there is no noise to model,
    pem's noise model describes the model-structure error alone and its K wanders (a 24 h soak
    gave K_clean 9 % below the service's for one pem window).
    """
    from fuelid.identify import OutputError
    from fuelid.online import model_of
    from fuelid.store import iodata_from_samples

    analyser = WindowAnalyser(
        service.settings, service.priors, site.sampling.period_s, k_plant=service.k_plant
    )
    init = model_of(warm) if warm is not None else None
    analyser.resume(init)
    noise_free = dataclasses.replace(samples, y=clean[samples.seq].astype(float))
    data = iodata_from_samples(noise_free, site.sampling.period_s, source="noise-free")
    settings = analyser._estimator_settings()
    oe = OutputError(covariance="auto", **settings).fit(data, init=init)
    return float(oe.model_.K)


def _held_out(result: SoakResult, rows: list[dict[str, Any]], k_plant: Any) -> None:
    observations = [o for o in (observation_of(r) for r in rows) if o is not None]
    if len(observations) < 5:
        return
    temps = np.array([o.T_fuel_C for o in observations])
    T_star = float(temps[np.argmin(np.abs(temps - np.median(temps)))])
    near = np.abs(temps - T_star) <= HELD_OUT_C
    train = [o for o, n in zip(observations, near, strict=True) if not n]
    result.held_out_T, result.held_out_n_fit = T_star, len(train)
    try:
        tracker = KTracker(k_plant=k_plant).fit(train)
    except TrackingError:
        return
    for o, n in zip(observations, near, strict=True):
        if not n:
            continue
        Kp = o.K_plant if o.K_plant is not None else k_plant(o.u, o.T_fuel_C)
        r, se_r = tracker.predict_ratio(o.T_fuel_C)
        assert tracker.fit_ is not None
        inflation = tracker.fit_.inflation
        se = math.sqrt(se_r**2 + inflation * (o.se_K / Kp) ** 2)
        result.held_out_z.append((o.K / Kp - r) / se)
        result.held_out_inflation = inflation
    # K at the held-out temperature: the mean ratio of the windows there against the curve's
    # prediction at T*, with the prediction's standard error and that of the mean (from the
    # held-out windows' own scatter, which the nonlinear plant makes larger than their se)
    ratios = np.array(
        [o.K / (o.K_plant or k_plant(o.u, o.T_fuel_C)) for o, n in zip(observations, near,
                                                                     strict=True) if n]
    )  # fmt: skip
    r_star, se_star = tracker.predict_ratio(T_star)
    # the mean's variance: the held-out windows' own scatter, or (for one or two windows, whose
    # scatter says nothing) the tracker's error model for a new window, whichever is larger
    held = [o for o, n in zip(observations, near, strict=True) if n]
    model_var = float(
        np.mean([inflation * (o.se_K / (o.K_plant or k_plant(o.u, o.T_fuel_C))) ** 2 for o in held])
    )
    scatter_var = float(np.var(ratios, ddof=1)) if ratios.size > 1 else 0.0
    spread = math.sqrt(max(scatter_var, model_var) / ratios.size)
    result.held_out_mean_z = (float(np.mean(ratios)) - r_star) / math.hypot(se_star, spread)


def _robustness(
    result: SoakResult,
    history: Any,
    windows: list[dict[str, Any]],
    config: Any,
    commissioning: tuple[float, float],
) -> None:
    """Ms of every gain set that was in the PLC on the plant linearised at every window's mean."""
    sets = [("commissioning", *commissioning)]
    for write in history.writes():
        if write["status"] == "verified":
            sets.append((f"write {write['id']} ({write['kind']})", write["kc"], write["ti"]))
    points = sorted(
        {
            (round(float(w["u_mean"]), 3), round(float(w["T_fuel"]), 1))
            for w in windows
            if w["u_mean"] is not None and w["T_fuel"] is not None
        }
    )
    plants = [(T, linearise(config, u, celsius_to_kelvin(T))) for u, T in points]
    for name, kc, ti in sets:
        pi = PISettings("applied", float(kc), float(ti), 1.0)
        worst, at = -math.inf, math.nan
        for T, plant in plants:
            ms = robustness(plant, pi).Ms
            if ms > worst:
                worst, at = ms, T
        result.ms.append((name, float(kc), float(ti), worst, at))


def check(result: SoakResult) -> None:
    """Every assertion of the module docstring, with the bands stated there before the run."""
    print("\n" + result.table())
    outside = [e for e in result.k_errors if abs(e[3]) > K_TOLERANCE]
    assert result.within >= 0.95 * result.accepted, f"K beyond 3 % (t, T, u, err): {outside}"
    n = len(result.coverage)
    misses = [c for c in result.coverage if not c[4]]
    assert n >= 5, result.coverage
    lo, hi = coverage_band(n)
    # too many misses: intervals too narrow; too few: too wide (gates and proposals slower
    # than they need be); both are defects
    assert lo <= len(misses) <= hi, (
        f"{n - len(misses)} of {n} covered, misses outside {lo}…{hi} (t, K, se, K_clean): {misses}"
    )
    # the misses' band cannot see intervals too wide below n ≈ 150 (its lower end is 0): the
    # standardised errors z = (K − K_clean)/se are, with the right se, N(0, 1), so Σz² ~ χ²(n);
    # pre-registered band at 0.1 % (before issue 23: Σz² = 0.78 over 10 windows, P = 5e-5)
    low, high = rmse_ratio_band(n)
    z2 = sum(((K - K_clean) / se) ** 2 for _, K, se, K_clean, _ in result.coverage)
    assert n * low**2 <= z2 <= n * high**2, (z2, n * low**2, n * high**2)
    assert result.no_excitation, "no window lay wholly inside a hold"
    for t_from, accepted, reason in result.no_excitation:
        assert not accepted, (t_from, reason)
        assert reason.startswith("no excitation"), (t_from, reason)
    assert result.held_out_z, "no held-out window"
    # every held-out window within the Šidák bound of its count, and their mean within 3 se
    bound = z_bound(len(result.held_out_z))
    assert max(abs(z) for z in result.held_out_z) <= bound, (bound, result.held_out_z)
    assert abs(result.held_out_mean_z) <= z_bound(1), (result.held_out_mean_z, result.held_out_z)
    for name, _kc, _ti, ms, T in result.ms:
        assert ms <= result.ms_target + MS_TOLERANCE, (name, ms, T)
    assert result.rss_growth_mb < RSS_LIMIT_MB, result.rss_mb
    eligible = result.windows - len(result.no_excitation)
    assert result.accepted >= MIN_ACCEPTED_SHARE * eligible, (
        f"{result.accepted} of {eligible} windows with excitation accepted "
        f"(< {MIN_ACCEPTED_SHARE:.0%}); rejections {result.reasons}"
    )


SOAK_HOURS = float(os.environ.get("FUELID_SOAK_HOURS", "6"))
"""Plant time of the soak [h]: 6 in CI's slow set, 24 with ``make soak``."""
SOAK_SPEED = 50.0
"""Times real time: 100x lost 3 % of the samples on a loaded 2-core machine, 50x none."""


def temperature_period_s(hours: float) -> float:
    """The fuel temperature's sinusoid period [s] for a soak of ``hours``.

    Shorter than a day: twice the run, so the fuel sweeps −10 → +45 °C once (half a sinusoid);
    a day or more: the daily cycle, −10 → +45 → −10 °C over each day.
    """
    return 86400.0 if hours >= 24.0 else 2.0 * hours * 3600.0


@pytest.mark.slow
# the wall time is hours·3600/speed; three times that plus 10 min of set-up and measuring
@pytest.mark.timeout(600 + 3 * SOAK_HOURS * 3600.0 / SOAK_SPEED)
@pytest.mark.parametrize("hours", [SOAK_HOURS], ids=lambda h: f"{h:g}h")
def test_a_soak_against_the_virtual_plc(tmp_path: Path, hours: float) -> None:
    result = run_soak(
        tmp_path, hours=hours, speed=SOAK_SPEED, temperature_period_s=temperature_period_s(hours)
    )
    check(result)
