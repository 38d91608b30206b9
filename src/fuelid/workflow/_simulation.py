"""What ``fuelid simulate`` runs: a PLC-like log of the nonlinear plant from a profile.

A :class:`SimulationRequest` names the command profile (a step, a step sequence, random levels or
a table read from a file by :func:`read_profile`), the fuel temperature [K] (constant, a ramp or
the file's trajectory), the sampling and the meter's noise; :func:`simulate_log` builds the
inputs (:func:`simulation_inputs`), runs :func:`fuelid.plant.simulate.simulate` and returns a
:class:`SimulationOutcome` whose :meth:`~SimulationOutcome.to_json` is the documented summary
(docs/reference/json.md). Nothing here writes the log: the caller writes
:meth:`SimulationOutcome.to_log`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fuelid.errors import DataError, FuelidError
from fuelid.io.tables import match_column, read_table, table_column
from fuelid.io.timeseries import (
    FUEL_TEMPERATURE_COLUMN,
    INPUT_COLUMN,
    OUTPUT_COLUMN,
    PRESSURE_COLUMN,
    TIME_COLUMN,
    TimeSeries,
)
from fuelid.plant import PlantConfig
from fuelid.plant.simulate import (
    PRESSURE_NOISE_STD,
    PRESSURE_RESOLUTION,
    FuelTemperature,
    SimulationResult,
    simulate,
)
from fuelid.profiles import InputProfile, held_profile, random_levels, step_profile, step_sequence
from fuelid.units import celsius_to_kelvin

PROFILES = ("step", "steps", "random", "file")
"""The profiles :class:`SimulationRequest` knows."""

DEFAULT_DURATIONS = {"step": 60.0, "random": 600.0}
"""Run length [s] of the profiles that have no natural end, when none is asked for."""

SIMULATION_UNITS = {"sample_time": "s", "duration": "s", "u_range": "V", "q_range": "L/min"}
"""Units of the numbers in :meth:`SimulationOutcome.to_json`."""


@dataclass(frozen=True)
class ProfileTable:
    """A command profile read from a file, with the file's fuel-temperature trajectory if any."""

    profile: InputProfile
    """The commands [V], each held from its row to the next."""
    T_fuel: FuelTemperature | None
    """The fuel temperature of the rows [K], interpolated between them; None without a column."""


def read_profile(path: str | Path, duration: float | None = None) -> ProfileTable:
    """Read a profile table: ``t_s`` [s], ``u_V`` [V] and optionally ``T_fuel_degC`` [°C].

    The table is read as logs are (:func:`fuelid.io.tables.read_table`: CSV-like text or
    Parquet, column names matched ignoring case and spaces). Each command is held from its row's
    time to the next row's (:func:`fuelid.profiles.held_profile`); the fuel temperature, when the
    table has the column, is interpolated linearly between rows and converted to kelvin.

    Parameters
    ----------
    path : str or Path
        The table.
    duration : float, optional
        End of the profile [s], after the last row; by default the last row is held for the
        previous interval.

    Returns
    -------
    ProfileTable

    Raises
    ------
    DataError
        If the file cannot be read, a column is missing or not numeric, the times do not start
        at 0 and increase, or a column looks like the fuel temperature but is not named
        ``T_fuel_degC`` (it would otherwise be ignored).
    """
    frame, _ = read_table(path)
    source = repr(str(path))
    t = table_column(frame, TIME_COLUMN, source)
    u = table_column(frame, INPUT_COLUMN, source)
    profile = held_profile(t, u, duration, source=str(path))
    column = match_column(frame, FUEL_TEMPERATURE_COLUMN)
    if column is None:
        _refuse_unread_temperature([str(name) for name in frame.columns], source)
        return ProfileTable(profile, None)
    temperatures = table_column(frame, column, source)
    kelvin = np.array([celsius_to_kelvin(float(value)) for value in temperatures])
    return ProfileTable(profile, FuelTemperature(t, kelvin))


def _refuse_unread_temperature(columns: list[str], source: str) -> None:
    """Refuse a column that looks like the fuel temperature but would not be read as it.

    Examples
    --------
    >>> _refuse_unread_temperature(["t_s", "u_V", "note", "T_inlet_degC"], "'p.csv'")
    >>> _refuse_unread_temperature(["t_s", "u_V", "T_fuel [degC]"], "'p.csv'")
    Traceback (most recent call last):
    ...
    fuelid.errors.DataError: 'p.csv' has a column 'T_fuel [degC]' that is not read as the fuel \
temperature; name it 'T_fuel_degC' (in °C, once)
    """
    looks = [name for name in columns if _squeezed(name).startswith("tfuel")]
    if looks:
        shown = ", ".join(repr(name) for name in looks)
        raise DataError(
            f"{source} has a column {shown} that is not read as the fuel temperature; name it "
            f"{FUEL_TEMPERATURE_COLUMN!r} (in °C, once)"
        )


