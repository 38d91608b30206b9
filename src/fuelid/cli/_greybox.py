"""``fuelid greybox``: fit the parameters of your own ODE model (a Python file) to logged data.

The command reads the model file (:mod:`fuelid.greybox.modelfile`) and the data files, applies
``--fix``/``--free``/``--set``, sets up the :class:`~fuelid.greybox.GreyBoxEstimator` and calls
:func:`~fuelid.workflow._greybox_fit.fit_greybox` (the fit, the validation on ``--validate-file``,
the profiles), then prints the parameters with their uncertainty and what the data determine.
The library is imported when the command runs (matplotlib only with ``--plot``).
"""

from __future__ import annotations

import enum
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from fuelid.cli._common import (
    ForceFigureOption,
    SampleTime,
    check_figure_path,
    emit_json,
    file_sha256,
    format_estimate,
    guarded,
    progress_display,
    provenance,
    warn,
)
from fuelid.errors import ConfigError, FuelidError

if TYPE_CHECKING:
    from rich.table import Table

    from fuelid.greybox import GreyBoxEstimator, Record
    from fuelid.greybox.modelfile import ModelFile
    from fuelid.workflow import GreyBoxFit

DEFAULT_INPUT = "u_V"
"""The input column without --input-col or the model file's inputs (for the help text)."""
DEFAULT_OUTPUT = "q_Lpm"
"""The output column without --output-col or the model file's outputs (for the help text)."""


class SolverName(enum.StrEnum):
    """The ODE solver (``--solver``); the values of :data:`fuelid.greybox._solvers.CHOICES`."""

    auto = "auto"
    lsoda = "lsoda"
    bdf = "bdf"
    radau = "radau"
    rk45 = "rk45"
    rk4 = "rk4"


class InitialState(enum.StrEnum):
    """How each record's initial state is set (``--initial-state``)."""

    auto = "auto"
    model = "model"
    estimate = "estimate"


def _names(text: str | None, option: str) -> list[str]:
    """Comma-separated names of an option; empty entries refused."""
    if text is None:
        return []
    names = [part.strip() for part in text.split(",")]
    if not all(names):
        raise ConfigError(f"{option} takes comma-separated names, got {text!r}")
    return names


def _segments(text: str) -> int | str | None:
    """--segments: auto, none or an integer ≥ 2."""
    word = text.strip().lower()
    if word in {"auto", "none"}:
        return None if word == "none" else "auto"
    try:
        count = int(word)
    except ValueError:
        count = 0
    if count < 2:
        raise ConfigError(f"--segments must be auto, none or an integer ≥ 2, not {text!r}")
    return count


def _assignments(text: str | None) -> dict[str, float]:
    """``--set NAME=VALUE,NAME=VALUE`` as a dict."""
    if text is None:
        return {}
    values: dict[str, float] = {}
    for part in text.split(","):
        name, sep, value = part.partition("=")
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not sep or not name.strip() or not math.isfinite(number):
            raise ConfigError(
                f"--set takes NAME=VALUE pairs separated by commas (finite numbers), got {part!r}"
            )
        values[name.strip()] = number
    return values


