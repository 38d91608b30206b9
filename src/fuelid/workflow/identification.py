"""Identification as the workflow runs it: the plant file's priors, the window, the JSON.

:func:`identify_log` is what ``fuelid identify`` runs, and :func:`plant_priors` what both it and
:func:`~fuelid.workflow.analysis.analyse_log` take from a plant file; the estimators and their
diagnostics are :func:`fuelid.identify.procedure.identify`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from fuelid.identify.procedure import IdentificationResult, IdentifyOptions, identify
from fuelid.io.timeseries import IOData
from fuelid.preprocess import select
from fuelid.units import celsius_to_kelvin

if TYPE_CHECKING:
    from fuelid.plant.config import PlantConfig

T_REF = celsius_to_kelvin(20.0)
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
        step-ls's N).
    T_fuel : float
        Fuel temperature of the settling time [K].

    Returns
    -------
    IdentifyOptions
    """
    meter = config.flowmeter
    settling = options.settling_time
    if settling is None:
        middle = 0.5 * (config.vfd.u_min_V + config.vfd.u_max_V)
        from fuelid.plant.linear import linearise  # the physics only when a plant file is given

        settling = linearise(config, middle, T_fuel).settling_time()
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

    @property
    def warnings(self) -> list[str]:
        """What the user should know about the fit (also inside the JSON)."""
        return self.result.warnings

    def to_json(self) -> dict[str, Any]:
        """The documented JSON object of ``fuelid identify --json`` (without provenance)."""
        return self.result.to_json() | {"units": IDENTIFY_UNITS}


def identify_log(
    data: IOData,
    options: IdentifyOptions,
    *,
    validation: IOData | None = None,
    t_start: float | None = None,
    t_stop: float | None = None,
) -> IdentifyOutcome:
    """Identify the model of a loaded log, on the samples with ``t_start ≤ t < t_stop`` [s].

    ``validation`` is a second log to score the model on (its offset and initial state
    estimated, or from rest at its first input with ``options.validation_initial="rest"``).
    Refusals (non-exciting data, priors the record contradicts) raise
    :class:`~fuelid.errors.FuelidError` with the reason.
    """
    if t_start is not None or t_stop is not None:
        data = select(data, t_start, t_stop)
    return IdentifyOutcome(identify(data, options, validation))
