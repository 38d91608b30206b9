"""``fuelid calibrate``: fit physical parameters of a plant file to logs (issue 16).

Thin: parse, call :func:`fuelid.calibration.calibrate.calibrate`, print. The library is imported
when the command runs.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import typer

from fuelid.cli._common import (
    BadValues,
    ConfigOption,
    FlowUnit,
    FuelTemperatureColumn,
    InputColumn,
    InputScale,
    MaxGap,
    OutputColumn,
    OutputScale,
    SampleTime,
    SkipRowsOption,
    TimeColumn,
    TimeFormatOption,
    TimeZoneOption,
    check_figure_path,
    emit_json,
    flow_unit_warning,
    format_estimate,
    guarded,
    provenance,
    read_log,
    warn,
)
from fuelid.errors import ConfigError, FuelidError


def _floats(text: str | None, option: str) -> list[float] | None:
    if text is None:
        return None
    try:
        return [float(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise ConfigError(f"{option} takes comma-separated numbers, got {text!r}") from None


@guarded
def calibrate_command(
    logs: Annotated[
        list[Path],
        typer.Argument(
            metavar="LOG...",
            help="Logs (CSV or Parquet), each starting at rest; the column, scaling, unit, gap "
            "and bad-value options below apply to every one.",
        ),
    ],
    free: Annotated[
        str,
        typer.Option(
            "--free",
            metavar="NAME[,NAME...]",
            help="Plant-file parameters to fit, dotted as in the file: pump.leakage_Lpm_per_MPa,"
            "vfd.lag_s,nozzle.discharge_coefficient,pipeline.roughness_mm,motor.inertia_kg_m2,"
            "flowmeter.time_constant_s …",
        ),
    ],
    config: ConfigOption = None,
    fuel_temp: Annotated[
        str | None,
        typer.Option(
            "--fuel-temp",
            metavar="DEGC[,DEGC...]",
            help="Fuel temperature of each log [°C], one per log in order (default: each log's "
            "T_fuel_degC column, averaged).",
            show_default=False,
        ),
    ] = None,
    pressure_col: Annotated[
        str | None,
        typer.Option(
            "--pressure-col",
            help="Column of the pump outlet pressure [MPa gauge] (fitted with the flow).",
            show_default=False,
        ),
    ] = None,
    time_col: TimeColumn = "t_s",
    input_col: InputColumn = "u_V",
    output_col: OutputColumn = "q_Lpm",
    sample_time: SampleTime = None,
    input_scale: InputScale = None,
    output_scale: OutputScale = None,
    fuel_temp_col: FuelTemperatureColumn = "T_fuel_degC",
    max_gap: MaxGap = None,
    bad_values: BadValues = None,
    flow_unit: FlowUnit = None,
    timezone: TimeZoneOption = None,
    time_format: TimeFormatOption = None,
    skip_rows: SkipRowsOption = None,
    accept_signals: Annotated[
        bool,
        typer.Option(
            "--accept-signals",
            help="Calibrate logs whose command or flow the signal check finds outside the "
            "plant file's drive range and meter span or in another unit (refused otherwise).",
        ),
    ] = False,
    holdout: Annotated[
        float,
        typer.Option(
            "--holdout",
            help="Share of each log's end left out of the fit and predicted (0: fit it all).",
        ),
    ] = 0.2,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            metavar="CALIBRATED.toml",
            help="Write the calibrated plant file (comments kept, a [calibration] table added).",
            show_default=False,
        ),
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="Overwrite an existing --out file or --plot figure.")
    ] = False,
    force_misfit: Annotated[
        bool,
        typer.Option(
            "--force-misfit",
            help="Write --out even when the calibrated model does not fit the data (residuals "
            "over 3× the logs' noise; refused otherwise); its [calibration] warnings say so.",
        ),
    ] = False,
    plot: Annotated[
        Path | None,
        typer.Option(
            "--plot",
            metavar="FIG.png",
            help="Measured and calibrated per log.",
            show_default=False,
        ),
    ] = None,
    profile: Annotated[
        str | None,
        typer.Option(
            "--profile",
            metavar="NAME[,NAME...]|all",
            help="Also give the profile-likelihood 95 % interval of these parameters (several "
            "refits each; done anyway where the standard error exceeds 10 % of the value).",
            show_default=False,
        ),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Calibrate physical parameters of the plant file from logs, by output error on its ODE.

    Each log is simulated from rest at its first command at its own fuel temperature; several
    logs at different temperatures separate the viscosity-dependent parameters. Prints the
    estimates with standard errors and 95 % intervals, their correlations, the fit % per log
    (and on its held-out end), and the identifiability report; refuses (exit 2) parameters the
    data cannot determine, naming them and what data would help.

    The column, scaling, unit, gap and bad-value options are those of fuelid identify and apply
    to every log. Each log's command and flow are checked against the plant file's drive range
    and meter span as identify checks them; a log in other units is refused (exit 2) with the
    fix. Gaps of up to 5 sample periods are simulated through with the command held; a longer
    gap ends the part of the log that is calibrated. A model that does not fit the data as well
    as their noise allows is said to be untrustworthy, and --out is then refused.
    """
    from fuelid.calibration import calibration_log
    from fuelid.calibration.calibrate import calibrate, calibrated_plant_text, check_free_names
    from fuelid.io.plantfile import write_text_atomically
    from fuelid.plant import load_plant_config
    from fuelid.workflow import PlantSource, check_signals

    names = check_free_names(free.split(","))
    temps = _floats(fuel_temp, "--fuel-temp")
    if temps is not None and len(temps) != len(logs):
        raise ConfigError(f"--fuel-temp gives {len(temps)} temperature(s) for {len(logs)} log(s)")
    if out is not None and out.exists() and not force:
        raise FuelidError(f"{out} exists: pass --force to overwrite it")
    if plot is not None:
        check_figure_path(plot, force)
    plant = load_plant_config(config)
    source = PlantSource(plant, str(config) if config is not None else None)
    edge_warnings: list[str] = []
    signal_check: dict[str, list[str]] = {}
    loaded = []
    for i, path in enumerate(logs):

        def read(column: str, scale: str | None, unit: str | None, path: Path = path) -> Any:
            return read_log(
                path, time_col, input_col, column, sample_time, input_scale, scale,
                fuel_temperature_col=fuel_temp_col, max_gap=max_gap, bad_values=bad_values,
                flow_unit=unit, timezone=timezone, time_format=time_format, skip_rows=skip_rows,
            )  # fmt: skip

        flow = read(output_col, output_scale, flow_unit)
        findings = check_signals(flow, source)
        if findings and not accept_signals:
            raise FuelidError(
                f"{path.name}: {'; '.join(findings)}; the calibrated parameters would absorb "
                "the wrong units (--accept-signals to calibrate anyway)"
            )
        if findings:
            signal_check[str(path)] = findings
            edge_warnings += [f"{path.name}: {finding}" for finding in findings]
        unit_warning = flow_unit_warning(flow, output_col)
        if unit_warning:
            edge_warnings.append(f"{path.name}: {unit_warning}")
        pressure = None if pressure_col is None else read(pressure_col, None, None)
        loaded.append(
            calibration_log(path, flow, pressure, fuel_temp_C=None if temps is None else temps[i])
        )
    profiles = [] if profile is None else [p.strip() for p in profile.split(",") if p.strip()]
    result = calibrate(plant, loaded, names, holdout=holdout, profile=profiles)
    if result.misfit and out is not None and not force_misfit:
        raise FuelidError(
            f"{result.misfit}; --out refused: the plant file would carry these numbers "
            "(--force-misfit to write it anyway, with this warning in its [calibration] table)"
        )
    written = None
    if out is not None:
        text = calibrated_plant_text(result, config)
        written = write_text_atomically(out, text)
    if plot is not None:
        _plot(result, plot)
    for message in edge_warnings + result.warnings:
        warn(message)
    if as_json:
        document = result.to_json()
        document["warnings"] = edge_warnings + document["warnings"]
        document["signal_check"] = signal_check
        document["calibrated_file"] = str(written) if written else None
        document.update(
            provenance(
                {
                    "free": list(names),
                    "config": str(config) if config else None,
                    "fuel_temp_C": temps,
                    "pressure_col": pressure_col,
                    "time_col": time_col,
                    "input_col": input_col,
                    "output_col": output_col,
                    "sample_time": sample_time,
                    "input_scale": input_scale,
                    "output_scale": output_scale,
                    "fuel_temp_col": fuel_temp_col,
                    "max_gap": max_gap,
                    "bad_values": bad_values,
                    "flow_unit": flow_unit,
                    "accept_signals": accept_signals,
                    "force_misfit": force_misfit,
                    "holdout": holdout,
                    "profile": profiles,
                },
                logs[0],  # every log's hash is in `logs`
            )
        )
        emit_json(document)
        return
    _print(result, written)


