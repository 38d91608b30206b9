"""Input profiles: the controller output as the PLC holds it (piecewise constant).

A profile is a list of change times and the command held from each change to the next. The
simulator aligns changes with the controller's update period (sample-and-hold of the PLC's
output) before it runs.

Generated profiles: :func:`step_profile`, :func:`step_sequence`, :func:`random_levels`; a table
of commands (from a file, read by :func:`fuelid.workflow._simulation.read_profile`, which sits above
both this module and :mod:`fuelid.io`): :func:`held_profile`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fuelid.errors import DataError, FuelidError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class InputProfile:
    """Piecewise-constant command: ``u[i]`` holds from ``t[i]`` until ``t[i+1]`` (or the end).

    Parameters
    ----------
    t : array
        Change times [s], strictly increasing, ``t[0] == 0``.
    u : array
        Command held from each change time [V].
    duration : float
        End of the profile [s], after the last change time.

    Examples
    --------
    >>> p = step_profile(1.0, 1.5, t_step=10.0, duration=30.0)
    >>> p.at([0.0, 9.99, 10.0, 29.0]).tolist()
    [1.0, 1.0, 1.5, 1.5]
    """

    t: FloatArray
    u: FloatArray
    duration: float

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float)
        u = np.asarray(self.u, dtype=float)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "u", u)
        if t.ndim != 1 or t.shape != u.shape or t.size == 0:
            raise FuelidError("an input profile needs as many change times as command values")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(u))):
            raise FuelidError("an input profile must hold finite times and commands")
        if t[0] != 0.0:
            raise FuelidError(f"an input profile must start at t = 0 s, not {t[0]:g} s")
        if np.any(np.diff(t) <= 0.0):
            raise FuelidError("the change times of an input profile must increase")
        if not (math.isfinite(self.duration) and self.duration > t[-1]):
            raise FuelidError(
                f"profile duration {self.duration:g} s must come after its last change {t[-1]:g} s"
            )

    def at(self, times: ArrayLike) -> FloatArray:
        """Command held at each of ``times`` [V] (zero-order hold, right-continuous)."""
        index = np.searchsorted(self.t, np.asarray(times, dtype=float), side="right") - 1
        return self.u[np.clip(index, 0, self.u.size - 1)]

    def aligned(self, control_period: float) -> InputProfile:
        """The profile as a controller updating every ``control_period`` s would apply it.

        Each change takes effect at the first controller update at or after it (changes that
        fall between two updates collapse onto the later value). ``control_period = 0`` means a
        continuous controller: the profile is returned unchanged.
        """
        if control_period <= 0.0:
            return self
        ticks = np.ceil(self.t / control_period - 1e-9) * control_period
        ticks = np.round(ticks, 12)
        keep = ticks < self.duration
        ticks, values = ticks[keep], self.u[keep]
        # a later change landing on the same tick wins
        last = np.r_[ticks[1:] != ticks[:-1], True]
        ticks, values = ticks[last], values[last]
        change = np.r_[True, values[1:] != values[:-1]]
        return InputProfile(ticks[change], values[change], self.duration)

    @property
    def u_range(self) -> tuple[float, float]:
        """Smallest and largest command [V]."""
        return float(self.u.min()), float(self.u.max())


def step_profile(u0: float, u1: float, t_step: float, duration: float) -> InputProfile:
    """A single step from ``u0`` to ``u1`` at ``t_step`` (the article's 1 V → 1.5 V experiment).

    Examples
    --------
    >>> step_profile(1.0, 1.5, 10.0, 40.0).u.tolist()
    [1.0, 1.5]
    """
    if not 0.0 < t_step < duration:
        raise FuelidError(f"step time {t_step:g} s must lie inside the run (0…{duration:g} s)")
    return InputProfile(np.array([0.0, t_step]), np.array([u0, u1]), duration)


def step_sequence(levels: Sequence[float], dwell: float) -> InputProfile:
    """Hold each level for ``dwell`` seconds, one after another.

    Examples
    --------
    >>> p = step_sequence([1.0, 2.0, 1.5], dwell=30.0)
    >>> p.t.tolist(), p.duration
    ([0.0, 30.0, 60.0], 90.0)
    """
    if len(levels) == 0:
        raise FuelidError("a step sequence needs at least one level")
    if not (math.isfinite(dwell) and dwell > 0.0):
        raise FuelidError(f"dwell time must be positive, got {dwell:g} s")
    t = dwell * np.arange(len(levels), dtype=float)
    return InputProfile(t, np.asarray(levels, dtype=float), dwell * len(levels))


def random_levels(
    levels: Sequence[float],
    hold: float,
    duration: float,
    seed: int | None = None,
    settle: float = 0.0,
) -> InputProfile:
    """A random binary (two levels) or multilevel sequence with a minimum hold time.

    Every ``hold`` seconds a level is drawn uniformly from ``levels``; with two levels this is
    a random binary sequence whose switching probability is 1/2 per hold interval. The first
    ``settle`` seconds hold the first level so the record starts at rest.

    Parameters
    ----------
    levels : sequence of float
        Allowed commands [V], at least two.
    hold : float
        Minimum time between changes [s] (a multiple of the control period is sensible).
    duration : float
        Length of the run [s].
    seed : int, optional
        Seed for reproducibility.
    settle : float
        Initial time at the first level [s].

    Examples
    --------
    >>> p = random_levels([1.0, 2.0], hold=5.0, duration=100.0, seed=1)
    >>> set(p.u.tolist()) <= {1.0, 2.0}, bool(np.all(np.diff(p.t) >= 5.0))
    (True, True)
    """
    if len(levels) < 2:
        raise FuelidError("a random sequence needs at least two levels")
    if not (math.isfinite(hold) and hold > 0.0):
        raise FuelidError(f"hold time must be positive, got {hold:g} s")
    if not (math.isfinite(settle) and 0.0 <= settle < duration):
        raise FuelidError(f"settling time {settle:g} s must lie inside the run")
    rng = np.random.default_rng(seed)
    starts = np.arange(settle, duration, hold)
    draws = rng.choice(np.asarray(levels, dtype=float), size=starts.size)
    t = np.r_[0.0, starts] if settle > 0.0 else starts
    u = np.r_[levels[0], draws] if settle > 0.0 else draws
    change = np.r_[True, u[1:] != u[:-1]]
    return InputProfile(
        np.asarray(t[change], dtype=float), np.asarray(u[change], dtype=float), duration
    )


def held_profile(
    t: ArrayLike, u: ArrayLike, duration: float | None = None, source: str = "the profile"
) -> InputProfile:
    """The profile of a table of commands, each held from its row's time to the next row's.

    Rows that repeat the previous command are merged into one change.

    Parameters
    ----------
    t : array
        Row times [s]: starting at 0 and strictly increasing.
    u : array
        Command of each row [V].
    duration : float, optional
        End of the profile [s], after the last row. By default the last row is held for the
        previous interval (for 1 s when the table has a single row).
    source : str
        Where the table came from (a file name), for messages.

    Returns
    -------
    InputProfile

    Raises
    ------
    DataError
        If the times do not start at 0 and increase strictly, or ``duration`` does not come
        after the last row.

    Examples
    --------
    >>> p = held_profile([0.0, 5.0, 10.0, 20.0], [1.0, 1.5, 1.5, 2.0])
    >>> p.t.tolist(), p.u.tolist(), p.duration
    ([0.0, 5.0, 20.0], [1.0, 1.5, 2.0], 30.0)
    >>> held_profile([0.0, 5.0], [1.0, 1.5], duration=5.0)
    Traceback (most recent call last):
    ...
    fuelid.errors.DataError: duration 5 s must exceed the profile's last time 5 s
    """
    times = np.asarray(t, dtype=float)
    commands = np.asarray(u, dtype=float)
    if times.ndim != 1 or times.shape != commands.shape:
        raise DataError(f"{source}: a profile needs one command per time")
    if times.size < 1 or times[0] != 0.0 or np.any(np.diff(times) <= 0.0):
        raise DataError(f"{source}: t_s must start at 0 and increase strictly")
    last = float(times[-1])
    if duration is None:
        end = last + (last - float(times[-2]) if times.size > 1 else 1.0)
    else:
        end = duration
    if not end > last:
        raise DataError(f"duration {end:g} s must exceed the profile's last time {last:g} s")
    change = np.r_[True, commands[1:] != commands[:-1]]
    return InputProfile(times[change], commands[change], end)
