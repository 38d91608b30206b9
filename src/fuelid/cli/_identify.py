"""``fuelid identify``: the equivalent model from a PLC log, with error bars and diagnostics.

The command checks its options, reads the log and prints what
:func:`~fuelid.workflow.identify_log` returns; the library is imported when the command runs
(matplotlib only with ``--plot``). While it reads, grids, fits and tests, a line on stderr (a
terminal only, not with ``--quiet``) names the stage, with a bar when its steps are counted.
"""

from __future__ import annotations

import enum
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from fuelid.cli._common import (
    BadValues,
    FillGaps,
    FlowUnit,
    ForceFigureOption,
    FuelTemperatureColumn,
    InputColumn,
    InputScale,
    LogReadOptions,
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
    fitted_part,
    flow_unit_warning,
    format_interval,
    guarded,
    progress_display,
    provenance,
    warn,
)
from fuelid.cli._identify_options import (
    DEFAULT_ORDER,
    CovarianceChoice,
    CovarianceOption,
    DelayOption,
    FitOptions,
    FlowmeterDelayOption,
    FlowmeterTOption,
    OrderOption,
    StepsOption,
)
from fuelid.errors import FuelidError
from fuelid.units import FUEL_TEMPERATURE_RANGE_C, celsius_to_kelvin, format_celsius

if TYPE_CHECKING:
    from rich.table import Table

    from fuelid.identify import IdentificationResult
    from fuelid.io.timeseries import IOData
    from fuelid.workflow import PlantSource


class ValidationStart(enum.StrEnum):
    """How a validation record starts (``--validate-initial``)."""

    estimate = "estimate"
    rest = "rest"


class MethodChoice(enum.StrEnum):
    """Estimators of ``fuelid identify``."""

    oe = "oe"
    step_ls = "step-ls"
    pem = "pem"
    auto = "auto"


FullRecordOption = Annotated[
    bool,
    typer.Option(
        "--full-record",
        help="oe on a log of over 500,000 samples (a day at 50 Hz): fit every sample (search "
        "on a copy, then polish, standard errors and tests on all of it; slower). Without it "
        "such a log is fitted on a copy of 100,000 samples in 8 stretches spread over it: its "
        "estimates, standard errors and tests are the copy's, the fit % the whole log's. No "
        "effect on shorter logs.",
    ),
]
"""``--full-record`` of the commands that identify (identify, report)."""

STEP_LS_PERIOD = 1.0
"""step-ls's decimation period without --control-period [s]: the article's PLC period."""


