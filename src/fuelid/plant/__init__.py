"""Mechanism (physics) model of the fuel supply: one module per component, then the assembly.

- :mod:`~fuelid.plant._vfd`, :mod:`~fuelid.plant._motor`, :mod:`~fuelid.plant._shaft`,
  :mod:`~fuelid.plant._pump`, :mod:`~fuelid.plant._pipeline`, :mod:`~fuelid.plant._nozzle`,
  :mod:`~fuelid.plant._flowmeter`: physics functions (SI) and each component's config section;
- :mod:`~fuelid.plant._config`: the whole plant's TOML file (and its ``[calibration]`` record);
- :mod:`~fuelid.plant._parameter_specs`: the registry of its numeric parameters by dotted name,
  and :mod:`~fuelid.plant._parameters` their values in a config (read, and set in a new one);
- :mod:`~fuelid.plant._system`: coefficients, nonlinear ODE, operating point;
- :mod:`~fuelid.plant._linear`: linearisation and reduction to the model family;
- :mod:`~fuelid.plant._uncertainty`: the calibration's covariance propagated to K, T, settling;
- :mod:`~fuelid.plant.simulate`: the nonlinear plant in time as the PLC sees it (a held command,
  the meter's dead time, noise and quantisation). It fills an :class:`~fuelid.io.timeseries.IOData`
  from an :class:`~fuelid.profiles.InputProfile`, so ``io`` and ``profiles`` sit below this
  package (pyproject.toml's layer contract).

The public API
--------------
The names in ``__all__``, and at :mod:`fuelid.plant.simulate`:
:func:`~fuelid.plant.simulate.simulate`, :class:`~fuelid.plant.simulate.SimulationResult`,
:class:`~fuelid.plant.simulate.FuelTemperature`, :func:`~fuelid.plant.simulate.integrate_held`
(``fuelid.simulate`` before 0.2.0; that path was removed in 0.3.0). ``import fuelid.plant``
does not load the simulator.
"""

from __future__ import annotations

from fuelid.plant._config import (
    CalibrationLog,
    CalibrationRecord,
    PlantConfig,
    calibrated_temperature_range,
    load_plant_config,
    plant_config_from_dict,
    reference_plant_text,
)
from fuelid.plant._flowmeter import measure_flow
from fuelid.plant._linear import EquivalentModel, LinearPlant, linearise
from fuelid.plant._parameter_specs import parameter_names
from fuelid.plant._parameters import (
    PlantParameter,
    get_parameter,
    plant_parameters,
    with_parameters,
)
from fuelid.plant._system import (
    N_STATES,
    STATE_NAMES,
    OperatingPoint,
    PlantCoefficients,
    input_jacobian,
    measured_state,
    operating_point,
    plant_coefficients,
    plant_jacobian,
    plant_rhs,
    steady_state,
)
from fuelid.plant._uncertainty import (
    PredictionUncertainty,
    calibration_summary,
    prediction_uncertainty,
)

__all__ = [
    "N_STATES",
    "STATE_NAMES",
    "CalibrationLog",
    "CalibrationRecord",
    "EquivalentModel",
    "LinearPlant",
    "OperatingPoint",
    "PlantCoefficients",
    "PlantConfig",
    "PlantParameter",
    "PredictionUncertainty",
    "calibrated_temperature_range",
    "calibration_summary",
    "get_parameter",
    "input_jacobian",
    "linearise",
    "load_plant_config",
    "measure_flow",
    "measured_state",
    "operating_point",
    "parameter_names",
    "plant_coefficients",
    "plant_config_from_dict",
    "plant_jacobian",
    "plant_parameters",
    "plant_rhs",
    "prediction_uncertainty",
    "reference_plant_text",
    "steady_state",
    "with_parameters",
]
