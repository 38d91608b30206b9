"""Fitting a user's ODE model file to logs: what ``fuelid greybox`` runs, without the printing.

The model file (:mod:`fuelid.greybox.modelfile`) gives the model; :func:`greybox_model` applies
the fixed, freed and set parameters, :func:`data_columns` and :func:`read_record` read the logs
as :class:`~fuelid.greybox.Record` objects, :func:`greybox_estimator` sets up the
:class:`~fuelid.greybox.GreyBoxEstimator` with the model file's solver settings,
:func:`fit_greybox` fits the records, validates (:func:`validate_fit`) and profiles,
:func:`fit_warnings` says what the fit should be read with, and :func:`greybox_result` is the
command's JSON object (without provenance).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fuelid.errors import ConfigError, DataError
from fuelid.greybox import (
    LINEARITY_LIMIT,
    SUSPECT_NOISE_RATIO,
    VALIDATION_HEAD_SHARE,
    GreyBoxEstimator,
    OdeModel,
    Record,
    check_request,
    correlation_warning,
    parameter_specs,
)
from fuelid.greybox.modelfile import ModelFile
from fuelid.io.tables import find_column, match_column, read_table, to_float
from fuelid.io.timeseries import INPUT_COLUMN, OUTPUT_COLUMN
from fuelid.model import nrmse_fit_columns
from fuelid.workflow._progress import Progress, announce

VALIDATION_CONVENTIONS = {
    "estimate": "fitted to the first 10 % of the validation record (at least 20 samples), "
    "parameters held",
    "model": "the model's x0",
}
"""How the validation record's initial state is set (JSON ``validation_initial_state``)."""
RELATIVE_STDERR_LIMIT = 0.5
"""A free parameter whose standard error exceeds this share of its value is warned about."""


def greybox_model(
    mf: ModelFile,
    fixed: Sequence[str] = (),
    free: Sequence[str] = (),
    values: Mapping[str, float] | None = None,
) -> OdeModel:
    """The model file's model with ``fixed`` parameters held, ``free`` ones estimated.

    ``values`` replaces start (or fixed) values, in the model file's units. A model whose every
    parameter ends up fixed is refused (:class:`~fuelid.errors.ConfigError`).
    """
    base = mf.model
    specs = parameter_specs(base.parameters, fixed=fixed, free=free, values=values)
    model = OdeModel(
        base.f if base.moded_f is None else base.moded_f,  # (a switched f takes the modes)
        specs,
        base.state_names,
        h=base.h,
        x0=base.x0,
        output_names=base.output_names,
        n_outputs=len(base.output_names),
        state_scale=base.state_scale,
        switches=base.switches,
    )
    if all(spec.fixed for spec in specs):
        raise ConfigError(
            f"every parameter of {mf.path} is fixed: free some with --free "
            f"({', '.join(spec.name for spec in specs)})"
        )
    return model


