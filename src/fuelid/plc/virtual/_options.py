"""The virtual PLC's settings checked: its profiles, fuel temperature, limits and run windows.

The engine (:mod:`fuelid.plc.virtual._engine`) takes them as given by a test, the command line or
the runner, and refuses what it cannot run with a :class:`~fuelid.errors.ConfigError` naming the
setting.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TypeAlias

from numpy.typing import ArrayLike

from fuelid.errors import ConfigError
from fuelid.plant.simulate import FuelTemperature
from fuelid.profiles.runs import Profile, run_profile, steps_profile
from fuelid.units import celsius_to_kelvin

__all__ = [
    "ProfileLike",
    "fuel_temperature_trajectory",
    "positive",
    "run_windows_checked",
    "setpoint_and_command_profiles",
]

ProfileLike: TypeAlias = Profile | tuple[ArrayLike, ArrayLike]
"""A profile, or a pair (times [s], values) to make one of."""


def _as_profile(value: ProfileLike | None, repeat: bool, name: str) -> Profile | None:
    """A Profile as it is, or one made of a pair (times, values); None stays None."""
    if value is None or isinstance(value, Profile):
        return value
    try:
        times, values = value
    except (TypeError, ValueError):
        raise ConfigError(f"{name}: give a Profile or a pair (times, values)") from None
    return Profile(times, values, repeat=repeat)


def setpoint_and_command_profiles(
    setpoint_profile: str | ProfileLike | None, command_profile: str | ProfileLike | None
) -> tuple[Profile | None, Profile | None]:
    """The setpoint and command profiles, the built-ins ("run", "steps") made; one at most."""
    if setpoint_profile is not None and command_profile is not None:
        raise ConfigError("give a setpoint profile (AUTO) or a command profile (MAN), not both")
    if isinstance(setpoint_profile, str):
        if setpoint_profile != "run":
            raise ConfigError(f"setpoint_profile: {setpoint_profile!r}; the built-in is 'run'")
        setpoint_profile = run_profile()
    if isinstance(command_profile, str):
        if command_profile != "steps":
            raise ConfigError(f"command_profile: {command_profile!r}; the built-in is 'steps'")
        command_profile = steps_profile()
    return (
        _as_profile(setpoint_profile, True, "setpoint_profile"),
        _as_profile(command_profile, True, "command_profile"),
    )


def positive(name: str, value: float) -> float:
    """``value`` as a float, refused unless finite and positive."""
    if not (math.isfinite(value) and value > 0.0):
        raise ConfigError(f"{name} must be finite and positive, got {value!r}")
    return float(value)


def fuel_temperature_trajectory(
    fuel_temp_C: float, profile: Profile | FuelTemperature | tuple[ArrayLike, ArrayLike] | None
) -> FuelTemperature:
    """The trajectory in kelvin: a FuelTemperature is in K, a profile or a pair in °C."""
    if profile is None:
        return FuelTemperature.constant(celsius_to_kelvin(fuel_temp_C))
    if isinstance(profile, FuelTemperature):
        return profile
    p = _as_profile(profile, repeat=False, name="fuel_temp_profile")
    assert p is not None  # not None here
    return FuelTemperature(p.times.copy(), p.values + celsius_to_kelvin(0.0))


def run_windows_checked(windows: Sequence[tuple[float, float]]) -> tuple[tuple[float, float], ...]:
    """The run windows checked: pairs (start, end) [s], finite, start < end."""
    checked = []
    for window in windows:
        try:
            start, end = (float(v) for v in window)
        except (TypeError, ValueError):
            raise ConfigError(f"run window {window!r}: give (start, end) in seconds") from None
        if not (math.isfinite(start) and math.isfinite(end) and start < end):
            raise ConfigError(
                f"run window {window!r}: start and end must be finite with start < end [s]"
            )
        checked.append((start, end))
    return tuple(checked)
