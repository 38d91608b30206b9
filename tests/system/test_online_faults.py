"""The online service under the faults and plant changes of issue 15 ("Tests and evidence", 2–5).

- the burst scenario: steady AUTO at one setpoint with a slow coloured disturbance: every
  window rejected for want of excitation, no proposal, the PLC's gains untouched;
- pump wear (K −15 %) mid-run: the windows after it find the worn plant's K, a proposal for a
  larger Kc follows within three windows;
- write-back: the gains are applied without a jump of the command;
- faults: link drops and a PLC restart in-process; ``kill -9`` of ``fuelid online`` mid-window
  and mid-write, restarted: nothing committed is lost, the schedule goes on, no proposal is
  written twice or half.

Everything runs against the virtual PLC on loopback at a speed-up; every run is bounded in wall
time. The long variants are marked slow (``make test-slow``).

Data time is the samples' own clock (the store's ``time``), as the service counts it.

Two faults these tests found are fixed and stay tested: the analysis worker process outlived a
``kill -9`` of the service (it now exits when its parent is gone), and a kill between a
window's record and the schedule's next end made the restarted service record that window
again (:func:`test_kill_9_during_a_window_s_revert_does_not_repeat_the_window`).
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import random
import signal
import sqlite3
import subprocess
import sys
import threading
import time
import tomllib
from collections.abc import Callable
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("pymodbus")

from fuelid.online import OnlineService, ServiceSite
from fuelid.plant import PlantConfig, linearise, load_plant_config
from fuelid.plc.virtual import VirtualPlcThread
from fuelid.profiles.runs import Profile
from fuelid.store import SQLiteStore
from support.online import approve_directly as _approve
from support.online import online_site as _site
from support.online import open_history as _open
from support.waiting import wait_until

# xdist: one worker runs every module that drives a PLC at speed, one after another
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("real-time")

REFERENCE_PLANT = str(resources.files("fuelid.data").joinpath("reference_plant.toml"))
HEARTBEAT_S = 0.05
"""Heartbeat of an in-process service [s of wall time]: inside the PLC's 10 s at 20–60×."""
RING = 6400
"""The virtual PLC's largest ring (128 s of plant time at 50 Hz): at 50–60× it holds 2–2.5 s of
wall time, so a busy machine (other test runs) does not make the recorder lose samples."""
T_FUEL_C = 20.0
"""The fuel temperature of every run here [°C] (constant)."""


# --- helpers -----------------------------------------------------------------------------------


def _run(
    site: ServiceSite,
    wall_s: float,
    watch: Callable[[OnlineService, Callable[[], None]], None] | None = None,
    **kwargs: Any,
) -> tuple[OnlineService, list[str]]:
    """Run the service for at most ``wall_s``; ``watch(service, stop)`` runs in a thread beside.

    ``stop()`` ends the run early (thread-safe). An exception in ``watch`` fails the test.
    """
    lines: list[str] = []
    service = OnlineService(site, on_message=lines.append, heartbeat_s=HEARTBEAT_S, **kwargs)
    failure: list[BaseException] = []

    async def main() -> None:
        loop = asyncio.get_running_loop()

        def stop() -> None:
            loop.call_soon_threadsafe(service.stop)

        def guarded() -> None:
            try:
                assert watch is not None
                watch(service, stop)
            except BaseException as exc:  # reported after the run
                failure.append(exc)
                stop()

        thread = threading.Thread(target=guarded, daemon=True) if watch else None
        if thread is not None:
            thread.start()
        await service.run(wall_s)
        if thread is not None:
            await asyncio.to_thread(thread.join, 10.0)

    asyncio.run(main())
    if failure:
        service.close()
        raise failure[0]
    return service, lines


def _sql(db: Path, query: str, *args: Any) -> list[tuple[Any, ...]]:
    """Rows of a read-only query (none when the table does not exist yet)."""
    if not db.exists():
        return []
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5.0)
    try:
        return list(con.execute(query, args).fetchall())
    except sqlite3.OperationalError:  # created, schema not yet committed
        return []
    finally:
        con.close()


def _count(db: Path, table: str) -> int:
    rows = _sql(db, f"SELECT count(*) FROM {table}")
    return int(rows[0][0]) if rows else 0


def _time_of_seq(store: SQLiteStore, seq: int, t_from: float | None = None) -> float:
    """Data time of the stored sample with sequence number ``seq`` (the first at or after it)."""
    data = store.read(t_from)
    found = np.flatnonzero(data.seq >= seq)
    assert found.size, f"no sample with seq >= {seq} stored"
    return float(data.time[found[0]])


def _assert_on_schedule(ends: list[float], every: float) -> None:
    """Window ends are first_end + k·every (k increasing, none twice)."""
    assert ends, "no window"
    assert len(set(ends)) == len(ends), f"a window end twice: {ends}"
    assert ends == sorted(ends)
    k = [(end - ends[0]) / every for end in ends]
    assert all(abs(x - round(x)) < 1e-6 for x in k), f"window ends off the schedule: {k}"


# --- the engine's coloured disturbance ------------------------------------------------------


