"""From a PLC log to PI gains in one call: identify, tune, check, run, schedule.

:func:`analyse_log` is what ``fuelid report`` and the demo run. It composes the same steps as the
individual commands: :func:`~fuelid.workflow.identification.plant_priors` and
:func:`~fuelid.identify.procedure.identify` (``fuelid identify``), then
:func:`~fuelid.workflow.tune.tune_model` with the nonlinear runs and
:func:`~fuelid.workflow.tune.schedule_gains` (``fuelid tune --simulate``, ``--schedule``) on the
identified model, so a report says exactly what the commands would.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from fuelid.blas import single_threaded_blas
from fuelid.errors import FuelidError
from fuelid.identify.diagnostics import (
    CorrelationTest,
    input_residual_correlation,
    residual_whiteness,
)
from fuelid.identify.procedure import IdentificationResult, IdentifyOptions, identify
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel, check_gain_identified
from fuelid.plant.config import PlantConfig
from fuelid.tuning.cases import DEFAULT_T_RANGE, CaseCache, FixedPIEvaluation
from fuelid.tuning.closedloop import ClosedLoopResult
from fuelid.tuning.frequency import frequency_grid, loop_function
from fuelid.tuning.result import UNITS, TuningResult
from fuelid.tuning.schedule import GainSchedule
from fuelid.workflow.identification import T_REF, plant_priors
from fuelid.workflow.progress import DIAGNOSTICS, IDENTIFICATION, Progress, announce
from fuelid.workflow.tune import (
    TuneOutcome,
    TuneRequest,
    check_conditions,
    schedule_gains,
    tune_model,
)

FloatArray = NDArray[np.float64]
Method = Literal["oe", "step-ls"]
METHODS: tuple[Method, ...] = ("step-ls", "oe")
"""Both estimators run side by side: the article's method and the output-error fit."""


@dataclass(frozen=True)
class AnalysisSettings:
    """What :func:`analyse_log` does beyond the log itself (defaults as ``fuelid report``)."""

    tune_from: Method = "oe"
    """Which identification the gains are computed from."""
    rule: str = "simc"
    closed_loop_time: float | None = None
    """The rule's τc (SIMC) or λ (lambda) [s], the desired closed-loop time constant: larger is
    slower and more robust; None for the rule's default."""
    control_period: float = 1.0
    """PLC period h [s] (0: continuous); also step-ls's decimation period."""
    T_fuel: float = T_REF
    """Fuel temperature during the log [K]."""
    T_range: tuple[float, float] = DEFAULT_T_RANGE
    """Fuel temperatures the gains are checked over [K]."""
    band_width: float = 10.0
    """Temperature band of the schedule [K]."""
    ms_target: float = 1.7
    """Largest Ms the schedule accepts [-]."""
    flow_bands: int = 3
    validate_split: float | None = 0.3
    """Share of the log held out for validation (None: fit on all of it)."""
    step_percent: float = 10.0
    """Setpoint step of the nonlinear closed-loop runs [% of the flowmeter span]."""

    def __post_init__(self) -> None:
        if self.tune_from not in METHODS:
            raise FuelidError(f"tune from 'oe' or 'step-ls', not {self.tune_from!r}")
        check_conditions(self.T_fuel, self.T_range, self.step_percent)

    def tune_request(self, model: ProcessModel, u: float) -> TuneRequest:
        """What :func:`~fuelid.workflow.tune.tune_model` is asked for a model found around ``u``.

        The nonlinear runs are part of the report; the flow span is the plant's meter span.
        """
        return TuneRequest(
            model=model,
            rule=self.rule,
            closed_loop_time=self.closed_loop_time,
            control_period=self.control_period,
            T_fuel=self.T_fuel,
            u=u,
            T_range=self.T_range,
            band_width=self.band_width,
            ms_target=self.ms_target,
            flow_bands=self.flow_bands,
            simulate=True,
            step_percent=self.step_percent,
        )


