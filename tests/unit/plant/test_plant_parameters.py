"""The registry of a plant's numeric parameters (:mod:`fuelid.plant._parameters`).

Checks: the registry holds exactly the float keys of the component sections (found here
independently from the config classes), with the values, units and bounds the sections declare;
unknown names are refused with the list of valid ones; :func:`with_parameters` gives the same
config as editing the TOML data and validating it from scratch, refuses what the file would
refuse, and is fast enough for an optimiser's loop.
"""

from __future__ import annotations

import copy
import math
import time
import tomllib
from importlib import resources
from typing import Any

import pytest
from pydantic import BaseModel

from fuelid.errors import ConfigError
from fuelid.plant import (
    PlantConfig,
    get_parameter,
    operating_point,
    parameter_names,
    plant_config_from_dict,
    plant_parameters,
    with_parameters,
)
from fuelid.units import LPM_PER_M3S

REFERENCE = tomllib.loads(
    resources.files("fuelid.data").joinpath("reference_plant.toml").read_text("utf-8")
)


def _float_keys() -> set[str]:
    """Every float-valued key of every table of the reference plant file."""
    return {
        f"{table}.{key}"
        for table, body in REFERENCE.items()
        if isinstance(body, dict)
        for key, value in body.items()
        if isinstance(value, float)
    }


def test_registry_is_every_float_key_of_the_sections(cfg: PlantConfig) -> None:
    names = set(parameter_names())
    # every float in the reference file is a parameter …
    assert _float_keys() <= names
    # … and every parameter is a float field of a component section
    for name in names:
        section, key = name.split(".")
        model = getattr(cfg, section)
        assert isinstance(model, BaseModel)
        assert type(model).model_fields[key].annotation is float
    # integers, strings, booleans and optional keys are not parameters
    for excluded in (
        "nozzle.count",
        "motor.pole_pairs",
        "pipeline.friction_method",
        "fuel.name",
        "fuel.allow_extrapolation",
        "vfd.max_rate_Hz_per_s",
    ):
        assert excluded not in names
    assert {
        "pump.leakage_Lpm_per_MPa",
        "vfd.lag_s",
        "nozzle.discharge_coefficient",
        "pipeline.roughness_mm",
        "motor.inertia_kg_m2",
        "flowmeter.time_constant_s",
    } <= names


def test_values_are_the_files(cfg: PlantConfig) -> None:
    params = plant_parameters(cfg)
    assert list(params) == list(parameter_names())
    for name, param in params.items():
        section, key = name.split(".")
        assert param.name == name
        assert param.value == REFERENCE[section].get(key, getattr(getattr(cfg, section), key))
        assert get_parameter(cfg, name) == param.value


@pytest.mark.parametrize(
    ("name", "unit", "lower", "upper", "positive"),
    [
        ("vfd.lag_s", "s", 0.0, 60.0, True),  # gt=0, le=60
        ("vfd.f_min_Hz", "Hz", 0.0, None, False),  # ge=0: zero allowed
        ("pump.leakage_Lpm_per_MPa", "(L/min)/MPa", 0.0, None, False),  # ge=0: a tight pump
        ("pump.mechanical_efficiency", "-", 0.0, 1.0, True),
        ("nozzle.discharge_coefficient", "-", 0.0, 1.0, True),  # no unit in key or description
        ("pipeline.roughness_mm", "mm", 0.0, None, False),  # smooth pipe allowed
        ("pipeline.bulk_modulus_MPa", "MPa", 0.0, None, True),
        ("motor.inertia_kg_m2", "kg·m²", 0.0, None, True),
        ("motor.damping_N_m_s_per_rad", "N·m·s/rad", 0.0, None, False),
        ("flowmeter.time_constant_s", "s", 0.0, 60.0, False),  # 0: no meter lag
        ("vfd.u_min_V", "V", None, None, False),  # no constraint of its own
    ],
)
def test_units_and_bounds_from_the_section(
    cfg: PlantConfig,
    name: str,
    unit: str,
    lower: float | None,
    upper: float | None,
    positive: bool,
) -> None:
    p = plant_parameters(cfg)[name]
    assert (p.unit, p.lower, p.upper, p.positive) == (unit, lower, upper, positive)
    assert p.description


