"""Calibrate chosen physical parameters of a plant file from logs, by output error on the ODE.

Each log is one record at its own fuel temperature (from ``--fuel-temp`` or the log's
fuel-temperature column); it starts at rest at its first command. The fit, its covariance and
the identifiability report come from :class:`~fuelid.greybox.GreyBoxEstimator` on
:class:`~fuelid.calibration.plant_model.PlantGreyBox`. The last ``holdout`` share of each log is
left out of the fit and predicted by simulating the whole log from its start: the held-out fit %.
A request the data cannot answer (a combination of parameters they leave undetermined, or two
whose sensitivities correlate above 0.999) is refused with the names and what data would help.
A fit that leaves residuals far above the logs' own noise is returned flagged as a misfit
(:mod:`~fuelid.calibration._fit_quality`). The logs are read by :mod:`~fuelid.calibration._logs`
(their names are re-exported here).
"""

from __future__ import annotations

import datetime as dt
import difflib
import math
import time
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid import __version__
from fuelid.calibration._fit_quality import LogFit, judge_fit, misfit_message
from fuelid.calibration._logs import (
    TEMPERATURE_SPREAD_K,
    CalibrationLog,
    calibration_log,
    load_calibration_log,
)
from fuelid.calibration.plant_model import NOT_CALIBRATABLE, PlantGreyBox
from fuelid.errors import ConfigError, DataError, FuelidError
from fuelid.greybox import GreyBoxEstimator, NotIdentifiableError, Record, correlation_warning
from fuelid.io.plantfile import update_plant_toml
from fuelid.model import nrmse_fit_columns
from fuelid.plant import (
    PlantConfig,
    load_plant_config,
    parameter_names,
    plant_config_from_dict,
    plant_parameters,
    reference_plant_text,
    with_parameters,
)

__all__ = [
    "TEMPERATURE_SPREAD_K",
    "CalibrationLog",
    "CalibrationRefused",
    "CalibrationResult",
    "calibrate",
    "calibrated_plant_text",
    "calibration_log",
    "check_free_names",
    "load_calibration_log",
    "starts_at_rest",
]

FloatArray = NDArray[np.float64]
METHOD = "output error on the nonlinear plant ODE (forward sensitivities), fuelid calibrate"
PROFILE_RELATIVE_STDERR = 0.1
"""Relative standard error above which the profile-likelihood interval is computed too."""
SEPARATE_TEMPERATURES_K = 5.0
RESIDUAL_NOISE_FACTOR = 2.0
"""Flow residuals beyond this multiple of the plant file's meter noise are warned about."""
REST_CHECK_S = 2.0
"""A log's first seconds that must be flat: it is simulated from rest at its first command."""
"""Logs this far apart in fuel temperature separate the viscosity-dependent parameters."""


class CalibrationRefused(FuelidError):
    """The data cannot support the requested calibration (names and advice in the message)."""


