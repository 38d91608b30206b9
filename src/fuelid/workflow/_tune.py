"""From a model to gains with their evidence: tune, check over temperature, runs, sweep, schedule.

:func:`tune_model` is what ``fuelid tune`` runs and :func:`schedule_gains` what
``fuelid tune --schedule`` runs; :func:`~fuelid.workflow._analysis.analyse_log` runs both on the
model it identified. Each step is the tuning layer's function, so every caller gets the same
numbers. Nothing here prints or writes files; fuel temperatures are in kelvin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fuelid.blas import single_threaded_blas
from fuelid.errors import FuelidError
from fuelid.identify import MisfitBound
from fuelid.io.fitted_model import FittedModel
from fuelid.lti import check_control_period
from fuelid.model import ProcessModel
from fuelid.plant import PlantConfig
from fuelid.tuning import (
    DEFAULT_T_RANGE,
    UNITS,
    Anchor,
    BandCheck,
    CaseCache,
    CommandBand,
    FixedPIEvaluation,
    GainSchedule,
    LinearResponse,
    PISettings,
    Robustness,
    RobustPeak,
    StateSpacePlant,
    SweepResult,
    TransferFunctionPlant,
    TuningResult,
    band_check,
    band_edges,
    check_sweep_size,
    check_tunable,
    evaluate_fixed,
    evaluate_tuning,
    full_order_closed_loop,
    gain_schedule,
    misfit_overshoot,
    plant_cases,
    robust_peak,
    robustness,
    step_duration,
    uncertainty_sweep,
)
from fuelid.tuning.closedloop import ClosedLoopResult, flow_at, standard_runs
from fuelid.units import kelvin_to_celsius
from fuelid.workflow._assumptions import REFERENCE_PLANT_NOTICE, T_REF, PlantSource
from fuelid.workflow._progress import (
    RUNS,
    SCHEDULE,
    SWEEP,
    TEMPERATURE_CHECK,
    TUNING,
    Progress,
    announce,
)
from fuelid.workflow._trust import NO_CONTROL_PERIOD, Basis, Spans, overridden, spans_from

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
    """A key of :data:`fuelid.tuning.TUNING_RULES`."""
    closed_loop_time: float | None = None
    """The rule's τc (SIMC) or λ (lambda) [s]: the desired closed-loop time constant, larger is
    slower and more robust; None for the rule's default."""
    control_period: float | None = None
    """PLC period h [s]; 0 for a continuous controller. None is refused by :func:`tune_model`
    and :func:`schedule_gains`: gains for another period are wrong gains, so none is assumed
    (:func:`~fuelid.workflow._trust.control_period_from` finds it in the user's facts)."""
    control_period_basis: Basis = "option"
    """Where the control period came from (:data:`~fuelid.workflow._trust.Basis`)."""
    y_span: float | None = None
    """Flowmeter span of the percent-of-span gain [L/min] given as an option; None: the site
    file's (``site_spans``), else the user's plant file's, else none (no %/% gains)."""
    u_span: float | None = None
    """Drive signal span of the percent-of-span gain [V] given as an option; None: as
    ``y_span``."""
    site_spans: tuple[float | None, float | None] = (None, None)
    """The site file's ``[controller]`` spans (u_span_V [V], y_span_Lpm [L/min])."""
    command_bands: tuple[CommandBand, ...] = ()
    """K per command band the identification's log shows (its ``diagnostics.nonlinearity``):
    the range check when no plant file gives the physics."""
    full_order: TransferFunctionPlant | None = None
    """The full-order linear model the reduced ``model`` stands for (a model file's
    ``linear_model``): the gains' margins and Ms are certified on it."""
    misfit: MisfitBound | None = field(default=None, compare=False)
    """The identified model's error that its log shows (``diagnostics.misfit``): the gains' Ms
    is also given as the worst over it."""
    T_fuel: float = T_REF
    """Fuel temperature the model was identified at [K] (anchors the physics)."""
    u: float | None = None
    """Command the model was identified around [V]; None: the middle of the drive's range."""
    clip_u: bool = False
    """Take a ``u`` outside the drive's range to its nearest end (a model file's or a log's mean
    command, which the signal check has judged) instead of refusing it (a command given)."""
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
        if self.control_period is not None:
            check_control_period(self.control_period)
        check_conditions(self.T_fuel, self.T_range, self.step_percent)
        if self.sweep is not None:
            check_sweep_size(self.sweep)
        if self.y_span is not None and not (math.isfinite(self.y_span) and self.y_span > 0.0):
            raise FuelidError(f"the flow span must be positive, got {self.y_span:g} L/min")
        if self.u_span is not None and not (math.isfinite(self.u_span) and self.u_span > 0.0):
            raise FuelidError(f"the drive span must be positive, got {self.u_span:g} V")
        if self.model is not None and self.control_period is not None:
            check_tunable(self.model, self.control_period)

    def period(self) -> float:
        """The control period h [s], refused when nobody gave one."""
        if self.control_period is None:
            raise FuelidError(NO_CONTROL_PERIOD)
        return self.control_period

    def span_notes(self, plant: PlantSource) -> list[str]:
        """Where another source gave a different span than the one the %/% gains use."""
        spans = self.spans(plant)
        config = plant.config
        notes: list[str] = []
        for kept, unit, index, own in (
            (spans.u_span, "V", 0, config.vfd.u_max_V - config.vfd.u_min_V),
            (spans.y_span, "L/min", 1, config.flowmeter.span_Lpm),
        ):
            if kept is None:
                continue
            sources = {
                "option": (self.u_span, self.y_span)[index],
                "site file": self.site_spans[index],
            }
            if not plant.is_reference:
                sources["plant file"] = own
            notes += overridden(sources, unit, kept)
        return notes

    def spans(self, plant: PlantSource) -> Spans:
        """The spans of the %/% gains from the user's facts: options, site file, plant file."""
        config = plant.config
        return spans_from(
            self.u_span,
            self.y_span,
            self.site_spans,
            None
            if plant.is_reference
            else (config.vfd.u_max_V - config.vfd.u_min_V, config.flowmeter.span_Lpm),
        )


