"""What every number rests on: which plant, which priors, which operating point, which units.

A tuning tool must never print an unsafe number as safe. The gains of ``fuelid report`` and
``fuelid tune`` rest on assumptions the log cannot show: the flowmeter's lag and dead time (priors
of the fit), the plant whose physics says how the loop moves with fuel temperature, the spans the
percent-of-span gains use, the fuel temperature and command the model was found at, and the units
of the signals. This module records each one with where it came from, so the outputs can say so,
and checks the signals against the spans the gains are computed for.

- :class:`PlantSource`: the plant file given, or the built-in reference plant (then said loudly);
- :class:`PlantKnowledge` / :func:`plant_knowledge`: what a plant file tells an identification
  before it sees data, and :func:`plant_priors`: the options with it;
- :func:`resolve_priors` / :func:`priors_json`: the identification's priors and their origin;
- :class:`OperatingPoint`: mean command, mean flow and fuel temperature of the fitted samples;
- :func:`check_signals`: command and flow against the drive's signal range, the meter span and the
  column units, naming the likely cause (an input left in mA, raw counts, a wrong unit);
- :func:`check_gain_against_plant`: the identified K against the user's plant file's prediction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from fuelid.io.timeseries import INPUT_UNIT, OUTPUT_UNIT, IOData
from fuelid.model import ProcessModel
from fuelid.units import DEFAULT_FUEL_TEMPERATURE_C, celsius_to_kelvin, kelvin_to_celsius

if TYPE_CHECKING:
    from fuelid.identify import IdentificationResult, IdentifyOptions
    from fuelid.plant import PlantConfig

REFERENCE_PLANT_NOTICE = (
    "no plant file given (--config): how your loop changes with fuel temperature is unknown, so "
    "no temperature check, schedule or nonlinear run is made (fuelid's built-in reference plant "
    "is not your loop); the margins are on the identified model and the range check on the "
    "log's command bands"
)
"""Said in every output (text, JSON, HTML) made without the user's plant file."""

PLANT_GAIN_BOUND = (0.5, 2.0)
"""Identified K over the plant file's prediction outside this range is flagged [-]: a unit or
scaling mistake, or a plant file that does not describe the loop (pump wear changes K by tens of
percent, not by a factor of two)."""

SPAN_TOLERANCE = 0.05
"""How far a signal may leave its span before it is flagged, as a fraction of the span [-]
(a drive command a little beyond 1…5 V is a calibration offset, not a unit mistake)."""


T_REF = celsius_to_kelvin(DEFAULT_FUEL_TEMPERATURE_C)
"""Fuel temperature assumed when none is given [K]: 20 °C."""


@dataclass(frozen=True)
class PlantKnowledge:
    """What a plant file tells an identification before it sees data: the one home of priors.

    ``fuelid identify --config``, ``fuelid report --config`` and the online service's windows
    (:func:`fuelid.online._window.window_priors`) all take their priors from here.
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
    from fuelid.plant import linearise  # the physics only when a plant file is given

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


PriorSource = Literal[
    "option",
    "plant file",
    "estimated",
    "not given",
    "output-error fit",
    "refit: the N its own model needs",
]


@dataclass(frozen=True)
class PlantSource:
    """The plant behind the checks: a user's plant file, or the built-in reference plant."""

    config: PlantConfig
    path: str | None = None
    """The plant TOML given by the user; None for the built-in reference plant."""

    @property
    def is_reference(self) -> bool:
        """True when no plant file was given and the built-in reference plant stands in."""
        return self.path is None

    def to_json(self) -> dict[str, Any]:
        """``{"source": "file" | "built-in reference", "path", "name", "notice"}``."""
        return {
            "source": "built-in reference" if self.is_reference else "file",
            "path": self.path,
            "name": self.config.name,
            "notice": REFERENCE_PLANT_NOTICE if self.is_reference else None,
        }


def resolve_priors(
    options: IdentifyOptions, plant: PlantSource, T_fuel: float
) -> tuple[IdentifyOptions, dict[str, PriorSource]]:
    """The identification's options with a user's plant file's priors, and where each came from.

    The built-in reference plant gives no priors: its flowmeter is not the user's. A meter lag
    that is not given is then estimated as the second lag T2 (T and T_f are interchangeable in the
    model), and the dead time is estimated.

    Returns
    -------
    options : IdentifyOptions
        With the plant file's flowmeter lag, dead time and settling time where none was given.
    sources : dict
        ``flowmeter_T``, ``flowmeter_delay``: "option", "plant file" or "not given".
    """
    sources: dict[str, PriorSource] = {
        "flowmeter_T": "option" if options.flowmeter_T is not None else "not given",
        "flowmeter_delay": "option" if options.flowmeter_delay is not None else "not given",
    }
    if plant.is_reference:
        return options, sources
    for key in sources:
        if sources[key] == "not given":
            sources[key] = "plant file"
    return plant_priors(options, plant.config, T_fuel), sources


