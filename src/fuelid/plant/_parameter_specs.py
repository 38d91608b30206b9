"""The registry of a plant's numeric parameters, by their dotted TOML name.

Every float key of the component sections of a plant file is a parameter: ``vfd.lag_s``,
``motor.inertia_kg_m2``, ``pump.leakage_Lpm_per_MPa``, ``pipeline.roughness_mm``,
``nozzle.discharge_coefficient``, ``flowmeter.time_constant_s`` … (integers such as
``nozzle.count`` and ``motor.pole_pairs``, strings, booleans and optional keys such as
``vfd.max_rate_Hz_per_s`` are not). Each is described by a :class:`ParameterSpec`, read from the
section classes alone: the unit, the bounds the config's validation imposes and whether it must
be strictly positive (the calibration estimates those in log space).

The plant config checks the names its ``[calibration]`` record lists against it
(:func:`check_parameter_names`); a config's values are read and set by
:mod:`fuelid.plant._parameters`.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from typing import Any

from fuelid.errors import ConfigError
from fuelid.plant._flowmeter import FlowmeterConfig
from fuelid.plant._motor import MotorConfig
from fuelid.plant._nozzle import NozzleConfig
from fuelid.plant._pipeline import PipelineConfig
from fuelid.plant._pump import PumpConfig
from fuelid.plant._section import Section
from fuelid.plant._vfd import VFDConfig

__all__ = [
    "PARAMETER_SECTIONS",
    "ParameterSpec",
    "check_parameter_names",
    "parameter_names",
    "parameter_spec",
    "parameter_specs",
]

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
class ParameterSpec:
    """What a plant parameter is, apart from its value: where it lives, its unit and bounds."""

    section: str
    key: str
    unit: str
    lower: float | None
    upper: float | None
    positive: bool
    description: str

    @property
    def name(self) -> str:
        """Dotted TOML name, ``section.key``."""
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
def parameter_specs() -> dict[str, ParameterSpec]:
    """Every float field of every parameter section, by dotted name (computed once)."""
    specs: dict[str, ParameterSpec] = {}
    for section, model in PARAMETER_SECTIONS.items():
        for key, field in model.model_fields.items():
            if field.annotation is not float:  # ints, strings, bools and optional keys
                continue
            description = field.description or ""
            lower, upper, positive = _bounds(field.metadata)
            spec = ParameterSpec(
                section, key, _unit(key, description), lower, upper, positive, description
            )
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
    return tuple(parameter_specs())


def parameter_spec(name: str) -> ParameterSpec:
    """The spec of a parameter, or a one-line :class:`ConfigError` listing the valid names."""
    try:
        return parameter_specs()[name]
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
        parameter_spec(str(name))
