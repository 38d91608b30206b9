"""``fuelid greybox``: fit the parameters of your own ODE model (a Python file) to logged data.

The command reads the model file (:mod:`fuelid.greybox.modelfile`) and the data files, applies
``--fix``/``--free``/``--set``, fits with :class:`~fuelid.greybox.GreyBoxEstimator`, validates on
``--validate-file`` and prints the parameters with their uncertainty and what the data determine.
The library is imported when the command runs (matplotlib only with ``--plot``).
"""

from __future__ import annotations

import enum
import math
import time
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
from fuelid.errors import ConfigError, DataError, FuelidError

if TYPE_CHECKING:
    from fuelid.greybox import GreyBoxEstimator, Record
    from fuelid.greybox.modelfile import ModelFile

VALIDATION_CONVENTIONS = {
    "estimate": "fitted to the first 10 % of the validation record (at least 20 samples), "
    "parameters held",
    "model": "the model's x0",
}
"""How the validation record's initial state is set (JSON ``validation_initial_state``)."""
RELATIVE_STDERR_LIMIT = 0.5
"""A free parameter whose standard error exceeds this share of its value is warned about."""
DEFAULT_INPUT = "u_V"
DEFAULT_OUTPUT = "q_Lpm"


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
            "records. auto: only when the plain fit fails or leaves residuals over 3× the "
            "records' sample-to-sample noise; none: never.",
        ),
    ] = "auto",
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
    from fuelid.greybox import GreyBoxEstimator, OdeModel, parameter_specs
    from fuelid.greybox.estimator import ConvergenceError, NotIdentifiableError
    from fuelid.greybox.modelfile import read_model_file

    check_figure_path(plot, overwrite=force)
    fixed_names = _names(fix, "--fix")
    free_names = _names(free, "--free")
    values = _assignments(set_values)
    mf = read_model_file(model_file)
    base = mf.model
    specs = parameter_specs(base.parameters, fixed=fixed_names, free=free_names, values=values)
    model = OdeModel(
        base.f,
        specs,
        base.state_names,
        h=base.h,
        x0=base.x0,
        output_names=base.output_names,
        n_outputs=len(base.output_names),
        state_scale=base.state_scale,
    )
    estimated = [spec.name for spec in specs if not spec.fixed]
    if not estimated:
        raise ConfigError(
            f"every parameter of {model_file} is fixed: free some with --free "
            f"({', '.join(spec.name for spec in specs)})"
        )
    profiled = _profiled(profile, estimated)
    if initial_state is InitialState.model and not mf.has_x0:
        raise ConfigError(
            f"--initial-state model, but {model_file} defines no x0(p, u0, y0); use estimate"
        )
    inputs, outputs = _columns(mf, input_col, output_col)
    records = [_read_record(path, time_col, inputs, outputs, sample_time) for path in data_files]
    validation = (
        _read_record(validate_file, time_col, inputs, outputs, sample_time)
        if validate_file is not None
        else None
    )
    mf.check(float(records[0].t[0]), records[0].u[0])

    start = _segments(segments)
    estimator = GreyBoxEstimator(
        model,
        initial_state=initial_state.value,
        max_iterations=max_iterations,
        segments=start,
    )
    started = time.perf_counter()
    with progress_display() as stage:
        stage("fitting")
        try:
            estimator.fit(records)
        except NotIdentifiableError as exc:
            raise FuelidError(
                _refusal(exc.report.message(), exc.report.undetermined_names, specs)
            ) from None
        except ConvergenceError as exc:
            hint = "; --segments auto or N tries a segmented start" if start is None else ""
            raise ConvergenceError(f"{exc}{hint}") from None
        fit_seconds = time.perf_counter() - started
        check = None
        if validation is not None:
            stage("validating")
            check = _validate(estimator, validation)
        intervals: dict[str, list[float]] = {}
        for name in profiled:
            stage(f"profiling {name}")
            lo, hi = estimator.profile_interval(name)
            intervals[name] = [lo, hi]
    warnings = _warnings(estimator)
    if validate_file is not None and any(
        path.resolve() == validate_file.resolve() for path in data_files
    ):
        warnings.append(
            f"{validate_file} is also fitted: its validation fit is not a test on unseen data"
        )
    for message in warnings:
        warn(message)
    if plot is not None:
        _plot(estimator, records, validation, check, plot, model_file, list(inputs))
    result = _result(
        mf, estimator, records, validation, check, intervals if profiled else None, warnings
    )
    result["wall_time_s"] = fit_seconds
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
        "profile": profiled,
        "plot": None if plot is None else str(plot),
    }
    files = [model_file, *data_files, *([validate_file] if validate_file is not None else [])]
    block = provenance(options, data_files[0])
    block["files_sha256"] = {str(path): file_sha256(path) for path in files}
    if as_json:
        emit_json(result | {"provenance": block} | block)
        return
    _print(result, model_file, fit_seconds)