def test_the_engine_disturbance_is_ar1_of_the_given_size_and_off_by_default() -> None:
    """σ and correlation time as asked (MAN, so the PI does not act on it); σ = 0: no change."""
    from fuelid.plc.virtual import VirtualPLC

    def flows(**kwargs: Any) -> np.ndarray:
        plc = VirtualPLC(command_profile=([0.0, 10.0], [3.0, 3.0]), seed=2, **kwargs)
        out = []
        for _ in range(30):  # 600 s
            out.extend(r[2] for r in plc.advance(1000).values())
        return np.array(out)

    assert np.array_equal(flows(), flows(disturbance_sd_Lpm=0.0, disturbance_time_s=5.0))
    # 1 s means take the meter's white noise (0.1 L/min) out; 600 s = 60 correlation times
    slow = flows(disturbance_sd_Lpm=1.0, disturbance_time_s=10.0).reshape(-1, 50).mean(axis=1)
    slow = slow - slow.mean()
    assert 0.6 < float(np.std(slow)) < 1.4
    lag = 10  # s: the correlation at one correlation time is e^-1 = 0.37
    rho = float(np.corrcoef(slow[:-lag], slow[lag:])[0, 1])
    assert 0.15 < rho < 0.6


# --- 1. the burst scenario ---------------------------------------------------------------------

BURST_SETPOINT_LPM = 40.0
BURST_DISTURBANCE = {"disturbance_sd_Lpm": 0.5, "disturbance_time_s": 60.0}
"""A slow load: 0.5 L/min (5× the meter's noise) with a one-minute correlation time."""


# both in the slow set (the 10-minute case is 11 s of a real-time run: the fast set's budget)
@pytest.mark.slow
@pytest.mark.parametrize(("plant_minutes", "speed"), [(10.0, 60.0), (120.0, 80.0)])
def test_burst_steady_auto_with_a_slow_disturbance_never_proposes(
    tmp_path: Path, plant_minutes: float, speed: float
) -> None:
    """Hours of one setpoint and a coloured load: the estimator is never fed, nothing proposed.

    The classic way an adaptive tuner bursts (Anderson 1985): steady closed-loop data hold only
    the loop's reaction to its own disturbance, a fitted model drifts, the gains follow. Here
    every window must be refused at the excitation gate with that reason, no proposal may
    appear, and the PLC's gains stay what they were.
    """
    store = tmp_path / "burst.db"
    constant = Profile([0.0, 3600.0], [BURST_SETPOINT_LPM] * 2, repeat=True)
    with VirtualPlcThread(
        speed=speed, setpoint_profile=constant, seed=3, ring_size=RING, **BURST_DISTURBANCE
    ) as virtual:
        site = _site(virtual, store, "identify_every_s = 120\nwindow_s = 240\n")
        gains_before = virtual.plc.gains
        service, _ = _run(site, plant_minutes * 60.0 / speed)
        try:
            windows = service.history.windows()
            proposals = service.history.proposals()
            writes = service.history.writes()
            data = service.store.read()
        finally:
            service.close()
        gains_after = virtual.plc.gains
    expected = (plant_minutes * 60.0 - 240.0) / 120.0 + 1.0
    assert len(windows) >= 0.6 * expected, f"{len(windows)} windows of ~{expected:.0f}"
    no_excitation = 0
    for window in windows:
        assert not window["accepted"], window["reason"]
        reasons = window["detail"]["gates"]["reasons"]
        if any(r.startswith("no excitation: the setpoint did not move") for r in reasons):
            no_excitation += 1
        else:  # a window the recorder could not fill (a busy machine at 100×): nothing to fit
            assert window["reason"].startswith("too few good samples"), reasons
    assert no_excitation >= 0.8 * len(windows), [w["reason"] for w in windows]
    assert proposals == []
    assert writes == []
    assert gains_after == gains_before
    # the disturbance is there and the PI fights it: the command wanders, the flow does not
    u = data.u[np.isfinite(data.u)]
    assert float(np.ptp(u)) > 0.05  # the load moves the command by tenths of a volt
    assert abs(float(np.mean(data.y)) - BURST_SETPOINT_LPM) < 0.1
    print(
        f"burst: {len(windows)} windows over {plant_minutes:g} min, {no_excitation} 'no "
        "excitation', the others empty; "
        f"0 proposals; command range {float(np.ptp(u)):.3f} V, flow sd {float(np.std(data.y)):.3f}"
    )


# --- 2. pump wear -----------------------------------------------------------------------------

WEAR_PROFILE = Profile(
    [0.0, 30.0, 30.0, 60.0, 60.0, 90.0, 90.0, 120.0],
    [38.0, 38.0, 42.0, 42.0, 39.0, 39.0, 41.0, 41.0],
    repeat=True,
)
"""Small setpoint steps around 40 L/min every 30 s (two in every 60 s window)."""
WEAR_EVERY_S = 60.0
WEAR_WINDOW_S = 60.0


def _worn(config: PlantConfig, factor: float) -> PlantConfig:
    pump = config.pump.model_copy(
        update={"leakage_Lpm_per_MPa": config.pump.leakage_Lpm_per_MPa * factor}
    )
    return config.model_copy(update={"pump": pump})


