"""From a model to gains with their evidence: tune, check over temperature, runs, sweep, schedule.

:func:`tune_model` is what ``fuelid tune`` runs and :func:`schedule_gains` what
``fuelid tune --schedule`` runs; :func:`~fuelid.workflow.analysis.analyse_log` runs both on the
model it identified. Each step is the tuning layer's function, so every caller gets the same
numbers. Nothing here prints or writes files; fuel temperatures are in kelvin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fuelid._deprecated import warn_renamed
from fuelid.blas import single_threaded_blas
from fuelid.errors import FuelidError
from fuelid.model import ProcessModel
from fuelid.plant.config import PlantConfig
from fuelid.tuning.cases import (
    DEFAULT_T_RANGE,
    Anchor,
    CaseCache,
    FixedPIEvaluation,
    evaluate_fixed,
    plant_cases,
)
from fuelid.tuning.closedloop import ClosedLoopResult, flow_at, standard_runs
from fuelid.tuning.frequency import robustness
from fuelid.tuning.limits import check_control_period, check_sweep_size, check_tunable
from fuelid.tuning.result import UNITS, TuningResult, evaluate_tuning
from fuelid.tuning.rules import PISettings
from fuelid.tuning.schedule import GainSchedule, band_edges, gain_schedule
from fuelid.tuning.sweep import SweepResult, uncertainty_sweep
from fuelid.units import kelvin_to_celsius
from fuelid.workflow.identification import T_REF
from fuelid.workflow.progress import (
    RUNS,
    SCHEDULE,
    SWEEP,
    TEMPERATURE_CHECK,
    TUNING,
    Progress,
    announce,
)

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class TuneRequest:
    """What to tune and how to check it: the settings of ``fuelid tune`` in the library's units.

    Invalid settings are refused on construction (:class:`~fuelid.errors.FuelidError`), before
    any work is done.
    """

    model: ProcessModel | None = None
    """The process model (K [(L/min)/V], times [s]); None only for a schedule from physics."""
    cov_names: tuple[str, ...] = ()
    """Names of the rows of ``cov`` (an identification's ``cov.names``)."""
    cov: ArrayLike | None = field(default=None, compare=False)
    """The identification's covariance, drawn from by the sweep (None: temperature only)."""
    rule: str = "simc"
    """A key of :data:`fuelid.tuning.rules.TUNING_RULES`."""
    closed_loop_time: float | None = None
    """The rule's τc (SIMC) or λ (lambda) [s]: the desired closed-loop time constant, larger is
    slower and more robust; None for the rule's default."""
    control_period: float = 1.0
    """PLC period h [s]; 0 for a continuous controller."""
    y_span: float | None = None
    """Flowmeter span of the percent-of-span gain [L/min]; None: the plant's meter span."""
    u_span: float | None = None
    """Drive signal span of the percent-of-span gain [V]; None: the plant's drive range."""
    T_fuel: float = T_REF
    """Fuel temperature the model was identified at [K] (anchors the physics)."""
    u: float | None = None
    """Command the model was identified around [V]; None: the middle of the drive's range."""
    T_range: tuple[float, float] = DEFAULT_T_RANGE
    """Coldest and warmest fuel of the checks, the runs and the schedule [K]."""
    band_width: float = 10.0
    """Temperature step of the check and band of the schedule [K]."""
    ms_target: float = 1.7
    """Largest Ms the schedule accepts in any band [-]."""
    flow_bands: int = 3
    """Command (flow) bands of the schedule where the gain depends on the flow."""
    simulate: bool = False
    """Run the standard test on the nonlinear plant at the coldest and the warmest fuel."""
    sweep: int | None = None
    """Evaluate the gains on this many plant variants (None: no sweep)."""
    step_percent: float = 10.0
    """Setpoint step of the nonlinear runs [% of ``y_span``]."""
    seed: int | None = 0
    """Seed of the sweep's draws."""
    alternatives: tuple[ProcessModel, ...] = ()
    """Structures the identification could not tell apart from ``model`` (its JSON
    ``structure.indistinct``): the gains are tuned on each too, and the chosen gains' Ms on each
    is reported."""

    def __post_init__(self) -> None:
        check_control_period(self.control_period)
        check_conditions(self.T_fuel, self.T_range, self.step_percent)
        if self.sweep is not None:
            check_sweep_size(self.sweep)
        if self.y_span is not None and not (math.isfinite(self.y_span) and self.y_span > 0.0):
            raise FuelidError(f"the flow span must be positive, got {self.y_span:g} L/min")
        if self.u_span is not None and not (math.isfinite(self.u_span) and self.u_span > 0.0):
            raise FuelidError(f"the drive span must be positive, got {self.u_span:g} V")
        if self.model is not None:
            check_tunable(self.model, self.control_period)

    def flow_span(self, config: PlantConfig) -> float:
        """The flow span of the percent-of-span gain [L/min]: ``y_span`` or the meter's."""
        return config.flowmeter.span_Lpm if self.y_span is None else self.y_span

    def drive_span(self, config: PlantConfig) -> float:
        """The drive span of the percent-of-span gain [V]: ``u_span`` or the drive's range."""
        return config.vfd.u_max_V - config.vfd.u_min_V if self.u_span is None else self.u_span


def check_conditions(T_fuel: float, T_range: tuple[float, float], step_percent: float) -> None:
    """Refuse a fuel temperature [K], a temperature range [K] or a setpoint step [%] that is wrong.

    Examples
    --------
    >>> check_conditions(293.15, (323.15, 253.15), 10.0)
    Traceback (most recent call last):
    ...
    fuelid.errors.FuelidError: the temperature range needs low < high, got 50…-20 °C
    """
    if not (math.isfinite(T_fuel) and T_fuel > 0.0):
        raise FuelidError(f"the fuel temperature must be a positive number of K, got {T_fuel:g}")
    low, high = T_range
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise FuelidError(
            f"the temperature range needs low < high, got {kelvin_to_celsius(low):g}…"
            f"{kelvin_to_celsius(high):g} °C"
        )
    if not (math.isfinite(step_percent) and 0.0 < step_percent <= 50.0):
        raise FuelidError(f"the setpoint step must be 0…50 % of span, got {step_percent:g}")


def operating_command(config: PlantConfig, u: float | None) -> float:
    """The command [V] a model describes: ``u``, or the middle of the drive's range when None."""
    lo, hi = config.vfd.u_min_V, config.vfd.u_max_V
    command = 0.5 * (lo + hi) if u is None else u
    if not (math.isfinite(command) and lo <= command <= hi):
        raise FuelidError(
            f"the command u = {command:g} V lies outside the drive's signal range {lo:g}…{hi:g} V"
        )
    return command


def check_over_temperature(
    config: PlantConfig,
    pi: PISettings,
    anchor: Anchor | None,
    T_range: tuple[float, float],
    band_width: float,
    u: float,
    cache: CaseCache | None = None,
) -> FixedPIEvaluation:
    """One PI over the temperatures ``T_range`` [K] in steps of ``band_width`` [K].

    At each temperature the drive's two ends and the operating command ``u`` [V]; margins on the
    full linearised plant, or on the anchored models when an identified model anchors them.
    """
    temperatures = tuple(float(T) for T in band_edges(T_range[0], T_range[1], band_width))
    commands = (config.vfd.u_min_V, u, config.vfd.u_max_V)
    return evaluate_fixed(pi, plant_cases(config, temperatures, commands, anchor, cache))


@dataclass(frozen=True)
class StructureGains:
    """The rule's gains on one structure the identification could not tell apart."""

    model: ProcessModel
    """The other structure's model (K [(L/min)/V], times [s])."""
    pi: PISettings
    """The rule's gains on it."""
    Ms_of_chosen_gains: float
    """Ms of the gains tuned on the kept model, if this structure is the true one [-]."""

    def as_dict(self, *args: Any, **kwargs: Any) -> dict[str, Any]:
        """Deprecated name of :meth:`to_json` (fuelid 0.2.0)."""
        warn_renamed(self, "as_dict")
        return self.to_json(*args, **kwargs)

    def to_json(self) -> dict[str, Any]:
        """JSON form: the model, its gains (Kc [V per L/min], Ti [s]) and the chosen gains' Ms."""
        return {
            "model": self.model.to_json(),
            "Kc": self.pi.Kc,
            "Ti": self.pi.Ti,
            "Ms_of_chosen_gains": self.Ms_of_chosen_gains,
        }


@dataclass(frozen=True)
class TuneOutcome:
    """One pair of gains with its evidence: what ``fuelid tune`` prints."""

    request: TuneRequest
    """What was asked."""
    u: float
    """The operating command the model describes [V] (``request.u`` or mid-range)."""
    y_span: float
    """The flow span of the percent-of-span gain [L/min] (``request.y_span`` or the meter's)."""
    tuning: TuningResult
    """The gains in every form, their margins and the linear closed loop on the model."""
    check: FixedPIEvaluation
    """The same gains over the temperature range, the drive's ends and the operating command."""
    runs: list[ClosedLoopResult] = field(default_factory=list)
    """The standard test on the nonlinear plant at the coldest and the warmest fuel."""
    sweep: SweepResult | None = None
    """The gains on plant variants (temperature and the model's covariance)."""
    structures: list[StructureGains] = field(default_factory=list)
    """The rule's gains on each structure the data could not tell apart from the model."""

    @property
    def pi(self) -> PISettings:
        """The gains."""
        return self.tuning.pi

    @property
    def warnings(self) -> list[str]:
        """What makes the gains unfit to use as they are (empty for a sound design)."""
        return self.tuning.warnings

    def structure_spread(self) -> dict[str, Any] | None:
        """The gains' spread over the model and the structures it could not be told from."""
        if not self.structures:
            return None
        Kc = [self.pi.Kc, *(s.pi.Kc for s in self.structures)]
        Ti = [self.pi.Ti, *(s.pi.Ti for s in self.structures)]
        return {
            "Kc": [min(Kc), max(Kc)],
            "Ti": [min(Ti), max(Ti)],
            "structures": [s.to_json() for s in self.structures],
        }

    def to_json(self) -> dict[str, Any]:
        """The documented JSON object of ``fuelid tune --json`` (without provenance)."""
        return self.tuning.to_json() | {
            "structure_spread": self.structure_spread(),
            "temperature_check": self.check.to_json(cases=True),
            "closed_loop_plant": [r.to_json(events=True) for r in self.runs] or None,
            "sweep": None if self.sweep is None else self.sweep.summary(),
            "units": UNITS,
        }


def tune_model(
    config: PlantConfig,
    request: TuneRequest,
    progress: Progress | None = None,
    cache: CaseCache | None = None,
) -> TuneOutcome:
    """Tune ``request.model`` and check the gains: the chain behind ``fuelid tune``.

    1. the rule's gains and their margins and linear closed loop on the model
       (:func:`~fuelid.tuning.result.evaluate_tuning`);
    2. the same gains over the fuel-temperature range and the drive's range, the physics
       anchored to the model (:func:`check_over_temperature`);
    3. with ``request.simulate``, the standard test on the nonlinear plant at the coldest and
       the warmest fuel, from rest at the flow of ``request.u`` at ``request.T_fuel``
       (:func:`~fuelid.tuning.closedloop.standard_runs`);
    4. with ``request.sweep``, the gains on that many plant variants
       (:func:`~fuelid.tuning.sweep.uncertainty_sweep`).

    The work is many small matrices, so BLAS runs on one thread throughout
    (:func:`~fuelid.blas.single_threaded_blas`).

    Parameters
    ----------
    config : PlantConfig
        The plant: spans, how the loop changes with fuel temperature, the nonlinear plant.
    request : TuneRequest
        What to tune and check; its ``model`` must be given.
    progress : callable, optional
        Called with each stage's name as it starts (:mod:`fuelid.workflow.progress`).
    cache : dict, optional
        Linearisations by (T_fuel, u), shared with a :func:`schedule_gains` of the same call.

    Returns
    -------
    TuneOutcome
    """
    if request.model is None:
        raise FuelidError("tuning needs a model (TuneRequest.model)")
    with single_threaded_blas():
        return _tune_model(config, request, request.model, progress, cache)


def _tune_model(
    config: PlantConfig,
    request: TuneRequest,
    model: ProcessModel,
    progress: Progress | None,
    cache: CaseCache | None,
) -> TuneOutcome:
    announce(progress, TUNING)
    u, y_span = operating_command(config, request.u), request.flow_span(config)
    u_span = request.drive_span(config)
    tuning = evaluate_tuning(
        model, request.rule, request.control_period, request.closed_loop_time, u_span, y_span
    )
    anchor = Anchor(model, request.T_fuel, u)
    announce(progress, TEMPERATURE_CHECK)
    check = check_over_temperature(
        config, tuning.pi, anchor, request.T_range, request.band_width, u, cache
    )
    runs = []
    if request.simulate:
        announce(progress, RUNS)
        start = flow_at(config, u, request.T_fuel)
        step = request.step_percent / 100.0 * y_span
        runs = standard_runs(config, tuning.pi, request.T_range, start, step)
    sweep = None
    if request.sweep is not None:
        announce(progress, SWEEP)
        cov = np.zeros((0, 0)) if request.cov is None else np.asarray(request.cov, dtype=float)
        sweep = uncertainty_sweep(
            tuning.pi,
            anchor,
            request.cov_names,
            cov,
            config,
            n=request.sweep,
            T_range=request.T_range,
            seed=request.seed,
        )
    structures = [
        StructureGains(
            model=other,
            pi=evaluate_tuning(
                other, request.rule, request.control_period, request.closed_loop_time
            ).pi,
            Ms_of_chosen_gains=robustness(other, tuning.pi).Ms,
        )
        for other in request.alternatives
    ]
    return TuneOutcome(
        request=request,
        u=u,
        y_span=y_span,
        tuning=tuning,
        check=check,
        runs=runs,
        sweep=sweep,
        structures=structures,
    )


@dataclass(frozen=True)
class ScheduleOutcome:
    """A gain schedule: what ``fuelid tune --schedule`` prints."""

    request: TuneRequest
    """What was asked."""
    u: float
    """The operating command the anchoring model describes [V] (``request.u`` or mid-range)."""
    schedule: GainSchedule

    def to_json(self) -> dict[str, Any]:
        """The documented JSON of ``fuelid tune --schedule --json`` (without provenance)."""
        model = self.request.model
        return self.schedule.to_json() | {
            "anchored_to_model": None if model is None else model.to_json(),
            "units": UNITS,
        }


def schedule_gains(
    config: PlantConfig,
    request: TuneRequest,
    progress: Progress | None = None,
    cache: CaseCache | None = None,
) -> ScheduleOutcome:
    """Gains per fuel-temperature (and flow) band: the chain behind ``fuelid tune --schedule``.

    From the plant's physics alone when ``request.model`` is None, else anchored to the model at
    ``request.T_fuel`` and ``request.u`` (:func:`~fuelid.tuning.schedule.gain_schedule`), with
    BLAS on one thread. ``progress`` is called with the stage's name as it starts
    (:mod:`fuelid.workflow.progress`).
    """
    u = operating_command(config, request.u)
    anchor = None if request.model is None else Anchor(request.model, request.T_fuel, u)
    announce(progress, SCHEDULE)
    with single_threaded_blas():
        schedule = gain_schedule(
            config,
            request.rule,
            request.control_period,
            request.closed_loop_time,
            T_range=request.T_range,
            band_width=request.band_width,
            ms_target=request.ms_target,
            flow_bands=request.flow_bands,
            anchor=anchor,
            cache=cache,
        )
    return ScheduleOutcome(request=request, u=u, schedule=schedule)
