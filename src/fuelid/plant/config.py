"""Plant configuration: the typed, validated parameter set of one fuel supply, read from TOML.

A plant TOML file has one table per component (``[fuel]``, ``[vfd]``, ``[motor]``, ``[pump]``,
``[pipeline]``, ``[nozzle]``, ``[flowmeter]``); every key carries its unit in its name and is
documented in the component's ``*Config`` class. Unknown or missing keys, wrong signs and
impossible values are refused with a :class:`~fuelid.errors.ConfigError` that names the field.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import Field, ValidationError, field_validator

from fuelid.errors import ConfigError, FuelidError
from fuelid.fuel import DEFAULT_FUEL, get_fuel
from fuelid.plant._section import Section
from fuelid.plant.flowmeter import FlowmeterConfig
from fuelid.plant.motor import MotorConfig
from fuelid.plant.nozzle import NozzleConfig
from fuelid.plant.pipeline import PipelineConfig
from fuelid.plant.pump import PumpConfig
from fuelid.plant.vfd import VFDConfig

REFERENCE_PLANT = "reference_plant.toml"


class FuelConfig(Section):
    """Which fuel correlation to use (TOML section ``[fuel]``)."""

    name: str = Field(DEFAULT_FUEL, description="fuel correlation set, see fuelid.fuel.FUELS")
    allow_extrapolation: bool = Field(
        False, description="evaluate the correlations outside their validity range"
    )

    @field_validator("name")
    @classmethod
    def _known_fuel(cls, value: str) -> str:
        try:
            return get_fuel(value).name
        except FuelidError as exc:
            raise ValueError(str(exc)) from None


class PlantConfig(Section):
    """The whole fuel supply: drive, motor, pump, line, nozzles and flowmeter."""

    name: str = Field(description="short name of the plant")
    description: str = Field("", description="free text: where the numbers come from")
    fuel: FuelConfig = Field(default_factory=FuelConfig)
    vfd: VFDConfig
    motor: MotorConfig
    pump: PumpConfig
    pipeline: PipelineConfig
    nozzle: NozzleConfig
    flowmeter: FlowmeterConfig


def _describe(error: Any) -> str:
    where = ".".join(str(part) for part in error["loc"]) or "(top level)"
    kind = error["type"]
    if kind == "missing":
        return f"{where}: missing required key"
    if kind == "extra_forbidden":
        return f"{where}: unknown key"
    message = str(error["msg"]).removeprefix("Value error, ")
    if kind not in {"value_error", "model_type"} and "input" in error:
        message += f" (got {error['input']!r})"
    return f"{where}: {message}"


def plant_config_from_dict(data: dict[str, Any], source: str = "plant config") -> PlantConfig:
    """Validate a plant configuration given as nested dictionaries.

    Parameters
    ----------
    data : dict
        The parsed TOML document.
    source : str
        Name used in error messages (usually the file name).

    Returns
    -------
    PlantConfig

    Raises
    ------
    ConfigError
        One line naming every offending field, e.g.
        ``pipeline.length_m: Input should be greater than 0 (got -80)``.
    """
    try:
        return PlantConfig.model_validate(data)
    except ValidationError as exc:
        details = "; ".join(_describe(err) for err in exc.errors())
        raise ConfigError(f"{source}: {details}") from None


def load_plant_config(path: str | Path | None = None) -> PlantConfig:
    """Read and validate a plant TOML file; the packaged reference plant when ``path`` is None.

    Parameters
    ----------
    path : str or Path, optional
        The TOML file.

    Returns
    -------
    PlantConfig

    Raises
    ------
    ConfigError
        If the file is missing, unreadable, not valid TOML, or fails validation.

    Examples
    --------
    >>> cfg = load_plant_config()
    >>> cfg.fuel.name, cfg.vfd.u_min_V, cfg.vfd.u_max_V
    ('RP-3', 1.0, 5.0)
    """
    if path is None:
        text = resources.files("fuelid.data").joinpath(REFERENCE_PLANT).read_text("utf-8")
        source = f"reference plant ({REFERENCE_PLANT})"
    else:
        file = Path(path)
        source = str(file)
        try:
            text = file.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise ConfigError(f"plant config {source} does not exist") from None
        except IsADirectoryError:
            raise ConfigError(f"plant config {source} is a directory, not a TOML file") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise ConfigError(f"cannot read plant config {source}: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source} is not valid TOML: {exc}") from None
    return plant_config_from_dict(data, source)
