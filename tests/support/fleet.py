"""Loops for the many-loops tests (issue 26): hours of a virtual loop written to a store offline.

:func:`simulate_loop` advances the virtual PLC's engine (not in real time: a few seconds for
hours of plant time at 10 Hz) and writes its samples and a ``restart`` event into a site's
SQLite store with the loop's id, as the recorder would. :func:`analyse_loop` then runs the
online service's own window analysis over the stored samples and records each window (and the
accepted windows' models) in the store's history, as the service's scheduler does, so that the
store holds windows, models and events like a store a service ran beside a PLC.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fuelid.online import Online, WindowAnalyser, window_priors
from fuelid.plc.virtual import VirtualPLC
from fuelid.store import Event, OnlineHistory, Quality, Sample, SQLiteStore

T0 = 1_767_225_600.0
"""2026-01-01 00:00:00 UTC [s]: the first sample's plant time unless told otherwise."""


@dataclass(frozen=True)
class SimulatedLoop:
    """A store written by :func:`simulate_loop`."""

    path: Path
    loop_id: str
    site_name: str
    period_s: float
    t_first: float
    t_last: float
    samples: int


def _steps(levels: tuple[float, ...], dwell_s: float) -> tuple[list[float], list[float]]:
    times: list[float] = []
    values: list[float] = []
    for i, level in enumerate(levels):
        times += [i * dwell_s, (i + 1) * dwell_s]
        values += [level, level]
    return times, values


def simulate_loop(
    path: Path,
    loop_id: str,
    *,
    hours: float,
    seed: int,
    period_s: float = 0.1,
    start: float = T0,
    mode: str = "AUTO",
    plant: Any = None,
    fuel_temp_C: float = 20.0,
    fuel_temp_profile: tuple[list[float], list[float]] | None = None,
    bad: Callable[[np.ndarray[Any, Any]], np.ndarray[Any, Any]] | None = None,
) -> SimulatedLoop:
    """Write ``hours`` of a virtual loop into the store at ``path`` (created or extended).

    Parameters
    ----------
    path : Path
        The SQLite store.
    loop_id : str
        ``[site] loop_id``; the site name is ``"fuel line <loop_id>"``.
    hours : float
        Plant time to simulate [h].
    seed : int
        The engine's noise seed.
    period_s : float
        Sample period [s] (10 Hz by default: tests stay fast; the analysis is rate-free).
    start : float
        Plant time of the first sample [s UTC].
    mode : "AUTO" or "MAN"
        Setpoint steps around 40 L/min (AUTO) or command steps around 3 V (MAN).
    plant : PlantConfig, optional
        The plant (the reference plant when None).
    fuel_temp_C, fuel_temp_profile
        A constant fuel temperature [°C], or (times [s from start], temperatures [°C]).
    bad : callable, optional
        Given the sample times, a boolean mask of samples to store with missing values (u, y
        and the temperature NULL, quality ``bad_value``): NULL round-trips in the archive tests.
    """
    profile: dict[str, Any]
    if mode == "AUTO":
        profile = {"setpoint_profile": _steps((40.0, 42.0, 39.0, 43.0, 40.0, 38.0), 40.0)}
    else:
        profile = {"command_profile": _steps((3.0, 3.2, 2.9, 3.3, 3.0, 2.8), 20.0)}
    plc = VirtualPLC(
        plant,
        period_s=period_s,
        seed=seed,
        fuel_temp_C=fuel_temp_C,
        fuel_temp_profile=fuel_temp_profile,
        **profile,
    )
    n = round(hours * 3600.0 / period_s)
    site_name = f"fuel line {loop_id}"
    store = SQLiteStore(
        path,
        site_name=site_name,
        tag_map_hash=f"hash-{loop_id}",
        period_s=period_s,
        loop_id=loop_id,
    )
    try:
        first_seq = store.last_seq()
        seq0 = 0 if first_seq is None else first_seq + 1
        store.append_events([Event(start, "restart", "simulated loop (tests/support/fleet.py)")])
        # advance a ring's worth at a time and take the records from the ring (seq, command,
        # flow, setpoint); the fuel temperature and the mode as the PLC reports them at the
        # chunk's end (the temperature drifts over hours, a chunk is minutes)
        done = 0
        while done < n:
            count = min(plc.ring_size - 1, n - done)
            records = np.array(list(plc.advance(count).values()))
            points = plc.read_points()
            times = start + (done + np.arange(count)) * period_s
            u, y, setpoint = records[:, 1].copy(), records[:, 2].copy(), records[:, 3]
            temperature = np.full(count, points["fuel_temperature"])
            quality = np.full(count, int(Quality.OK))
            if bad is not None:
                mask = bad(times)
                u[mask] = y[mask] = temperature[mask] = math.nan
                quality[mask] = int(Quality.BAD_VALUE)
            store.append_samples(
                Sample(
                    float(t),
                    seq0 + done + i,
                    float(a),
                    float(b),
                    float(c),
                    float(d),
                    int(points["mode"]),
                    int(q),
                )
                for i, (t, a, b, c, d, q) in enumerate(
                    zip(times, u, y, setpoint, temperature, quality, strict=True)
                )
            )
            done += count
        t_first, t_last = store.first_time(), store.last_time()
    finally:
        store.close()
    assert t_first is not None
    assert t_last is not None
    return SimulatedLoop(path, loop_id, site_name, period_s, t_first, t_last, n)