def test_unknown_name_lists_the_valid_ones(cfg: PlantConfig) -> None:
    with pytest.raises(ConfigError) as info:
        get_parameter(cfg, "pump.leak")
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("unknown plant parameter 'pump.leak'; valid: ")
    assert all(name in message for name in parameter_names())
    with pytest.raises(ConfigError, match=r"unknown plant parameter 'nozzle\.count'"):
        with_parameters(cfg, {"nozzle.count": 4.0})


def test_with_parameters_equals_editing_the_file(cfg: PlantConfig) -> None:
    values = {"pump.leakage_Lpm_per_MPa": 4.5, "vfd.lag_s": 0.8, "nozzle.diameter_mm": 2.5}
    data: dict[str, Any] = copy.deepcopy(REFERENCE)
    for name, value in values.items():
        section, key = name.split(".")
        data[section][key] = value
    assert with_parameters(cfg, values) == plant_config_from_dict(data)


def test_with_parameters_leaves_the_rest_alone(cfg: PlantConfig) -> None:
    new = with_parameters(cfg, {"pump.leakage_Lpm_per_MPa": 3.0})
    assert cfg.pump.leakage_Lpm_per_MPa == 7.0  # the original is untouched
    assert new.pump.leakage_Lpm_per_MPa == 3.0
    assert new.vfd is cfg.vfd
    assert new.pipeline is cfg.pipeline
    assert with_parameters(cfg, {}) is cfg


def test_with_parameters_changes_the_physics(cfg: PlantConfig) -> None:
    # leakage C·p at the operating pressure: halving C_p at the same speed and pressure adds
    # half the old leakage to the delivered flow (to first order; the pressure rises with it)
    base = operating_point(cfg, 3.0, 293.15)
    tight = operating_point(with_parameters(cfg, {"pump.leakage_Lpm_per_MPa": 3.5}), 3.0, 293.15)
    gained = (tight.q - base.q) * LPM_PER_M3S
    assert tight.q_leak < base.q_leak
    assert gained == pytest.approx(0.5 * base.q_leak * LPM_PER_M3S, rel=0.1)


@pytest.mark.parametrize(
    ("values", "field"),
    [
        ({"vfd.lag_s": -1.0}, "vfd.lag_s"),
        ({"vfd.lag_s": 0.0}, "vfd.lag_s"),  # gt=0
        ({"nozzle.discharge_coefficient": 1.2}, "nozzle.discharge_coefficient"),
        ({"pump.leakage_Lpm_per_MPa": math.nan}, "pump.leakage_Lpm_per_MPa"),
        ({"pump.leakage_Lpm_per_MPa": math.inf}, "pump.leakage_Lpm_per_MPa"),
        ({"vfd.f_min_Hz": 60.0}, "f_max_Hz must be greater than f_min_Hz"),  # cross-field
        ({"motor.rated_speed_rpm": 1600.0}, "synchronous speed"),  # above 1500 rpm
    ],
)
def test_with_parameters_refuses_what_the_file_would(
    cfg: PlantConfig, values: dict[str, float], field: str
) -> None:
    with pytest.raises(ConfigError, match=field.replace(".", r"\.")):
        with_parameters(cfg, values)


def test_with_parameters_is_fast(cfg: PlantConfig) -> None:
    # an optimiser calls it ~100 times per second; leave it well under 1 % of that budget
    start = time.perf_counter()
    for k in range(200):
        with_parameters(cfg, {"pump.leakage_Lpm_per_MPa": 5.0 + 0.01 * k, "vfd.lag_s": 1.0})
    per_call = (time.perf_counter() - start) / 200
    assert per_call < 1e-3