def model_file_fields(loaded: FittedModel | None) -> dict[str, Any]:
    """What a model file gives a :class:`TuneRequest` beyond its model; empty for no file.

    Its covariance, the log's command bands, the model's misfit, its full-order linear model and
    the structures it could not rule out.
    """
    if loaded is None:
        return {}
    linear = loaded.linear_model
    return {
        "cov_names": loaded.cov_names,
        "cov": loaded.cov,
        "command_bands": tuple(CommandBand(*band) for band in loaded.gain_bands),
        "misfit": None if loaded.misfit is None else MisfitBound.from_json(loaded.misfit),
        "full_order": None
        if linear is None
        else TransferFunctionPlant.from_coefficients(linear.num, linear.den, linear.delay),
        "alternatives": loaded.alternatives,
    }


def tune_notices(
    plant: PlantSource,
    request: TuneRequest,
    *,
    fuel_basis: str | None,
    conditional: bool = False,
    model_label: str = "the model",
) -> list[str]:
    """The assumptions every output of a tuning states first, from the library, not the CLI.

    ``fuel_basis`` says where the model's fuel temperature came from (None: nobody gave it and
    20 °C is assumed); ``conditional`` that the model's intervals hold only within its
    structure (the identification's ``structure.conditional``); ``model_label`` names the
    model in the text (a file name).
    """
    notices = []
    if plant.is_reference:
        notices.append(REFERENCE_PLANT_NOTICE)
    if fuel_basis is None and request.model is not None and not plant.is_reference:
        notices.append(
            f"fuel temperature of the model assumed {kelvin_to_celsius(T_REF):g} °C: "
            "--fuel-temp not given and the model file has none; the temperature check is "
            "anchored there"
        )
    if conditional:
        notices.append(
            f"the model's intervals are conditional on its structure ({model_label}: "
            "structure.conditional): see the gains' spread across the structures the log "
            "could not tell apart"
            if request.alternatives
            else f"the model's intervals are conditional on its structure ({model_label}: see "
            "its structure and warnings): they hold if that structure is right; --sweep, which "
            "draws from the covariance, shows the spread within that structure only"
        )
    return notices + calibration_notices(plant, request)