@guarded
def identify_command(
    file: Annotated[
        Path,
        typer.Argument(metavar="LOG", help="PLC log: CSV (any of , ; tab) or Parquet."),
    ],
    method: Annotated[
        MethodChoice,
        typer.Option(
            help="oe: output-error fit on the raw samples; step-ls: the article's step-response "
            "least squares at the control period; pem: prediction-error fit with a noise model "
            "(efficient under coloured noise, consistent in closed loop); auto: pem when oe's "
            "residuals are coloured and the noise model is significant, else oe."
        ),
    ] = MethodChoice.oe,
    order: OrderOption = DEFAULT_ORDER,
    delay: DelayOption = None,
    flowmeter_T: FlowmeterTOption = None,
    flowmeter_delay: FlowmeterDelayOption = None,
    n_steps: StepsOption = None,
    covariance: CovarianceOption = CovarianceChoice.auto,
    full_record: FullRecordOption = False,
    control_period: Annotated[
        float | None,
        typer.Option(
            metavar="SECONDS",
            help="How often the PLC runs its PI [s]: step-ls decimates to it (default 1 s, the "
            "article's period), and --json records it so that fuelid tune needs no "
            "--control-period (without it, none is recorded).",
            show_default=False,
        ),
    ] = None,
    validate_split: Annotated[
        float | None,
        typer.Option(
            help="Hold out the last fraction F of the record for validation.", show_default=False
        ),
    ] = None,
    validate_file: Annotated[
        Path | None,
        typer.Option(
            metavar="LOG",
            help="A second log (same columns) to validate on (see --validate-initial).",
            show_default=False,
        ),
    ] = None,
    validate_initial: Annotated[
        ValidationStart,
        typer.Option(
            help="How the --validate-file record starts: estimate (its offset and initial state "
            "fitted, as a record that does not start at rest needs) or rest (at rest at its first "
            "input).",
        ),
    ] = ValidationStart.estimate,
    config: Annotated[
        Path | None,
        typer.Option(
            "--config",
            "-c",
            metavar="PLANT.toml",
            help="Plant TOML of your loop: its flowmeter gives T_f and the delay priors, its "
            "settling time N, its drive range and meter span the signal check, its K at the "
            "log's operating point a comparison (default: no plant, no priors).",
            show_default=False,
        ),
    ] = None,
    fuel_temp: Annotated[
        float | None,
        typer.Option(
            help="Fuel temperature during the log [°C] when it has no fuel-temperature column "
            "(recorded in operating_point for fuelid tune --model).",
            show_default=False,
        ),
    ] = None,
    u_before: Annotated[
        float | None,
        typer.Option(
            help="oe: steady input before the record [input unit] (default: estimate "
            "the initial state).",
            show_default=False,
        ),
    ] = None,
    t_start: Annotated[
        float | None,
        typer.Option(help="Use samples from this time on [s, log time].", show_default=False),
    ] = None,
    t_stop: Annotated[
        float | None,
        typer.Option(help="Use samples before this time [s, log time].", show_default=False),
    ] = None,
    time_col: TimeColumn = "t_s",
    input_col: InputColumn = "u_V",
    output_col: OutputColumn = "q_Lpm",
    sample_time: SampleTime = None,
    input_scale: InputScale = None,
    output_scale: OutputScale = None,
    fuel_temp_col: FuelTemperatureColumn = "T_fuel_degC",
    fill_gaps: FillGaps = None,
    max_gap: MaxGap = None,
    bad_values: BadValues = None,
    flow_unit: FlowUnit = None,
    timezone: TimeZoneOption = None,
    time_format: TimeFormatOption = None,
    skip_rows: SkipRowsOption = None,
    plot: Annotated[
        Path | None,
        typer.Option(
            metavar="FIG.png",
            help="Write the measured-versus-model figure (PNG, SVG, PDF); an existing file "
            "only with --force.",
            show_default=False,
        ),
    ] = None,
    force: ForceFigureOption = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
) -> None:
    """Identify K·e^(−θs)/((T·s+1)(T2·s+1)(T_f·s+1)) from a logged input and output.

    A flowmeter time constant or delay that is given is prior knowledge and stays fixed; what is
    not given is estimated. Non-exciting data are refused (exit code 2).
    """
    from fuelid.workflow import identify_log

    check_figure_path(plot, overwrite=force)
    fit = FitOptions(order, delay, flowmeter_T, flowmeter_delay, n_steps, covariance, full_record)
    _check_period_and_fuel(control_period, fuel_temp)
    options = fit.identify_options(
        method=method.value,
        control_period=STEP_LS_PERIOD if control_period is None else control_period,
        validate_split=validate_split,
        u_before=u_before,
        validation_initial=validate_initial.value,
    )
    plant = _plant_source(config)
    log = LogReadOptions(
        time_col=time_col,
        input_col=input_col,
        output_col=output_col,
        sample_time=sample_time,
        input_scale=input_scale,
        output_scale=output_scale,
        fuel_temp_col=fuel_temp_col,
        fill_gaps=fill_gaps,
        max_gap=max_gap,
        bad_values=bad_values,
        flow_unit=flow_unit,
        timezone=timezone,
        time_format=time_format,
        skip_rows=skip_rows,
    )
    # reading, gridding, fitting and testing a day at 50 Hz take seconds each: shown on stderr
    with progress_display(quiet) as stage:
        data = log.read(file, stage)
        validation = log.read(validate_file) if validate_file is not None else None
        outcome = identify_log(
            data,
            options,
            validation=validation,
            t_start=t_start,
            t_stop=t_stop,
            plant=plant,
            fuel_temperature=None if fuel_temp is None else celsius_to_kelvin(fuel_temp),
            progress=stage,
        )
    unit_warning = flow_unit_warning(data, output_col)
    warnings = outcome.warnings + ([unit_warning] if unit_warning else [])
    for message in warnings:
        warn(message)
    if plot is not None:
        _plot(outcome.result, data, file, plot, output_col)
    data_json = outcome.to_json() | {"warnings": warnings}
    if as_json:
        given = {
            "method": method.value,
            **fit.to_json(),
            "control_period": control_period,
            "control_period_given": control_period is not None,
            "validate_split": validate_split,
            "validate_initial": validate_initial.value,
            "config": str(config) if config else None,
            "fuel_temp": fuel_temp,
            "u_before": u_before,
        }
        emit_json(data_json | provenance(given | log.to_json(), file))
        return
    part = _fitted_part(data, outcome.result, (t_start, t_stop), validate_file)
    gain_unit, units = _units(data, output_col)
    _print_table(data_json, file, gain_unit, units, part)