# --- steps ----------------------------------------------------------------------------------------


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


def _columns(
    mf: ModelFile, input_col: str | None, output_col: str | None
) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The input and output column names, checked against the model's inputs and outputs."""
    model = mf.model
    inputs = tuple(_names(input_col, "--input-col")) or mf.input_names or (DEFAULT_INPUT,)
    outputs = tuple(_names(output_col, "--output-col")) or mf.output_names or (DEFAULT_OUTPUT,)
    if mf.input_names is not None and len(inputs) != len(mf.input_names):
        raise ConfigError(
            f"{mf.path} has {len(mf.input_names)} input(s) ({', '.join(mf.input_names)}); "
            f"--input-col gives {len(inputs)} ({', '.join(inputs)})"
        )
    if len(outputs) != len(model.output_names):
        raise ConfigError(
            f"{mf.path} has {len(model.output_names)} output(s) ({', '.join(model.output_names)}); "
            f"--output-col gives {len(outputs)} ({', '.join(outputs)})"
            + ("" if mf.output_names else ": name the model's outputs with outputs = [...]")
        )
    for role, names in (("input", inputs), ("output", outputs)):
        if len(set(names)) != len(names):
            raise ConfigError(f"{role} columns repeat a name: {', '.join(names)}")
    both = sorted(set(inputs) & set(outputs))
    if both:
        raise ConfigError(f"column(s) {', '.join(both)} given both as input and as output")
    return inputs, outputs


def _read_record(
    path: Path,
    time_col: str,
    inputs: tuple[str, ...],
    outputs: tuple[str, ...],
    sample_time: float | None,
) -> Record:
    """One data file as a record: a time column (or a sample time), inputs, outputs.

    Input cells must all be numbers; an empty output cell is a missing sample (NaN), a
    non-numeric one is refused.
    """
    import numpy as np

    from fuelid.greybox import Record
    from fuelid.io.tables import find_column, match_column, read_table, to_float

    source = repr(str(path))
    frame, _ = read_table(path)
    if sample_time is not None and not (math.isfinite(sample_time) and sample_time > 0.0):
        raise DataError(f"--sample-time must be a positive number of seconds, got {sample_time}")

    def column(name: str, role: str, missing_ok: bool) -> Any:
        found = find_column(frame, name, role, source)
        raw = frame[found]
        values = to_float(raw)
        if missing_ok:
            text = raw.astype(str).str.strip()
            empty = raw.isna().to_numpy() | text.isin(["", "nan", "NaN"]).to_numpy()
            bad = np.flatnonzero(~np.isfinite(values) & ~empty)
        else:
            bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            cell = str(raw.iloc[int(bad[0])])
            raise DataError(
                f"{source}: {role} column {found!r} has {bad.size} "
                f"{'non-numeric or infinite' if missing_ok else 'empty, non-numeric or infinite'} "
                f"cell(s), first at data row {int(bad[0]) + 1} ({cell[:24]!r})"
            )
        return values

    u = np.column_stack([column(name, "input", False) for name in inputs])
    y = np.column_stack([column(name, "output", True) for name in outputs])
    if match_column(frame, time_col) is None and sample_time is not None:
        t = sample_time * np.arange(len(frame), dtype=float)
    else:
        if match_column(frame, time_col) is None:
            find_column(frame, time_col, "time", source, hint="or give --sample-time")
        t = column(time_col, "time", False)
        if sample_time is not None and len(t) > 1:
            period = float(np.median(np.diff(t)))
            if not abs(period - sample_time) <= 0.01 * sample_time:
                raise DataError(
                    f"{source}: --sample-time {sample_time:g} s disagrees with the time column "
                    f"{time_col!r} (median interval {period:g} s)"
                )
    return Record.from_arrays(t, u, y, name=path.name)