def _k_at(config: PlantConfig, flow_Lpm: float) -> float:
    """The plant's linearised K at the command that holds ``flow_Lpm`` [(L/min)/V]."""
    from fuelid.tuning.closedloop import steady_command
    from fuelid.units import celsius_to_kelvin

    T = celsius_to_kelvin(T_FUEL_C)
    return linearise(config, steady_command(config, flow_Lpm, T), T).static_gain


def _leakage_factor_for(config: PlantConfig, ratio: float, flow_Lpm: float) -> float:
    """The factor on the pump's leakage that makes K at ``flow_Lpm`` ``ratio`` × today's."""
    from scipy.optimize import brentq

    k0 = _k_at(config, flow_Lpm)
    factor = brentq(lambda f: _k_at(_worn(config, f), flow_Lpm) / k0 - ratio, 1.0, 4.0, xtol=1e-3)
    return float(factor)


def _tuned_gains(config: PlantConfig, settings: str) -> tuple[float, float]:
    """The gains the service's own rule gives for ``config``: SIMC on its own window fit.

    Identifies one window of the engine alone (no server: ~1 s) with the service's analyser
    and its plant-file priors, so the PLC starts at gains the service has no reason to change.
    """
    from fuelid.online import Online, WindowAnalyser, window_priors
    from fuelid.plc.virtual import VirtualPLC
    from fuelid.store import SampleArrays
    from fuelid.tuning import tune

    online = Online.model_validate(tomllib.loads(settings))
    kc, ti = None, None
    for _ in range(2):  # once more under the gains found: closed-loop data depend on them
        plc = VirtualPLC(config, setpoint_profile=WEAR_PROFILE, seed=11, kc=kc, ti=ti)
        n = round(2 * online.window_s / plc.period_s)
        records: list[Any] = []
        while len(records) < n:
            records.extend(plc.advance(min(1000, n - len(records))).values())
        r = np.array(records[-round(online.window_s / plc.period_s) :])
        m = r.shape[0]
        t = 1.7e9 + r[:, 0] * plc.period_s
        samples = SampleArrays(
            time=t,
            seq=r[:, 0].astype(np.int64),
            u=r[:, 1],
            y=r[:, 2],
            setpoint=r[:, 3],
            fuel_temperature=np.full(m, T_FUEL_C),
            mode=np.ones(m, dtype=np.int64),
            quality=np.zeros(m, dtype=np.int64),
        )
        priors, k_plant = window_priors(REFERENCE_PLANT, control_period=plc.control_period_s)
        analyser = WindowAnalyser(online, priors, plc.period_s, k_plant=k_plant)
        result = analyser.analyse(samples, float(t[0]), float(t[-1]) + plc.period_s)
        assert result.accepted, result.reason
        assert result.model is not None
        pi = tune(result.model, online.rule, plc.control_period_s)
        kc, ti = pi.Kc, pi.Ti
    assert kc is not None
    assert ti is not None
    return kc, ti