@dataclass
class CalibrationResult:
    """The calibrated parameters, their uncertainty and how well the plant now fits."""

    config: PlantConfig
    """The plant with the calibrated values."""
    free: tuple[str, ...]
    start: dict[str, float]
    parameters: dict[str, float]
    stderr: dict[str, float | None]
    ci95: dict[str, tuple[float, float] | None]
    covariance: FloatArray
    correlation: FloatArray
    units: dict[str, str]
    logs: list[CalibrationLog]
    fit_percent: list[dict[str, float | None]]
    noise_std: dict[str, float]
    identifiability: dict[str, Any]
    warnings: list[str] = field(default_factory=list)
    iterations: int = 0
    wall_time_s: float = 0.0
    created: str = ""
    simulated: list[FloatArray] = field(default_factory=list)
    """Each whole log simulated with the calibrated plant (flow, and pressure)."""
    fitted_samples: list[int] = field(default_factory=list)
    """How many samples of each log the fit used (the rest were held out)."""
    profile_ci95: dict[str, tuple[float, float]] = field(default_factory=dict)
    """Profile-likelihood 95 % intervals, where asked for or where the Gaussian one is shaky."""
    fit_quality: list[LogFit] = field(default_factory=list)
    """Each log's flow residuals against its own noise (:mod:`~fuelid.calibration._fit_quality`)."""
    misfit: str = ""
    """Why the model does not fit the data and its parameters are not to be trusted ("": it
    fits every log within the noise). Also the first of ``warnings``."""

    @property
    def trusted(self) -> bool:
        """False when the calibrated model does not fit the data (see ``misfit``)."""
        return not self.misfit

    def calibration_table(self) -> dict[str, Any]:
        """The plant file's ``[calibration]`` table."""
        return {
            "parameters": list(self.free),
            "values": [self.parameters[name] for name in self.free],
            "stderr": [self.stderr[name] for name in self.free],
            "covariance": self.covariance.tolist(),
            "ci95": [list(self.ci95[name] or (math.nan, math.nan)) for name in self.free],
            "logs": [
                {
                    "file": log.path.name,
                    "sha256": log.sha256,
                    "fuel_temperature_C": round(log.fuel_temperature_C, 3),
                }
                for log in self.logs
            ],
            "fit_percent": [entry["flow"] for entry in self.fit_percent],
            "created": self.created,
            "fuelid_version": __version__,
            "method": METHOD,
            "warnings": list(self.warnings),
        }

    def to_json(self) -> dict[str, Any]:
        """The documented JSON keys (docs/reference/json.md, "fuelid calibrate")."""
        return {
            "parameters": self.parameters,
            "start": self.start,
            "stderr": self.stderr,
            "ci95": {k: (list(v) if v else None) for k, v in self.ci95.items()},
            "profile_ci95": {k: list(v) for k, v in self.profile_ci95.items()},
            "correlation": {"parameters": list(self.free), "matrix": self.correlation.tolist()},
            "covariance": {"parameters": list(self.free), "matrix": self.covariance.tolist()},
            "fit_percent": self.fit_percent,
            "trusted": self.trusted,
            "misfit": self.misfit or None,
            "fit_quality": [judged.to_json() for judged in self.fit_quality],
            "noise_std": self.noise_std,
            "identifiability": self.identifiability,
            "warnings": self.warnings,
            "logs": [
                {
                    "file": str(log.path),
                    "sha256": log.sha256,
                    "fuel_temperature_C": log.fuel_temperature_C,
                    "samples": log.record.n_samples,
                }
                for log in self.logs
            ],
            "iterations": self.iterations,
            "wall_time_s": self.wall_time_s,
            "units": {
                **self.units,
                "fit_percent": "% (NRMSE fit: 100·(1 − ‖y − ŷ‖/‖y − ȳ‖))",
                "noise_std": "flow L/min, pressure MPa",
                "fit_quality": "noise_std, residual_rms: L/min; ratio: -; allowed_*: %",
                "fuel_temperature_C": "°C",
            },
        }


def check_free_names(free: Sequence[str]) -> tuple[str, ...]:
    """Validate the names to calibrate: known, calibratable, each once."""
    names = tuple(name.strip() for name in free if name.strip())
    if not names:
        raise ConfigError("name at least one parameter to calibrate (--free)")
    calibratable = [name for name in parameter_names() if name not in NOT_CALIBRATABLE]
    for name in names:
        if name not in NOT_CALIBRATABLE and name not in calibratable:
            if _is_plant_setting(name):
                raise ConfigError(
                    f"{name} is a setting of the plant file (a count, a text or a switch), not a "
                    f"physical parameter to fit: set it in the file; calibratable: "
                    f"{', '.join(calibratable)}"
                )
            close = difflib.get_close_matches(name, calibratable, n=1)
            hint = f"did you mean {close[0]}? " if close else ""
            raise ConfigError(
                f"unknown plant parameter {name!r}; {hint}calibratable: {', '.join(calibratable)}"
            )
        if name in NOT_CALIBRATABLE:
            raise ConfigError(f"{name} cannot be calibrated here: {NOT_CALIBRATABLE[name]}")
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise ConfigError(f"parameter(s) named twice in --free: {', '.join(repeated)}")
    return names