def _squeezed(name: str) -> str:
    """``name`` in lower case without spaces, underscores and hyphens (``tfuel[k]``)."""
    return "".join(ch for ch in name.casefold() if ch not in " _-")


@dataclass(frozen=True)
class SimulationRequest:
    """What to simulate: the settings of ``fuelid simulate`` in the library's units.

    Settings that cannot be right whatever the plant are refused on construction
    (:class:`~fuelid.errors.FuelidError`); the rest when the profile is built or the plant run.
    """

    profile: str = "step"
    """One of :data:`PROFILES`: a single step, a step sequence, random levels, a file's table."""
    u0: float = 1.0
    """step: command before the step [V]."""
    u1: float = 1.5
    """step: command after the step [V]."""
    t_step: float = 10.0
    """step: time of the step [s]."""
    levels: tuple[float, ...] = (1.0, 1.5, 2.0, 1.5, 1.0)
    """steps and random: the command levels [V]."""
    dwell: float = 30.0
    """steps: time at each level [s]."""
    hold: float = 5.0
    """random: minimum time between changes [s], also the time at the first level."""
    input_file: Path | None = None
    """file: the table read by :func:`read_profile`."""
    duration: float | None = None
    """Length of the run [s]; None: :data:`DEFAULT_DURATIONS`, the sequence's or the file's."""
    sample_time: float = 0.02
    """PLC sampling interval [s]."""
    control_period: float = 1.0
    """Controller update period [s]; 0 applies changes at once."""
    noise_std: float | None = None
    """Flowmeter noise standard deviation [m³/s]; None: the plant's."""
    resolution: float | None = None
    """Quantisation step of the reading [m³/s]; None: the plant's."""
    T_fuel: float = 293.15
    """Fuel temperature at the start [K] (unless the file has a trajectory)."""
    T_fuel_end: float | None = None
    """Fuel temperature at the end [K], reached by a linear ramp; None: constant."""
    seed: int | None = 0
    """Seed of the noise and of random profiles."""
    truth: bool = False
    """Add the noise-free meter reading ``q_true_Lpm`` to the log."""
    pressure: bool = False
    """Also log the pump outlet pressure ``p_pump_MPa`` (a pressure transmitter's reading)."""
    pressure_noise_std: float = PRESSURE_NOISE_STD
    """The transmitter's white noise [Pa]."""
    pressure_resolution: float = PRESSURE_RESOLUTION
    """Quantisation step of the pressure the PLC reads [Pa]."""

    def __post_init__(self) -> None:
        if self.profile not in PROFILES:
            raise FuelidError(
                f"unknown profile {self.profile!r}; choose one of {', '.join(PROFILES)}"
            )
        if self.profile == "file" and self.input_file is None:
            raise FuelidError("a file profile needs an input file")
        if self.duration is not None and not (math.isfinite(self.duration) and self.duration > 0.0):
            raise FuelidError(f"the run duration must be positive, got {self.duration:g} s")
        for name, T in (("start", self.T_fuel), ("end", self.T_fuel_end)):
            if T is not None and not (math.isfinite(T) and T > 0.0):
                raise FuelidError(
                    f"the fuel temperature at the {name} must be a positive number of K, got {T:g}"
                )


@dataclass(frozen=True)
class SimulationInputs:
    """What the plant is driven with: the command profile and the fuel temperature."""

    profile: InputProfile
    """Commands [V] as the controller outputs them (before alignment to its period)."""
    T_fuel: FuelTemperature
    """Fuel temperature over the run [K]."""

    @property
    def duration(self) -> float:
        """Length of the run [s]."""
        return self.profile.duration


