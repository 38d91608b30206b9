"""A plant config's numeric parameters: read them, and set some in a new validated config.

The parameters are the float keys of the plant file's component sections, by their dotted TOML
name (the registry: :mod:`fuelid.plant._parameter_specs`). :func:`plant_parameters` gives each
as a :class:`PlantParameter`: its value in the file's (natural) unit, the unit, the bounds the
config's validation imposes and whether it must be strictly positive.

:func:`with_parameters` returns a new, validated plant config with some parameters changed; it
revalidates only the sections that changed, so it is cheap enough for an optimiser's inner loop
(tens of microseconds per call).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from pydantic import ValidationError

from fuelid.errors import ConfigError, validation_reason
from fuelid.plant._config import PlantConfig
from fuelid.plant._parameter_specs import parameter_spec, parameter_specs
from fuelid.plant._section import Section

__all__ = ["PlantParameter", "get_parameter", "plant_parameters", "with_parameters"]


@dataclass(frozen=True, slots=True)
class PlantParameter:
    """One numeric parameter of a plant config.

    Examples
    --------
    >>> from fuelid.plant import load_plant_config
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
    >>> from fuelid.plant import load_plant_config
    >>> params = plant_parameters(load_plant_config())
    >>> params["vfd.lag_s"].value, params["vfd.lag_s"].unit, params["vfd.lag_s"].positive
    (1.2, 's', True)
    """
    out: dict[str, PlantParameter] = {}
    for name, spec in parameter_specs().items():
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
    >>> from fuelid.plant import load_plant_config
    >>> get_parameter(load_plant_config(), "nozzle.discharge_coefficient")
    0.7
    """
    spec = parameter_spec(name)
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
    >>> from fuelid.plant import load_plant_config
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
        spec = parameter_spec(name)
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