@guarded
def greybox_command(
    model_file: Annotated[
        Path,
        typer.Argument(
            metavar="MODEL.py",
            help="The model: a Python file with states, parameters, f(t, x, u, p) and optionally "
            "h(x, u, p), x0(p, u0, y0), inputs, outputs (see examples/two_tanks.py). It is RUN as "
            "Python: only give files you trust.",
        ),
    ],
    data_files: Annotated[
        list[Path],
        typer.Argument(
            metavar="DATA.csv",
            help="One or more logs (CSV or Parquet) to fit jointly, each with its own initial "
            "state.",
        ),
    ],
    validate_file: Annotated[
        Path | None,
        typer.Option(
            metavar="V.csv",
            help="A log (same columns) to validate on: the fitted model is simulated over it, its "
            "initial state fitted to the first 10 % (at least 20 samples) unless the model "
            "gives x0.",
            show_default=False,
        ),
    ] = None,
    time_col: Annotated[str, typer.Option(metavar="COLUMN", help="Time column [s].")] = "t_s",
    input_col: Annotated[
        str | None,
        typer.Option(
            metavar="COL[,COL..]",
            help="Input column(s), comma-separated, in the order of u[0], u[1], ... (default: "
            f"the model file's inputs, else {DEFAULT_INPUT}).",
            show_default=False,
        ),
    ] = None,
    output_col: Annotated[
        str | None,
        typer.Option(
            metavar="COL[,COL..]",
            help="Output column(s), comma-separated, one per model output (default: the model "
            f"file's outputs, else {DEFAULT_OUTPUT}); an empty cell is a missing sample.",
            show_default=False,
        ),
    ] = None,
    sample_time: SampleTime = None,
    fix: Annotated[
        str | None,
        typer.Option(
            metavar="NAME[,NAME..]",
            help="Hold these parameters at their value (the file's, or --set's).",
            show_default=False,
        ),
    ] = None,
    free: Annotated[
        str | None,
        typer.Option(
            metavar="NAME[,NAME..]",
            help="Estimate these parameters although the file fixes them.",
            show_default=False,
        ),
    ] = None,
    set_values: Annotated[
        str | None,
        typer.Option(
            "--set",
            metavar="NAME=VALUE[,..]",
            help="Start values (or fixed values) replacing the file's, in the model's units.",
            show_default=False,
        ),
    ] = None,
    initial_state: Annotated[
        InitialState,
        typer.Option(
            help="model: the file's x0(p, u0, y0); estimate: each record's initial state is "
            "estimated with the parameters; auto: the file's x0 when it has one.",
        ),
    ] = InitialState.auto,
    max_iterations: Annotated[
        int,
        typer.Option(
            min=1, help="Most iterations (Jacobian evaluations) of the least-squares solver."
        ),
    ] = 60,
    segments: Annotated[
        str,
        typer.Option(
            metavar="auto|none|N",
            help="Robust start for long records: fit first with the records cut into N segments "
            "(each with its own initial state; stages of a quarter as many), then the whole "
            "records. auto: only when the plain fit fails, or leaves residuals over 3× the "
            "records' sample-to-sample noise that its parameters would take on the segments "
            "(a local minimum, not a model error); none: never.",
        ),
    ] = "auto",
    solver: Annotated[
        SolverName | None,
        typer.Option(
            help="ODE solver. auto: LSODA, or where it cannot simulate the start values BDF with "
            "its step bounded by the sample interval, then fixed-step RK4 with its steps per "
            "sample doubled until they agree (up to 64; a stiffer model is refused). Default: "
            "the model file's solver, else auto.",
            show_default=False,
        ),
    ] = None,
    max_step: Annotated[
        float | None,
        typer.Option(
            metavar="SECONDS",
            help="Longest step of a variable-step solver (default: the model file's, else none).",
            show_default=False,
        ),
    ] = None,
    substeps: Annotated[
        int | None,
        typer.Option(
            metavar="N",
            help="RK4 steps per sample interval, 1…64 (default: the model file's, else chosen by "
            "doubling until the result agrees with twice as many).",
            show_default=False,
        ),
    ] = None,
    hold_undetermined: Annotated[
        bool,
        typer.Option(
            "--hold-undetermined",
            help="Hold a parameter the outputs do not depend on at all (one that acts only beyond "
            "a limit or kink the data never reach) at its value and fit the rest; the JSON lists "
            "it under not_determined with the reason. Without it such a fit is refused.",
        ),
    ] = False,
    profile: Annotated[
        str | None,
        typer.Option(
            metavar="NAME|all",
            help="Also give the profile-likelihood 95 % interval of these free parameters "
            "(comma-separated, or all); each costs a few fits.",
            show_default=False,
        ),
    ] = None,
    plot: Annotated[
        Path | None,
        typer.Option(
            metavar="FIG.png",
            help="Write measured versus simulated output with residuals, per record and for "
            "the validation log (PNG, SVG, PDF); an existing file only with --force.",
            show_default=False,
        ),
    ] = None,
    force: ForceFigureOption = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Fit the parameters of a nonlinear ODE model written in Python to one or more logs.

    The model file is Python and runs as such: only run files you trust. Its parameters, states
    and outputs are in your units; fuelid converts nothing. The fit is output error (free-run
    simulation against the measured outputs), with standard errors, 95 % intervals and an
    identifiability report. Parameters the data cannot tell apart are refused before fitting
    (exit code 2): fix one of them with --fix (and --set its known value).
    """
    from fuelid.greybox import describe_identifiability
    from fuelid.greybox.modelfile import read_model_file
    from fuelid.workflow import (
        fit_warnings,
        greybox_estimator,
        greybox_model,
        greybox_result,
    )

    check_figure_path(plot, overwrite=force)
    fixed_names = _names(fix, "--fix")
    free_names = _names(free, "--free")
    values = _assignments(set_values)
    mf = read_model_file(model_file)
    for message in mf.undeclared_switches:  # before the fit, which they may well end
        warn(message)
    model = greybox_model(mf, fixed_names, free_names, values)
    specs = model.parameters
    profiled = _profiled(profile, [spec.name for spec in specs if not spec.fixed])
    if initial_state is InitialState.model and not mf.has_x0:
        raise ConfigError(
            f"--initial-state model, but {model_file} defines no x0(p, u0, y0); use estimate"
        )
    columns = (_names(input_col, "--input-col"), _names(output_col, "--output-col"))
    inputs, outputs, records, validation = _read_records(
        mf, columns, data_files, validate_file, time_col, sample_time
    )
    start = _segments(segments)
    estimator = greybox_estimator(
        mf,
        model,
        initial_state=initial_state.value,
        max_iterations=max_iterations,
        segments=start,
        solver=None if solver is None else solver.value,
        max_step=max_step,
        substeps=substeps,
        hold_undetermined=hold_undetermined,
    )
    fitted = _fit(estimator, records, validation, profiled, segmented=start is not None)
    warnings = fit_warnings(estimator) + _also_fitted(validate_file, data_files)
    for message in warnings:
        warn(message)
    warnings = [*mf.undeclared_switches, *warnings]
    if plot is not None:
        _plot(estimator, records, validation, fitted.check, plot, model_file, list(inputs))
    profiles = fitted.profile if profiled else None
    result = greybox_result(mf, estimator, records, validation, fitted.check, profiles, warnings)
    result["wall_time_s"] = fitted.fit_seconds
    options = {
        "model_file": str(model_file),
        "data_files": [str(path) for path in data_files],
        "validate_file": None if validate_file is None else str(validate_file),
        "time_col": time_col,
        "input_col": list(inputs),
        "output_col": list(outputs),
        "sample_time": sample_time,
        "fix": fixed_names,
        "free": free_names,
        "set": values,
        "initial_state": initial_state.value,
        "max_iterations": max_iterations,
        "segments": segments,
        "solver": None if solver is None else solver.value,
        "max_step": max_step,
        "substeps": substeps,
        "hold_undetermined": hold_undetermined,
        "profile": profiled,
        "plot": None if plot is None else str(plot),
    }
    if as_json:
        block = _provenance(options, model_file, data_files, validate_file)
        emit_json(result | {"provenance": block} | block)
        return
    identifiability = describe_identifiability(result["identifiability"])
    _print(result, model_file, fitted.fit_seconds, identifiability)


# --- steps ----------------------------------------------------------------------------------------


def _read_records(
    mf: ModelFile,
    columns: tuple[list[str], list[str]],
    data_files: list[Path],
    validate_file: Path | None,
    time_col: str,
    sample_time: float | None,
) -> tuple[tuple[str, ...], tuple[str, ...], list[Record], Record | None]:
    """(input columns, output columns, the records, the validation record) from the logs.

    ``columns`` are ``--input-col`` and ``--output-col``'s names (empty: the model file's).
    The model file is checked at the first record's start before any fit.
    """
    from fuelid.workflow import data_columns, read_record

    inputs, outputs = data_columns(mf, *columns)
    records = [read_record(path, time_col, inputs, outputs, sample_time) for path in data_files]
    validation = (
        read_record(validate_file, time_col, inputs, outputs, sample_time)
        if validate_file is not None
        else None
    )
    mf.check(float(records[0].t[0]), records[0].u[0])
    return inputs, outputs, records, validation


def _fit(
    estimator: GreyBoxEstimator,
    records: list[Record],
    validation: Record | None,
    profiled: list[str],
    segmented: bool,
) -> GreyBoxFit:
    """:func:`~fuelid.workflow._greybox_fit.fit_greybox` with its stages on stderr.

    A refusal becomes a one-line reason that says what to type (``--fix``, ``--segments``).
    """
    from fuelid.greybox import ConvergenceError, NotIdentifiableError
    from fuelid.workflow import fit_greybox

    with progress_display() as stage:
        try:
            return fit_greybox(estimator, records, validation, profiled, progress=stage)
        except NotIdentifiableError as exc:
            report = exc.report
            raise FuelidError(
                _refusal(
                    report.message(),
                    report.undetermined_names,
                    estimator.model.parameters,
                    report.zero_sensitivity,
                )
            ) from None
        except ConvergenceError as exc:
            hint = "" if segmented else "; --segments auto or N tries a segmented start"
            raise ConvergenceError(f"{exc}{hint}") from None


def _also_fitted(validate_file: Path | None, data_files: list[Path]) -> list[str]:
    """The warning for a validation log that is also fitted (empty: none is)."""
    if validate_file is None or all(
        path.resolve() != validate_file.resolve() for path in data_files
    ):
        return []
    return [f"{validate_file} is also fitted: its validation fit is not a test on unseen data"]


def _provenance(
    options: dict[str, Any], model_file: Path, data_files: list[Path], validate_file: Path | None
) -> dict[str, Any]:
    """The provenance block, with the SHA-256 of every file read (the model file's too)."""
    files = [model_file, *data_files, *([validate_file] if validate_file is not None else [])]
    block = provenance(options, data_files[0])
    block["files_sha256"] = {str(path): file_sha256(path) for path in files}
    return block


def _profiled(profile: str | None, estimated: list[str]) -> list[str]:
    """The free parameters ``--profile`` asks for, refusing others before any work."""
    if profile is None:
        return []
    if profile.strip() == "all":
        return list(estimated)
    names = _names(profile, "--profile")
    unknown = [name for name in names if name not in estimated]
    if unknown:
        raise ConfigError(
            f"--profile {', '.join(unknown)}: not a free parameter; free: {', '.join(estimated)}"
        )
    return names


def _refusal(message: str, names: tuple[str, ...], specs: Any, unused: tuple[str, ...] = ()) -> str:
    """The one-line reason of a refused fit, with the --fix (or --hold-undetermined) it suggests."""
    parameters = [spec.name for spec in specs if spec.name in names]
    if not parameters:  # initial states alone: nothing --fix can hold
        return (
            f"{message}; give the model file an x0(p, u0, y0) that fixes the initial state, or "
            "a record that starts where the states are seen"
        )
    example = parameters[-1]
    # the message already says which to fix; the command line is what the user types
    text = f"{message}; with this command: --fix {example} --set {example}=VALUE"
    if any(spec.name in unused for spec in specs):
        text += (
            ", or --hold-undetermined to hold what the outputs do not depend on at its value "
            "and report it as not determined"
        )
    return text


def _plot(
    estimator: GreyBoxEstimator,
    records: list[Record],
    validation: Record | None,
    check: dict[str, Any] | None,
    path: Path,
    model_file: Path,
    input_names: list[str],
) -> None:
    from fuelid.plots import FitPanel, plot_greybox_fit, save_figure

    panels = [
        FitPanel(
            f"estimation: {record.name}",
            record.t,
            record.y,
            trajectory.outputs,
            fit.tolist(),
            input_u=record.u,
            input_names=input_names,
        )
        for record, trajectory, fit in zip(
            records, estimator.trajectories_, estimator.fit_percent_, strict=True
        )
    ]
    from fuelid.workflow import validation_head_end

    if validation is not None and check is not None:
        head = validation_head_end(validation) if check["convention"] == "estimate" else None
        panels.append(
            FitPanel(
                f"validation: {validation.name}",
                validation.t,
                validation.y,
                check["y_hat"],
                check["fit"],
                head,
                input_u=validation.u,
                input_names=input_names,
            )
        )
    fig = plot_greybox_fit(
        panels, estimator.model.output_names, title=f"{model_file.name}: measured and simulated"
    )
    save_figure(fig, path)


# --- text output ----------------------------------------------------------------------------------


def _print(
    result: dict[str, Any], model_file: Path, seconds: float, identifiability: list[str]
) -> None:
    """The text of ``fuelid greybox``: the parameter table, then the fit and what it rests on."""
    from rich.console import Console

    console = Console()
    console.print(_parameter_table(result, model_file))
    for line in _summary_lines(result, seconds, identifiability):
        console.print(line, highlight=False, markup=False)


def _parameter_table(result: dict[str, Any], model_file: Path) -> Table:
    """The parameters with their standard errors, 95 % intervals, status and units."""
    from rich.markup import escape
    from rich.table import Table

    units = result["units"].get("parameter_units", {})
    misfit = result["misfit"]
    # on a misfit the table itself says what its intervals rest on (the first screen)
    table = Table(
        title=escape(f"{model_file.name}: parameters (units of the model file)"),
        caption=None if misfit is None else escape(misfit["note"]),
        caption_justify="left",
    )
    for column in ("parameter", "value", "std. error", "95 % interval", "", "unit"):
        if column != "unit" or units:
            table.add_column(column, justify="right")
    for name, value in result["parameters"].items():
        se, ci = result["stderr"][name], result["ci95"][name]
        fixed = name in result["fixed"]
        status = (
            "fixed"
            if fixed
            else "not determined"
            if name in result["not_determined"]
            else "free"
            if se is not None
            else "free, undetermined"
        )
        cells = [
            name,
            format_estimate(value, se),
            "" if se is None else f"{se:.2g}",
            "" if ci is None else f"{format_estimate(ci[0], se)} … {format_estimate(ci[1], se)}",
            status,
        ]
        if units:
            cells.append(units.get(name, ""))
        table.add_row(*(escape(cell) for cell in cells))
    return table


def _summary_lines(result: dict[str, Any], seconds: float, identifiability: list[str]) -> list[str]:
    """The lines below the table: fits, validation, noise, initial states, profiles, the run."""
    lines = [
        f"fit (NRMSE, free-run simulation) on {name}: "
        + ", ".join(f"{k} {v:.2f} %" for k, v in fits.items())
        for name, fits in result["fit_percent"].items()
    ]
    if result["validation_fit_percent"] is not None:
        fits, rmse = result["validation_fit_percent"], result["validation_rmse"]
        lines.append(
            f"validation on {result['validation_file']}: "
            + ", ".join(f"{k} fit {fits[k]:.2f} %, RMSE {rmse[k]:.4g}" for k in fits)
            + f" (initial state {result['validation_initial_state']})"
        )
    lines.append(
        "noise level (residual std): "
        + ", ".join(f"{k} {v:.4g}" for k, v in result["noise_std"].items())
    )
    for name, x0 in result["initial_states"].items():
        lines.append(
            f"initial state of {name} ({result['initial_state']}): "
            + ", ".join(f"{k} = {v:.4g}" for k, v in x0.items())
        )
    if result["profile"]:
        for name, (lo, hi) in result["profile"].items():
            se = result["stderr"].get(name)
            lines.append(
                f"profile-likelihood 95 % interval of {name}: "
                f"{format_estimate(lo, se)} … {format_estimate(hi, se)}"
            )
    if result["start_search"] is not None:
        lines.append(result["start_search"]["reason"])
    for name, reason in result["not_determined"].items():
        lines.append(f"{name} not determined: {reason}")
    lines.extend(identifiability)
    lines.append(
        f"{result['n_iterations']} iterations, {result['start']}, solver "
        f"{result['solver_description']}, {seconds:.1f} s"
    )
    return lines
