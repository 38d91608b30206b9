"""Mechanism (physics) model of the fuel supply: one module per component, then the assembly.

- :mod:`~fuelid.plant.vfd`, :mod:`~fuelid.plant.motor`, :mod:`~fuelid.plant.shaft`,
  :mod:`~fuelid.plant.pump`, :mod:`~fuelid.plant.pipeline`, :mod:`~fuelid.plant.nozzle`,
  :mod:`~fuelid.plant.flowmeter`: physics functions (SI) and each component's config section;
- :mod:`~fuelid.plant.config`: the whole plant's TOML file;
- :mod:`~fuelid.plant.system`: coefficients, nonlinear ODE, operating point;
- :mod:`~fuelid.plant.linear`: linearisation and reduction to the model family.
"""

from __future__ import annotations

from fuelid.plant.config import PlantConfig, load_plant_config
from fuelid.plant.linear import EquivalentModel, LinearPlant, linearise
from fuelid.plant.system import (
    OperatingPoint,
    PlantCoefficients,
    operating_point,
    plant_coefficients,
    plant_jacobian,
    plant_rhs,
)

__all__ = [
    "EquivalentModel",
    "LinearPlant",
    "OperatingPoint",
    "PlantCoefficients",
    "PlantConfig",
    "linearise",
    "load_plant_config",
    "operating_point",
    "plant_coefficients",
    "plant_jacobian",
    "plant_rhs",
]