@pytest.mark.slow
@pytest.mark.parametrize("speed", [50.0])
def test_pump_wear_is_tracked_and_a_larger_gain_proposed_within_three_windows(
    tmp_path: Path, speed: float
) -> None:
    """Pump wear (K −15 % at the operating point) mid-run.

    Why 60 s windows every 60 s: a proposal needs two accepted windows on *separate* excitation
    events (``agree_windows = 2``), and the window that straddles the change holds two plants
    (the gates refuse it or it mixes them). With windows that do not overlap the first window
    wholly after the change is the 2nd to end after it and the next independent one the 3rd,
    so "a proposal within three windows" is reachable; 120 s windows every 60 s share their
    steps with their neighbours and would need five. Two setpoint steps in each window.

    The PLC starts at the gains the service's own rule gives for the unworn plant
    (:func:`_tuned_gains`), so no proposal comes before the change (checked); write-back is off.
    """
    online = f"identify_every_s = {WEAR_EVERY_S:g}\nwindow_s = {WEAR_WINDOW_S:g}\n"
    config = load_plant_config()
    factor = _leakage_factor_for(config, 0.85, 40.0)
    worn = _worn(config, factor)
    k_new, k_old = _k_at(worn, 40.0), _k_at(config, 40.0)
    assert k_new / k_old == pytest.approx(0.85, abs=0.002)
    kc0, ti0 = _tuned_gains(config, online)
    store = tmp_path / "wear.db"
    change: dict[str, Any] = {}
    with VirtualPlcThread(
        speed=speed, setpoint_profile=WEAR_PROFILE, seed=5, ring_size=RING, kc=kc0, ti=ti0
    ) as virtual:
        site = _site(virtual, store, online, plant=REFERENCE_PLANT)

        def watch(service: OnlineService, stop: Callable[[], None]) -> None:
            opened, history = _open(site, store)
            try:
                wait_until(
                    lambda: sum(w["accepted"] for w in history.windows()) >= 3,
                    60.0,
                    "three accepted windows",
                )
                # the PLC's sample counter, not the store's newest sample: the recorder
                # commits once a second of wall time, 50 s of data at 50×
                change["seq"] = virtual.plc.seq
                change["proposals_before"] = len(history.proposals())
                virtual.plc.set_plant(worn)
                wait_until(lambda: opened.last_time() is not None and _seq_stored(), 30.0, "data")
                change["time"] = _time_of_seq(opened, change["seq"])
                wait_until(
                    lambda: len(history.windows(t_from=change["time"])) >= 5,
                    60.0,
                    "five windows after the change",
                )
            finally:
                history.close()
                opened.close()
                stop()

        def _seq_stored() -> bool:
            rows = _sql(store, "SELECT max(seq) FROM samples")
            return bool(rows) and rows[0][0] is not None and rows[0][0] > change["seq"] + 100

        started = time.monotonic()
        service, _lines = _run(site, 90.0, watch)
        wall = time.monotonic() - started
        try:
            windows = service.history.windows()
            proposals = service.history.proposals()
            models = {m["id"]: m for m in service.history.accepted_models()}
        finally:
            service.close()
    t_change = change["time"]
    assert change["proposals_before"] == 0, "a proposal before the change: gains not tuned"
    before = [w for w in windows if w["t_to"] <= t_change]
    assert sum(w["accepted"] for w in before) >= 3
    for w in before:
        if w["accepted"]:
            assert w["detail"]["model"]["K"] == pytest.approx(
                linearise(config, w["u_mean"], 293.15).static_gain, rel=0.03
            )
    after = [w for w in windows if w["t_to"] > t_change]
    wholly_after = [w for w in after if w["accepted"] and w["t_from"] >= t_change]
    assert len(wholly_after) >= 2, [(w["t_to"] - t_change, w["reason"]) for w in after]
    for w in wholly_after:
        K = w["detail"]["model"]["K"]
        K_worn = linearise(worn, w["u_mean"], 293.15).static_gain
        assert abs(K / K_worn - 1.0) <= 0.03, (w["t_to"] - t_change, K, K_worn)
    # the first proposal, and the window whose model it rests on
    assert proposals, [(w["t_to"] - t_change, w["reason"]) for w in after]
    first = proposals[0]
    model = models[first["model_id"]]
    rank = [w["id"] for w in after].index(model["window_id"]) + 1
    assert rank <= 3, f"proposal on the {rank}th window after the change"
    assert first["new"]["Kc"] > first["old"]["Kc"]  # lower K, higher gain (SIMC: Kc ∝ 1/K)
    assert math.isclose(first["old"]["Kc"], kc0, rel_tol=1e-5)
    for w in after[:5]:
        K = (w["detail"].get("model") or {}).get("K")
        K_worn = linearise(worn, w["u_mean"], 293.15).static_gain
        print(
            f"  window ending {w['t_to'] - t_change:+.0f} s after the change (from "
            f"{w['t_from'] - t_change:+.0f} s): accepted={w['accepted']} K={K} "
            f"worn K={K_worn:.3f}: {w['reason'][:70]}"
        )
    print(
        f"pump wear: leakage ×{factor:.3f}, K {k_old:.3f} → {k_new:.3f}; proposal on window "
        f"{rank} after the change: Kc {first['old']['Kc']:.4g} → {first['new']['Kc']:.4g}; "
        f"wall {wall:.1f} s"
    )


# --- 3. write-back is bumpless ----------------------------------------------------------------

BUMP_SPEED = 20.0
NO_WINDOWS = 'identify_every_s = 3600\nwindow_s = 3600\nwrite_back = "approve"\n'