def calibration_notices(plant: PlantSource, request: TuneRequest) -> list[str]:
    """What a calibrated plant file's calibration warned, at the model's and edge temperatures."""
    config = plant.config
    if plant.is_reference or config.calibration is None:
        return []
    from fuelid.plant import calibration_summary

    summary, _ = calibration_summary(config, request.T_fuel)
    warned = summary["warnings"]
    notices = [f"calibrated plant: the calibration warned: {w}" for w in warned]
    for T_edge in request.T_range:
        edge_notes = calibration_summary(config, T_edge)[1]
        # the calibration's own warnings come last in the notes and are given once above
        notices.extend(
            f"calibrated plant: {n}" for n in edge_notes[: len(edge_notes) - len(warned)]
        )
    return notices


PLANT_MODEL_AGREEMENT = 0.15
"""Relative gap between the plant file's K and the model's above which the outputs say the plant
file describes another loop (its runs and trend then are not this loop's)."""

OVERSHOOT_AGREEMENT = 5.0
"""Percentage points between the nonlinear run's overshoot and the linear prediction above which
the outputs say the two disagree and which to believe (issue 37)."""


def detuned_for(
    plant: StateSpacePlant | ProcessModel, pi: PISettings, ms_target: float
) -> PISettings | None:
    """``pi`` with Kc lowered (Ti kept) until its Ms on ``plant`` is ``ms_target``.

    Bisection on the factor, to 0.1 %; None when even a factor of 0.05 does not reach it.
    """
    if robustness(plant, pi.with_gain_factor(0.05)).Ms > ms_target:
        return None
    low, high = 0.05, 1.0
    while high - low > 1e-3:
        middle = 0.5 * (low + high)
        r = robustness(plant, pi.with_gain_factor(middle))
        if r.stable and r.Ms <= ms_target:
            low = middle
        else:
            high = middle
    return pi.with_gain_factor(low)


def plant_static_gain(
    config: PlantConfig, T_fuel: float, u: float, cache: CaseCache | None = None
) -> float:
    """The plant file's static gain at fuel temperature ``T_fuel`` [K] and command ``u`` [V]."""
    return float(plant_cases(config, (T_fuel,), (u,), None, cache)[0].model.K)


def _same_gain(model_K: float, plant_K: float) -> bool:
    """Whether a model's K is the plant file's own, to rounding: the plant file's reduction.

    A plant info file's model agrees to rounding; one identified from data never to 1e-6.
    """
    return abs(plant_K - model_K) <= 1e-6 * abs(plant_K)


def as_plant_source(plant: PlantSource | PlantConfig) -> PlantSource:
    """A plant given to the library: a :class:`PlantSource`, or a bare config taken as the user's.

    A script that passes a :class:`~fuelid.plant._config.PlantConfig` passes its own plant; the
    built-in reference plant stands in only where a :class:`PlantSource` says so.
    """
    if isinstance(plant, PlantSource):
        return plant
    return PlantSource(plant, f"(plant {plant.name!r} given to the library)")


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


