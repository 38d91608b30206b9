"""From a PLC log to PI gains in one call: identify, tune, check over fuel temperature, schedule.

This is the chain ``fuelid report`` and the demo run; each step is the library function the
individual commands use (:func:`~fuelid.identify.procedure.identify`,
:func:`~fuelid.tuning.result.evaluate_tuning`, :func:`~fuelid.tuning.schedule.evaluate_fixed`,
:func:`~fuelid.tuning.closedloop.standard_runs`, :func:`~fuelid.tuning.schedule.gain_schedule`),
so a report says exactly what the commands would.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import FuelidError
from fuelid.identify.diagnostics import (
    CorrelationTest,
    input_residual_correlation,
    residual_whiteness,
)
from fuelid.identify.procedure import IdentificationResult, IdentifyOptions, identify
from fuelid.io.timeseries import IOData
from fuelid.model import check_gain_identified
from fuelid.plant.config import PlantConfig
from fuelid.plant.linear import linearise
from fuelid.tuning.closedloop import ClosedLoopResult, flow_at, standard_runs
from fuelid.tuning.frequency import frequency_grid, loop_function
from fuelid.tuning.result import TuningResult, evaluate_tuning
from fuelid.tuning.schedule import (
    Anchor,
    FixedPIEvaluation,
    GainSchedule,
    band_edges,
    evaluate_fixed,
    gain_schedule,
    plant_cases,
)
from fuelid.units import T0 as KELVIN

FloatArray = NDArray[np.float64]
Method = Literal["oe", "step-ls"]
METHODS: tuple[Method, ...] = ("step-ls", "oe")
"""Both estimators run side by side: the article's method and the output-error fit."""


@dataclass(frozen=True)
class AnalysisSettings:
    """What :func:`analyse_log` does beyond the log itself (defaults as ``fuelid tune``)."""

    tune_from: Method = "oe"
    """Which identification the gains are computed from."""
    rule: str = "simc"
    speed: float | None = None
    """The rule's tuning parameter (τc for SIMC, λ for lambda) [s]; None: the rule's default."""
    control_period: float = 1.0
    """PLC period h [s] (0: continuous); also step-ls's decimation period."""
    fuel_temperature: float = 20.0
    """Fuel temperature during the log [°C]."""
    t_range: tuple[float, float] = (-20.0, 50.0)
    """Fuel temperatures the gains are checked over [°C]."""
    band_width: float = 10.0
    """Temperature band of the schedule [°C]."""
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
        low, high = self.t_range
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise FuelidError(f"the temperature range needs low < high, got {low:g}…{high:g} °C")
        if not math.isfinite(self.fuel_temperature):
            raise FuelidError("the fuel temperature must be a finite number of °C")
        if not (math.isfinite(self.step_percent) and 0.0 < self.step_percent <= 50.0):
            raise FuelidError(f"the setpoint step must be 0…50 % of span, got {self.step_percent}")


@dataclass
class LogAnalysis:
    """Everything found on one log, ready for figures, tables and JSON."""

    data: IOData
    settings: AnalysisSettings
    identifications: dict[str, IdentificationResult]
    """By method, in the order of :data:`METHODS`."""
    u_operating: float
    """Mean command of the log: the operating point the model describes [V]."""
    tuning: TuningResult
    whiteness: CorrelationTest
    """Residual autocorrelation of the tuned-from model on the fitted samples."""
    input_correlation: CorrelationTest
    """Input–residual cross-correlation of the same."""
    bode_frequency: FloatArray
    """[rad/s]"""
    bode_loop: NDArray[np.complex128]
    """Loop frequency response L = C·G on the identified model (sampled PI, exact delay)."""
    check: FixedPIEvaluation
    """The gains on the plant over the temperature range and the drive's range."""
    runs: list[ClosedLoopResult]
    """Nonlinear closed loop at the coldest and the warmest fuel."""
    schedule: GainSchedule
    warnings: list[str] = field(default_factory=list)

    @property
    def model_result(self) -> IdentificationResult:
        """The identification the gains come from."""
        return self.identifications[self.settings.tune_from]


