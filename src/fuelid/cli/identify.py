"""``fuelid identify``: the equivalent model from a PLC log, with error bars and diagnostics.

The command checks its options, reads the log and prints what
:func:`~fuelid.workflow.identify_log` returns; the library is imported when the command runs
(matplotlib only with ``--plot``).
"""

from __future__ import annotations

import enum
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import typer

from fuelid.cli._common import (
    ForceFigureOption,
    InputColumn,
    InputScale,
    OutputColumn,
    OutputScale,
    SampleTime,
    TimeColumn,
    check_figure_path,
    emit_json,
    guarded,
    provenance,
    read_log,
    warn,
)
from fuelid.errors import FuelidError

if TYPE_CHECKING:
    from fuelid.io.timeseries import IOData


class ValidationStart(enum.StrEnum):
    """How a validation record starts (``--validate-initial``)."""

    estimate = "estimate"
    rest = "rest"


class MethodChoice(enum.StrEnum):
    """Estimators of ``fuelid identify``."""

    oe = "oe"
    step_ls = "step-ls"


def _order(text: str) -> Literal[1, 2, "auto"]:
    if text == "1":
        return 1
    if text == "2":
        return 2
    if text == "auto":
        return "auto"
    raise FuelidError(f"--order must be 1, 2 or auto, got {text!r}")