def _refusal(message: str, names: tuple[str, ...], specs: Any) -> str:
    """The one-line reason of a refused fit, with the --fix it suggests."""
    parameters = [spec.name for spec in specs if spec.name in names]
    example = parameters[-1] if parameters else (names[0] if names else "NAME")
    # the message already says which to fix; the command line is what the user types
    return f"{message}; with this command: --fix {example} --set {example}=VALUE"


def _validate(estimator: GreyBoxEstimator, record: Record) -> dict[str, Any]:
    """Simulate the fitted model over the validation record: outputs, fit %, RMSE."""
    import numpy as np

    from fuelid.model import nrmse_fit_columns

    x0 = estimator.validation_initial_state(record)
    trajectory = estimator.simulate(record, x0)
    y_hat = trajectory.outputs
    error = record.y - y_hat
    rmse = [
        float(np.sqrt(np.mean(error[np.isfinite(error[:, k]), k] ** 2)))
        for k in range(error.shape[1])
    ]
    return {
        "y_hat": y_hat,
        "fit": [float(v) for v in nrmse_fit_columns(record.y, y_hat)],
        "rmse": rmse,
        "x0": trajectory.states[0],
        "convention": "model" if x0 is None else "estimate",
    }


def _warnings(estimator: GreyBoxEstimator) -> list[str]:
    """What a successful fit should be read with: confounded parameters, wide errors, bounds."""
    out = []
    report = estimator.identifiability_
    if not report.identifiable:
        out.append(report.message())
    from fuelid.greybox.estimator import SUSPECT_NOISE_RATIO, correlation_warning

    out.extend(correlation_warning(*pair) for pair in estimator.correlated_pairs())
    for name, ratio in zip(
        estimator.model.output_names, estimator.sigma_ / estimator.noise_floor_, strict=True
    ):
        if ratio > SUSPECT_NOISE_RATIO:
            out.append(
                f"the residuals of {name} are {ratio:.1f}× the records' sample-to-sample noise "
                "(a model error, slow disturbances or a local minimum): the standard errors "
                "assume white residuals and are too small"
            )
    for spec in estimator.model.parameters:
        if spec.fixed:
            continue
        value, se = estimator.params_[spec.name], estimator.stderr_[spec.name]
        if se is not None and value != 0.0 and se > RELATIVE_STDERR_LIMIT * abs(value):
            out.append(
                f"{spec.name}: standard error {se:.3g} is {100 * se / abs(value):.0f} % of its "
                "value: the data hardly determine it"
            )
        for side, bound in (("lower", spec.lower), ("upper", spec.upper)):
            if bound is not None and abs(value - bound) <= 1e-6 * max(abs(bound), 1e-12):
                out.append(
                    f"{spec.name} ended at its {side} bound {bound:g}: its error bars do not hold"
                )
    return out


