"""What the virtual PLC's operator does over time: setpoint, manual command and fuel temperature.

The run profiles of ``fuelid plant serve`` and ``fuelid online --virtual`` (this module was
``fuelid.plc.virtual.profiles`` before 0.2.0).

A profile is a table of breakpoints (t [s], value), linearly interpolated between rows; two rows
at the same t make a step. Setpoint and command profiles repeat, the last row's t being the
length of the cycle; a fuel-temperature profile plays once and is held after its last row.

Profile files are CSV with a header row: a column ``t`` (or ``t_s``) in seconds and one value
column, ``setpoint`` (L/min), ``u`` (V) or ``fuel_temperature`` (degC); the unit-suffixed names
``setpoint_Lpm``, ``u_V`` and ``T_fuel_degC`` are accepted too.

Examples
--------
>>> p = Profile([0.0, 10.0, 10.0, 20.0], [1.0, 1.0, 2.0, 2.0], repeat=True)
>>> p.at(5.0), p.at(10.0), p.at(25.0)
(1.0, 2.0, 1.0)
>>> ramp = Profile([0.0, 10.0], [0.0, 5.0])
>>> ramp.at(4.0), ramp.at(99.0)
(2.0, 5.0)
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fuelid.errors import ConfigError

FloatArray = NDArray[np.float64]

PROFILE_COLUMNS = {
    "setpoint": ("setpoint", "setpoint_Lpm"),
    "u": ("u", "u_V", "command"),
    "fuel_temperature": ("fuel_temperature", "T_fuel_degC", "fuel_temperature_degC"),
}
"""Value column names accepted in a profile file, by kind."""
TIME_COLUMNS = ("t", "t_s")


class Profile:
    """Breakpoints (t [s], value) read by linear interpolation; duplicated t make steps.

    Parameters
    ----------
    times : array_like
        Non-decreasing breakpoint times [s], starting at 0 or later.
    values : array_like
        Values at the breakpoints (the unit of the quantity profiled).
    repeat : bool
        True: the profile repeats with the last time as its cycle length; False: the first and
        last values are held outside the table.
    """

    def __init__(self, times: ArrayLike, values: ArrayLike, repeat: bool = False) -> None:
        t = np.asarray(times, dtype=float).ravel()
        v = np.asarray(values, dtype=float).ravel()
        if t.size == 0 or t.size != v.size:
            raise ConfigError("a profile needs as many values as times, at least one")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
            raise ConfigError("a profile's times and values must be finite numbers")
        if np.any(np.diff(t) < 0.0) or t[0] < 0.0:
            raise ConfigError("a profile's times must start at 0 or later and never decrease")
        if repeat and not t[-1] > 0.0:
            raise ConfigError("a repeating profile needs a last time > 0 s (its cycle length)")
        self.times: FloatArray = t
        self.values: FloatArray = v
        self.repeat = repeat

    @property
    def cycle_s(self) -> float:
        """Length of one cycle [s] (the last breakpoint's time)."""
        return float(self.times[-1])

    def at(self, t: float) -> float:
        """The value at time ``t`` [s]: the last row at or before t, interpolated to the next."""
        if self.repeat:
            t = math.fmod(t, self.cycle_s)
        times, values = self.times, self.values
        i = int(np.searchsorted(times, t, side="right")) - 1
        if i < 0:
            return float(values[0])
        if i >= times.size - 1:
            return float(values[-1])
        # side="right" lands past duplicated times, so t0 < t1 here and a step takes its new
        # value exactly at its time
        t0, t1 = times[i], times[i + 1]
        return float(values[i] + (values[i + 1] - values[i]) * (t - t0) / (t1 - t0))


def run_profile() -> Profile:
    """A wind-tunnel run of 270 s in AUTO, repeated: setpoints [L/min] for the reference plant.

    Ignition at 18 L/min for 30 s, a 30 s ramp to the first test point (40 L/min), four test
    points 30 s each (50, 35, 55, 45 L/min), a 30 s ramp down and 30 s at the shutdown flow.
    Every setpoint lies inside what the reference plant delivers at 1–5 V (about 15–67 L/min
    at 20 °C, ``fuelid plant info``), so the PI does not sit at a limit.
    """
    rows = [
        (0.0, 18.0),
        (30.0, 18.0),
        (60.0, 40.0),
        (90.0, 40.0),
        (90.0, 50.0),
        (120.0, 50.0),
        (120.0, 35.0),
        (150.0, 35.0),
        (150.0, 55.0),
        (180.0, 55.0),
        (180.0, 45.0),
        (210.0, 45.0),
        (240.0, 18.0),
        (270.0, 18.0),
    ]
    t, v = zip(*rows, strict=True)
    return Profile(t, v, repeat=True)


DEMO_TEMPERATURE_C = (-10.0, 45.0)
"""The fuel temperature's range over the virtual run's day [°C]."""
DEMO_DAY_S = 86400.0
"""Period of the virtual run's fuel-temperature cycle [s of plant time]."""
DEMO_TEST_POINTS_LPM = (30.0, 45.0, 25.0, 50.0, 35.0, 40.0)
"""Test points of :func:`demo_run_profile` [L/min]."""


def demo_run_profile(seed: int = 7) -> Profile:
    """Wind-tunnel runs in AUTO for the virtual PLC: test points held for minutes, with trims.

    Six test points (30, 45, 25, 50, 35 and 40 L/min), each reached by a 20 s ramp and held
    for 5 min, with setpoint trims of ±2–3 L/min every 60–90 s (each trim returns to the test
    point at the next change); a 20 s ramp down to 20 L/min and a minute there between runs.
    The cycle (about 35 min) repeats. Every setpoint lies inside what the reference plant gives
    at 1–5 V over −10…+45 °C (about 15–65 L/min), so the PI does not sit at a limit.
    (``fuelid online --virtual`` plays it.)
    """
    rng = np.random.default_rng(seed)
    t, v, now = [0.0], [20.0], 0.0
    for point in DEMO_TEST_POINTS_LPM:
        now += 20.0
        t.append(now)
        v.append(point)
        end, level = now + 300.0, point
        while now < end:
            nxt = min(now + float(rng.uniform(60.0, 90.0)), end)
            t.append(nxt)
            v.append(level)
            trim = float(rng.choice([-1.0, 1.0]) * rng.uniform(2.0, 3.0))
            level = point + trim if level == point and nxt < end else point
            t.append(nxt)
            v.append(level)
            now = nxt
    t += [now + 20.0, now + 80.0]
    v += [20.0, 20.0]
    return Profile(t, v, repeat=True)


def demo_temperature(
    duration_s: float,
    period_s: float = DEMO_DAY_S,
    range_C: tuple[float, float] = DEMO_TEMPERATURE_C,
) -> tuple[list[float], list[float]]:
    """The fuel temperature of the virtual run: a sinusoid over −10…+45 °C, from −10 °C.

    Parameters
    ----------
    duration_s : float
        Plant time to cover [s].
    period_s : float
        Period of the cycle [s] (default a day, as ``fuelid online --virtual`` plays it).
    range_C : (float, float)
        Lowest and highest temperature [°C].

    Returns
    -------
    (times [s], temperatures [°C])
        At most 2000 points, at least one a minute.

    Examples
    --------
    >>> times, temps = demo_temperature(86400.0)
    >>> round(min(temps), 6), round(max(temps), 6), temps[0]
    (-10.0, 45.0, -10.0)
    """
    low, high = range_C
    step = max(60.0, duration_s / 2000.0)
    n = math.ceil(duration_s / step) + 2
    times = [i * step for i in range(n)]
    mid, amp = 0.5 * (low + high), 0.5 * (high - low)
    return times, [mid - amp * math.cos(2.0 * math.pi * t / period_s) for t in times]


STEP_LEVELS_V = (3.0, 3.5, 2.5, 4.0, 2.0, 4.5, 1.5, 3.0, 2.0, 4.0)
"""Command levels [V] of :func:`steps_profile`: within 1.5–4.5 V, steps up and down of
0.5–3 V."""
STEP_DWELL_S = 15.0
"""How long :func:`steps_profile` holds each level [s]: about three 98 % settling times of the
reference plant (5.3 s), so each step settles."""


def steps_profile(
    levels: tuple[float, ...] = STEP_LEVELS_V, dwell_s: float = STEP_DWELL_S
) -> Profile:
    """MAN command steps for open-loop identification, repeated (150 s by default) [V]."""
    t: list[float] = []
    v: list[float] = []
    for i, level in enumerate(levels):
        t += [i * dwell_s, (i + 1) * dwell_s]
        v += [level, level]
    return Profile(t, v, repeat=True)


def load_profile(path: str | Path, kind: str) -> Profile:
    """Read a profile CSV (columns ``t`` [s] and the value column of ``kind``).

    Parameters
    ----------
    path : str or Path
        The CSV file.
    kind : {"setpoint", "u", "fuel_temperature"}
        Which quantity: setpoint and u profiles repeat, a fuel temperature is held at the end.

    Raises
    ------
    ConfigError
        One line naming the file and what is wrong (missing column, non-numeric cell, …).
    """
    source = str(path)
    names = PROFILE_COLUMNS[kind]
    try:
        with Path(path).open(encoding="utf-8-sig", newline="") as handle:
            rows = list(csv.DictReader(handle))
    except FileNotFoundError:
        raise ConfigError(f"profile {source!r} does not exist") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ConfigError(f"cannot read profile {source!r}: {exc}") from None
    header = [name.strip() for name in (rows[0].keys() if rows else [])]
    time_col = next((c for c in TIME_COLUMNS if c in header), None)
    value_col = next((c for c in names if c in header), None)
    if time_col is None or value_col is None:
        raise ConfigError(
            f"profile {source!r}: needs columns t (s) and {names[0]}; it has "
            f"{', '.join(header) or 'no rows'}"
        )
    times, values = [], []
    for line, row in enumerate(rows, start=2):
        clean = {key.strip(): (cell or "").strip() for key, cell in row.items() if key}
        try:
            times.append(float(clean[time_col]))
            values.append(float(clean[value_col]))
        except ValueError:
            raise ConfigError(
                f"profile {source!r} line {line}: {clean[time_col]!r}, {clean[value_col]!r} "
                "are not numbers"
            ) from None
    try:
        return Profile(times, values, repeat=kind != "fuel_temperature")
    except ConfigError as exc:
        raise ConfigError(f"profile {source!r}: {exc}") from None