def data_columns(
    mf: ModelFile, input_cols: Sequence[str], output_cols: Sequence[str]
) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The input and output column names, checked against the model's inputs and outputs.

    ``input_cols`` and ``output_cols`` are the names given (``--input-col``, ``--output-col``);
    empty: the model file's, else the fuel loop's (``u_V``, ``q_Lpm``).
    """
    model = mf.model
    inputs = tuple(input_cols) or mf.input_names or (INPUT_COLUMN,)
    outputs = tuple(output_cols) or mf.output_names or (OUTPUT_COLUMN,)
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


def read_record(
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


def greybox_estimator(
    mf: ModelFile,
    model: OdeModel,
    *,
    initial_state: str = "auto",
    max_iterations: int = 60,
    segments: int | str | None = "auto",
    solver: str | None = None,
    max_step: float | None = None,
    substeps: int | None = None,
    hold_undetermined: bool = False,
) -> GreyBoxEstimator:
    """The estimator of ``model``, its solver settings taken from the model file unless given.

    ``solver``, ``max_step`` and ``substeps`` None take the model file's (its solver defaults
    to ``auto``). The file's substeps belong to RK4 (``auto`` may end there): a solver given
    that is neither drops them. A combination no solver runs is refused
    (:func:`fuelid.greybox.check_request`) before any work.
    """
    solver_name = solver if solver is not None else (mf.solver or "auto")
    if substeps is None and solver_name in {"rk4", "auto"}:
        substeps = mf.substeps
    estimator = GreyBoxEstimator(
        model,
        initial_state=initial_state,
        max_iterations=max_iterations,
        segments=segments,
        solver=solver_name,
        max_step=max_step if max_step is not None else mf.max_step,
        substeps=substeps,
        hold_undetermined=hold_undetermined,
    )
    check_request(estimator.solver, estimator.max_step, estimator.substeps)
    return estimator


@dataclass(frozen=True)
class GreyBoxFit:
    """What :func:`fit_greybox` did: the fitted estimator and the checks after the fit."""

    estimator: GreyBoxEstimator
    """Fitted (its ``params_``, ``stderr_``, ``ci95_``, ...)."""
    fit_seconds: float
    """Wall time of the fit alone [s] (not of the validation or the profiles)."""
    check: dict[str, Any] | None = None
    """:func:`validate_fit` on the validation record; None without one."""
    profile: dict[str, list[float]] = field(default_factory=dict)
    """Profile-likelihood 95 % interval [lower, upper] of each parameter asked for."""


def fit_greybox(
    estimator: GreyBoxEstimator,
    records: list[Record],
    validation: Record | None = None,
    profiled: Sequence[str] = (),
    progress: Progress | None = None,
) -> GreyBoxFit:
    """Fit ``records`` jointly, simulate ``validation``, profile the ``profiled`` parameters.

    ``progress`` is told each stage as it starts: ``fitting``, ``validating``,
    ``profiling NAME``. A fit the data do not determine raises
    :class:`~fuelid.greybox.NotIdentifiableError`, one that does not converge
    :class:`~fuelid.greybox.ConvergenceError`, both before anything else is done.
    """
    started = time.perf_counter()
    announce(progress, "fitting")
    estimator.fit(records)
    fit_seconds = time.perf_counter() - started
    check = None
    if validation is not None:
        announce(progress, "validating")
        check = validate_fit(estimator, validation)
    intervals: dict[str, list[float]] = {}
    for name in profiled:
        announce(progress, f"profiling {name}")
        lo, hi = estimator.profile_interval(name)
        intervals[name] = [lo, hi]
    return GreyBoxFit(estimator, fit_seconds, check, intervals)


def validate_fit(estimator: GreyBoxEstimator, record: Record) -> dict[str, Any]:
    """Simulate the fitted model over the validation record: outputs, fit %, RMSE.

    Returns ``y_hat``, ``fit`` [%] and ``rmse`` (output units) per output, the initial state
    ``x0`` and its ``convention`` (a key of :data:`VALIDATION_CONVENTIONS`).
    """
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


def fit_warnings(estimator: GreyBoxEstimator) -> list[str]:
    """What a successful fit should be read with: confounded parameters, wide errors, bounds."""
    out = []
    report = estimator.identifiability_
    if not report.identifiable:
        out.append(report.message())
    if report.unconfirmed:
        out.append(report.unconfirmed_message())
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
    for name, discrepancy in estimator.linearity_.items():
        if discrepancy is None and estimator.stderr_.get(name) is not None:
            out.append(
                f"{name}: its interval was not checked against the simulation (a step of one "
                f"standard error reaches a bound): --profile {name} gives one from simulations"
            )
        if discrepancy is not None and not discrepancy <= LINEARITY_LIMIT:
            shown = (
                "cannot be simulated"
                if math.isinf(discrepancy)
                else (f"is missed by its sensitivity by {100 * discrepancy:.0f} %")
            )
            out.append(
                f"{name}: the simulated change over one standard error {shown} (a switch the "
                "sensitivities do not follow, or strong nonlinearity): its standard error and "
                f"interval are not reliable; --profile {name} gives an interval from "
                "simulations alone"
            )
    for spec in estimator.model.parameters:
        if spec.fixed or spec.name in estimator.not_determined_:
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


def greybox_result(
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
        "free": [n for n in estimator.free_names_ if n not in estimator.not_determined_],
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
        "solver": estimator.solver_.to_json(),
        "solver_description": estimator.solver_.describe(),
        "not_determined": dict(estimator.not_determined_),
        "start_search": None
        if estimator.start_search_ is None
        else estimator.start_search_.to_json(),
        "linearity": dict(estimator.linearity_),
        "misfit": misfit(estimator, check),
        "identifiability": estimator.identifiability_.to_json(),
        "profile": profile,
        "warnings": warnings,
        "units": units,
    }


def misfit(estimator: GreyBoxEstimator, check: dict[str, Any] | None) -> dict[str, Any] | None:
    """What the intervals rest on when the residuals are many times the records' noise.

    None when every output's residual standard deviation is within
    :data:`~fuelid.greybox._multiple_shooting.SUSPECT_NOISE_RATIO` times its sample-to-sample
    noise. Otherwise ``residual_to_noise`` (the ratio per output) and ``note``: the standard
    errors and intervals are conditional on the model being right, and the error to quote is
    the validation RMSE (or, without a validation log, the residual standard deviation).
    """
    ratios = estimator.sigma_ / estimator.noise_floor_
    if not np.any(ratios > SUSPECT_NOISE_RATIO):
        return None
    names = estimator.model.output_names
    worst = int(np.argmax(ratios))
    if check is not None:
        quote = (
            "the validation RMSE ("
            + ", ".join(
                f"{name} {rmse:.4g}" for name, rmse in zip(names, check["rmse"], strict=True)
            )
            + ")"
        )
    else:
        quote = (
            "the residual standard deviation ("
            + ", ".join(
                f"{name} {sigma:.4g}" for name, sigma in zip(names, estimator.sigma_, strict=True)
            )
            + "); give --validate-file for an error on unseen data"
        )
    note = (
        f"the residuals are {ratios[worst]:.1f}× the records' sample-to-sample noise "
        f"({names[worst]}): the model misses something the data show (or the fit sits in a local "
        "minimum), so the standard errors "
        "and 95 % intervals hold only if the model were right; the figure to quote is " + quote
    )
    return {
        "residual_to_noise": dict(zip(names, (float(r) for r in ratios), strict=True)),
        "note": note,
    }


def validation_head_end(record: Record) -> float:
    """End time [s] of the head of a validation record its initial state is fitted to."""
    n_head = max(20, int(VALIDATION_HEAD_SHARE * record.n_samples))
    return float(record.t[min(n_head, record.n_samples) - 1])