def analyse_log(data: IOData, config: PlantConfig, settings: AnalysisSettings) -> LogAnalysis:
    """Identify ``data`` with both methods, tune, check over temperature and build a schedule.

    ``config`` supplies the flowmeter priors (its lag and delay are held fixed), the prior
    settling time for step-ls, the signal and flow spans of the percent-of-span gains, and the
    physics of how the loop changes with fuel temperature (anchored to the identified model).
    The nonlinear closed-loop runs are on ``config``'s plant.
    """
    meter = config.flowmeter
    u_mid = 0.5 * (config.vfd.u_min_V + config.vfd.u_max_V)
    settling = linearise(config, u_mid, settings.fuel_temperature + KELVIN).settling_time()
    identifications: dict[str, IdentificationResult] = {}
    warnings: list[str] = []
    for method in METHODS:
        result = identify(
            data,
            IdentifyOptions(
                method=method,
                flowmeter_T=meter.time_constant_s,
                flowmeter_delay=meter.delay_s,
                settling_time=settling,
                control_period=max(settings.control_period, data.sample_time),
                validate_split=settings.validate_split,
            ),
        )
        identifications[method] = result
        warnings.extend(f"{method}: {w}" for w in result.warnings)
    chosen = identifications[settings.tune_from]
    check_gain_identified(chosen.model.K, chosen.stderr.get("K"), f"{settings.tune_from} fit")
    u_op = float(np.clip(np.mean(data.u), config.vfd.u_min_V, config.vfd.u_max_V))
    u_span = config.vfd.u_max_V - config.vfd.u_min_V
    tuning = evaluate_tuning(
        chosen.model,
        settings.rule,
        settings.control_period,
        settings.speed,
        u_span,
        meter.span_Lpm,
    )
    warnings.extend(f"tuning: {w}" for w in tuning.warnings)
    fitted = chosen.time < (chosen.split_time if chosen.split_time is not None else math.inf)
    residuals = chosen.y[fitted] - chosen.y_hat[fitted]
    u_model = data.u if chosen.time.size == data.n_samples else _held(data, chosen.time)
    max_lag = min(
        max(25, round(2.0 * settings.control_period / data.sample_time)), fitted.sum() // 4
    )
    anchor = Anchor(chosen.model, settings.fuel_temperature, u_op)
    low, high = settings.t_range
    temps = tuple(float(t) for t in band_edges(low, high, settings.band_width))
    commands = (config.vfd.u_min_V, u_op, config.vfd.u_max_V)
    omega = frequency_grid(chosen.model, tuning.pi)
    return LogAnalysis(
        data=data,
        settings=settings,
        identifications=identifications,
        u_operating=u_op,
        tuning=tuning,
        whiteness=residual_whiteness(residuals),
        input_correlation=input_residual_correlation(u_model[fitted], residuals, max_lag),
        bode_frequency=omega,
        bode_loop=loop_function(chosen.model, tuning.pi)(omega),
        check=evaluate_fixed(tuning.pi, plant_cases(config, temps, commands, anchor)),
        runs=standard_runs(
            config,
            tuning.pi,
            (low, high),
            flow_at(config, u_op, settings.fuel_temperature),
            settings.step_percent / 100 * meter.span_Lpm,
        ),
        schedule=gain_schedule(
            config,
            settings.rule,
            settings.control_period,
            settings.speed,
            t_range=settings.t_range,
            band_width=settings.band_width,
            ms_target=settings.ms_target,
            flow_bands=settings.flow_bands,
            anchor=anchor,
        ),
        warnings=warnings,
    )


def _held(data: IOData, times: FloatArray) -> FloatArray:
    """The input held (zero-order) at other sample times, e.g. a decimated record's."""
    index = np.clip(np.searchsorted(data.t, times, side="right") - 1, 0, data.n_samples - 1)
    return np.asarray(data.u[index], dtype=float)
