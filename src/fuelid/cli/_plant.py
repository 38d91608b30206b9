"""``fuelid plant …``: the mechanism model of a plant (operating point, linearised model).

The library is imported when the command runs, not when ``fuelid --help`` is asked for.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from fuelid.cli._common import ConfigOption, checked_kelvin, emit_json, guarded, provenance
from fuelid.cli._serve import serve_command
from fuelid.errors import FuelidError
from fuelid.units import DEFAULT_FUEL_TEMPERATURE_C

if TYPE_CHECKING:
    from rich.table import Table

    from fuelid.plant import PlantConfig

app = typer.Typer(
    help="The plant's physics model: operating point and linearised model; the virtual PLC.",
    rich_markup_mode=None,
)
app.command("serve")(serve_command)


#: rows of the model's numbers that a calibration's covariance gives an uncertainty to
_UNCERTAIN_ROWS = {
    "K (static gain)": "K",
    "T (process lag, fitted)": "T",
    "T_f (flowmeter lag)": "T_f",
    "98 % settling time": "settling_time",
}


def _table(summary: dict[str, Any]) -> Table:
    from rich.table import Table

    op, model = summary["operating_point"], summary["model"]
    uncertainty: dict[str, Any] = summary.get("uncertainty") or {}
    table = Table(
        title=(
            f"plant {summary['plant']}"
            + (" (calibrated)" if summary.get("calibration") else "")
            + f": u = {summary['u']:g} V, "
            f"{summary['fuel']} at {summary['fuel_temperature']:g} °C"
        ),
        show_header=True,
    )
    table.add_column("quantity")
    table.add_column("value", justify="right")
    if uncertainty:
        table.add_column("± (1σ)", justify="right")
        table.add_column("95 % interval", justify="right")
    table.add_column("unit")
    rows = [
        ("flow", op["flow"], "L/min", ".3f"),
        ("pump outlet pressure", op["pump_pressure"], "MPa", ".4f"),
        ("nozzle pressure", op["nozzle_pressure"], "MPa", ".4f"),
        ("shaft speed", op["speed"], "rpm", ".1f"),
        ("shaft torque", op["torque"], "N·m", ".3f"),
        ("drive frequency", op["frequency"], "Hz", ".2f"),
        ("pump leakage", op["leakage"], "L/min", ".3f"),
        ("Reynolds number (line)", op["reynolds"], "-", ".0f"),
        ("K (static gain)", model["K"], "(L/min)/V", ".4f"),
        ("T (process lag, fitted)", model["T"], "s", ".4f"),
        ("T2 (second process lag)", model["T2"], "s", ".4f"),
        ("T_f (flowmeter lag)", model["T_f"], "s", ".4f"),
        ("delay (flowmeter)", model["delay"], "s", ".4f"),
        ("98 % settling time", model["settling_time"], "s", ".3f"),
        ("reduction RMS error", 100 * model["reduction_rms"], "% of K", ".3f"),
    ]
    for name, value, unit, fmt in rows:
        if not uncertainty:
            table.add_row(name, format(value, fmt), unit)
            continue
        spread = uncertainty.get(_UNCERTAIN_ROWS.get(name, ""))
        if spread is None:
            table.add_row(name, format(value, fmt), "", "", unit)
        else:
            lo, hi = spread["ci95"]
            interval = f"{format(lo, fmt)} … {format(hi, fmt)}"
            table.add_row(name, format(value, fmt), format(spread["stderr"], fmt), interval, unit)
    calibration = summary.get("calibration")
    if calibration:
        span = calibration["fuel_temperature_range_C"]
        logs = "" if span is None else f" (logs at {span[0]:g}…{span[1]:g} °C)"
        table.caption = "± from the calibration of " + ", ".join(calibration["parameters"]) + logs
    return table


def _add_uncertainty(
    summary: dict[str, Any], plant: PlantConfig, u: float, T_fuel: float
) -> list[str]:
    """Put the calibration's uncertainty of K, T, settling time into ``summary``; the notes.

    Without a covariance the ``calibration`` block is still given, ``uncertainty`` is null.
    """
    from fuelid.plant import calibration_summary, prediction_uncertainty

    if plant.calibration is not None and plant.calibration.covariance is None:
        summary["calibration"], notes = calibration_summary(plant, T_fuel)
        summary["uncertainty"] = None
        return [
            "the [calibration] table has no covariance: K, T are shown without uncertainty",
            *notes,
        ]
    spread = prediction_uncertainty(plant, u, T_fuel)
    summary |= spread.to_json()
    return list(spread.warnings)


@app.command("init")
@guarded
def init(
    out: Annotated[Path, typer.Argument(metavar="PLANT.toml", help="File to write.")],
    force: Annotated[bool, typer.Option("--force", help="Overwrite an existing file.")] = False,
) -> None:
    """Write the built-in reference plant file (with its comments) to edit into your own plant.

    Every value is commented with its unit and why it is plausible; change what you know of your
    plant (pipeline length and bore, pump displacement, nozzles …), check it with
    ``fuelid plant info --config PLANT.toml``, and calibrate what you do not know from logs
    (``fuelid calibrate``).
    """
    from fuelid.io.plantfile import write_text_atomically
    from fuelid.plant import reference_plant_text

    if out.exists() and not force:
        raise FuelidError(f"{out} exists: pass --force to overwrite it")
    written = write_text_atomically(out, reference_plant_text())
    typer.echo(f"wrote {written} (the reference plant: edit it to describe yours)")


@app.command("info")
@guarded
def info(
    config: ConfigOption = None,
    fuel_temp: Annotated[
        float, typer.Option("--fuel-temp", help="Fuel temperature [°C].")
    ] = DEFAULT_FUEL_TEMPERATURE_C,
    u: Annotated[
        float | None,
        typer.Option(
            "--u",
            help="Command [V] (default: the middle of the drive's signal range).",
            show_default=False,
        ),
    ] = None,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print one JSON object instead of a table.")
    ] = False,
) -> None:
    """Operating point and linearised model of a plant at one command and fuel temperature.

    The model is the equivalent K·e^(−τs)/((T·s+1)(T2·s+1)(T_f·s+1)) of fuelid identify and
    tune, with one process lag: K the exact static gain of the linearised plant [(L/min)/V], T a
    least-squares fit of its step response [s], T2 = 0 (the hydraulics are lumped into T), T_f
    and τ the flowmeter's [s]; the settling time is that of the full linearised plant (98 %).

    When the plant file has a [calibration] table with a covariance, K, T and the settling time
    also get a standard error and a 95 % interval (delta method over the calibrated parameters);
    a note on stderr says when the fuel temperature is outside the calibration logs' range.
    """
    from fuelid.plant import load_plant_config
    from fuelid.workflow import plant_info

    plant = load_plant_config(config)
    T_fuel = checked_kelvin(fuel_temp)
    result = plant_info(plant, T_fuel, u)
    summary = result.to_json() | {"config": str(config) if config else "reference"}
    if plant.calibration is not None:
        notes = _add_uncertainty(summary, plant, result.u, T_fuel)
        if notes:
            summary["warnings"] = notes
        for message in notes:
            typer.echo(f"note: {message}", err=True)
    if as_json:
        options = {"config": str(config) if config else None, "fuel_temp": fuel_temp, "u": u}
        emit_json(summary | provenance(options, config))
    else:
        from rich.console import Console

        Console().print(_table(summary))
