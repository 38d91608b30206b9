"""``fuelid simulate``: write a PLC-like log of the nonlinear plant."""

from __future__ import annotations

import enum
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from fuelid.cli._common import celsius_to_kelvin, emit_json, guarded, provenance
from fuelid.errors import FuelidError
from fuelid.units import LPM_PER_M3S
from fuelid.units import T0 as KELVIN

if TYPE_CHECKING:
    from fuelid.profiles import InputProfile

#: simulated time above which a progress bar is shown [s]
PROGRESS_THRESHOLD = 600.0


class ProfileKind(enum.StrEnum):
    """The input profiles ``fuelid simulate`` can generate."""

    step = "step"
    steps = "steps"
    random = "random"
    file = "file"


def _levels(text: str) -> list[float]:
    try:
        values = [float(part) for part in text.replace(";", ",").split(",") if part.strip()]
    except ValueError:
        raise FuelidError(f"--levels must be comma-separated volts, got {text!r}") from None
    if not values or not all(math.isfinite(v) for v in values):
        raise FuelidError(f"--levels must be comma-separated finite volts, got {text!r}")
    return values


def _profile_from_file(path: Path, duration: float | None) -> tuple[InputProfile, Any]:
    """A command profile (``t_s``, ``u_V`` and optionally ``T_fuel_degC``) read from a table."""
    import numpy as np

    from fuelid.errors import DataError
    from fuelid.io.tables import read_table, table_column
    from fuelid.io.timeseries import FUEL_TEMPERATURE_COLUMN, INPUT_COLUMN, TIME_COLUMN
    from fuelid.profiles import InputProfile
    from fuelid.simulate import FuelTemperature

    frame, _ = read_table(path)
    source = repr(str(path))
    t = table_column(frame, TIME_COLUMN, source)
    u = table_column(frame, INPUT_COLUMN, source)
    if t.size < 1 or t[0] != 0.0 or np.any(np.diff(t) <= 0.0):
        raise DataError(f"{path}: {TIME_COLUMN} must start at 0 and increase strictly")
    end = (
        duration if duration is not None else float(t[-1]) + (t[-1] - t[-2] if t.size > 1 else 1.0)
    )
    if end <= t[-1]:
        raise DataError(f"--duration {end:g} s must exceed the profile's last time {t[-1]:g} s")
    change = np.r_[True, u[1:] != u[:-1]]
    profile = InputProfile(t[change], u[change], end)
    temperature = None
    if FUEL_TEMPERATURE_COLUMN in frame.columns:
        temps = table_column(frame, FUEL_TEMPERATURE_COLUMN, source)
        temperature = FuelTemperature(t, temps + KELVIN)
    return profile, temperature