def analyse_loop(
    loop: SimulatedLoop,
    settings: Online | None = None,
    plant_path: str | None = None,
) -> int:
    """Run the service's window analysis over the stored samples and record every window.

    Windows end every ``identify_every_s`` from ``window_s`` after the first sample, each
    warm-started from the last accepted one, as the service runs them. Returns the windows
    recorded.
    """
    online = settings or Online()
    priors, k_plant = window_priors(plant_path, control_period=1.0)
    analyser = WindowAnalyser(online, priors, loop.period_s, k_plant=k_plant, step_ls=False)
    store = SQLiteStore(loop.path)
    history = OnlineHistory(store)
    recorded = 0
    try:
        end = loop.t_first + online.window_s
        while end <= loop.t_last + loop.period_s:
            samples = store.read(end - online.window_s, end)
            result = analyser.analyse(samples, end - online.window_s, end)
            analyser.accept(result)
            model = None
            if result.accepted and result.model is not None:
                model = {**(result.model_json() or {}), "T_fuel": result.T_fuel_C}
            history.add_window(
                t_from=result.t_from,
                t_to=result.t_to,
                accepted=result.accepted,
                reason=result.reason,
                T_fuel=result.T_fuel_C,
                u_mean=result.u_mean,
                detail=result.to_json(),
                model=model,
            )
            recorded += 1
            end += online.identify_every_s
    finally:
        store.close()
    return recorded


def checkpoint(path: Path) -> None:
    """Move a store's write-ahead log into its main file (a copy of the file is then whole)."""
    import sqlite3

    con = sqlite3.connect(path)
    try:
        con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    finally:
        con.close()


def copy_loop(loop: SimulatedLoop, folder: Path) -> SimulatedLoop:
    """A copy of a simulated loop's store in ``folder`` (checkpointed when it was built)."""
    import shutil

    folder.mkdir(parents=True, exist_ok=True)
    target = folder / loop.path.name
    shutil.copyfile(loop.path, target)
    return SimulatedLoop(
        target, loop.loop_id, loop.site_name, loop.period_s, loop.t_first, loop.t_last,
        loop.samples,
    )  # fmt: skip


def with_proposal(loop: SimulatedLoop) -> int:
    """A pending proposal on the loop's newest accepted model (as the service files one); its id."""
    store = SQLiteStore(
        loop.path, site_name=loop.site_name, tag_map_hash=f"hash-{loop.loop_id}",
        loop_id=loop.loop_id,
    )  # fmt: skip
    try:
        with OnlineHistory(store) as history:
            model_id = history.accepted_models(limit=1)[0]["id"]
            return history.add_proposal(
                model_id=model_id, old={"Kc": 0.10, "Ti": 2.0}, new={"Kc": 0.12, "Ti": 2.2},
                detail={"rule": "test"}, who="online", why="test proposal",
            )  # fmt: skip
    finally:
        store.close()