def priors_json(
    options: IdentifyOptions,
    sources: dict[str, PriorSource],
    result: IdentificationResult,
    plant: PlantSource | None,
) -> dict[str, Any]:
    """The ``priors`` object of the JSON: each assumption of the fit, its value and its origin.

    ``flowmeter_T`` and ``flowmeter_delay`` are the meter priors (held fixed when given);
    ``delay`` and ``order`` say whether the fit estimated them; ``plant`` names the plant file
    (or the built-in reference plant with its notice).
    """
    model = result.model
    fixed = set(result.fixed)
    meter_lag: dict[str, Any] = {
        "value": options.flowmeter_T,
        "source": sources.get("flowmeter_T", "not given"),
    }
    if options.flowmeter_T is None:
        meter_lag["note"] = (
            "not fixed: a meter lag, if any, is estimated as a second lag T2 when the order is 2"
        )
    delay_source: PriorSource
    if "delay" in sources:
        delay_source = sources["delay"]
    elif "delay" in fixed:
        delay_source = (
            "option"
            if options.delay not in (None, "auto")
            else sources.get("flowmeter_delay", "option")
        )
    else:
        delay_source = "estimated"
    order_value = 2 if model.T2 > 0.0 else 1
    step_ls = (
        {"N": {"value": result.extra.get("N"), "source": sources.get("N", "option")}}
        if result.method == "step-ls"
        else {}
    )
    return step_ls | {
        "plant": None if plant is None else plant.to_json(),
        "flowmeter_T": meter_lag,
        "flowmeter_delay": {
            "value": options.flowmeter_delay,
            "source": sources.get("flowmeter_delay", "not given"),
        },
        "delay": {"value": model.delay, "source": delay_source},
        "order": {
            "value": order_value,
            "source": "information criterion" if options.order == "auto" else "option",
        },
    }


@dataclass(frozen=True)
class OperatingPoint:
    """Where the model was found: what the temperature check and the schedule are anchored to."""

    u: float
    """Mean command of the fitted samples [input unit, V]."""
    y: float
    """Mean flow of the fitted samples [output unit, L/min]."""
    T_fuel: float | None
    """Fuel temperature [K]; None when neither the log nor an option gives it."""
    T_fuel_source: Literal["log", "option"] | None = None

    @classmethod
    def of(cls, data: IOData, T_fuel_option: float | None) -> OperatingPoint:
        """The operating point of ``data``: its means and its fuel temperature.

        The fuel temperature is the mean of the log's column when it has one, else
        ``T_fuel_option`` [K] (None when that is not given either).
        """
        if data.T_fuel is not None:
            return cls(
                float(np.mean(data.u)), float(np.mean(data.y)), float(np.mean(data.T_fuel)), "log"
            )
        source: Literal["option"] | None = None if T_fuel_option is None else "option"
        return cls(float(np.mean(data.u)), float(np.mean(data.y)), T_fuel_option, source)

    def to_json(self) -> dict[str, Any]:
        """``{"u", "y", "fuel_temperature" [°C], "fuel_temperature_source"}``."""
        return {
            "u": self.u,
            "y": self.y,
            "fuel_temperature": None if self.T_fuel is None else kelvin_to_celsius(self.T_fuel),
            "fuel_temperature_source": self.T_fuel_source,
        }


def _range(values: np.ndarray[Any, Any]) -> tuple[float, float]:
    return float(np.min(values)), float(np.max(values))


def _looks_like_counts(low: float, high: float) -> bool:
    """Raw analog-input counts: large values (Siemens 0…27648, 12-bit 0…4095, 16-bit)."""
    return high > 1000.0 and low >= -32768.0


def _looks_like_milliamps(low: float, high: float) -> bool:
    """A 4–20 mA loop current: values inside 3.5…21 reaching well above 5."""
    return low >= 3.5 and 6.0 < high <= 21.0