@dataclass
class LogAnalysis:
    """Everything found on one log, ready for figures, tables and JSON (:meth:`to_json`)."""

    data: IOData
    settings: AnalysisSettings
    identifications: dict[str, IdentificationResult]
    """By method, in the order of :data:`METHODS`."""
    outcome: TuneOutcome
    """The gains from the chosen model, checked over temperature and run on the plant."""
    schedule: GainSchedule
    """Gains per temperature (and flow) band, anchored to the chosen model."""
    whiteness: CorrelationTest
    """Residual autocorrelation of the tuned-from model on the fitted samples."""
    input_correlation: CorrelationTest
    """Input–residual cross-correlation of the same."""
    bode_frequency: FloatArray
    """[rad/s]"""
    bode_loop: NDArray[np.complex128]
    """Loop frequency response L = C·G on the identified model (sampled PI, exact delay)."""
    warnings: list[str] = field(default_factory=list)

    @property
    def model_result(self) -> IdentificationResult:
        """The identification the gains come from."""
        return self.identifications[self.settings.tune_from]

    @property
    def u_operating(self) -> float:
        """Mean command of the log: the operating point the model describes [V]."""
        return self.outcome.u

    @property
    def tuning(self) -> TuningResult:
        """The gains in every form with their margins and the linear closed loop on the model."""
        return self.outcome.tuning

    @property
    def check(self) -> FixedPIEvaluation:
        """The gains on the plant over the temperature range and the drive's range."""
        return self.outcome.check

    @property
    def runs(self) -> list[ClosedLoopResult]:
        """Nonlinear closed loop at the coldest and the warmest fuel."""
        return self.outcome.runs

    def to_json(self) -> dict[str, Any]:
        """The documented JSON of ``fuelid report --json``, without the paths and provenance."""
        return {
            "identification": {m: r.to_json() for m, r in self.identifications.items()},
            "tuned_from": self.settings.tune_from,
            "tuning": self.tuning.to_json(),
            "temperature_check": self.check.as_dict(cases=False),
            "closed_loop_plant": [r.as_dict(events=False) for r in self.runs],
            "schedule": self.schedule.as_dict(),
            "warnings": self.warnings,
            "units": UNITS,
        }


def analyse_log(
    data: IOData,
    config: PlantConfig,
    settings: AnalysisSettings,
    progress: Progress | None = None,
) -> LogAnalysis:
    """Identify ``data`` with both methods, tune, check over temperature and build a schedule.

    ``config`` supplies the flowmeter priors (its lag and delay are held fixed), the prior
    settling time for step-ls, the signal and flow spans of the percent-of-span gains, and the
    physics of how the loop changes with fuel temperature (anchored to the identified model).
    The nonlinear closed-loop runs are on ``config``'s plant.

    ``progress``, when given, is called with each stage's name as it starts, in the order of
    :data:`~fuelid.workflow.progress.ANALYSIS_STAGES`. The work is many small matrices and long
    vectors, so BLAS runs on one thread throughout (:func:`~fuelid.blas.single_threaded_blas`):
    several times faster on a busy two-core machine.
    """
    with single_threaded_blas():
        return _analyse(data, config, settings, progress)


def _analyse(
    data: IOData, config: PlantConfig, settings: AnalysisSettings, progress: Progress | None
) -> LogAnalysis:
    """:func:`analyse_log`'s stages."""
    announce(progress, IDENTIFICATION)
    base = plant_priors(
        IdentifyOptions(
            control_period=max(settings.control_period, data.sample_time),
            validate_split=settings.validate_split,
        ),
        config,
        settings.T_fuel,
    )
    identifications: dict[str, IdentificationResult] = {}
    # what the loader noticed is said once, not once per method
    warnings: list[str] = [f"log: {note}" for note in data.notes]
    for method in METHODS:
        result = identify(data, replace(base, method=method))
        identifications[method] = result
        warnings.extend(f"{method}: {w}" for w in result.warnings if w not in data.notes)
    chosen = identifications[settings.tune_from]
    check_gain_identified(chosen.model.K, chosen.stderr.get("K"), f"{settings.tune_from} fit")
    u_op = float(np.clip(np.mean(data.u), config.vfd.u_min_V, config.vfd.u_max_V))
    request = settings.tune_request(chosen.model, u_op)
    cache: CaseCache = {}  # the check and the schedule share linearisations
    outcome = tune_model(config, request, progress, cache)
    warnings.extend(f"tuning: {w}" for w in outcome.warnings)
    schedule = schedule_gains(config, request, progress, cache).schedule
    announce(progress, DIAGNOSTICS)
    fitted = chosen.time < (chosen.split_time if chosen.split_time is not None else math.inf)
    residuals = chosen.y[fitted] - chosen.y_hat[fitted]
    u_model = data.u if chosen.time.size == data.n_samples else _held(data, chosen.time)
    max_lag = min(
        max(25, round(2.0 * settings.control_period / data.sample_time)), fitted.sum() // 4
    )
    omega = frequency_grid(chosen.model, outcome.pi)
    return LogAnalysis(
        data=data,
        settings=settings,
        identifications=identifications,
        outcome=outcome,
        schedule=schedule,
        whiteness=residual_whiteness(residuals),
        input_correlation=input_residual_correlation(u_model[fitted], residuals, max_lag),
        bode_frequency=omega,
        bode_loop=loop_function(chosen.model, outcome.pi)(omega),
        warnings=warnings,
    )


def _held(data: IOData, times: FloatArray) -> FloatArray:
    """The input held (zero-order) at other sample times, e.g. a decimated record's."""
    index = np.clip(np.searchsorted(data.t, times, side="right") - 1, 0, data.n_samples - 1)
    return np.asarray(data.u[index], dtype=float)