def _is_plant_setting(name: str) -> bool:
    """A key the plant file has that is no numeric parameter (``nozzle.count``, say)."""
    section, _, key = name.partition(".")
    reference = load_plant_config()
    return bool(key) and hasattr(getattr(reference, section, None), key)


def _advice(names: Sequence[str], logs: Sequence[CalibrationLog], pressure: bool) -> list[str]:
    temps = [log.fuel_temperature_C for log in logs]
    advice = []
    if max(temps) - min(temps) < SEPARATE_TEMPERATURES_K:
        advice.append(
            "add a log at another fuel temperature (the fuel's viscosity moves the leakage, "
            "not the other parameters)"
        )
    if not pressure:
        advice.append("log the pump outlet pressure (--pressure-col)")
    advice.append("make larger command steps")
    advice.append(
        f"or hold one of {', '.join(names)} at its plant-file value (drop it from --free)"
    )
    return advice


def _meter_noise(config: PlantConfig) -> float:
    """The flow residual the plant file's meter alone gives [L/min]: noise and quantisation."""
    meter = config.flowmeter
    return math.hypot(meter.noise_std_Lpm, meter.resolution_Lpm / math.sqrt(12.0))


COLLAPSE_FACTOR = 1e3
"""A free parameter driven this factor from its plant-file value has collapsed (a leakage to
nothing): the fit is compensating for something else."""


def _misfit(
    config: PlantConfig,
    registry: dict[str, Any],
    estimator: GreyBoxEstimator,
    names: Sequence[str],
) -> str | None:
    """Why a fit is no calibration when its flow residuals exceed the meter's noise (or None)."""
    expected = _meter_noise(config)
    flow_sigma = float(estimator.sigma_[0])
    if expected <= 0.0 or flow_sigma <= RESIDUAL_NOISE_FACTOR * expected:
        return None
    collapsed = [
        name
        for name in names
        if registry[name].value != 0.0
        and not COLLAPSE_FACTOR**-1
        < estimator.params_[name] / registry[name].value
        < COLLAPSE_FACTOR
    ]
    if not collapsed:
        return None  # a misfit, but the gap in the data is real: say that
    moves = ", ".join(
        f"{name} from {registry[name].value:.4g} to {estimator.params_[name]:.3g}"
        for name in collapsed
    )
    return (
        f"the plant file does not fit these logs: the flow residuals are {flow_sigma:.3g} L/min "
        f"against the meter's {expected:.3g} L/min, and the fit drove {moves}, where the "
        "data no longer determine it; parameters held at their file values are probably "
        "wrong for this plant: free them too or correct them in the file (no numbers are given)"
    )


def _fit_warnings(
    config: PlantConfig,
    names: Sequence[str],
    flow_sigma: float,
    pressure: bool,
    logs: Sequence[CalibrationLog],
) -> list[str]:
    """Warnings the fit's own numbers cannot give.

    A residual far above the meter's noise, a log that does not start at rest, two lags that
    flow alone cannot tell apart.
    """
    warnings = []
    expected = _meter_noise(config)
    if expected > 0.0 and flow_sigma > RESIDUAL_NOISE_FACTOR * expected:
        warnings.append(
            f"the flow residuals ({flow_sigma:.3g} L/min) are {flow_sigma / expected:.1f}× the "
            f"plant file's meter noise ({expected:.3g} L/min): the calibrated plant does not "
            "fit the logs; check the parameters held at their file values, the fuel "
            "temperatures, and that each log starts at rest"
        )
    for log in logs:
        if not starts_at_rest(log.record, expected):
            warnings.append(
                f"{log.path.name} does not start at rest (the flow moves in its first "
                f"{REST_CHECK_S:g} s): the calibration simulates each log from the steady state "
                "at its first command; cut the log to begin in a steady stretch"
            )
    lags = {"vfd.lag_s", "flowmeter.time_constant_s"}
    if lags <= set(names) and not pressure:
        warnings.append(
            "vfd.lag_s and flowmeter.time_constant_s are both free with flow alone: two lags in "
            "series give nearly the same flow whichever is which, so the fit may have swapped "
            "them; log the pump pressure (--pressure-col), which sees the drive but not the "
            "meter, or hold one at a known value"
        )
    return warnings


