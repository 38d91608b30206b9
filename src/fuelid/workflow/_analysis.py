"""From a PLC log to PI gains in one call: identify, tune, check, run, schedule.

:func:`analyse_log` is what ``fuelid report`` and the demo run. It composes the same steps as the
individual commands: :func:`~fuelid.workflow._assumptions.plant_priors` and
:func:`~fuelid.identify._procedure.identify` (``fuelid identify``), then
:func:`~fuelid.workflow._tune.tune_model` with the nonlinear runs and
:func:`~fuelid.workflow._tune.schedule_gains` (``fuelid tune --simulate``, ``--schedule``) on the
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
from fuelid.identify import (
    CorrelationTest,
    IdentificationResult,
    IdentifyOptions,
    MisfitBound,
    identify,
    input_residual_correlation,
    lead_check,
    long_record_note,
    residual_whiteness,
    steps_only,
)
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel, check_gain_identified
from fuelid.tuning import (
    DEFAULT_T_RANGE,
    UNITS,
    BlockForm,
    CaseCache,
    CommandBand,
    FixedPIEvaluation,
    GainSchedule,
    TuningResult,
    frequency_grid,
    loop_function,
    robustness,
)
from fuelid.tuning.closedloop import ClosedLoopResult
from fuelid.units import DEFAULT_FUEL_TEMPERATURE_C
from fuelid.workflow._assumptions import (
    REFERENCE_PLANT_NOTICE,
    T_REF,
    OperatingPoint,
    PlantSource,
    PriorSource,
    check_gain_against_plant,
    check_signals,
    priors_json,
    resolve_priors,
)
from fuelid.workflow._identification import identify_step_ls
from fuelid.workflow._progress import DIAGNOSTICS, IDENTIFICATION, Progress, announce
from fuelid.workflow._trust import (
    LEADING_RESPONSE,
    NO_CONTROL_PERIOD,
    Basis,
    undetermined,
    undetermined_refusal,
    undetermined_refusal_line,
)
from fuelid.workflow._tune import (
    TuneOutcome,
    TuneRequest,
    check_conditions,
    schedule_gains,
    tune_model,
)

FloatArray = NDArray[np.float64]
Method = Literal["oe", "step-ls", "pem"]
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
    control_period: float | None = None
    """PLC period h [s] (0: continuous); also step-ls's decimation period. None is refused by
    :func:`analyse_log`: gains for another period are wrong gains, so none is assumed."""
    control_period_basis: Basis = "option"
    """Where the control period came from (:data:`~fuelid.workflow._trust.Basis`)."""
    accept_undetermined: bool = False
    """Tune even a model whose K, T or dead time the log does not determine
    (:func:`~fuelid.workflow._trust.undetermined`; otherwise refused); every output then repeats
    the refusal as a warning."""
    T_fuel: float | None = None
    """Fuel temperature during the log [K]; None: the log's fuel-temperature column, else 20 °C
    (said in the outputs)."""
    identify: IdentifyOptions = field(default_factory=IdentifyOptions)
    """The identification's settings (order, delay, meter priors, N) as ``fuelid identify``
    takes them; the method and the validation split are set per analysis."""
    accept_signals: bool = False
    """Tune even when the signal check finds the command or the flow outside the spans the gains
    are computed for (otherwise refused)."""
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
    y_span: float | None = None
    """Flowmeter span of the %/% gains [L/min]; None: the site file's, else the user's plant
    file's, else none (no %/% gains)."""
    u_span: float | None = None
    """Drive signal span of the %/% gains [V]; None: as ``y_span``."""
    site_spans: tuple[float | None, float | None] = (None, None)
    """The site file's ``[controller]`` spans (u_span_V [V], y_span_Lpm [L/min])."""
    block: BlockForm | None = None
    """The site file's PI block (``[controller]``): the page gives the gains in its form too."""

    def __post_init__(self) -> None:
        if self.tune_from not in (*METHODS, "pem"):
            raise FuelidError(f"tune from 'oe', 'step-ls' or 'pem', not {self.tune_from!r}")
        check_conditions(
            T_REF if self.T_fuel is None else self.T_fuel, self.T_range, self.step_percent
        )

    def tune_request(
        self,
        model: ProcessModel,
        u: float,
        T_fuel: float,
        *,
        simulate: bool,
        command_bands: tuple[CommandBand, ...] = (),
    ) -> TuneRequest:
        """What :func:`~fuelid.workflow._tune.tune_model` is asked for a model found at ``u``.

        ``u`` [V] and ``T_fuel`` [K] are the identification's conditions; ``simulate`` runs the
        closed loop on the nonlinear plant (only a user's plant file is the user's loop);
        ``command_bands`` are K per command band of the log. The spans of the %/% gains are
        ``u_span`` and ``y_span``, else the site file's, else the user's plant file's.
        """
        return TuneRequest(
            clip_u=True,  # the log's mean command, judged by the signal check
            model=model,
            rule=self.rule,
            closed_loop_time=self.closed_loop_time,
            control_period=self.control_period,
            control_period_basis=self.control_period_basis,
            site_spans=self.site_spans,
            command_bands=command_bands,
            T_fuel=T_fuel,
            u=u,
            T_range=self.T_range,
            band_width=self.band_width,
            ms_target=self.ms_target,
            flow_bands=self.flow_bands,
            simulate=simulate,
            step_percent=self.step_percent,
            y_span=self.y_span,
            u_span=self.u_span,
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
    schedule: GainSchedule | None
    """Gains per temperature (and flow) band, anchored to the chosen model; None without the
    user's plant file (the trend over temperature would be the reference plant's)."""
    whiteness: CorrelationTest
    """Residual autocorrelation of the tuned-from model on the fitted samples."""
    input_correlation: CorrelationTest
    """Input–residual cross-correlation of the same."""
    bode_frequency: FloatArray
    """[rad/s]"""
    bode_loop: NDArray[np.complex128]
    """Loop frequency response L = C·G on the identified model (sampled PI, exact delay)."""
    plant: PlantSource
    """The plant of the temperature trend, the spans and the nonlinear runs."""
    operating_point: OperatingPoint
    """Mean command and flow of the log, and the fuel temperature (from the log or an option)."""
    priors: dict[str, Any]
    """The identification's assumptions and their origin (:func:`priors_json`)."""
    signal_check: list[str] = field(default_factory=list)
    """Findings that the signals are not in the units the gains are computed for (accepted)."""
    warnings: list[str] = field(default_factory=list)
    undetermined: list[str] = field(default_factory=list)
    """The chosen model's parameters the log does not determine (accepted by the user)."""

    @property
    def T_fuel(self) -> float:
        """Fuel temperature the model was identified at [K] (20 °C when nothing gives it)."""
        return T_REF if self.operating_point.T_fuel is None else self.operating_point.T_fuel

    @property
    def notices(self) -> list[str]:
        """The assumptions every output states first.

        The reference plant standing in for the user's, an assumed fuel temperature, signal
        findings the user accepted.
        """
        found = []
        if self.plant.is_reference:
            found.append(REFERENCE_PLANT_NOTICE)
        if self.undetermined:
            found.append(
                "accepted (--accept-undetermined): "
                + undetermined_refusal(self.undetermined, f"the {self.settings.tune_from} model")
            )
        if self.operating_point.T_fuel is None:
            found.append(
                f"fuel temperature assumed {DEFAULT_FUEL_TEMPERATURE_C:g} °C: the log has no "
                "fuel-temperature column and "
                "--fuel-temp was not given"
            )
        found.extend(f"signal check overridden: {f}" for f in self.signal_check)
        found.extend(f"figures disagree: {d}" for d in self.outcome.disagreements())
        chosen = self.identifications[self.settings.tune_from]
        if chosen.extra.get("structure", {}).get("conditional"):
            found.append(
                f"the {self.settings.tune_from} model's intervals are conditional on its "
                "structure (see its warnings): the gains on the structures the log does not rule "
                "out are shown beside the PI gains"
                if self.outcome.structures
                else f"the {self.settings.tune_from} model's intervals are conditional on its "
                "structure (see its warnings): they hold if that structure is right"
            )
        fitted = self.identifications["oe"].extra.get("long_record") or {}
        if fitted.get("fitted_on") == "copy":  # a day-long log: its errors and tests the copy's
            found.append(f"the oe model was {long_record_note(fitted, self.data.sample_time)}")
        return found

    @property
    def span_note(self) -> str:
        """Where the spans of the %/% gains come from, said beside them, or why there are none."""
        spans = self.outcome.spans
        if spans.u_span is None or spans.y_span is None:
            return spans.missing_reason or ""
        where = {
            "option": "as given",
            "site file": "from the site file",
            "plant file": f"from {self.plant.path}",
        }
        bases = {spans.u_span.basis, spans.y_span.basis}
        return (
            f"{spans.y_span.value:g} L/min meter span, {spans.u_span.value:g} V drive span, "
            + " and ".join(where.get(b, b) for b in sorted(bases))
        )

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
    def check(self) -> FixedPIEvaluation | None:
        """The gains on the user's plant over the temperature and drive ranges (None without)."""
        return self.outcome.check

    @property
    def runs(self) -> list[ClosedLoopResult]:
        """Nonlinear closed loop at the coldest and the warmest fuel."""
        return self.outcome.runs

    def to_json(self) -> dict[str, Any]:
        """The documented JSON of ``fuelid report --json``, without the paths and provenance."""
        return {
            "plant": self.plant.to_json(),
            "priors": self.priors,
            "operating_point": self.operating_point.to_json(),
            "signal_check": self.signal_check,
            "notices": self.notices,
            "identification": {m: r.to_json() for m, r in self.identifications.items()},
            "tuned_from": self.settings.tune_from,
            "tuning": self.tuning.to_json()
            | {
                key: value
                for key, value in self.outcome.to_json().items()
                if key
                in (
                    "structure_spread",
                    "control_period_basis",
                    "spans",
                    "misfit_Ms",
                    "disagreements",
                )
            },
            "temperature_check": None if self.check is None else self.check.to_json(cases=False),
            "command_band_check": None
            if self.outcome.bands is None
            else self.outcome.bands.to_json(),
            "closed_loop_plant": [r.to_json(events=False) for r in self.runs],
            "schedule": None if self.schedule is None else self.schedule.to_json(),
            "provenance": self.outcome.provenance()
            | {"schedule": None if self.schedule is None else "plant file"},
            "undetermined": self.undetermined,
            "warnings": self.warnings,
            "units": UNITS,
        }


def analyse_log(
    data: IOData,
    plant: PlantSource,
    settings: AnalysisSettings,
    progress: Progress | None = None,
    cache: CaseCache | None = None,
) -> LogAnalysis:
    """Identify ``data`` with both methods, tune, check over temperature and build a schedule.

    ``plant`` is the user's plant file or the built-in reference plant
    (:class:`~fuelid.workflow._assumptions.PlantSource`). Only a user's plant file gives priors
    (its flowmeter's lag and delay are held fixed unless ``settings.identify`` sets them) and
    the nonlinear closed-loop runs; the reference plant gives only the trend over fuel
    temperature and flow, anchored to the identified model, and the spans, and the outputs say so
    (:attr:`LogAnalysis.notices`). Without priors the dead time is estimated and a meter lag is
    found as a second lag (order chosen by the information criterion).

    The signals are checked against the spans the gains are computed for
    (:func:`~fuelid.workflow._assumptions.check_signals`, and with a plant file the identified K
    against its prediction): findings refuse the analysis unless ``settings.accept_signals``.

    ``progress``, when given, is called with each stage's name as it starts, in the order of
    :data:`~fuelid.workflow._progress.ANALYSIS_STAGES`. The work is many small matrices and long
    vectors, so BLAS runs on one thread throughout (:func:`~fuelid.blas.single_threaded_blas`):
    several times faster on a busy two-core machine.

    ``cache``, when given, keeps the plant's linearisations (by fuel temperature and command)
    for the next analysis on the same plant (the dashboard's window reports share one per plant
    file): the check over temperature and the schedule then reuse them. Never share one between
    plants.
    """
    with single_threaded_blas():
        return _analyse(data, plant, settings, progress, {} if cache is None else cache)


def _refuse_signals(findings: list[str]) -> None:
    raise FuelidError(
        f"signal check: {'; '.join(findings)}; the gains would be wrong by the same factor "
        "(--accept-signals to tune anyway)"
    )


def _analyse(
    data: IOData,
    plant: PlantSource,
    settings: AnalysisSettings,
    progress: Progress | None,
    cache: CaseCache,
) -> LogAnalysis:
    """:func:`analyse_log`'s stages."""
    config = plant.config
    if settings.control_period is None:
        raise FuelidError(NO_CONTROL_PERIOD)
    point = OperatingPoint.of(data, settings.T_fuel)
    T_fuel = T_REF if point.T_fuel is None else point.T_fuel
    findings = _checked_signals(data, plant, settings)
    announce(progress, IDENTIFICATION)
    base, sources = resolve_priors(
        replace(
            settings.identify,
            control_period=max(settings.control_period, data.sample_time),
            validate_split=settings.validate_split,
        ),
        plant,
        T_fuel,
    )
    identifications, step_sources = _identify_all(data, base, settings.tune_from, progress)
    if settings.tune_from == "step-ls":
        sources |= step_sources
    warnings = _identification_warnings(data, identifications)
    chosen = identifications[settings.tune_from]
    loose = _check_chosen(chosen, settings)
    mismatch = check_gain_against_plant(chosen.model, plant, point, T_fuel)
    if mismatch is not None:
        findings.append(mismatch)
        if not settings.accept_signals:
            _refuse_signals([mismatch])
    warnings[:0] = [f"signals: {f}" for f in findings]
    u_op = float(np.clip(point.u, config.vfd.u_min_V, config.vfd.u_max_V))
    request = _tune_request(settings, chosen, u_op, T_fuel, plant.is_reference)
    # the check and the schedule share linearisations (and the next analysis, given a cache)
    outcome = tune_model(plant, request, progress, cache)
    warnings.extend(f"tuning: {w}" for w in outcome.warnings)
    cross_check = _cross_check(identifications, settings.tune_from, outcome)
    if cross_check:
        warnings.append(cross_check)
    schedule = (
        None if plant.is_reference else schedule_gains(plant, request, progress, cache).schedule
    )
    announce(progress, DIAGNOSTICS)
    whiteness, input_correlation = _residual_tests(data, chosen, settings.control_period)
    omega = frequency_grid(chosen.model, outcome.pi)
    return LogAnalysis(
        data=data,
        settings=replace(settings, T_fuel=T_fuel),
        identifications=identifications,
        outcome=outcome,
        schedule=schedule,
        whiteness=whiteness,
        input_correlation=input_correlation,
        bode_frequency=omega,
        bode_loop=loop_function(chosen.model, outcome.pi)(omega),
        plant=plant,
        operating_point=point,
        priors=priors_json(base, sources, chosen, plant),
        signal_check=findings,
        warnings=warnings,
        undetermined=loose,
    )


def _checked_signals(data: IOData, plant: PlantSource, settings: AnalysisSettings) -> list[str]:
    """The signal check's findings; refused (unless accepted) and on a flow leading its command."""
    findings = check_signals(data, plant)
    # a flow that moves before its command first: the signal check's unit remedies would mislead
    if lead_check(data.u, data.y, data.sample_time, segment_starts=data.segment_starts).leads:
        raise FuelidError(LEADING_RESPONSE)
    if findings and not settings.accept_signals:
        _refuse_signals(findings)
    return findings


def _identify_all(
    data: IOData, base: IdentifyOptions, tune_from: str, progress: Progress | None
) -> tuple[dict[str, IdentificationResult], dict[str, PriorSource]]:
    """Both methods' fits (and pem's when the gains come from it), in the order shown.

    Also returns where step-ls's priors came from (its response length may be the output-error
    fit's settling time).
    """
    identifications: dict[str, IdentificationResult] = {}
    # the output-error fit first: without a plant file its settling time is the data's own
    # prior for step-ls's response length N
    # the fit's own steps (its structures, a long record's search and polish) under this stage
    identifications["oe"] = identify(
        data, replace(base, method="oe"), progress=steps_only(progress)
    )
    identifications["step-ls"], step_sources = identify_step_ls(
        data, replace(base, method="step-ls"), identifications["oe"].model
    )
    if tune_from == "pem":  # the noise-model fit, beside the two always shown
        identifications["pem"] = identify(data, replace(base, method="pem"))
    order = (*METHODS, "pem")
    return {m: identifications[m] for m in order if m in identifications}, step_sources


def _identification_warnings(
    data: IOData, identifications: dict[str, IdentificationResult]
) -> list[str]:
    """The loader's notes and each method's warnings, by source."""
    # what the loader noticed is said once, not once per method
    warnings: list[str] = [f"log: {note}" for note in data.notes]
    for name, result in identifications.items():
        warnings.extend(f"{name}: {w}" for w in result.warnings if w not in data.notes)
    return warnings


def _check_chosen(chosen: IdentificationResult, settings: AnalysisSettings) -> list[str]:
    """The chosen model's undetermined parameters, once it is fit to tune from.

    Refused: a model whose gain the log does not determine, one with the flow leading its
    command, and one with undetermined parameters (unless ``accept_undetermined``).
    """
    check_gain_identified(chosen.model.K, chosen.stderr.get("K"), f"{settings.tune_from} fit")
    # two lags not told apart have no intervals of their own, though the response they give is
    # determined (the identification warns of the split): T is not judged alone then
    judged_apart = ("T",) if chosen.lags_merged else ()
    loose = undetermined(chosen.model.to_json(), _intervals(chosen), (*chosen.fixed, *judged_apart))
    if (chosen.diagnostics.get("lead") or {}).get("leads"):
        raise FuelidError(LEADING_RESPONSE)
    if loose and not settings.accept_undetermined:
        raise FuelidError(undetermined_refusal_line(loose, f"the {settings.tune_from} model"))
    return loose


def _tune_request(
    settings: AnalysisSettings,
    chosen: IdentificationResult,
    u_op: float,
    T_fuel: float,
    reference_plant: bool,
) -> TuneRequest:
    """What to tune on the chosen model, with its misfit bound and the rival structures.

    The structures the log could not tell from the chosen one are tuned too (the gains on each
    are shown).
    """
    request = settings.tune_request(
        chosen.model,
        u_op,
        T_fuel,
        simulate=not reference_plant,
        command_bands=command_bands(chosen.diagnostics),
    )
    found_misfit = chosen.diagnostics.get("misfit")
    if found_misfit is not None:
        request = replace(request, misfit=MisfitBound.from_json(found_misfit))
    # the structures the log could not tell from the chosen fit's: the gains on each are shown
    indistinct = chosen.extra.get("structure", {}).get("indistinct", [])
    return replace(
        request, alternatives=tuple(ProcessModel(**item["model"]) for item in indistinct)
    )


def _residual_tests(
    data: IOData, chosen: IdentificationResult, control_period: float
) -> tuple[CorrelationTest, CorrelationTest]:
    """The chosen fit's residuals: their whiteness and their correlation with the input.

    On the fitted part only, and within segments (a log with gaps is not correlated across
    them); pem's tests are on its prediction errors.
    """
    fitted = chosen.time < (chosen.split_time if chosen.split_time is not None else math.inf)
    residuals = (
        chosen.prediction_errors  # pem: the tests are on its prediction errors
        if chosen.prediction_errors is not None
        else chosen.y[fitted] - chosen.y_hat[fitted]
    )
    u_model = data.u if chosen.time.size == data.n_samples else _held(data, chosen.time)
    max_lag = min(max(25, round(2.0 * control_period / data.sample_time)), fitted.sum() // 4)
    # within segments only: a log with gaps is not correlated across them
    times = chosen.time[fitted]
    starts = tuple(int(i) for i in np.flatnonzero(np.diff(times) > 1.5 * chosen.sample_time) + 1)
    return (
        residual_whiteness(residuals, segment_starts=starts),
        input_residual_correlation(u_model[fitted], residuals, max_lag, starts),
    )


def command_bands(diagnostics: dict[str, Any]) -> tuple[CommandBand, ...]:
    """K per command band from an identification's ``diagnostics.nonlinearity`` (none: ())."""
    nonlinearity = diagnostics.get("nonlinearity") or {}
    return tuple(CommandBand.from_json(row) for row in nonlinearity.get("bands", []))


def _intervals(result: IdentificationResult) -> dict[str, tuple[float, float] | None]:
    """The 95 % intervals of an identification, by parameter (None: fixed or not known)."""
    return {
        name: None if interval is None else (float(interval[0]), float(interval[1]))
        for name, interval in result.ci95().items()
    }


CROSS_CHECK_RATIO = 1.1
"""Ms of the gains on the other identified model above this multiple of the Ms printed is said."""


def _cross_check(
    identifications: dict[str, IdentificationResult], tune_from: str, outcome: TuneOutcome
) -> str | None:
    """The gains on the other method's model when it fits the log better and is less robust.

    Both models describe the same log; when the one the gains do not come from fits it better
    and gives a larger Ms, the Ms printed is optimistic, and the user must hear it.
    """
    other = "step-ls" if tune_from == "oe" else "oe"
    chosen, check = identifications[tune_from], identifications[other]
    if check.fit_percent <= chosen.fit_percent:
        return None
    ms = robustness(check.model, outcome.pi).Ms
    printed = outcome.tuning.robustness.Ms
    if ms <= CROSS_CHECK_RATIO * printed:
        return None
    return (
        f"tuning: on the {other} model, which fits the log better ({check.fit_percent:.1f} % "
        f"against {chosen.fit_percent:.1f} %), these gains give Ms {ms:.2f}, not {printed:.2f}: "
        f"the {tune_from} model is optimistic here; tune from {other} (--method {other})"
    )


def _held(data: IOData, times: FloatArray) -> FloatArray:
    """The input held (zero-order) at other sample times, e.g. a decimated record's."""
    index = np.clip(np.searchsorted(data.t, times, side="right") - 1, 0, data.n_samples - 1)
    return np.asarray(data.u[index], dtype=float)