def _check_period_and_fuel(control_period: float | None, fuel_temp: float | None) -> None:
    """Refuse a ``--control-period`` no PLC runs and a ``--fuel-temp`` no fuel has."""
    if control_period is not None:
        from fuelid.lti import check_control_period

        check_control_period(control_period, "control period (--control-period)")
    low, high = FUEL_TEMPERATURE_RANGE_C
    if fuel_temp is not None and not (math.isfinite(fuel_temp) and low <= fuel_temp <= high):
        raise FuelidError(f"--fuel-temp must lie within {low:g}…{high:g} °C, got {fuel_temp:g}")


def _plant_source(config: Path | None) -> PlantSource | None:
    """The user's plant file of ``--config`` (None without one: no priors, no plant)."""
    if config is None:
        return None
    from fuelid.plant import load_plant_config
    from fuelid.workflow import PlantSource

    return PlantSource(load_plant_config(config), str(config))


def _plot(
    result: IdentificationResult, data: IOData, file: Path, plot: Path, output_col: str
) -> None:
    """``--plot``: the measured output against the model's free-run simulation."""
    from fuelid.plots import plot_identification, save_figure

    fig = plot_identification(
        result.time,
        result.y,
        [(f"{result.method} model", result.y_hat)],
        result.split_time,
        f"{file.name}: measured and {result.method} model output",
        ylabel=output_col,
        unit=data.y_unit or None,
    )
    save_figure(fig, plot)


def _fitted_part(
    data: IOData,
    result: IdentificationResult,
    window: tuple[float | None, float | None],
    validate_file: Path | None,
) -> str:
    """The table's first line: the part of the log fitted (``window``: --t-start, --t-stop).

    The fit ends where the held-out part starts, else at --t-stop's last sample, else at the
    log's end; without a held-out part it says why ``fuelid report`` scores differently.
    """
    t_start, t_stop = window
    log = (float(data.t[0]), float(data.t[-1]))
    if result.split_time is not None:
        end = result.split_time
    elif t_stop is not None:
        end = float(result.time[-1])
    else:
        end = log[1]
    fitted = (float(result.time[0]) if t_start is not None else log[0], end)
    validated_on = (
        "the rest"
        if result.split_time is not None
        else validate_file.name
        if validate_file is not None
        else None
    )
    part = fitted_part(log, fitted, validated_on)
    if validated_on is None:  # report holds out 30 % by default: say why the two differ
        part += " (fuelid report holds out the last 30 %: --validate-split 0.3 does so here)"
    return part


def _units(data: IOData, output_col: str) -> tuple[str, tuple[str, str]]:
    """The table's gain unit and the operating point's (input, output) units.

    An unknown flow unit is named by its column (and said on stderr), not "output unit"; the
    operating point names its units as the table's K does: an unknown one in words.
    """
    from dataclasses import replace

    from fuelid.workflow import gain_unit

    named = data if data.y_unit else replace(data, y_unit=f"unit of {output_col}")
    return gain_unit(named), (data.u_unit or "input unit", named.y_unit)