def check_signals(data: IOData, plant: PlantSource) -> list[str]:
    """Findings that the command or the flow is not in the units the gains are computed for.

    The gains are per V of the drive's signal range and per L/min of flow. The command is checked
    against the drive's range (``plant``'s ``vfd.u_min_V…u_max_V``, 1…5 V on the reference
    plant) and its column unit; the flow against its column unit and, with a user's plant file,
    against the meter span (the built-in reference plant's span says nothing about another loop).
    Each finding names the likely cause: an input left in mA or counts, a percent command, a
    wrong unit. Empty when nothing is wrong.
    """
    findings: list[str] = []
    lo, hi = plant.config.vfd.u_min_V, plant.config.vfd.u_max_V
    tolerance = SPAN_TOLERANCE * (hi - lo)
    u_low, u_high = _range(data.u)
    where = f"the command ({u_low:.4g}…{u_high:.4g}"
    unit = data.u_unit
    if unit and unit != INPUT_UNIT:
        findings.append(
            f"the command column is in {unit}, but the gains are per V of the drive's "
            f"{lo:g}…{hi:g} V signal: scale it (e.g. --input-scale 4:20:{lo:g}:{hi:g} for 4–20 mA)"
        )
    elif u_low < lo - tolerance or u_high > hi + tolerance:
        if _looks_like_counts(u_low, u_high):
            cause = "it looks like raw analog-input counts: scale it with --input-scale"
        elif _looks_like_milliamps(u_low, u_high):
            cause = (
                f"it looks like a 4–20 mA current: scale it with --input-scale 4:20:{lo:g}:{hi:g}"
            )
        elif u_high > 10.0 and u_high <= 100.0 + tolerance:
            cause = f"it looks like percent: scale it with --input-scale 0:100:{lo:g}:{hi:g}"
        else:
            cause = "an unscaled input or a different drive (give its plant file with --config)"
        findings.append(
            f"{where} {unit or 'unit unknown'}) leaves the drive's {lo:g}…{hi:g} V signal range: "
            f"{cause}"
        )
    y_low, y_high = _range(data.y)
    y_unit = data.y_unit
    if y_unit and y_unit != OUTPUT_UNIT:
        findings.append(
            f"the flow column is in {y_unit}, but the gains are per L/min: scale it with "
            "--output-scale RAW_LOW:RAW_HIGH:0:SPAN"
        )
    elif _looks_like_counts(y_low, y_high) and (plant.is_reference or y_high > 2.0 * _span(plant)):
        findings.append(
            f"the flow ({y_low:.5g}…{y_high:.5g}) looks like raw analog-input counts, not L/min: "
            "scale it with --output-scale (e.g. 0:27648:0:SPAN)"
        )
    elif not plant.is_reference and y_high > (1.0 + SPAN_TOLERANCE) * _span(plant):
        findings.append(
            f"the flow reaches {y_high:.4g} L/min, beyond the meter span of {_span(plant):g} L/min "
            f"in {plant.path}: an unscaled output, or a plant file of another loop"
        )
    return findings


def _span(plant: PlantSource) -> float:
    return plant.config.flowmeter.span_Lpm


def check_gain_against_plant(
    model: ProcessModel, plant: PlantSource, point: OperatingPoint, T_fuel: float
) -> str | None:
    """A finding when the identified K is far from what the user's plant file predicts, else None.

    Compared at the log's operating command and fuel temperature ``T_fuel`` [K] with the bound
    :data:`PLANT_GAIN_BOUND`. Never against the built-in reference plant, which would flag every
    other pump.
    """
    if plant.is_reference:
        return None
    lo, hi = plant.config.vfd.u_min_V, plant.config.vfd.u_max_V
    if not lo <= point.u <= hi:
        return None  # the signal check has already said why
    from fuelid.plant import linearise

    predicted = linearise(plant.config, point.u, T_fuel).static_gain
    if not (math.isfinite(predicted) and predicted > 0.0):
        return None
    ratio = model.K / predicted
    low, high = PLANT_GAIN_BOUND
    if low <= ratio <= high:
        return None
    return (
        f"the identified K = {model.K:.4g} is {ratio:.2f}× what {plant.path} predicts "
        f"({predicted:.4g} (L/min)/V at {point.u:.3g} V and {kelvin_to_celsius(T_fuel):g} °C; "
        f"accepted {low:g}…{high:g}×): a scaling or unit mistake in the log, or a plant file "
        "of another loop"
    )


def gain_unit(data: IOData) -> str:
    """K's unit from the signals' units: ``(L/min)/V``; ``(output unit)/(input unit)`` unknown."""
    u_unit = data.u_unit or "input unit"
    y_unit = data.y_unit or "output unit"

    def wrap(unit: str) -> str:
        return f"({unit})" if "/" in unit or " " in unit else unit

    return f"{wrap(y_unit)}/{wrap(u_unit)}"
