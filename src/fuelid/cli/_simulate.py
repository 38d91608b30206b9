"""``fuelid simulate``: write a PLC-like log of the nonlinear plant.

The command parses and checks its options, builds a
:class:`~fuelid.workflow._simulation.SimulationRequest`, runs
:func:`~fuelid.workflow._simulation.simulate_log`, writes the log atomically and prints the
outcome's summary. The library is imported when the command runs, not when ``fuelid --help`` is
asked for.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer

from fuelid.cli._common import checked_kelvin, emit_json, guarded, provenance
from fuelid.errors import FuelidError
from fuelid.units import DEFAULT_FUEL_TEMPERATURE_C, LPM_PER_M3S, PA_PER_MPA

#: simulated time above which a progress bar is shown [s]
PROGRESS_THRESHOLD = 600.0


class ProfileKind(enum.StrEnum):
    """The input profiles ``fuelid simulate`` can generate."""

    step = "step"
    steps = "steps"
    random = "random"
    file = "file"


def _levels(text: str) -> tuple[float, ...]:
    try:
        values = [float(part) for part in text.replace(";", ",").split(",") if part.strip()]
    except ValueError:
        raise FuelidError(f"--levels must be comma-separated volts, got {text!r}") from None
    if not values or not all(math.isfinite(v) for v in values):
        raise FuelidError(f"--levels must be comma-separated finite volts, got {text!r}")
    return tuple(values)


@guarded
def simulate_command(
    output: Annotated[
        Path,
        typer.Argument(metavar="LOG", help="Log to write: .csv or .parquet (format by extension)."),
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
    fuel_temp: Annotated[
        float, typer.Option(help="Fuel temperature at the start [°C].")
    ] = DEFAULT_FUEL_TEMPERATURE_C,
    fuel_temp_end: Annotated[
        float | None,
        typer.Option(
            help="Fuel temperature at the end [°C]: a linear ramp (default: constant).",
            show_default=False,
        ),
    ] = None,
    seed: Annotated[int | None, typer.Option(help="Seed of noise and random profiles.")] = 0,
    truth: Annotated[
        bool,
        typer.Option(
            "--truth",
            help="Add q_true_Lpm, the noise-free meter reading (and p_true_MPa with --pressure).",
        ),
    ] = False,
    pressure: Annotated[
        bool,
        typer.Option(
            "--pressure",
            help="Also log p_pump_MPa, the pump outlet pressure (gauge) [MPa], sampled like the "
            "flow but without the flowmeter's dead time.",
        ),
    ] = False,
    pressure_noise_std: Annotated[
        float | None,
        typer.Option(
            help="--pressure: noise std of the logged pressure [MPa] (default 0.002).",
            show_default=False,
        ),
    ] = None,
    pressure_resolution: Annotated[
        float | None,
        typer.Option(
            help="--pressure: quantisation step of the logged pressure [MPa]; 0: none "
            "(default 0.0001).",
            show_default=False,
        ),
    ] = None,
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
    With --pressure the log also has p_pump_MPa, the pump outlet pressure a transmitter reads.
    """
    from fuelid.io.files import check_output_path
    from fuelid.lti import check_control_period
    from fuelid.plant import load_plant_config
    from fuelid.workflow import SimulationRequest, simulate_log, simulation_inputs

    out = check_output_path(output, overwrite=force)
    check_control_period(control_period, "control period (--control-period)")  # 0: changes at once
    pressure_noise_std, pressure_resolution = _pressure_options(
        pressure, pressure_noise_std, pressure_resolution
    )
    plant = load_plant_config(config)
    if profile is ProfileKind.file and input_file is None:
        raise FuelidError("--profile file needs --input-file")
    request = SimulationRequest(
        profile=profile.value,
        u0=u0,
        u1=u1,
        t_step=t_step,
        levels=_levels(levels) if profile in (ProfileKind.steps, ProfileKind.random) else (),
        dwell=dwell,
        hold=hold,
        input_file=input_file,
        duration=duration,
        sample_time=sample_time,
        control_period=control_period,
        noise_std=None if noise_std is None else noise_std / LPM_PER_M3S,
        resolution=None if resolution is None else resolution / LPM_PER_M3S,
        T_fuel=checked_kelvin(fuel_temp, "--fuel-temp"),
        T_fuel_end=(
            None if fuel_temp_end is None else checked_kelvin(fuel_temp_end, "--fuel-temp-end")
        ),
        seed=seed,
        truth=truth,
        pressure=pressure,
        pressure_noise_std=pressure_noise_std * PA_PER_MPA,
        pressure_resolution=pressure_resolution * PA_PER_MPA,
    )
    inputs = simulation_inputs(request)
    hidden = quiet or as_json or inputs.duration < PROGRESS_THRESHOLD
    with _progress_bar(hidden) as progress:
        outcome = simulate_log(plant, request, inputs=inputs, progress=progress)
    outcome.to_log().write(out, overwrite=force)
    summary = outcome.to_json(out)
    if not as_json:
        typer.echo(_summary_line(summary, out))
        return
    options: dict[str, Any] = {
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
        "pressure": pressure,
        "pressure_noise_std": pressure_noise_std,
        "pressure_resolution": pressure_resolution,
    }
    emit_json(summary | provenance(options, input_file))


def _pressure_options(
    pressure: bool, noise_std: float | None, resolution: float | None
) -> tuple[float, float]:
    """``--pressure-noise-std`` and ``--pressure-resolution`` [MPa], defaults filled in.

    Either given without ``--pressure`` is refused: it would set nothing the log has.
    """
    from fuelid.plant.simulate import PRESSURE_NOISE_STD, PRESSURE_RESOLUTION

    given = [
        name
        for name, value in (
            ("--pressure-noise-std", noise_std),
            ("--pressure-resolution", resolution),
        )
        if value is not None
    ]
    if given and not pressure:
        raise FuelidError(f"{' and '.join(given)} set the logged pressure: add --pressure")
    if noise_std is None:
        noise_std = PRESSURE_NOISE_STD / PA_PER_MPA
    if resolution is None:
        resolution = PRESSURE_RESOLUTION / PA_PER_MPA
    for name, value in (("--pressure-noise-std", noise_std), ("--pressure-resolution", resolution)):
        if not (math.isfinite(value) and value >= 0.0):
            raise FuelidError(f"{name} must be zero or a positive number of MPa, got {value:g}")
    return noise_std, resolution


@contextmanager
def _progress_bar(hidden: bool) -> Iterator[Callable[[float], None]]:
    """A bar on stderr over the simulated time; yields the callback told the fraction done."""
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    with Progress(
        TextColumn("simulating"),
        BarColumn(),
        TextColumn("{task.percentage:>3.0f}%"),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        transient=True,
        disable=hidden,
    ) as bar:
        task = bar.add_task("simulate", total=1.0)

        def progress(done: float) -> None:
            bar.update(task, completed=done)

        yield progress


def _summary_line(summary: dict[str, Any], out: Path) -> str:
    """The text of ``fuelid simulate``: the file written, its samples and its signals' ranges."""
    u_range, q_range = summary["u_range"], summary["q_range"]
    p_text = ""
    if "p_range" in summary:
        p_lo, p_hi = summary["p_range"]
        p_text = f", p {p_lo:.4f}…{p_hi:.4f} MPa"
    return (
        f"wrote {out}: {summary['n_samples']} samples every {summary['sample_time']:g} s over "
        f"{summary['duration']:g} s, u {u_range[0]:g}…{u_range[1]:g} V, "
        f"q {q_range[0]:.2f}…{q_range[1]:.2f} L/min{p_text}"
    )
