"""Identification as the workflow runs it: the plant file's priors, the window, the JSON.

:func:`identify_log` is what ``fuelid identify`` runs; the plant file's priors it takes, as
:func:`~fuelid.workflow._analysis.analyse_log` does, are
:func:`fuelid.workflow._assumptions.plant_priors`; the estimators and their diagnostics are
:func:`fuelid.identify._procedure.identify`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

from fuelid.identify import IdentificationResult, IdentifyOptions, StageCallback, identify
from fuelid.identify.preprocess import select
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel
from fuelid.workflow._assumptions import (
    T_REF,
    OperatingPoint,
    PlantSource,
    PriorSource,
    check_gain_against_plant,
    check_signals,
    priors_json,
    resolve_priors,
)

if TYPE_CHECKING:
    pass


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
    (:mod:`fuelid.workflow._progress`).
    """
    from fuelid.plant import load_plant_config

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
    ``diagnose=False``: the fit without its diagnostics (:func:`~fuelid.identify._procedure.
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