def starts_at_rest(record: Record, noise: float) -> bool:
    """True when the flow's first :data:`REST_CHECK_S` s are flat to within the noise.

    The means of the first and second halves of that stretch may differ by at most five
    standard errors of their difference (noise ``noise`` [L/min], white).
    """
    span = record.t - record.t[0]
    first = record.y[span <= REST_CHECK_S / 2, 0]
    second = record.y[(span > REST_CHECK_S / 2) & (span <= REST_CHECK_S), 0]
    first, second = first[np.isfinite(first)], second[np.isfinite(second)]
    if len(first) < 3 or len(second) < 3 or noise <= 0.0:
        return True
    standard_error = noise * math.sqrt(1.0 / len(first) + 1.0 / len(second))
    return bool(abs(np.mean(first) - np.mean(second)) <= 5.0 * standard_error)


def _split(record: Record, holdout: float) -> tuple[Record, int]:
    n_fit = record.n_samples if holdout <= 0.0 else round((1.0 - holdout) * record.n_samples)
    if n_fit < 50:
        raise DataError(f"{record.name}: too few samples to fit after the hold-out ({n_fit})")
    return record.head(n_fit), n_fit


def calibrate(
    config: PlantConfig,
    logs: Sequence[CalibrationLog],
    free: Sequence[str],
    *,
    holdout: float = 0.2,
    max_iterations: int = 60,
    profile: Sequence[str] = (),
) -> CalibrationResult:
    """Fit the ``free`` parameters of ``config`` to the logs.

    Parameters
    ----------
    config : PlantConfig
        The plant file: its values start the fit and hold every parameter not free.
    logs : sequence of CalibrationLog
        One or several logs, each at its fuel temperature, all with or all without pressure.
    free : sequence of str
        Dotted plant-file names (``pump.leakage_Lpm_per_MPa``, ``vfd.lag_s`` …).
    holdout : float
        Share of each log's end left out of the fit and predicted (0 fits everything).
    max_iterations : int
        Most iterations of the solver.
    profile : sequence of str
        Parameters to give a profile-likelihood 95 % interval as well ("all": every one). It is
        computed anyway for a parameter whose standard error exceeds
        :data:`PROFILE_RELATIVE_STDERR` of its value, where the Gaussian interval is not to be
        trusted (each costs several refits).

    Returns
    -------
    CalibrationResult
        With ``misfit`` (and ``trusted`` False) when a log's flow residuals exceed
        :data:`~fuelid.calibration._fit_quality.MISFIT_NOISE_RATIO` times its own noise: the
        model does not fit the data and the estimates are not to be trusted (the finding is
        also the first warning, so it travels into the plant file's ``[calibration]`` table).

    Raises
    ------
    CalibrationRefused
        If the data do not determine the parameters (names and advice in the message).
    ConvergenceError
        If the fit does not converge (no numbers).
    """
    names = check_free_names(free)
    pressure = _check_logs(logs, holdout)
    registry = plant_parameters(config)
    model = PlantGreyBox(config, names, pressure)
    splits = [_split(log.record, holdout) for log in logs]
    started = time.perf_counter()
    # single shooting only: the plant is well damped and each log starts from its steady state,
    # so the fit converges from the plant file's values; residuals above the meter's noise there
    # mean a model error (warned about below), which a segmented start cannot mend
    estimator = GreyBoxEstimator(
        model, initial_state="model", max_iterations=max_iterations, segments=None
    )
    records = [record for record, _ in splits]
    _fit_or_refuse(estimator, records, config, registry, names, logs, pressure)
    wall = time.perf_counter() - started
    values = {name: float(estimator.params_[name]) for name in names}
    calibrated = with_parameters(config, values)
    warnings = [note for log in logs for note in log.notes]
    warnings += _fit_warnings(config, names, estimator.sigma_[0], pressure, logs)
    fits, simulated = _log_fits(estimator, logs, splits, pressure)
    warnings += _estimate_warnings(estimator, model, values)
    warnings.extend(correlation_warning(*pair) for pair in estimator.correlated_pairs())
    fit_quality = judge_fit([log.record for log in logs], simulated, [n_fit for _, n_fit in splits])
    misfit = misfit_message(fit_quality, fits)
    if misfit:
        warnings.insert(0, misfit)
    profiles = _profiles(estimator, values, profile)
    return CalibrationResult(
        fit_quality=fit_quality,
        misfit=misfit,
        profile_ci95=profiles,
        config=calibrated,
        free=names,
        start={name: registry[name].value for name in names},
        parameters=values,
        stderr={name: estimator.stderr_[name] for name in names},
        ci95={name: estimator.ci95_[name] for name in names},
        covariance=np.asarray(estimator.cov_, dtype=float),
        correlation=np.asarray(estimator.correlation_, dtype=float),
        units={name: registry[name].unit for name in names},
        logs=list(logs),
        fit_percent=fits,
        noise_std=dict(zip(model.output_names, map(float, estimator.sigma_), strict=True)),
        identifiability=estimator.identifiability_.to_json(),
        warnings=warnings,
        iterations=int(estimator.n_iterations_),
        wall_time_s=wall,
        created=dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        simulated=simulated,
        fitted_samples=[n_fit for _, n_fit in splits],
    )