def _print_table(
    data: dict[str, Any], file: Path, gain_unit: str, units: tuple[str, str], part: str
) -> None:
    """The text of ``fuelid identify``: the part fitted, the parameters, the fit and its basis.

    ``data`` is the command's JSON object; ``units`` the operating point's (input, output).
    """
    from rich.console import Console

    from fuelid.identify import long_record_note

    console = Console(emoji=False)
    console.print(part, highlight=False, soft_wrap=True)  # first: which part was fitted
    console.print(_parameter_table(data, file, gain_unit))
    console.print(f"fit {data['fit_percent']:.2f} % (NRMSE, free-run simulation)")
    if data["validation_fit_percent"] is not None:
        console.print(f"validation fit {data['validation_fit_percent']:.2f} % (held-out data)")
    point = data["operating_point"]
    fuel = point["fuel_temperature"]
    u_unit, y_unit = (f"({unit})" if " " in unit else unit for unit in units)
    console.print(
        f"operating point: u = {point['u']:.3g} {u_unit}, flow {point['y']:.4g} {y_unit}; fuel "
        + (
            f"{format_celsius(celsius_to_kelvin(fuel))} °C ({point['fuel_temperature_source']})"
            if fuel is not None
            else "unknown"
        )
    )
    console.print(f"assumed: {_describe_priors(data['priors'])}", highlight=False)
    console.print(f"standard errors: {_covariance_basis(data)}", highlight=False)
    noise = data.get("noise_model")
    if noise is not None:
        console.print(
            f"noise model C/D with nc = {noise['nc']}, nd = {noise['nd']}, poles "
            f"{_poles(noise['poles'])}, σ_v {noise['sigma_v']:.3g}; one-step prediction fit "
            f"{data['one_step_fit_percent']:.2f} %",
            highlight=False,
        )
    structure = data.get("structure")
    if structure is not None and len(structure["compared"]) > 1:
        compared = ", ".join(f"{c['order']} (BIC {c['bic']:.1f})" for c in structure["compared"])
        console.print(f"orders compared: {compared}; kept {structure['reason']}", highlight=False)
    if "method_choice" in data:
        console.print(data["method_choice"], highlight=False)
    note = long_record_note(data.get("long_record"), data.get("sample_time"))
    if note:  # a day fitted on a copy, or searched there and polished: say which
        console.print(note, highlight=False)


def _parameter_table(data: dict[str, Any], file: Path, gain_unit: str) -> Table:
    """The model's parameters with their standard errors, 95 % intervals and units."""
    from rich.table import Table

    from fuelid.model import MODEL_KEYS

    table = Table(
        title=f"{data['method']} on {file.name} ({data['n_samples']} samples every "
        f"{data['sample_time']:g} s)"
    )
    for column in ("parameter", "value", "std. error", "95 % interval", "unit"):
        table.add_column(column, justify="right")
    for key in MODEL_KEYS:
        value, se, ci = data["model"][key], data["stderr"][key], data["ci95"][key]
        fixed = key in data["fixed"]
        table.add_row(
            key,
            f"{value:.5g}",
            # fixed is a prior the user gave; estimated without an interval is not determined
            "fixed" if fixed else "not determined" if se is None else f"{se:.2g}",
            "" if ci is None else format_interval(ci[0], ci[1], minimum=5),
            gain_unit if key == "K" else "s",
        )
    return table


_COVARIANCE_BASES = {
    "white": "white residuals, σ²(JᵀJ)⁻¹",
    "hac": "the sandwich with the coloured residuals' spectrum",
    "noise-model": "the prediction-error fit's, with its noise model",
}
"""What the standard errors rest on, by the JSON's ``covariance``."""


def _covariance_basis(data: dict[str, Any]) -> str:
    """What the standard errors rest on, in words."""
    if data.get("residual_colour") == "model":
        # coloured residuals whose colour is the model's misfit: the noise alone is counted
        return (
            "σ²(JᵀJ)⁻¹ with the noise's level where the output has settled (the residuals' "
            "colour is the model's misfit, not noise)"
        )
    covariance = str(data["covariance"])
    return _COVARIANCE_BASES.get(covariance, covariance)


def _describe_priors(priors: dict[str, Any]) -> str:
    """One line of what the fit held fixed and where it came from, what it estimated."""
    parts = []
    lag = priors["flowmeter_T"]
    parts.append(
        f"meter lag {lag['value']:g} s ({lag['source']})"
        if lag["value"] is not None
        else "no meter lag (a lag is found as T2)"
    )
    delay = priors["delay"]
    parts.append(f"dead time {delay['value']:.3g} s ({delay['source']})")
    order = priors["order"]
    parts.append(f"order {order['value']} ({order['source']})")
    if "N" in priors:
        parts.append(f"N = {priors['N']['value']} ({priors['N']['source']})")
    plant = priors["plant"]
    parts.append(f"plant {plant['path']}" if plant is not None else "no plant file")
    return "; ".join(parts)


def _poles(poles: list[Any]) -> str:
    """Noise poles for the table: reals, and complex ones (JSON [re, im]) as a ± bj."""
    shown = [f"{p:.4g}" if not isinstance(p, list) else f"{p[0]:.3g}{p[1]:+.3g}j" for p in poles]
    return ", ".join(shown) or "none"