def operating_command(config: PlantConfig, u: float | None, clip: bool = False) -> float:
    """The command [V] a model describes: ``u``, or the middle of the drive's range when None.

    With ``clip`` a ``u`` a little outside the drive's range (a log's mean command, which the
    signal check has judged) is taken to the nearest end; otherwise it is refused.
    """
    lo, hi = config.vfd.u_min_V, config.vfd.u_max_V
    command = 0.5 * (lo + hi) if u is None else u
    if clip and math.isfinite(command):
        command = min(max(command, lo), hi)
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
    plant: PlantSource
    """The plant behind the checks: the user's plant file, or the reference plant standing in
    (then no figure rests on it: no temperature check, no runs)."""
    u: float
    """The operating command the model describes [V] (``request.u`` or mid-range)."""
    spans: Spans
    """The spans of the %/% gains and where they come from, or why there are none."""
    tuning: TuningResult
    """The gains in every form, their margins and the linear closed loop on the model."""
    check: FixedPIEvaluation | None
    """The same gains over the temperature range, the drive's ends and the operating command,
    on the user's plant file's physics; None without a plant file."""
    bands: BandCheck | None = None
    """The same gains over the command bands the identification's log shows (K per band)."""
    full_order: Robustness | None = None
    """The gains' margins and Ms on the full-order model (``request.full_order``), which the
    headline reports first."""
    full_order_step: LinearResponse | None = None
    """The linear closed loop's steps on the full-order model."""
    full_order_detuned: PISettings | None = None
    """The gains with Kc lowered until Ms on the full-order model meets ``request.ms_target``,
    when the rule's do not (None otherwise)."""
    plant_gain: float | None = None
    """The user's plant file's static gain at the model's command and fuel temperature
    [(L/min)/V]; None without a plant file."""
    misfit_peak: RobustPeak | None = None
    """The worst Ms over the model error the log shows (``request.misfit``), where it bounds it."""
    misfit_step: float | None = None
    """The setpoint overshoot of the model with that error [%] (a sampled PI only)."""
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
    def y_span(self) -> float | None:
        """The flow span of the percent-of-span gain [L/min], None when nobody gave one."""
        return self.tuning.y_span

    @property
    def certified(self) -> Robustness:
        """The margins and Ms to believe: on the full-order model when given, else the model's."""
        return self.tuning.robustness if self.full_order is None else self.full_order

    @property
    def warnings(self) -> list[str]:
        """What makes the gains unfit to use as they are (empty for a sound design)."""
        return self.tuning.warnings + self.disagreements()

    def disagreements(self) -> list[str]:
        """Where two figures of this outcome disagree, and which one to believe.

        The full-order model's Ms more than 10 % above the reduction's; the nonlinear run's
        overshoot more than :data:`OVERSHOOT_AGREEMENT` points from the linear prediction at the
        same fuel temperature and command.
        """
        found = []
        reduced = self.tuning.robustness.Ms
        worst = None if self.misfit_peak is None else self.misfit_peak.Ms
        if worst is not None and math.isfinite(worst) and worst > 1.1 * reduced:
            found.append(
                f"allowing for the misfit its log shows, these gains' Ms may reach {worst:.2f}, "
                f"not the model's {reduced:.2f}: the model misses dynamics the log holds; "
                "believe the larger figure"
            )
        elif worst is not None and not math.isfinite(worst):
            found.append(
                "the model's misfit its log shows could make this loop unstable, or the log "
                "does not excite the loop near its crossover to bound it: the model's Ms "
                f"{reduced:.2f} is not certain; a slower loop (a larger --tau-c or --lambda) "
                "or a log with faster command changes"
            )
        if self.full_order is not None and self.full_order.Ms > 1.1 * reduced:
            detuned = self.full_order_detuned
            found.append(
                f"on the full-order linear_model these gains give Ms {self.full_order.Ms:.2f}, "
                f"not the reduction's {reduced:.2f}: the reduction misses dynamics that matter; "
                "believe the full-order figure (it is the one printed)"
                + (
                    ""
                    if detuned is None
                    else f"; for Ms ≤ {self.request.ms_target:g} on it: Kc = {detuned.Kc:.4g} "
                    f"V/(L/min), Ti = {detuned.Ti:.4g} s"
                )
            )
        if self.plant_gain is not None:
            ratio = self.tuning.model.K / self.plant_gain
            if abs(ratio - 1.0) > PLANT_MODEL_AGREEMENT:
                found.append(
                    f"your plant file's K at the model's operating point is "
                    f"{self.plant_gain:.4g} (L/min)/V, the model's {self.tuning.model.K:.4g} "
                    f"({ratio:.2f}×): the plant file describes another loop, so its nonlinear "
                    "runs and its trend over temperature are not this loop's; calibrate it to "
                    "your logs (fuelid calibrate) before trusting them"
                )
        for run in self.runs:
            predicted = self._predicted_overshoot(run.T_fuel)
            actual = run.summary()["overshoot_percent"]
            if predicted is None or not math.isfinite(actual):
                continue
            if abs(actual - predicted) > OVERSHOOT_AGREEMENT:
                found.append(
                    f"the nonlinear plant overshoots {actual:.1f} % at "
                    f"{kelvin_to_celsius(run.T_fuel):g} °C, the linear prediction "
                    f"{predicted:.1f} %: believe the larger, "
                    + (
                        "the nonlinear run's (your plant file's nonlinearity and limits, which "
                        "the linear figures leave out)"
                        if actual > predicted
                        else "the linear prediction's (the run starts from rest at one flow and "
                        "its limits can hold the command back; the loop need not)"
                    )
                )
        return found

    def _predicted_overshoot(self, T_fuel: float) -> float | None:
        """The temperature check's overshoot at ``T_fuel`` [K] and the operating command [%]."""
        if self.check is None:
            return None
        cases = [c for c in self.check.cases if abs(c.case.T_fuel - T_fuel) < 1e-6]
        if not cases:
            return None
        return min(cases, key=lambda c: abs(c.case.u - self.u)).overshoot_percent

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

    def provenance(self) -> dict[str, Basis | list[Basis] | None]:
        """What each figure rests on (:mod:`fuelid.workflow._trust`); None: not computed."""
        spans = self.spans
        return {
            "Kc": "identified model",
            "Ti": "identified model",
            "control_period": self.request.control_period_basis,
            "percent_of_span": spans.basis,
            "robustness": "identified model",
            "full_order": None if self.full_order is None else "model file",
            "closed_loop": "identified model",
            "temperature_check": None if self.check is None else "plant file",
            "command_band_check": None if self.bands is None else "log",
            "closed_loop_plant": "plant file" if self.runs else None,
            "misfit_Ms": None if self.misfit_peak is None else "log",
            "sweep": None
            if self.sweep is None
            else "identified model"
            if self.check is None
            else "plant file",
        }

    def to_json(self) -> dict[str, Any]:
        """The documented JSON object of ``fuelid tune --json`` (without provenance)."""
        return self.tuning.to_json() | {
            "control_period_basis": self.request.control_period_basis,
            "spans": self.spans.to_json(),
            "structure_spread": self.structure_spread(),
            "temperature_check": None if self.check is None else self.check.to_json(cases=True),
            "command_band_check": None if self.bands is None else self.bands.to_json(),
            "full_order": None
            if self.full_order is None
            else self.full_order.to_json()
            | {
                "detuned": None
                if self.full_order_detuned is None
                else {"Kc": self.full_order_detuned.Kc, "Ti": self.full_order_detuned.Ti},
                "basis": "model file (linear_model)",
                "setpoint_step": None
                if self.full_order_step is None
                else self.full_order_step.setpoint.to_json(),
            },
            "misfit_Ms": None
            if self.misfit_peak is None
            else {
                **self.misfit_peak.to_json(),
                "overshoot_percent": self.misfit_step,
                "basis": "log",
            },
            "disagreements": self.disagreements(),
            "closed_loop_plant": [r.to_json(events=True) for r in self.runs] or None,
            "sweep": None if self.sweep is None else self.sweep.summary(),
            "provenance": self.provenance(),
            "warnings": self.warnings,
            "units": UNITS,
        }