def _check_logs(logs: Sequence[CalibrationLog], holdout: float) -> bool:
    """Refuse no logs, a hold-out outside [0, 0.9) or logs mixed with and without pressure.

    Returns whether the logs have the pump pressure.
    """
    if not logs:
        raise DataError("give at least one log")
    if not 0.0 <= holdout < 0.9:
        raise ConfigError(f"--holdout must lie in [0, 0.9), got {holdout:g}")
    n_outputs = {log.record.y.shape[1] for log in logs}
    if len(n_outputs) > 1:
        raise DataError("either every log has the pump pressure or none has")
    return bool(n_outputs.pop() == 2)


def _fit_or_refuse(
    estimator: GreyBoxEstimator,
    records: list[Record],
    config: PlantConfig,
    registry: dict[str, Any],
    names: Sequence[str],
    logs: Sequence[CalibrationLog],
    pressure: bool,
) -> None:
    """Fit ``estimator`` to the records, or refuse with what the data cannot determine.

    Raises
    ------
    CalibrationRefused
        If the parameters are not identifiable from the logs, or the fit collapsed a free
        parameter to make up for a plant file wrong elsewhere (a misfit, said so).
    """
    try:
        estimator.fit(records)
    except NotIdentifiableError as exc:
        report = exc.report.with_advice(_advice(exc.report.undetermined_names, logs, pressure))
        raise CalibrationRefused(report.message()) from None
    report = estimator.identifiability_
    if report.identifiable:
        return
    # a plant file wrong elsewhere drives the free parameters to the edge (a leakage to
    # nothing), where they lose their sensitivity: that is a misfit, not missing data
    misfit = _misfit(config, registry, estimator, names)
    if misfit is not None:
        raise CalibrationRefused(misfit)
    report = report.with_advice(_advice(report.undetermined_names, logs, pressure))
    raise CalibrationRefused(report.message())


def _log_fits(
    estimator: GreyBoxEstimator,
    logs: Sequence[CalibrationLog],
    splits: Sequence[tuple[Record, int]],
    pressure: bool,
) -> tuple[list[dict[str, float | None]], list[FloatArray]]:
    """Each log's fit % (fitted part, and held-out part by simulating the whole log from its start).

    Also returns each whole log simulated with the calibrated plant.
    """
    fits: list[dict[str, float | None]] = []
    simulated: list[FloatArray] = []
    for log, (_, n_fit), fitted in zip(logs, splits, estimator.fit_percent_, strict=True):
        entry: dict[str, float | None] = {"flow": float(fitted[0])}
        if pressure:
            entry["pressure"] = float(fitted[1])
        entry["heldout_flow"] = None
        whole = estimator.simulate(log.record).outputs
        simulated.append(whole)
        if n_fit < log.record.n_samples:
            tail = nrmse_fit_columns(log.record.y[n_fit:], whole[n_fit:])
            entry["heldout_flow"] = float(tail[0])
            if pressure:
                entry["heldout_pressure"] = float(tail[1])
        fits.append(entry)
    return fits, simulated