def _number(value: float | None) -> float:
    return math.nan if value is None else float(value)


def _plot(result: Any, path: Path) -> None:
    from fuelid.plots import FitPanel, plot_greybox_fit, save_figure

    names = ["flow [L/min]"] + (["pressure [MPa]"] if result.simulated[0].shape[1] > 1 else [])
    panels = []
    for log, simulated, fits, n_fit in zip(
        result.logs, result.simulated, result.fit_percent, result.fitted_samples, strict=True
    ):
        record = log.record
        pressure = simulated.shape[1] > 1
        held_out = n_fit < record.n_samples
        panels.append(
            FitPanel(
                title=f"{log.path.name}, {log.fuel_temperature_C:.0f} °C",
                t=record.t,
                y=record.y,
                y_hat=simulated,
                fit_percent=[_number(fits["flow"])]
                + ([_number(fits.get("pressure"))] if pressure else []),
                heldout_start=float(record.t[n_fit]) if held_out else None,
                heldout_fit_percent=[_number(fits.get("heldout_flow"))]
                + ([_number(fits.get("heldout_pressure"))] if pressure else [])
                if held_out
                else None,
                input_u=record.u,
                input_names=["command [V]"],
            )
        )
    save_figure(plot_greybox_fit(panels, names, title="calibrated plant against the logs"), path)