@guarded
def simulate_command(
    output: Annotated[
        Path, typer.Argument(help="Log to write: .csv or .parquet (format by extension).")
    ],
    config: Annotated[
        Path | None,
        typer.Option(
            "--config", "-c", help="Plant TOML file (default: reference plant).", show_default=False
        ),
    ] = None,
    profile: Annotated[
        ProfileKind, typer.Option("--profile", "-p", help="Input profile to apply.")
    ] = ProfileKind.step,
    u0: Annotated[float, typer.Option(help="step: command before the step [V].")] = 1.0,
    u1: Annotated[float, typer.Option(help="step: command after the step [V].")] = 1.5,
    t_step: Annotated[float, typer.Option(help="step: time of the step [s].")] = 10.0,
    levels: Annotated[
        str, typer.Option(help="steps/random: comma-separated command levels [V].")
    ] = "1.0,1.5,2.0,1.5,1.0",
    dwell: Annotated[float, typer.Option(help="steps: time at each level [s].")] = 30.0,
    hold: Annotated[float, typer.Option(help="random: minimum time between changes [s].")] = 5.0,
    input_file: Annotated[
        Path | None,
        typer.Option(
            help="file: table with t_s, u_V (and optionally T_fuel_degC).", show_default=False
        ),
    ] = None,
    duration: Annotated[
        float | None,
        typer.Option(
            help="Length of the run [s] (step default 60, random default 600).", show_default=False
        ),
    ] = None,
    sample_time: Annotated[float, typer.Option(help="PLC sampling interval [s].")] = 0.02,
    control_period: Annotated[
        float, typer.Option(help="Controller update period [s]; 0 applies changes at once.")
    ] = 1.0,
    noise_std: Annotated[
        float | None,
        typer.Option(
            help="Flowmeter noise std [L/min] (default: the plant config's).", show_default=False
        ),
    ] = None,
    resolution: Annotated[
        float | None,
        typer.Option(
            help="Quantisation step of the reading [L/min] (default: config's).", show_default=False
        ),
    ] = None,
    fuel_temp: Annotated[float, typer.Option(help="Fuel temperature at the start [°C].")] = 20.0,
    fuel_temp_end: Annotated[
        float | None,
        typer.Option(
            help="Fuel temperature at the end [°C]: a linear ramp (default: constant).",
            show_default=False,
        ),
    ] = None,
    seed: Annotated[int | None, typer.Option(help="Seed of noise and random profiles.")] = 0,
    truth: Annotated[
        bool, typer.Option("--truth", help="Add q_true_Lpm, the noise-free meter reading.")
    ] = False,
    force: Annotated[bool, typer.Option("--force", help="Overwrite an existing file.")] = False,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print a JSON summary instead of text.")
    ] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
) -> None:
    """Simulate the nonlinear plant and write a PLC-like log (t_s, u_V, q_Lpm, T_fuel_degC).

    The plant starts at rest at the first command. Profiles: 'step' (the article's 1 V to 1.5 V
    step by default), 'steps' (each of --levels for --dwell s), 'random' (a random binary or
    multilevel sequence over --levels with minimum hold --hold s), 'file' (read from
    --input-file). The controller output is held for --control-period s (sample-and-hold).
    """
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from fuelid.io.files import check_output_path
    from fuelid.plant import load_plant_config
    from fuelid.profiles import InputProfile, random_levels, step_profile, step_sequence
    from fuelid.simulate import FuelTemperature, simulate

    out = check_output_path(output, overwrite=force)
    plant = load_plant_config(config)
    temperature: Any = None
    if profile is ProfileKind.step:
        prof = step_profile(u0, u1, t_step, 60.0 if duration is None else duration)
    elif profile is ProfileKind.steps:
        prof = step_sequence(_levels(levels), dwell)
        if duration is not None:
            prof = InputProfile(prof.t[prof.t < duration], prof.u[prof.t < duration], duration)
    elif profile is ProfileKind.random:
        prof = random_levels(
            _levels(levels), hold, 600.0 if duration is None else duration, seed=seed, settle=hold
        )
    else:
        if input_file is None:
            raise FuelidError("--profile file needs --input-file")
        prof, temperature = _profile_from_file(input_file, duration)
    T_start = celsius_to_kelvin(fuel_temp)
    if temperature is None:
        temperature = (
            FuelTemperature.constant(T_start)
            if fuel_temp_end is None
            else FuelTemperature.ramp(T_start, celsius_to_kelvin(fuel_temp_end), prof.duration)
        )
    with Progress(
        TextColumn("simulating"),
        BarColumn(),
        TextColumn("{task.percentage:>3.0f}%"),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        transient=True,
        disable=quiet or as_json or prof.duration < PROGRESS_THRESHOLD,
    ) as bar:
        task = bar.add_task("simulate", total=1.0)
        result = simulate(
            plant,
            prof,
            T_fuel=temperature,
            sample_time=sample_time,
            control_period=control_period,
            noise_std=None if noise_std is None else noise_std / LPM_PER_M3S,
            resolution=None if resolution is None else resolution / LPM_PER_M3S,
            seed=seed,
            progress=lambda done: bar.update(task, completed=done),
        )
    log = result.to_log(include_truth=truth)
    log.write(out, overwrite=force)
    q_range = [float(log["q_Lpm"].min()), float(log["q_Lpm"].max())]
    summary: dict[str, Any] = {
        "output": str(out),
        "n_samples": len(log),
        "sample_time": sample_time,
        "duration": prof.duration,
        "profile": profile.value,
        "u_range": list(prof.u_range),
        "q_range": q_range,
        "units": {
            "sample_time": "s",
            "duration": "s",
            "u_range": "V",
            "q_range": "L/min",
        },
    }
    if as_json:
        options = {
            "config": str(config) if config else None,
            "profile": profile.value,
            "u0": u0,
            "u1": u1,
            "t_step": t_step,
            "levels": levels,
            "dwell": dwell,
            "hold": hold,
            "input_file": str(input_file) if input_file else None,
            "duration": duration,
            "sample_time": sample_time,
            "control_period": control_period,
            "noise_std": noise_std,
            "resolution": resolution,
            "fuel_temp": fuel_temp,
            "fuel_temp_end": fuel_temp_end,
            "seed": seed,
        }
        emit_json(summary | provenance(options, input_file))
    else:
        typer.echo(
            f"wrote {out}: {len(log)} samples every {sample_time:g} s over {prof.duration:g} s, "
            f"u {prof.u_range[0]:g}…{prof.u_range[1]:g} V, "
            f"q {q_range[0]:.2f}…{q_range[1]:.2f} L/min"
        )