def _estimate_warnings(
    estimator: GreyBoxEstimator, model: PlantGreyBox, values: dict[str, float]
) -> list[str]:
    """A parameter poorly determined (its error over half its value) or ended on a bound."""
    warnings = []
    for name, value in values.items():
        error = estimator.stderr_[name]
        if error is not None and abs(error) > 0.5 * abs(value):
            warnings.append(
                f"{name} is poorly determined: standard error {error:.3g} is over half its "
                f"value {value:.3g}"
            )
        spec = next(spec for spec in model.parameters if spec.name == name)
        for bound in (spec.lower, spec.upper):
            if bound is not None and bound != 0.0 and abs(value - bound) < 1e-6 * abs(bound):
                warnings.append(f"{name} ended on its bound {bound:g}: the interval is not valid")
    return warnings


def _profiles(
    estimator: GreyBoxEstimator, values: dict[str, float], profile: Sequence[str]
) -> dict[str, tuple[float, float]]:
    """Profile-likelihood intervals: those asked for, and where the standard error is large.

    Raises
    ------
    ConfigError
        If ``profile`` names a parameter that was not free.
    """
    names = list(values)
    wanted = set(names) if "all" in profile else set(profile)
    unknown = wanted - set(names)
    if unknown:
        raise ConfigError(f"--profile names {', '.join(sorted(unknown))}, which is not in --free")
    profiles: dict[str, tuple[float, float]] = {}
    for name in names:
        error = estimator.stderr_[name]
        shaky = error is not None and abs(error) > PROFILE_RELATIVE_STDERR * abs(values[name])
        if name in wanted or shaky:
            profiles[name] = estimator.profile_interval(name)
    return profiles


def _significant(value: float, digits: int) -> float:
    return float(f"{value:.{digits}g}") if math.isfinite(value) else value


def rounded_to_precision(value: float, stderr: float | None) -> float:
    """``value`` with the digits its standard error justifies, and two more (at least 6).

    The rounding moves it by at most a thousandth of a standard error.

    >>> rounded_to_precision(0.8399201234567, 0.000258)
    0.83992
    >>> rounded_to_precision(9.798612345, 0.00157), rounded_to_precision(1234.5678, None)
    (9.79861, 1234.57)
    """
    if value == 0.0 or not math.isfinite(value):
        return value
    digits = 6
    if stderr is not None and stderr > 0.0 and math.isfinite(stderr):
        digits = max(6, math.floor(math.log10(abs(value))) - math.floor(math.log10(stderr)) + 3)
    return float(f"{value:.{min(digits, 17)}g}")


def calibrated_plant_text(result: CalibrationResult, source: Path | None) -> str:
    """The calibrated plant file's text, checked to load back.

    ``source`` (or the packaged reference plant) with the calibrated values and a
    ``[calibration]`` table; its comments kept.
    """
    text = source.read_text(encoding="utf-8") if source is not None else reference_plant_text()
    values = {
        name: rounded_to_precision(value, result.stderr.get(name))
        for name, value in result.parameters.items()
    }
    table = result.calibration_table()
    table["values"] = [values[name] for name in result.free]
    # the rest to the digits that matter: 4 for errors, 6 for a covariance (made exactly
    # symmetric, which rounding of the two halves apart would not keep), 0.01 % for fits
    table["stderr"] = [None if e is None else _significant(e, 4) for e in table["stderr"]]
    covariance = 0.5 * (result.covariance + result.covariance.T)
    table["covariance"] = [[_significant(c, 6) for c in row] for row in covariance.tolist()]
    table["ci95"] = [
        [rounded_to_precision(bound, result.stderr.get(name)) for bound in pair]
        for name, pair in zip(result.free, table["ci95"], strict=True)
    ]
    table["fit_percent"] = [round(fit, 2) for fit in table["fit_percent"]]
    updated = update_plant_toml(text, values, table)
    plant_config_from_dict(tomllib.loads(updated), "the calibrated plant file")
    return updated
