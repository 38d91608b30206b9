"""Identification as the workflow runs it: the plant file's priors, the window, the JSON.

:func:`identify_log` is what ``fuelid identify`` runs, and :func:`plant_priors` what both it and
:func:`~fuelid.workflow.analysis.analyse_log` take from a plant file; the estimators and their
diagnostics are :func:`fuelid.identify.procedure.identify`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

from fuelid.identify.preprocess import select
from fuelid.identify.procedure import IdentificationResult, IdentifyOptions, identify
from fuelid.identify.progress import StageCallback
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel
from fuelid.units import DEFAULT_FUEL_TEMPERATURE_C, celsius_to_kelvin
from fuelid.workflow.assumptions import (
    OperatingPoint,
    PlantSource,
    PriorSource,
    check_gain_against_plant,
    check_signals,
    priors_json,
    resolve_priors,
)

if TYPE_CHECKING:
    from fuelid.plant.config import PlantConfig

T_REF = celsius_to_kelvin(DEFAULT_FUEL_TEMPERATURE_C)
"""Fuel temperature assumed when none is given [K]: 20 °C."""

IDENTIFY_UNITS: dict[str, str] = {
    "K": "output unit per input unit ((L/min)/V for the fuel loop)",
    "T": "s",
    "T2": "s",
    "delay": "s",
    "T_f": "s",
    "sample_time": "s",
    "fit_percent": "%",
    "validation_fit_percent": "%",
    "noise_std": "output unit",
}
"""Units of the numbers in the JSON of ``fuelid identify`` (by key name)."""


@dataclass(frozen=True)
class PlantKnowledge:
    """What a plant file tells an identification before it sees data: the one home of priors.

    ``fuelid identify --config``, ``fuelid report --config`` and the online service's windows
    (:func:`fuelid.online.window.window_priors`) all take their priors from here.
    """

    flowmeter_T: float
    """The flowmeter's lag [s], held fixed in the fit."""
    flowmeter_delay: float
    """The meter's dead time [s], held fixed (the model's whole delay)."""
    settling_time: float
    """The 98 % settling time of the plant's linearisation at mid-range [s] (step-ls's N, the
    online window's length check)."""
    u_limits: tuple[float, float]
    """The drive's signal range [V]."""
    y_span: float
    """The meter's span [L/min]."""
    middle: float
    """The mid-range command the settling time is for [V]."""


def plant_knowledge(config: PlantConfig, T_fuel: float = T_REF) -> PlantKnowledge:
    """The prior knowledge of a plant file at fuel temperature ``T_fuel`` [K] (default 20 °C)."""
    from fuelid.plant.linear import linearise  # the physics only when a plant file is given

    meter, vfd = config.flowmeter, config.vfd
    middle = 0.5 * (vfd.u_min_V + vfd.u_max_V)
    return PlantKnowledge(
        flowmeter_T=float(meter.time_constant_s),
        flowmeter_delay=float(meter.delay_s),
        settling_time=float(linearise(config, middle, T_fuel).settling_time()),
        u_limits=(float(vfd.u_min_V), float(vfd.u_max_V)),
        y_span=float(meter.span_Lpm),
        middle=float(middle),
    )


def plant_priors(
    options: IdentifyOptions, config: PlantConfig, T_fuel: float = T_REF
) -> IdentifyOptions:
    """``options`` with a plant file's prior knowledge wherever the options give none.

    Parameters
    ----------
    options : IdentifyOptions
        The identification's settings; a flowmeter lag, delay or settling time given there wins.
    config : PlantConfig
        The plant: its flowmeter's lag and dead time (held fixed in the fit), and the 98 %
        settling time of its linearisation at the middle of the drive's range (which chooses
        step-ls's N), as :func:`plant_knowledge` gives them.
    T_fuel : float
        Fuel temperature of the settling time [K].

    Returns
    -------
    IdentifyOptions
    """
    meter = config.flowmeter
    settling = options.settling_time
    if settling is None:
        settling = plant_knowledge(config, T_fuel).settling_time
    return replace(
        options,
        flowmeter_T=meter.time_constant_s if options.flowmeter_T is None else options.flowmeter_T,
        flowmeter_delay=meter.delay_s
        if options.flowmeter_delay is None
        else options.flowmeter_delay,
        settling_time=settling,
    )