def _delay(text: str | None) -> float | Literal["auto"] | None:
    if text is None:
        return None
    if text == "auto":
        return "auto"
    try:
        value = float(text)
    except ValueError:
        raise FuelidError(f"--delay must be 'auto' or seconds, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0.0):
        raise FuelidError(f"--delay must be a non-negative number of seconds, got {text!r}")
    return value


@guarded
def identify_command(
    file: Annotated[
        Path,
        typer.Argument(metavar="LOG", help="PLC log: CSV (any of , ; tab) or Parquet."),
    ],
    method: Annotated[
        MethodChoice,
        typer.Option(
            help="oe: output-error fit on the raw samples; step-ls: the "
            "article's step-response least squares at the control "
            "period."
        ),
    ] = MethodChoice.oe,
    order: Annotated[
        str,
        typer.Option(
            metavar="1|2|auto",
            help="Process time constants: 1, 2, or auto (the order of lower AIC).",
        ),
    ] = "1",
    delay: Annotated[
        str | None,
        typer.Option(
            metavar="SECONDS|auto",
            help="Dead time: a number of seconds [s] fixes it, 'auto' estimates it (default: "
            "the flowmeter delay when given, else auto).",
            show_default=False,
        ),
    ] = None,
    flowmeter_T: Annotated[
        float | None,
        typer.Option(
            "--flowmeter-T",
            "--T-f",
            metavar="SECONDS",
            help="Flowmeter time constant T_f [s], held fixed (alias --T-f, as in fuelid tune).",
            show_default=False,
        ),
    ] = None,
    flowmeter_delay: Annotated[
        float | None,
        typer.Option(
            "--flowmeter-delay",
            metavar="SECONDS",
            help="Flowmeter dead time [s], the model's delay unless --delay.",
            show_default=False,
        ),
    ] = None,
    n_steps: Annotated[
        int | None,
        typer.Option(
            "--N",
            help="step-ls: step-response length N [control periods] (default: "
            "from --config's settling time).",
            show_default=False,
        ),
    ] = None,
    control_period: Annotated[
        float, typer.Option(help="step-ls: controller period to decimate to [s].")
    ] = 1.0,
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
            help="Plant TOML: its flowmeter gives T_f and the delay "
            "priors, its settling time gives N.",
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
) -> None:
    """Identify K·e^(−θs)/((T·s+1)(T2·s+1)(T_f·s+1)) from a logged input and output.

    A flowmeter time constant or delay that is given is prior knowledge and stays fixed; what is
    not given is estimated. Non-exciting data are refused (exit code 2).
    """
    from fuelid.identify.procedure import IdentifyOptions
    from fuelid.workflow.identification import identify_log, plant_priors

    check_figure_path(plot, overwrite=force)
    for name, value in (("--flowmeter-T", flowmeter_T), ("--flowmeter-delay", flowmeter_delay)):
        if value is not None and not (math.isfinite(value) and value >= 0.0):
            raise FuelidError(f"{name} must be a non-negative number of seconds")
    options = IdentifyOptions(
        method="step-ls" if method is MethodChoice.step_ls else "oe",
        order=_order(order),
        delay=_delay(delay),
        flowmeter_T=flowmeter_T,
        flowmeter_delay=flowmeter_delay,
        N=n_steps,
        control_period=control_period,
        validate_split=validate_split,
        u_before=u_before,
        validation_initial=validate_initial.value,
    )
    if config is not None:
        from fuelid.plant.config import load_plant_config  # physics only with a plant file

        options = plant_priors(options, load_plant_config(config))

    def read(path: Path) -> IOData:
        return read_log(
            path, time_col, input_col, output_col, sample_time, input_scale, output_scale
        )

    data = read(file)
    validation = read(validate_file) if validate_file is not None else None
    outcome = identify_log(data, options, validation=validation, t_start=t_start, t_stop=t_stop)
    result = outcome.result
    for message in outcome.warnings:
        warn(message)
    if plot is not None:
        from fuelid.plots import plot_identification, save_figure

        fig = plot_identification(
            result.time,
            result.y,
            [(f"{result.method} model", result.y_hat)],
            result.split_time,
            f"{file.name}: measured and {result.method} model output",
            ylabel=output_col,
        )
        save_figure(fig, plot)
    data_json = outcome.to_json()
    if as_json:
        opts = {
            "method": method.value,
            "order": order,
            "delay": delay,
            "flowmeter_T": flowmeter_T,
            "flowmeter_delay": flowmeter_delay,
            "N": n_steps,
            "control_period": control_period,
            "validate_split": validate_split,
            "validate_initial": validate_initial.value,
            "config": str(config) if config else None,
            "u_before": u_before,
            "time_col": time_col,
            "input_col": input_col,
            "output_col": output_col,
            "sample_time": sample_time,
            "input_scale": input_scale,
            "output_scale": output_scale,
        }
        emit_json(data_json | provenance(opts, file))
        return
    _print_table(data_json, file, _gain_unit(input_col, output_col, input_scale, output_scale))


_UNIT_SUFFIXES = {"_V": "V", "_mA": "mA", "_Lpm": "L/min", "_pct": "%", "_percent": "%"}
"""Unit suffixes of column names, as fuelid's own logs carry them (``u_V``, ``q_Lpm``)."""


def _column_unit(column: str, scale: str | None) -> str | None:
    """The unit a column's name says, or None: unknown, or rescaled to an unnamed unit."""
    if scale:
        return None
    for suffix, unit in _UNIT_SUFFIXES.items():
        if column.endswith(suffix):
            return unit
    return None


def _gain_unit(
    input_col: str, output_col: str, input_scale: str | None, output_scale: str | None
) -> str:
    """K's unit for the table: (L/min)/V for ``u_V`` and ``q_Lpm``, a neutral label when unknown.

    Examples
    --------
    >>> _gain_unit("u_V", "q_Lpm", None, None)
    '(L/min)/V'
    >>> _gain_unit("u_mA", "q_Lpm", "4:20:1:5", None)
    '(out)/(in)'
    """
    u_unit = _column_unit(input_col, input_scale)
    y_unit = _column_unit(output_col, output_scale)
    if u_unit is None or y_unit is None:
        return "(out)/(in)"

    def wrap(unit: str) -> str:
        return f"({unit})" if "/" in unit else unit

    return f"{wrap(y_unit)}/{wrap(u_unit)}"


def _print_table(data: dict[str, Any], file: Path, gain_unit: str) -> None:
    from rich.console import Console
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
            "fixed" if fixed or se is None else f"{se:.2g}",
            "" if ci is None else f"{ci[0]:.5g} … {ci[1]:.5g}",
            gain_unit if key == "K" else "s",
        )
    console = Console()
    console.print(table)
    console.print(f"fit {data['fit_percent']:.2f} % (NRMSE, free-run simulation)")
    if data["validation_fit_percent"] is not None:
        console.print(f"validation fit {data['validation_fit_percent']:.2f} % (held-out data)")
