"""Windows of the virtual PLC's engine for the online window's tests (no Modbus, no store).

The engine (:class:`fuelid.plc.virtual._engine.VirtualPLC`) is advanced in chunks shorter than
its ring, and its ring records (seq, command, flow, setpoint) become the samples the recorder
would store, all of quality OK; the fuel temperature and the mode are read once per chunk (they
change slowly or not at all). Units: time [s UTC], u [V], y and setpoint [L/min], [°C].
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

from fuelid.plc.virtual import VirtualPLC
from fuelid.store import Quality, SampleArrays

T0 = 1.8e9
"""An epoch for the sample times [s UTC]."""
CHUNK = 1000
"""Samples per engine advance (under the ring's 2048)."""


def local_setpoints(
    centre: float = 40.0, steps: tuple[float, ...] = (0.0, 2.0, -1.0, 3.0, 0.0, -2.0, 1.0, -1.0)
) -> tuple[list[float], list[float]]:
    """Setpoint steps around ``centre`` held 30 s each, as (times [s], setpoints [L/min])."""
    t: list[float] = []
    v: list[float] = []
    for i, step in enumerate(steps):
        t += [30.0 * i, 30.0 * (i + 1)]
        v += [centre + step, centre + step]
    return t, v


def engine_windows(
    plc: VirtualPLC, n_windows: int, window_s: float = 600.0, skip_s: float = 0.0
) -> Iterator[tuple[SampleArrays, float, float]]:
    """Consecutive windows (samples, t_from, t_to) of ``plc``, after ``skip_s`` of run-in."""
    h = plc.period_s
    plc.advance(round(skip_s / h))
    per_window = round(window_s / h)
    k = round(skip_s / h)
    for _ in range(n_windows):
        cols: list[np.ndarray[Any, Any]] = []
        temps: list[float] = []
        modes: list[int] = []
        left = per_window
        while left:
            m = min(CHUNK, left)
            records = plc.advance(m)
            block = np.array(list(records.values()))
            cols.append(block)
            p = plc.read_points()
            temps += [p["fuel_temperature"]] * m
            modes += [int(p["mode"])] * m
            left -= m
        rows = np.concatenate(cols)
        time = T0 + h * (k + np.arange(per_window))
        samples = SampleArrays(
            time=time,
            seq=rows[:, 0].astype(np.int64),
            u=rows[:, 1].astype(float),
            y=rows[:, 2].astype(float),
            setpoint=rows[:, 3].astype(float),
            fuel_temperature=np.asarray(temps, dtype=float),
            mode=np.asarray(modes, dtype=np.int64),
            quality=np.full(per_window, int(Quality.OK), dtype=np.int64),
        )
        yield samples, float(time[0]), float(time[0] + window_s)
        k += per_window