def _moves(seq: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|Δu| between consecutive samples with consecutive sequence numbers, and their index.

    The PLC holds its command over a control period, so a non-zero Δu is one scan's move: the
    largest of them is the largest move between consecutive control periods.
    """
    ok = (np.diff(seq) == 1) & np.isfinite(np.diff(u))
    idx = np.flatnonzero(ok) + 1
    return np.abs(np.diff(u))[ok], idx


def test_an_applied_write_moves_the_command_no_more_than_the_pi_does(tmp_path: Path) -> None:
    """Write-back is bumpless: around the scan that takes the new gains, no jump of the command.

    At a constant setpoint the command moves each second by the PI's reaction to the meter's
    noise. The largest |Δu| between consecutive control periods within ±3 s of the apply must
    stay within the largest one of the 30 s before, widened by the gain ratio (after the apply
    the same noise moves the command Kc_new/Kc_old times as much: that is the new gains at
    work, not a bump) and 1 mV (float32 registers round the command to ~0.2 µV; the margin is
    far below any bump worth the name).

    That check is weak at a constant setpoint: a write that did not absorb the proportional
    change into the integral would add (Kc_new − Kc_old)·e at the apply, and e is the meter's
    noise there (~0.1 L/min: ~2 mV with Kc ×1.5, a fifth of a typical move). So the scans are
    also checked exactly: the PLC's PI is positional, u_k = Kc·e_k + I_k with
    I_k+1 = I_k + Kc·h/Ti·e_k, so between scans Δu_k = Kc·(e_k − e_k−1) + Kc·h/Ti·e_k−1 with
    e = setpoint − flow of the scan's sample, all in the store. Every scan up to and including
    the apply must follow the old gains (the apply scan outputs what the old gains give:
    bumpless), every scan after it the new gains, to float32 rounding.
    """
    store = tmp_path / "bump.db"
    constant = Profile([0.0, 3600.0], [40.0, 40.0], repeat=True)
    applied: dict[str, Any] = {}
    with VirtualPlcThread(
        speed=BUMP_SPEED, setpoint_profile=constant, seed=4, ring_size=RING
    ) as virtual:
        site = _site(virtual, store, NO_WINDOWS)
        kc0, ti0 = virtual.plc.gains
        kc, ti = round(1.5 * kc0, 6), round(0.9 * ti0, 6)

        def watch(service: OnlineService, stop: Callable[[], None]) -> None:
            # 40 s of data at the constant setpoint first, then approve: the service writes
            wait_until(lambda: virtual.plc.time_s > 45.0 and _count(store, "samples") > 2000, 30.0,
                  "40 s of samples")  # fmt: skip
            _approve(site, store, kc, ti)
            wait_until(lambda: virtual.plc.gains != (kc0, ti0), 30.0, "the apply")
            applied["seq"] = virtual.plc.seq  # within a tick (1 ms of wall time) of the scan
            end = virtual.plc.seq + round(15.0 / virtual.plc.period_s)
            wait_until(lambda: virtual.plc.seq > end, 30.0, "15 s after the apply")
            wait_until(
                lambda: _sql(store, "SELECT max(seq) FROM samples")[0][0] >= end, 30.0,
                "the samples up to 15 s after the apply committed",
            )  # fmt: skip
            stop()

        service, _ = _run(site, 30.0, watch)
        try:
            data = service.store.read()
            writes = service.history.writes()
        finally:
            service.close()
        gains_new = virtual.plc.gains
        n_control = virtual.plc.n_control
    assert [w["status"] for w in writes] == ["verified"]
    assert gains_new == pytest.approx((kc, ti), rel=1e-6)
    found = np.flatnonzero(data.seq == applied["seq"])
    assert found.size == 1
    t_apply = float(data.time[found[0]])
    moves, idx = _moves(data.seq, data.u)
    t = data.time[idx]
    around = moves[np.abs(t - t_apply) <= 3.0]
    before = moves[(t >= t_apply - 33.0) & (t < t_apply - 3.0)]
    assert before.size > 1000  # no gap hides a move
    assert around.size > 200
    tolerance = float(before.max()) * (kc / kc0 - 1.0) + 0.001
    assert float(around.max()) <= float(before.max()) + tolerance, (around.max(), before.max())
    # the scans, exactly: old gains up to the apply (included), new gains after
    scans = np.flatnonzero((data.seq % n_control == 0) & (np.abs(data.time - t_apply) <= 10.0))
    assert np.all(np.diff(data.seq[scans]) == n_control)  # no scan missing
    e = data.setpoint[scans] - data.y[scans]
    du = np.diff(data.u[scans])
    h = n_control * 0.02

    def predicted(gains: tuple[float, float]) -> np.ndarray:
        return gains[0] * (e[1:] - e[:-1]) + gains[0] * h / gains[1] * e[:-1]

    # float32 registers: u, flow and the gains to ~6e-8 relative, a few µV of command at most
    tol = 2e-5
    old_fit = np.abs(du - predicted((kc0, ti0)))
    new_fit = np.abs(du - predicted(gains_new))
    # du[i] is the move at scans[i + 1]; a: the last move the new gains do not explain (the
    # apply scan's own move, or the one before when e at the apply was too small to tell)
    a = int(np.flatnonzero(new_fit > tol)[-1])
    assert data.seq[scans][a + 1] <= applied["seq"] < data.seq[scans][a + 1] + 2 * n_control
    assert np.all(old_fit[: a + 1] < tol), old_fit[: a + 1].max()
    assert np.all(new_fit[a + 1 :] < tol), new_fit[a + 1 :].max()
    bump = abs((gains_new[0] - kc0) * e[a + 1])  # what a write without absorption would add
    print(
        f"bumpless: apply scan follows the old gains to {1e6 * old_fit[a]:.2f} µV (a bump "
        f"would have been {1000 * bump:.2f} mV); "
        f"largest |Δu| within ±3 s of the apply {1000 * around.max():.2f} mV, "
        f"in the 30 s before {1000 * before.max():.2f} mV (+ tolerance {1000 * tolerance:.2f} mV)"
    )


# --- 4. faults during the service --------------------------------------------------------------

FAULT_SPEED = 20.0
FAULT_EVERY_S = 30.0
FAULT_ONLINE = f"identify_every_s = {FAULT_EVERY_S:g}\nwindow_s = 60\n"


# both in the slow set: 16 s of a real-time run for [3] (the fast set's budget, issue 39); the
# link's blips and the recorder's back-fill stay in the fast set (test_recorder.py,
# test_record_cli.py)
@pytest.mark.slow
@pytest.mark.parametrize("drops", [3, 12])
def test_link_drops_and_a_plc_restart_leave_the_schedule_going(tmp_path: Path, drops: int) -> None:
    """Link drops (1–2 s of wall time, 20–40 s of data) and one PLC restart mid-run.

    The service keeps going (no exception, the run ends on its duration), every drop is a
    link_down/link_up pair in the store, and windows keep coming on the schedule: their ends
    are first_end + k·identify_every_s, none twice, some after the last fault.
    """
    store = tmp_path / "faults.db"
    rng = random.Random(15)
    faults: list[str] = []
    with VirtualPlcThread(
        speed=FAULT_SPEED, setpoint_profile="run", seed=6, ring_size=RING
    ) as virtual:
        site = _site(virtual, store, FAULT_ONLINE)

        def watch(service: OnlineService, stop: Callable[[], None]) -> None:
            wait_until(lambda: _count(store, "windows") >= 1, 30.0, "a first window")

            def reconnected() -> bool:
                return service.recorder is not None and service.recorder.connected

            for i in range(drops):
                # one fault at a time: the recorder's reconnect backoff grows to 5 s, so wait
                # for its link_up before the next (else the faults merge into one outage)
                # the sleeps are the behaviour: faults at seeded random times, each drop 1–2 s
                # (5–10 ring polls), and 0.5 s for the recorder to notice one before the wait
                # for its reconnect
                wait_until(reconnected, 20.0, "the recorder back on the link")
                time.sleep(rng.uniform(0.5, 1.5))
                if i == drops // 2:
                    virtual.restart_plc()
                    faults.append("restart")
                    time.sleep(0.5)
                    continue
                virtual.stop_link()
                time.sleep(rng.uniform(1.0, 2.0))
                virtual.start_link()
                faults.append("drop")
                time.sleep(0.5)
            wait_until(reconnected, 20.0, "the recorder back on the link")
            after = _count(store, "windows")
            wait_until(
                lambda: _count(store, "windows") >= after + 2, 30.0, "windows after the faults"
            )
            stop()

        started = time.monotonic()
        service, lines = _run(site, 30.0 + 10.0 * drops, watch)
        wall = time.monotonic() - started
        try:
            windows = service.history.windows()
            read = service.store.read_events()
            events = [e.kind for e in read]
            info = service.store.info()
        finally:
            service.close()
    assert faults.count("restart") == 1
    assert events.count("link_down") >= drops  # a restart drops the link too
    assert events.count("link_up") == events.count("link_down")
    ends = [w["t_to"] for w in windows]
    _assert_on_schedule(ends, FAULT_EVERY_S)
    assert not any("Traceback" in line for line in lines)
    print(
        f"faults: {faults.count('drop')} drops + 1 restart in {wall:.1f} s wall: "
        f"{len(windows)} windows on schedule, {events.count('link_down')} link_down, "
        f"{info.rows} samples, {info.gaps} gaps, skipped {events.count('windows_skipped')}"
    )


def _children(pid: int) -> list[int]:
    """Direct children of ``pid`` (Linux /proc; empty elsewhere)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _service(site_file: Path, db: Path, duration_s: float = 120.0) -> subprocess.Popen[str]:
    """``fuelid online --config SITE --store DB --duration S``; its stderr to ``DB.N.log``."""
    logs = sorted(db.parent.glob(f"{db.name}.*.log"))
    with (db.parent / f"{db.name}.{len(logs)}.log").open("w", encoding="utf-8") as log:
        return subprocess.Popen(
            [sys.executable, "-m", "fuelid", "online", "--config", str(site_file),
             "--store", str(db), "--duration", f"{duration_s:g}"],
            stdout=subprocess.DEVNULL, stderr=log, text=True,
        )  # fmt: skip


def _kill_9(child: subprocess.Popen[str]) -> list[int]:
    """SIGKILL the service; its worker processes must not outlive it (returns any that did)."""
    workers = _children(child.pid)
    child.send_signal(signal.SIGKILL)
    child.wait(10.0)
    with contextlib.suppress(AssertionError):  # the ones left are returned, for the test to say
        wait_until(lambda: not any(_alive(p) for p in workers), 10.0, "the workers' exit")
    orphans = [p for p in workers if _alive(p)]
    for p in orphans:  # ours (started by the service we started): do not leave them running
        _kill_quietly(p)
    return orphans


def _kill_quietly(pid: int) -> None:
    import os

    with contextlib.suppress(OSError):
        os.kill(pid, signal.SIGKILL)


def _stop(child: subprocess.Popen[str], db: Path) -> str:
    """SIGTERM (a clean stop); the newest service log."""
    if child.poll() is None:
        child.send_signal(signal.SIGTERM)
    try:
        child.wait(30.0)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    logs = sorted(db.parent.glob(f"{db.name}.*.log"), key=lambda p: int(p.suffixes[-2][1:]))
    return logs[-1].read_text(encoding="utf-8")


def _fault_site(virtual: VirtualPlcThread, tmp_path: Path, db: Path, online: str) -> Path:
    site_file = tmp_path / "site.toml"
    site_file.write_text(
        virtual.site_text(store_url=f"sqlite:///{db}") + "\n[online]\n" + online,
        encoding="utf-8",
    )
    return site_file


def _more_windows_or_exit(db: Path, seen: int, child: subprocess.Popen[str]) -> Callable[[], bool]:
    return lambda: _count(db, "windows") > seen or child.poll() is not None


def _intent_or_exit(db: Path, pid: int, child: subprocess.Popen[str]) -> Callable[[], bool]:
    query = "SELECT 1 FROM writes WHERE proposal_id = ? AND status = 'intent'"
    return lambda: bool(_sql(db, query, pid)) or child.poll() is not None


def _windows_in(db: Path) -> list[tuple[int, float]]:
    return [(int(i), float(t)) for i, t in _sql(db, "SELECT id, t_to FROM windows ORDER BY id")]


@pytest.mark.slow
@pytest.mark.parametrize("kills", [5])
def test_kill_9_mid_window_loses_nothing_committed_and_the_schedule_goes_on(
    tmp_path: Path, kills: int
) -> None:
    """``kill -9`` of ``fuelid online`` while it analyses windows, then the same command again.

    Killed at a random moment after its first window (windows every 1.5 s of wall time, each
    taking a good part of it): the samples committed before the kill are all there after it,
    the windows go on with increasing ids and no end twice, on the schedule
    first_end + k·identify_every_s; the analysis worker dies with the service.
    """
    db = tmp_path / "kill.db"
    rng = random.Random(9)
    orphans: list[int] = []
    history: list[tuple[int, int, int]] = []  # (samples, windows) before each kill, after
    with VirtualPlcThread(
        speed=FAULT_SPEED, setpoint_profile="run", seed=7, ring_size=RING,
        heartbeat_timeout_s=1e6,
    ) as virtual:  # fmt: skip
        site_file = _fault_site(virtual, tmp_path, db, FAULT_ONLINE)
        started = time.monotonic()
        for _ in range(kills):
            seen = _count(db, "windows")
            child = _service(site_file, db)
            try:
                wait_until(_more_windows_or_exit(db, seen, child), 60.0, "a window of the service")
                assert child.poll() is None, _stop(child, db)
                time.sleep(rng.uniform(0.0, 1.5))  # the behaviour: a kill at a seeded random point
                samples_before, windows_before = _count(db, "samples"), _windows_in(db)
                orphans += _kill_9(child)
            finally:
                if child.poll() is None:
                    child.kill()
                    child.wait()
            assert _count(db, "samples") >= samples_before
            assert _windows_in(db)[: len(windows_before)] == windows_before
            history.append((samples_before, len(windows_before), _count(db, "samples")))
        # the last restart runs to a few windows more and stops cleanly
        seen = _count(db, "windows")
        child = _service(site_file, db)
        try:
            wait_until(_more_windows_or_exit(db, seen + 1, child), 60.0, "two windows after it")
        finally:
            err = _stop(child, db)
        wall = time.monotonic() - started
    assert child.returncode == 0, err
    assert "Traceback" not in err
    con = sqlite3.connect(db)
    try:
        assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    finally:
        con.close()
    windows = _windows_in(db)
    ids = [i for i, _ in windows]
    assert ids == sorted(ids)
    _assert_on_schedule([t for _, t in windows], FAULT_EVERY_S)
    print(
        f"kill -9 mid-window: {kills} kills, {len(windows)} windows, {history}, wall {wall:.1f} s"
    )
    assert not orphans, f"analysis worker processes outlived the killed service: {orphans}"


@pytest.mark.parametrize("kills", [1, pytest.param(4, marks=pytest.mark.slow)])
def test_kill_9_mid_write_is_reconciled_from_the_echo_and_never_written_twice(
    tmp_path: Path, kills: int
) -> None:
    """``kill -9`` of ``fuelid online`` while a write of gains waits for its echo.

    The write is made to wait deterministically: the virtual PLC's heartbeat timeout is
    10 ms of plant time, so to the PLC the advisor's heartbeat is always stale and it refuses
    the staged set (status bit 2, echo unchanged), and ``echo_timeout_s = 30`` keeps the
    service waiting with the intent open in the store. Each round approves a proposal, starts
    the service, kills it once the intent is committed; the next start reconciles it from the
    echo (not applied: the echo never moved) before it writes anything. At the end: every
    write reconciled, none left open, no proposal with two writes (and none verified twice),
    the PLC's gains the old set, never a mix.
    """
    db = tmp_path / "write.db"
    rng = random.Random(21)
    online = (
        'identify_every_s = 3600\nwindow_s = 3600\nwrite_back = "approve"\necho_timeout_s = 30\n'
    )
    orphans: list[int] = []
    pids: list[int] = []
    with VirtualPlcThread(
        speed=FAULT_SPEED, setpoint_profile="run", seed=8, ring_size=RING,
        heartbeat_timeout_s=0.01,
    ) as virtual:  # fmt: skip
        site_file = _fault_site(virtual, tmp_path, db, online)
        site = ServiceSite.model_validate(tomllib.loads(site_file.read_text(encoding="utf-8")))
        kc0, ti0 = virtual.plc.gains
        started = time.monotonic()
        for k in range(kills):
            pid = _approve(site, db, round((1.2 + 0.05 * k) * kc0, 6), round(ti0, 6))
            pids.append(pid)
            child = _service(site_file, db)
            try:
                wait_until(_intent_or_exit(db, pid, child), 60.0, "the write's intent")
                assert child.poll() is None, _stop(child, db)
                # the behaviour: a kill at a seeded random point (the echo is awaited for 30 s)
                time.sleep(rng.uniform(0.2, 2.0))
                orphans += _kill_9(child)
            finally:
                if child.poll() is None:
                    child.kill()
                    child.wait()
            open_writes = _sql(db, "SELECT proposal_id FROM writes WHERE status = 'intent'")
            assert open_writes == [(pid,)]  # the earlier ones reconciled by this start
            assert virtual.plc.gains == (kc0, ti0)
        child = _service(site_file, db)  # the last start reconciles the last write
        try:

            def reconciled() -> bool:  # every write closed, its proposal failed, its event
                failed = {
                    p for (p,) in _sql(db, "SELECT id FROM proposals WHERE status = 'failed'")
                }
                return child.poll() is not None or (
                    not _sql(db, "SELECT 1 FROM writes WHERE status = 'intent'")
                    and failed >= set(pids)
                    and len(_sql(db, "SELECT 1 FROM events WHERE kind = 'write_reconciled'"))
                    >= kills
                )

            wait_until(reconciled, 60.0, "the reconciliation")
        finally:
            err = _stop(child, db)
        wall = time.monotonic() - started
        gains = virtual.plc.gains
    assert child.returncode == 0, err
    assert "Traceback" not in err
    writes = _sql(db, "SELECT proposal_id, status, kind FROM writes ORDER BY id")
    statuses = dict(_sql(db, "SELECT id, status FROM proposals"))
    events = _sql(db, "SELECT kind FROM events WHERE kind = 'write_reconciled'")
    assert [(p, s, k) for p, s, k in writes] == [(p, "not_applied", "proposal") for p in pids]
    for pid in pids:  # one write each, never verified twice
        assert sum(1 for p, _, _ in writes if p == pid) == 1
        assert statuses[pid] == "failed"
    assert len(events) == kills
    assert gains == (kc0, ti0)  # the old set (the PLC refused every new one), no mix
    print(f"kill -9 mid-write: {kills} kills, writes {writes}, wall {wall:.1f} s")
    assert not orphans, f"analysis worker processes outlived the killed service: {orphans}"


@pytest.mark.slow
def test_kill_9_during_a_window_s_revert_does_not_repeat_the_window(tmp_path: Path) -> None:
    """The gap between a window's record and the schedule's next end, made wide on purpose.

    The history says one of our writes was made (``last_write``, with a tiny IAE before it), so
    the first window with setpoint steps reverts, from inside the window's processing; the PLC
    refuses the revert (its heartbeat is always stale to it) and ``echo_timeout_s = 30`` keeps
    the service waiting for the echo. Killed then and restarted, the service must go on with
    the next window, not record the same window end again. (At half the speed of the other
    fault tests, so that a restart takes less than the three windows of data after which the
    schedule skips overdue windows anyway.)
    """
    db = tmp_path / "revert.db"
    online = f'{FAULT_ONLINE}write_back = "approve"\necho_timeout_s = 30\n'
    with VirtualPlcThread(
        speed=FAULT_SPEED / 2, setpoint_profile="run", seed=10, ring_size=RING,
        heartbeat_timeout_s=0.01,
    ) as virtual:  # fmt: skip
        site_file = _fault_site(virtual, tmp_path, db, online)
        site = ServiceSite.model_validate(tomllib.loads(site_file.read_text(encoding="utf-8")))
        opened, history = _open(site, db)
        try:
            history.set_state(
                "last_write",
                {"proposal": None, "time": 0.0, "data_time": 0.0, "iae_before": 1e-6,
                 "judged": False},
            )  # fmt: skip
            # last-known-good gains other than the PLC's, so the revert has a block to write (a
            # revert to the gains the PLC already runs is not written)
            kc0, ti0 = virtual.plc.gains
            history.set_state("last_known_good", {"Kc": 0.9 * kc0, "Ti": ti0})
        finally:
            history.close()
            opened.close()
        query = "SELECT 1 FROM writes WHERE kind = 'revert' AND status = 'intent'"
        child = _service(site_file, db)
        try:
            wait_until(lambda: bool(_sql(db, query)) or child.poll() is not None, 60.0, "a revert")
            assert child.poll() is None, _stop(child, db)
            windows_before = _windows_in(db)
            _kill_9(child)
        finally:
            if child.poll() is None:
                child.kill()
                child.wait()
        child = _service(site_file, db)
        try:
            seen = len(windows_before)
            wait_until(_more_windows_or_exit(db, seen, child), 60.0, "a window after the restart")
        finally:
            _kill_9(child)
    ends = [t for _, t in _windows_in(db)]
    assert len(ends) == len(set(ends)), f"window end recorded twice: {ends}"