def tune_model(
    plant: PlantSource | PlantConfig,
    request: TuneRequest,
    progress: Progress | None = None,
    cache: CaseCache | None = None,
) -> TuneOutcome:
    """Tune ``request.model`` and check the gains: the chain behind ``fuelid tune``.

    1. the rule's gains and their margins and linear closed loop on the model
       (:func:`~fuelid.tuning._result.evaluate_tuning`), with %/% gains only on spans the user
       gave (:meth:`TuneRequest.spans`);
    2. with the user's plant file, the same gains over the fuel-temperature range and the
       drive's range, the physics anchored to the model (:func:`check_over_temperature`);
       without one, no figure rests on the reference plant: the check is the log's command
       bands (``request.command_bands``, :func:`~fuelid.tuning._bands.band_check`) when given;
    3. with ``request.simulate`` (a plant file only), the standard test on the nonlinear plant
       at the coldest and the warmest fuel, from rest at the flow of ``request.u`` at
       ``request.T_fuel`` (:func:`~fuelid.tuning.closedloop.standard_runs`);
    4. with ``request.sweep``, the gains on that many variants of the model
       (:func:`~fuelid.tuning._sweep.uncertainty_sweep`), over temperature with a plant file.

    The work is many small matrices, so BLAS runs on one thread throughout
    (:func:`~fuelid.blas.single_threaded_blas`).

    Parameters
    ----------
    plant : PlantSource or PlantConfig
        The plant: the user's plant file, or the reference plant standing in
        (:class:`~fuelid.workflow._assumptions.PlantSource`); a bare config is the user's.
    request : TuneRequest
        What to tune and check; its ``model`` and ``control_period`` must be given.
    progress : callable, optional
        Called with each stage's name as it starts (:mod:`fuelid.workflow._progress`).
    cache : dict, optional
        Linearisations by (T_fuel, u), shared with a :func:`schedule_gains` of the same call.

    Returns
    -------
    TuneOutcome
    """
    if request.model is None:
        raise FuelidError("tuning needs a model (TuneRequest.model)")
    source = as_plant_source(plant)
    if request.simulate and source.is_reference:
        raise FuelidError(
            "the closed loop on the nonlinear plant needs your plant file (--config "
            "PLANT.toml): the built-in reference plant is not your loop"
        )
    request.period()
    with single_threaded_blas():
        return _tune_model(source, request, request.model, progress, cache)


