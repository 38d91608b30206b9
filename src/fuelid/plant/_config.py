"""Plant configuration: the typed, validated parameter set of one fuel supply, read from TOML.

A plant TOML file has one table per component (``[fuel]``, ``[vfd]``, ``[motor]``, ``[pump]``,
``[pipeline]``, ``[nozzle]``, ``[flowmeter]``); every key carries its unit in its name and is
documented in the component's ``*Config`` class. Unknown or missing keys, wrong signs and
impossible values are refused with a :class:`~fuelid.errors.ConfigError` that names the field.

An optional ``[calibration]`` table (:class:`CalibrationRecord`) records how some of the
parameters were estimated from logs (``fuelid calibrate``): which ones, their values, standard
errors, covariance and 95 % intervals in the keys' own units, and the logs they came from.
"""

from __future__ import annotations

import math
import re
import tomllib
from datetime import date, datetime
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field, ValidationError, field_validator, model_validator

from fuelid.errors import ConfigError, FuelidError, validation_reason
from fuelid.fuel import DEFAULT_FUEL, get_fuel
from fuelid.plant._flowmeter import FlowmeterConfig
from fuelid.plant._motor import MotorConfig
from fuelid.plant._nozzle import NozzleConfig
from fuelid.plant._parameter_specs import check_parameter_names
from fuelid.plant._pipeline import PipelineConfig
from fuelid.plant._pump import PumpConfig
from fuelid.plant._section import Section
from fuelid.plant._vfd import VFDConfig
from fuelid.units import T0 as KELVIN_AT_0C

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


_SHA256 = re.compile(r"^[0-9a-f]{64}$")
#: relative asymmetry of a covariance matrix still taken for rounding [-]
_SYMMETRY_RTOL = 1e-9
#: most negative eigenvalue of a covariance, relative to its largest, taken for rounding [-]
_PSD_RTOL = 1e-9


class CalibrationLog(Section):
    """One log a calibration used (an entry of ``logs`` in the ``[calibration]`` table)."""

    file: str = Field(description="the log's file name, as given to fuelid calibrate")
    sha256: str = Field(description="SHA-256 of the log's bytes, 64 hex digits")
    fuel_temperature_C: float = Field(description="fuel temperature of the log [°C]")

    @field_validator("sha256")
    @classmethod
    def _hex_digest(cls, value: str) -> str:
        digest = value.strip().lower()
        if not _SHA256.match(digest):
            raise ValueError(f"sha256 must be 64 hexadecimal digits, got {value!r}")
        return digest

    @field_validator("fuel_temperature_C")
    @classmethod
    def _finite_temperature(cls, value: float) -> float:
        if not (math.isfinite(value) and value > -KELVIN_AT_0C):
            raise ValueError(f"fuel_temperature_C must be a finite temperature, got {value!r}")
        return value


class CalibrationRecord(Section):
    """How parameters of this plant were calibrated from logs (TOML section ``[calibration]``).

    Every number is in the unit of the parameter's key (``pump.leakage_Lpm_per_MPa`` in
    (L/min)/MPa …), whatever space the estimator worked in. ``parameters`` lists the dotted
    names (:func:`fuelid.plant.parameter_names`); ``values``, ``stderr``, ``ci95``
    and the rows and columns of ``covariance`` follow that order.
    """

    parameters: tuple[str, ...] = Field(
        min_length=1, description="dotted names of the calibrated parameters"
    )
    values: tuple[float, ...] = Field(description="estimates, in the keys' units")
    stderr: tuple[float, ...] | None = Field(
        None, description="standard errors of the estimates, in the keys' units"
    )
    covariance: tuple[tuple[float, ...], ...] | None = Field(
        None, description="covariance of the estimates, in the products of the keys' units"
    )
    ci95: tuple[tuple[float, float], ...] | None = Field(
        None, description="95 % confidence interval [lo, hi] of each estimate, in the keys' units"
    )
    logs: tuple[CalibrationLog, ...] = Field(
        (), description="the logs the calibration used: file, sha256, fuel_temperature_C"
    )
    fit_percent: tuple[float, ...] = Field(
        (), description="fit of the calibrated model to each log, 100·(1 − ‖e‖/‖y − ȳ‖) [%]"
    )
    created: str | None = Field(None, description="when the calibration ran (ISO 8601)")
    fuelid_version: str = Field("", description="version of fuelid that ran it")
    method: str = Field("", description="estimator, e.g. 'output error, nonlinear ODE'")
    warnings: tuple[str, ...] = Field(
        (),
        description="what the calibration warned about (a misfit, correlated estimates …); "
        "repeated wherever the calibrated plant is used",
    )

    @field_validator("created", mode="before")
    @classmethod
    def _iso_time(cls, value: Any) -> Any:
        if isinstance(value, date):  # a TOML date-time literal
            return value.isoformat()
        if isinstance(value, str):
            try:
                datetime.fromisoformat(value)
            except ValueError:
                raise ValueError(f"created must be an ISO 8601 date-time, got {value!r}") from None
        return value

    @field_validator("parameters")
    @classmethod
    def _known_parameters(cls, names: tuple[str, ...]) -> tuple[str, ...]:
        try:
            check_parameter_names(names)
        except FuelidError as exc:
            raise ValueError(str(exc)) from None
        repeated = sorted({name for name in names if names.count(name) > 1})
        if repeated:
            raise ValueError(f"parameters listed twice: {', '.join(repeated)}")
        return names

    @model_validator(mode="after")
    def _consistent(self) -> CalibrationRecord:
        n = len(self.parameters)
        self._check_vector("values", self.values, n)
        if self.stderr is not None:
            self._check_vector("stderr", self.stderr, n)
            if any(s < 0.0 for s in self.stderr):
                raise ValueError("stderr must not be negative")
        if self.ci95 is not None:
            self._check_vector("ci95", self.ci95, n)
            if any(lo > hi for lo, hi in self.ci95):
                raise ValueError("ci95: each interval must be [lo, hi] with lo <= hi")
        if self.covariance is not None:
            _check_covariance(self.covariance, n)
        if self.fit_percent:
            self._check_vector("fit_percent", self.fit_percent, len(self.logs))
        return self

    @staticmethod
    def _check_vector(name: str, values: tuple[Any, ...], size: int) -> None:
        if len(values) != size:
            per = "log" if name == "fit_percent" else "parameter"
            raise ValueError(f"{name} has {len(values)} entries, expected {size} (one per {per})")
        flat = [v for item in values for v in (item if isinstance(item, tuple) else (item,))]
        if not all(math.isfinite(v) for v in flat):
            raise ValueError(f"{name} must hold finite numbers only")

    @property
    def covariance_matrix(self) -> np.ndarray[Any, np.dtype[np.float64]] | None:
        """``covariance`` as an (n, n) array, in the order of ``parameters``; None if absent."""
        if self.covariance is None:
            return None
        return np.array(self.covariance, dtype=float)

    @property
    def temperature_range(self) -> tuple[float, float] | None:
        """Lowest and highest fuel temperature of the calibration logs [°C]; None without logs."""
        if not self.logs:
            return None
        temperatures = [log.fuel_temperature_C for log in self.logs]
        return min(temperatures), max(temperatures)


