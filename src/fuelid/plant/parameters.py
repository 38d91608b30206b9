"""The registry of a plant's numeric parameters, by their dotted TOML name.

Every float key of the component sections of a plant file is a parameter: ``vfd.lag_s``,
``motor.inertia_kg_m2``, ``pump.leakage_Lpm_per_MPa``, ``pipeline.roughness_mm``,
``nozzle.discharge_coefficient``, ``flowmeter.time_constant_s`` … (integers such as
``nozzle.count`` and ``motor.pole_pairs``, strings, booleans and optional keys such as
``vfd.max_rate_Hz_per_s`` are not). Each is described by a :class:`PlantParameter`: its value in
the file's (natural) unit, the unit, the bounds the config's validation imposes and whether it
must be strictly positive (the calibration estimates those in log space).

:func:`with_parameters` returns a new, validated plant config with some parameters changed; it
revalidates only the sections that changed, so it is cheap enough for an optimiser's inner loop
(tens of microseconds per call).
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from pydantic import ValidationError

from fuelid.errors import ConfigError, validation_reason
from fuelid.plant._section import Section
from fuelid.plant.flowmeter import FlowmeterConfig
from fuelid.plant.motor import MotorConfig
from fuelid.plant.nozzle import NozzleConfig
from fuelid.plant.pipeline import PipelineConfig
from fuelid.plant.pump import PumpConfig
from fuelid.plant.vfd import VFDConfig

if TYPE_CHECKING:
    from fuelid.plant.config import PlantConfig

PARAMETER_SECTIONS: dict[str, type[Section]] = {
    "vfd": VFDConfig,
    "motor": MotorConfig,
    "pump": PumpConfig,
    "pipeline": PipelineConfig,
    "nozzle": NozzleConfig,
    "flowmeter": FlowmeterConfig,
}
"""The plant config's sections that hold numeric parameters, by their TOML table name."""

#: units of the name suffixes, longest first where one suffix ends another
_SUFFIX_UNITS = (
    ("_N_m_s_per_rad", "N·m·s/rad"),
    ("_cm3_per_rev", "cm³/rev"),
    ("_Lpm_per_MPa", "(L/min)/MPa"),
    ("_Hz_per_s", "Hz/s"),
    ("_kg_m2", "kg·m²"),
    ("_mPa_s", "mPa·s"),
    ("_Lpm", "L/min"),
    ("_MPa", "MPa"),
    ("_rpm", "rpm"),
    ("_kW", "kW"),
    ("_Hz", "Hz"),
    ("_mm", "mm"),
    ("_V", "V"),
    ("_m", "m"),
    ("_s", "s"),
)
_TRAILING_UNIT = re.compile(r"\[([^\[\]]+)\]\s*$")


@dataclass(frozen=True, slots=True)
class PlantParameter:
    """One numeric parameter of a plant config.

    Examples
    --------
    >>> from fuelid.plant.config import load_plant_config
    >>> p = plant_parameters(load_plant_config())["pump.leakage_Lpm_per_MPa"]
    >>> p.value, p.unit, p.lower, p.upper, p.positive
    (7.0, '(L/min)/MPa', 0.0, None, False)
    """

    name: str
    """Dotted TOML name, ``section.key``."""
    value: float
    """Value in the unit of the key [``unit``]."""
    unit: str
    """Engineering unit of the value (``-`` for a pure number)."""
    lower: float | None
    """Lowest value the config accepts (the bound itself excluded when ``positive``); None: none."""
    upper: float | None
    """Highest value the config accepts; None: none."""
    positive: bool
    """True when the value must be strictly greater than zero (estimated in log space)."""
    description: str
    """What the parameter is, from the config section's field description."""


@dataclass(frozen=True, slots=True)
class _Spec:
    """The value-independent part of a :class:`PlantParameter`."""

    section: str
    key: str
    unit: str
    lower: float | None
    upper: float | None
    positive: bool
    description: str

    @property
    def name(self) -> str:
        return f"{self.section}.{self.key}"


def _unit(key: str, description: str) -> str:
    """The unit of a key: the description's trailing ``[unit]``, else the name's suffix, else -."""
    match = _TRAILING_UNIT.search(description)
    if match:
        return match.group(1)
    for suffix, unit in _SUFFIX_UNITS:
        if key.endswith(suffix):
            return unit
    return "-"


def _bounds(metadata: list[Any]) -> tuple[float | None, float | None, bool]:
    """Lower and upper bound and strict positivity from a field's annotated-types constraints."""
    lower: float | None = None
    upper: float | None = None
    positive = False
    for item in metadata:  # annotated_types' Gt, Ge, Lt, Le (pydantic's constraint objects)
        gt, ge = getattr(item, "gt", None), getattr(item, "ge", None)
        lt, le = getattr(item, "lt", None), getattr(item, "le", None)
        if gt is not None:
            lower = float(gt)
            positive = positive or lower >= 0.0
        if ge is not None:
            lower = float(ge)
            positive = positive or lower > 0.0
        if lt is not None:
            upper = float(lt)
        if le is not None:
            upper = float(le)
    return lower, upper, positive