def _tune_model(
    plant: PlantSource,
    request: TuneRequest,
    model: ProcessModel,
    progress: Progress | None,
    cache: CaseCache | None,
) -> TuneOutcome:
    announce(progress, TUNING)
    config, h = plant.config, request.period()
    u, spans = operating_command(config, request.u, clip=request.clip_u), request.spans(plant)
    tuning = evaluate_tuning(
        model,
        request.rule,
        h,
        request.closed_loop_time,
        None if spans.u_span is None else spans.u_span.value,
        None if spans.y_span is None else spans.y_span.value,
    )
    anchor = Anchor(model, request.T_fuel, u)
    announce(progress, TEMPERATURE_CHECK)
    check = plant_gain = None
    if not plant.is_reference:
        plant_gain = plant_static_gain(config, request.T_fuel, u, cache)
        # a model that is the plant file's own linearisation (plant info's) needs no anchoring:
        # the margins are then computed on the full linearised plant at every case
        own = request.full_order is not None and _same_gain(model.K, plant_gain)
        check = check_over_temperature(
            config,
            tuning.pi,
            None if own else anchor,
            request.T_range,
            request.band_width,
            u,
            cache,
        )
    full_order = full_order_step = full_order_detuned = None
    if request.full_order is not None:
        full_order = robustness(request.full_order, tuning.pi)
        full_order_step = full_order_closed_loop(
            request.full_order, tuning.pi, step_duration(model, tuning.pi)
        )
        if full_order.Ms > request.ms_target:
            full_order_detuned = detuned_for(request.full_order, tuning.pi, request.ms_target)
    misfit = request.misfit
    misfit_peak = misfit_step = None
    if misfit is not None:
        misfit_peak = robust_peak(model, tuning.pi, misfit.at, misfit.excited_up_to)
        misfit_step = misfit_overshoot(model, tuning.pi, misfit.at, misfit.excited_up_to)
    misfit_fn = None if misfit is None else (misfit.at, misfit.excited_up_to)
    bands = band_check(tuning.pi, model, request.command_bands, misfit_fn)
    runs = []
    if request.simulate:
        announce(progress, RUNS)
        start = flow_at(config, u, request.T_fuel)
        y_span = config.flowmeter.span_Lpm if spans.y_span is None else spans.y_span.value
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
            None if plant.is_reference else config,
            n=request.sweep,
            T_range=request.T_range,
            seed=request.seed,
        )
    structures = [
        StructureGains(
            model=other,
            pi=evaluate_tuning(other, request.rule, h, request.closed_loop_time).pi,
            Ms_of_chosen_gains=robustness(other, tuning.pi).Ms,
        )
        for other in request.alternatives
    ]
    return TuneOutcome(
        request=request,
        plant=plant,
        u=u,
        spans=spans,
        tuning=tuning,
        check=check,
        bands=bands,
        full_order=full_order,
        full_order_step=full_order_step,
        full_order_detuned=full_order_detuned,
        plant_gain=plant_gain,
        misfit_peak=misfit_peak,
        misfit_step=misfit_step,
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
    plant: PlantSource | None = None
    """The user's plant file the schedule rests on."""
    anchored: bool = True
    """Whether the model anchors the physics (False for physics alone, or a plant file's own
    reduction, whose full linearisation the bands are checked on)."""

    def to_json(self) -> dict[str, Any]:
        """The documented JSON of ``fuelid tune --schedule --json`` (without provenance)."""
        model = self.request.model
        spans = self.request.spans(self.plant) if self.plant is not None else None
        return self.schedule.to_json() | {
            "anchored_to_model": None if model is None or not self.anchored else model.to_json(),
            "control_period_basis": self.request.control_period_basis,
            "provenance": {
                "bands": "plant file",
                "control_period": self.request.control_period_basis,
                "percent_of_span": None if spans is None else spans.basis,
                "anchored_to_model": None if model is None or not self.anchored else "model",
            },
            "units": UNITS,
        }


def schedule_gains(
    plant: PlantSource | PlantConfig,
    request: TuneRequest,
    progress: Progress | None = None,
    cache: CaseCache | None = None,
) -> ScheduleOutcome:
    """Gains per fuel-temperature (and flow) band: the chain behind ``fuelid tune --schedule``.

    From the plant's physics alone when ``request.model`` is None, else anchored to the model at
    ``request.T_fuel`` and ``request.u`` (:func:`~fuelid.tuning._schedule.gain_schedule`), with
    BLAS on one thread. How the gains move with fuel temperature and flow is the plant file's
    physics: with the built-in reference plant standing in, no schedule is made (refused), as
    it would be the reference plant's, not the user's loop. ``progress`` is called with the
    stage's name as it starts (:mod:`fuelid.workflow._progress`).
    """
    source = as_plant_source(plant)
    if source.is_reference:
        raise FuelidError(NO_SCHEDULE_WITHOUT_PLANT)
    config, h = source.config, request.period()
    u = operating_command(config, request.u, clip=request.clip_u)
    anchor = None if request.model is None else Anchor(request.model, request.T_fuel, u)
    operating = anchor
    if (
        request.model is not None
        and request.full_order is not None
        and _same_gain(request.model.K, plant_static_gain(config, request.T_fuel, u, cache))
    ):
        anchor = None  # the plant file's own reduction: the cases are its linearisation
    spans = request.spans(source)
    announce(progress, SCHEDULE)
    with single_threaded_blas():
        schedule = gain_schedule(
            config,
            request.rule,
            h,
            request.closed_loop_time,
            T_range=request.T_range,
            band_width=request.band_width,
            ms_target=request.ms_target,
            flow_bands=request.flow_bands,
            anchor=anchor,
            operating=operating,
            y_span=None if spans.y_span is None else spans.y_span.value,
            u_span=None if spans.u_span is None else spans.u_span.value,
            cache=cache,
        )
    return ScheduleOutcome(
        request=request, u=u, schedule=schedule, plant=source, anchored=anchor is not None
    )


NO_SCHEDULE_WITHOUT_PLANT = (
    "a gain schedule over fuel temperature and flow rests on your plant's physics: give your "
    "plant file (--config PLANT.toml); the built-in reference plant's trend is not your loop's"
)