def simulation_inputs(request: SimulationRequest) -> SimulationInputs:
    """The profile and the fuel-temperature trajectory a request describes.

    Examples
    --------
    >>> inputs = simulation_inputs(
    ...     SimulationRequest(profile="steps", levels=(1.0, 2.0), dwell=10.0, T_fuel_end=313.15)
    ... )
    >>> inputs.profile.u.tolist(), inputs.duration, round(float(inputs.T_fuel.at(10.0)), 2)
    ([1.0, 2.0], 20.0, 303.15)
    """
    table_temperature: FuelTemperature | None = None
    duration = request.duration
    if request.profile == "step":
        end = DEFAULT_DURATIONS["step"] if duration is None else duration
        profile = step_profile(request.u0, request.u1, request.t_step, end)
    elif request.profile == "steps":
        profile = step_sequence(request.levels, request.dwell)
        if duration is not None:
            kept = profile.t < duration
            profile = InputProfile(profile.t[kept], profile.u[kept], duration)
    elif request.profile == "random":
        end = DEFAULT_DURATIONS["random"] if duration is None else duration
        profile = random_levels(
            request.levels, request.hold, end, seed=request.seed, settle=request.hold
        )
    elif request.input_file is None:
        raise FuelidError("a file profile needs an input file")
    else:
        table = read_profile(request.input_file, duration)
        profile, table_temperature = table.profile, table.T_fuel
    if table_temperature is not None:
        temperature = table_temperature
    elif request.T_fuel_end is None:
        temperature = FuelTemperature.constant(request.T_fuel)
    else:
        temperature = FuelTemperature.ramp(request.T_fuel, request.T_fuel_end, profile.duration)
    return SimulationInputs(profile, temperature)


@dataclass(frozen=True)
class SimulationOutcome:
    """A simulated log with what drove it: what ``fuelid simulate`` writes and reports."""

    request: SimulationRequest
    """What was asked."""
    inputs: SimulationInputs
    """The profile and the fuel temperature the plant was driven with."""
    result: SimulationResult
    """The sampled run (SI)."""

    def to_log(self) -> TimeSeries:
        """The PLC-like log: ``t_s``, ``u_V``, ``q_Lpm``, ``T_fuel_degC`` (+ ``q_true_Lpm``)."""
        return self.result.to_log(include_truth=self.request.truth)

    def to_json(self, output: str | Path | None = None) -> dict[str, Any]:
        """The JSON summary of ``fuelid simulate --json`` (without provenance).

        With ``request.pressure`` the summary ends with ``p_range``, the lowest and highest
        logged pump pressure [MPa].

        Parameters
        ----------
        output : str or Path, optional
            Where the caller wrote the log (the ``output`` key; null when not written).
        """
        log = self.to_log()
        q = log[OUTPUT_COLUMN]
        profile = self.inputs.profile
        summary: dict[str, Any] = {
            "output": None if output is None else str(output),
            "n_samples": int(self.result.time.size),
            "sample_time": self.request.sample_time,
            "duration": profile.duration,
            "profile": self.request.profile,
            "u_range": list(profile.u_range),
            "q_range": [float(q.min()), float(q.max())],
            "units": dict(SIMULATION_UNITS),
        }
        if self.request.pressure:
            p = log[PRESSURE_COLUMN]
            summary["units"]["p_range"] = "MPa"
            summary["p_range"] = [float(p.min()), float(p.max())]
        return summary


def simulate_log(
    config: PlantConfig,
    request: SimulationRequest,
    *,
    inputs: SimulationInputs | None = None,
    progress: Callable[[float], None] | None = None,
) -> SimulationOutcome:
    """Simulate ``config`` as ``request`` asks: the chain behind ``fuelid simulate``.

    The plant starts at rest at the first command; the controller output is held for
    ``request.control_period`` (:func:`fuelid.plant.simulate.simulate`).

    Parameters
    ----------
    config : PlantConfig
        The plant.
    request : SimulationRequest
        What to simulate.
    inputs : SimulationInputs, optional
        ``simulation_inputs(request)`` when the caller already built them (to know the run's
        length first, without reading a profile file twice).
    progress : callable, optional
        Called with the fraction of simulated time done.

    Returns
    -------
    SimulationOutcome

    Examples
    --------
    >>> from fuelid.plant import load_plant_config
    >>> request = SimulationRequest(u0=1.0, u1=1.5, t_step=1.0, duration=2.0, T_fuel=273.15)
    >>> outcome = simulate_log(load_plant_config(), request)
    >>> summary = outcome.to_json()
    >>> summary["n_samples"], summary["u_range"], outcome.to_log()["T_fuel_degC"].tolist()[-1]
    (101, [1.0, 1.5], 0.0)
    """
    if inputs is None:
        inputs = simulation_inputs(request)
    result = simulate(
        config,
        inputs.profile,
        T_fuel=inputs.T_fuel,
        sample_time=request.sample_time,
        control_period=request.control_period,
        noise_std=request.noise_std,
        resolution=request.resolution,
        seed=request.seed,
        progress=progress,
        pressure=request.pressure,
        pressure_noise_std=request.pressure_noise_std,
        pressure_resolution=request.pressure_resolution,
    )
    return SimulationOutcome(request=request, inputs=inputs, result=result)