@functools.cache
def _specs() -> dict[str, _Spec]:
    """Every float field of every parameter section, by dotted name (computed once)."""
    specs: dict[str, _Spec] = {}
    for section, model in PARAMETER_SECTIONS.items():
        for key, field in model.model_fields.items():
            if field.annotation is not float:  # ints, strings, bools and optional keys
                continue
            description = field.description or ""
            lower, upper, positive = _bounds(field.metadata)
            spec = _Spec(section, key, _unit(key, description), lower, upper, positive, description)
            specs[spec.name] = spec
    return specs


def parameter_names() -> tuple[str, ...]:
    """The dotted names of all plant parameters, in the order of the plant file.

    Examples
    --------
    >>> names = parameter_names()
    >>> names[0], "pump.leakage_Lpm_per_MPa" in names, "nozzle.count" in names
    ('vfd.u_min_V', True, False)
    """
    return tuple(_specs())


def _spec(name: str) -> _Spec:
    """The spec of a parameter, or a one-line :class:`ConfigError` listing the valid names."""
    try:
        return _specs()[name]
    except KeyError:
        valid = ", ".join(parameter_names())
        raise ConfigError(f"unknown plant parameter {name!r}; valid: {valid}") from None


def check_parameter_names(names: Any) -> None:
    """Refuse any name that is not a plant parameter (:class:`ConfigError` listing the valid ones).

    Examples
    --------
    >>> check_parameter_names(["pump.leakage_Lpm_per_MPa", "vfd.lag_s"])
    >>> check_parameter_names(["pump.leak"])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    fuelid.errors.ConfigError: unknown plant parameter 'pump.leak'; valid: vfd.u_min_V, ...
    """
    for name in names:
        _spec(str(name))


def plant_parameters(config: PlantConfig) -> dict[str, PlantParameter]:
    """All numeric parameters of a plant config, by dotted name, in the order of the file.

    Parameters
    ----------
    config : PlantConfig
        The plant.

    Returns
    -------
    dict of str to PlantParameter

    Examples
    --------
    >>> from fuelid.plant.config import load_plant_config
    >>> params = plant_parameters(load_plant_config())
    >>> params["vfd.lag_s"].value, params["vfd.lag_s"].unit, params["vfd.lag_s"].positive
    (1.2, 's', True)
    """
    out: dict[str, PlantParameter] = {}
    for name, spec in _specs().items():
        value = float(getattr(getattr(config, spec.section), spec.key))
        out[name] = PlantParameter(
            name=name,
            value=value,
            unit=spec.unit,
            lower=spec.lower,
            upper=spec.upper,
            positive=spec.positive,
            description=spec.description,
        )
    return out


def get_parameter(config: PlantConfig, name: str) -> float:
    """The value of one parameter in its natural unit (see :class:`PlantParameter`).

    Raises
    ------
    ConfigError
        If ``name`` is not a plant parameter; the message lists the valid names.

    Examples
    --------
    >>> from fuelid.plant.config import load_plant_config
    >>> get_parameter(load_plant_config(), "nozzle.discharge_coefficient")
    0.7
    """
    spec = _spec(name)
    return float(getattr(getattr(config, spec.section), spec.key))


def with_parameters(config: PlantConfig, values: Mapping[str, float]) -> PlantConfig:
    """A new, validated plant config with some parameters set (natural units).

    Only the sections that change are revalidated (with all their checks, cross-field ones
    included); the others are shared with ``config``. The ``[calibration]`` record, if any, is
    kept as it is.

    Parameters
    ----------
    config : PlantConfig
        The plant.
    values : mapping of str to float
        New values by dotted name, in the unit of the key.

    Returns
    -------
    PlantConfig

    Raises
    ------
    ConfigError
        If a name is unknown (the message lists the valid ones), or a value is not a finite
        number or fails the section's validation (the message names the field).

    Examples
    --------
    >>> from fuelid.plant.config import load_plant_config
    >>> cfg = with_parameters(load_plant_config(), {"vfd.lag_s": 2.0})
    >>> cfg.vfd.lag_s, get_parameter(cfg, "pump.leakage_Lpm_per_MPa")
    (2.0, 7.0)
    >>> with_parameters(cfg, {"vfd.lag_s": -1.0})
    Traceback (most recent call last):
    ...
    fuelid.errors.ConfigError: vfd.lag_s: Input should be greater than 0 (got -1.0)
    """
    updates: dict[str, dict[str, float]] = {}
    for name, value in values.items():
        spec = _spec(name)
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"{name}: not a number (got {value!r})") from None
        if not math.isfinite(number):
            raise ConfigError(f"{name}: must be a finite number (got {number!r})")
        updates.setdefault(spec.section, {})[spec.key] = number
    if not updates:
        return config
    sections: dict[str, Section] = {}
    for section, changes in updates.items():
        current: Section = getattr(config, section)
        try:
            sections[section] = type(current).model_validate(current.model_dump() | changes)
        except ValidationError as exc:
            raise ConfigError(_describe(section, exc)) from None
    return config.model_copy(update=sections)


def _describe(section: str, exc: ValidationError) -> str:
    """One line naming each offending field of a section, as the plant file's loader does."""
    parts = []
    for error in exc.errors():
        where = ".".join([section, *(str(part) for part in error["loc"])])
        parts.append(f"{where}: {validation_reason(error)}")
    return "; ".join(parts)