def _result(
    mf: ModelFile,
    estimator: GreyBoxEstimator,
    records: list[Record],
    validation: Record | None,
    check: dict[str, Any] | None,
    profile: dict[str, list[float]] | None,
    warnings: list[str],
) -> dict[str, Any]:
    """The JSON object of the command (without provenance)."""
    model = estimator.model
    outputs = list(model.output_names)
    specs = model.parameters
    units: dict[str, Any] = {
        "parameters": "the model file's own units: fuelid converts nothing",
        "t": "s",
        "inputs": "the data files' units",
        "outputs": "the data files' units",
        "noise_std": "output units",
        "validation_rmse": "output units",
        "fit_percent": "%",
        "wall_time_s": "s",
    }
    if mf.units:
        units["parameter_units"] = dict(mf.units)
    return {
        "model_file": str(mf.path),
        "states": list(model.state_names),
        "outputs": outputs,
        "parameters": dict(estimator.params_),
        "stderr": dict(estimator.stderr_),
        "ci95": {k: None if v is None else list(v) for k, v in estimator.ci95_.items()},
        "fixed": [spec.name for spec in specs if spec.fixed],
        "free": list(estimator.free_names_),
        "correlation": {
            "parameters": list(estimator.free_names_),
            "matrix": estimator.correlation_.tolist(),
        },
        "fit_percent": {
            record.name: dict(zip(outputs, (float(v) for v in fit), strict=True))
            for record, fit in zip(records, estimator.fit_percent_, strict=True)
        },
        "initial_states": {
            record.name: dict(zip(model.state_names, x0.tolist(), strict=True))
            for record, x0 in zip(records, estimator.x0_, strict=True)
        },
        "initial_state": "estimated" if estimator.estimate_x0_ else "the model's x0",
        "validation_file": None if validation is None else validation.name,
        "validation_fit_percent": None
        if check is None
        else dict(zip(outputs, check["fit"], strict=True)),
        "validation_rmse": None
        if check is None
        else dict(zip(outputs, check["rmse"], strict=True)),
        "validation_initial_state": None
        if check is None
        else VALIDATION_CONVENTIONS[check["convention"]],
        "noise_std": dict(zip(outputs, (float(s) for s in estimator.sigma_), strict=True)),
        "n_iterations": estimator.n_iterations_,
        "start": estimator.start_,
        "identifiability": estimator.identifiability_.to_json(),
        "profile": profile,
        "warnings": warnings,
        "units": units,
    }


def _plot(
    estimator: GreyBoxEstimator,
    records: list[Record],
    validation: Record | None,
    check: dict[str, Any] | None,
    path: Path,
    model_file: Path,
    input_names: list[str],
) -> None:
    from fuelid.plots_greybox import FitPanel, plot_greybox_fit, save_greybox_figure

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
    if validation is not None and check is not None:
        head = None
        if check["convention"] == "estimate":
            n_head = max(20, int(0.1 * validation.n_samples))
            head = float(validation.t[min(n_head, validation.n_samples) - 1])
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
    save_greybox_figure(fig, path)


# --- text output ----------------------------------------------------------------------------------


def _print(result: dict[str, Any], model_file: Path, seconds: float) -> None:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    console = Console()
    units = result["units"].get("parameter_units", {})
    table = Table(title=escape(f"{model_file.name}: parameters (units of the model file)"))
    for column in ("parameter", "value", "std. error", "95 % interval", "", "unit"):
        if column != "unit" or units:
            table.add_column(column, justify="right")
    for name, value in result["parameters"].items():
        se, ci = result["stderr"][name], result["ci95"][name]
        fixed = name in result["fixed"]
        status = "fixed" if fixed else "free" if se is not None else "free, undetermined"
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
    console.print(table)
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
    lines.extend(_describe_identifiability(result["identifiability"]))
    lines.append(f"{result['n_iterations']} iterations, {result['start']}, {seconds:.1f} s")
    for line in lines:
        console.print(line, highlight=False, markup=False)


def _describe_identifiability(report: dict[str, Any]) -> list[str]:
    """The identifiability report as text lines."""
    condition = report["condition_number"]
    gamma = report["collinearity_index"]
    lines = [
        f"identifiability: rank {report['rank']} of {report['n_estimated']} "
        f"({', '.join(report['parameters'])}); condition number "
        f"{'inf' if condition is None else f'{condition:.3g}'}; collinearity index "
        f"{'inf' if gamma is None else f'{gamma:.3g}'} (1: independent sensitivities)"
    ]
    combos = report["undetermined"]
    lines.append(
        "undetermined combinations: "
        + (
            "; ".join(
                f"{c['combination']} (±{100 * c['relative_uncertainty']:.3g} %)"
                if c["relative_uncertainty"] is not None
                else f"{c['combination']} (unbounded)"
                for c in combos
            )
            or "none"
        )
    )
    pairs = report["confounded_pairs"]
    lines.append(
        "confounded pairs: "
        + (
            "; ".join(
                f"{p['parameters'][0]}–{p['parameters'][1]} (sensitivity correlation "
                f"{p['sensitivity_correlation']:.4f})"
                for p in pairs
            )
            or "none"
        )
    )
    if report["zero_sensitivity"]:
        lines.append(f"no effect on the outputs: {', '.join(report['zero_sensitivity'])}")
    return lines