@dataclass(frozen=True)
class IdentifyOutcome:
    """One identification of a log, with the documented JSON of ``fuelid identify --json``."""

    result: IdentificationResult
    priors: dict[str, Any] = field(default_factory=dict)
    """Each assumption of the fit, its value and where it came from (:func:`priors_json`)."""
    operating_point: OperatingPoint | None = None
    """Mean command, mean flow and fuel temperature of the fitted samples."""
    signal_check: list[str] = field(default_factory=list)
    """Findings that the signals are not in the units the gains are computed for."""

    @property
    def warnings(self) -> list[str]:
        """What the user should know about the fit and the signals (also inside the JSON)."""
        if (self.result.diagnostics.get("lead") or {}).get("leads"):
            # the flow moving before its command comes first: a unit remedy would mislead
            return [*self.result.warnings, *self.signal_check]
        return [*self.signal_check, *self.result.warnings]

    def to_json(self) -> dict[str, Any]:
        """The documented JSON object of ``fuelid identify --json`` (without provenance)."""
        return self.result.to_json() | {
            "warnings": self.warnings,
            "priors": self.priors,
            "operating_point": None
            if self.operating_point is None
            else self.operating_point.to_json(),
            "signal_check": self.signal_check,
            "units": IDENTIFY_UNITS,
        }


def identify_log(
    data: IOData,
    options: IdentifyOptions,
    *,
    validation: IOData | None = None,
    t_start: float | None = None,
    t_stop: float | None = None,
    plant: PlantSource | None = None,
    fuel_temperature: float | None = None,
    progress: StageCallback | None = None,
) -> IdentifyOutcome:
    """Identify the model of a loaded log, on the samples with ``t_start ≤ t < t_stop`` [s].

    ``validation`` is a second log to score the model on (its offset and initial state
    estimated, or from rest at its first input with ``options.validation_initial="rest"``).
    ``plant`` is a user's plant file (its flowmeter gives the priors not set in ``options``, and
    the identified K is compared with its prediction) or None: then no meter prior is assumed,
    and the signals are checked against the fuel loop's 1…5 V drive range.
    ``fuel_temperature`` [K] is the fuel's during the log when the log has no such column.
    Refusals (non-exciting data, priors the record contradicts) raise
    :class:`~fuelid.errors.FuelidError` with the reason. ``progress`` is told as the fit and
    its diagnostics start, and the fit's steps when it can show them
    (:mod:`fuelid.workflow.progress`).
    """
    from fuelid.plant.config import load_plant_config

    if t_start is not None or t_stop is not None:
        data = select(data, t_start, t_stop)
    source = plant if plant is not None else PlantSource(load_plant_config(None))
    point = OperatingPoint.of(data, fuel_temperature)
    T_fuel = T_REF if point.T_fuel is None else point.T_fuel
    resolved, sources = resolve_priors(options, source, T_fuel)
    if resolved.method == "step-ls":
        result, step_sources = identify_step_ls(
            data, resolved, validation=validation, progress=progress
        )
        sources |= step_sources
    else:
        result = identify(data, resolved, validation, progress=progress)
    findings = check_signals(data, source)
    mismatch = check_gain_against_plant(result.model, source, point, T_fuel)
    if mismatch is not None:
        findings.append(mismatch)
    return IdentifyOutcome(
        result,
        priors=priors_json(resolved, sources, result, plant),
        operating_point=point,
        signal_check=findings,
    )


def identify_step_ls(
    data: IOData,
    options: IdentifyOptions,
    oe_model: ProcessModel | None = None,
    validation: IOData | None = None,
    *,
    diagnose: bool = True,
    progress: StageCallback | None = None,
) -> tuple[IdentificationResult, dict[str, PriorSource]]:
    """The article's step-ls fit with the prior knowledge it needs, and where that came from.

    step-ls needs the dead time and the response length N as priors. An option or a plant file
    gives them; otherwise the output-error fit of the same log does (``oe_model``, fitted here
    when not given): its dead time, and N from its 98 % settling time. When the fitted step-ls
    model has not settled within N periods (its response would be truncated, biasing K and T)
    and N was not fixed by an option, the fit is repeated once with the N that model needs.
    ``diagnose=False``: the fit without its diagnostics (:func:`~fuelid.identify.procedure.
    identify`). ``progress``: told as each fit and its diagnostics start.

    Returns
    -------
    result : IdentificationResult
    sources : dict
        ``"N"`` and, when it came from the output-error fit, ``"delay"``.
    """
    sources: dict[str, PriorSource] = {}
    needs_N = options.N is None and options.settling_time is None
    needs_delay = options.resolved_delay() is None
    if (needs_N or needs_delay) and oe_model is None:
        oe_model = identify(
            data, replace(options, method="oe", validate_split=None), progress=progress
        ).model
    if oe_model is not None and needs_N:
        options = replace(options, settling_time=oe_model.settling_time())
    if oe_model is not None and needs_delay:
        options = replace(options, delay=oe_model.delay)
        sources["delay"] = "output-error fit"
    sources["N"] = (
        "option" if options.N is not None else "output-error fit" if needs_N else "plant file"
    )
    result = identify(data, options, validation, diagnose=diagnose, progress=progress)
    if options.N is None:
        needed = math.ceil(result.model.settling_time() / result.sample_time)
        if needed > int(result.extra.get("N", needed)):
            result = identify(
                data, replace(options, N=needed), validation, diagnose=diagnose, progress=progress
            )
            sources["N"] = "refit: the N its own model needs"
    return result, sources