def _print(result: Any, written: Path | None) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title="calibrated parameters", show_header=True)
    for column in ("parameter", "start", "estimate", "± (1σ)", "95 % interval", "unit"):
        table.add_column(column, justify="left" if column == "parameter" else "right")
    for name in result.free:
        interval = result.ci95[name]
        error = result.stderr[name]
        table.add_row(
            name,
            f"{result.start[name]:.5g}",
            format_estimate(result.parameters[name], error),
            "—" if error is None else f"{error:.3g}",
            "—"
            if interval is None
            else f"{format_estimate(interval[0], error)} … {format_estimate(interval[1], error)}",
            result.units[name],
        )
    console = Console(width=110)
    console.print(table)
    for name, (low, high) in result.profile_ci95.items():
        error = result.stderr[name]
        console.print(
            f"profile-likelihood 95 % interval of {name}: "
            f"{format_estimate(low, error)} … {format_estimate(high, error)}"
        )
    for log, fits in zip(result.logs, result.fit_percent, strict=True):
        line = f"{log.path.name} ({log.fuel_temperature_C:.1f} °C): fit {fits['flow']:.2f} %"
        if "pressure" in fits:
            line += f", pressure {fits['pressure']:.2f} %"
        if fits.get("heldout_flow") is not None:
            line += f"; held-out end {fits['heldout_flow']:.2f} %"
            if fits.get("heldout_pressure") is not None:
                line += f", pressure {fits['heldout_pressure']:.2f} %"
        console.print(line)
    if len(result.free) > 1:
        pairs = [
            f"{a}/{b} {result.correlation[i, j]:+.3f}"
            for i, a in enumerate(result.free)
            for j, b in enumerate(result.free)
            if j > i
        ]
        console.print("correlation of the estimates: " + ", ".join(pairs))
    report = result.identifiability
    verdict = (
        "every parameter determined"
        if result.trusted
        else "but the model does not fit the data: the parameters are NOT to be trusted"
    )
    console.print(
        f"identifiability: rank {report['rank']} of {report['n_estimated']}, collinearity index "
        f"{report['collinearity_index']:.3g} (1 = independent), {verdict}"
    )
    if not result.trusted:
        console.print(f"MISFIT: {result.misfit}", highlight=False)
    noise = ", ".join(f"{k} {v:.3g}" for k, v in result.noise_std.items())
    console.print(f"residual noise std: {noise}; {result.iterations} iterations, "
                  f"{result.wall_time_s:.1f} s")  # fmt: skip
    if written is not None:
        console.print(f"calibrated plant written to {written}")