def _check_covariance(rows: tuple[tuple[float, ...], ...], n: int) -> None:
    """Refuse a covariance that is not n×n, finite, symmetric and positive semi-definite."""
    if len(rows) != n or any(len(row) != n for row in rows):
        shape = f"{len(rows)} rows of {sorted({len(row) for row in rows})} entries"
        raise ValueError(f"covariance must be {n}×{n} (one row per parameter), got {shape}")
    matrix = np.array(rows, dtype=float)
    if not np.all(np.isfinite(matrix)):
        raise ValueError("covariance must hold finite numbers only")
    scale = float(np.max(np.abs(matrix)))
    if np.any(np.abs(matrix - matrix.T) > _SYMMETRY_RTOL * scale):
        raise ValueError("covariance must be symmetric")
    if np.any(np.diag(matrix) < 0.0):
        raise ValueError("covariance must have a non-negative diagonal (variances)")
    if scale > 0.0 and float(np.min(np.linalg.eigvalsh(matrix))) < -_PSD_RTOL * scale:
        raise ValueError("covariance must be positive semi-definite")


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
    calibration: CalibrationRecord | None = Field(
        None, description="how parameters were calibrated from logs (fuelid calibrate)"
    )


def calibrated_temperature_range(config: PlantConfig) -> tuple[float, float] | None:
    """Fuel-temperature range of the logs a plant was calibrated on [°C].

    Parameters
    ----------
    config : PlantConfig
        The plant.

    Returns
    -------
    (float, float) or None
        Lowest and highest ``fuel_temperature_C`` of the ``[calibration]`` logs; None when the
        config has no ``[calibration]`` table or it lists no logs.

    Examples
    --------
    >>> calibrated_temperature_range(load_plant_config()) is None
    True
    """
    return None if config.calibration is None else config.calibration.temperature_range


def _describe(error: Any) -> str:
    where = ".".join(str(part) for part in error["loc"]) or "(top level)"
    return f"{where}: {validation_reason(error)}"


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


def reference_plant_text() -> str:
    """The packaged reference plant file, comments and all (``fuelid plant init`` writes it)."""
    return resources.files("fuelid.data").joinpath(REFERENCE_PLANT).read_text("utf-8")


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
        text = reference_plant_text()
        source = f"reference plant ({REFERENCE_PLANT})"
    else:
        file = Path(path)
        source = str(file)
        try:
            text = file.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise ConfigError(f"plant config {source} does not exist") from None
        except IsADirectoryError:
            raise ConfigError(
                f"{source} is a folder; --config takes a plant file (fuelid plant init writes one)"
            ) from None
        except (OSError, UnicodeDecodeError) as exc:
            raise ConfigError(f"cannot read plant config {source}: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source} is not valid TOML: {exc}") from None
    if "plc" in data and "vfd" not in data:  # the other TOML file a newcomer has at hand
        raise ConfigError(
            f"{source} is a site file (it has a [plc] table); --config takes a plant file "
            "(fuelid plant init writes one)"
        )
    return plant_config_from_dict(data, source)
