"""Mechanism (physics) model of the fuel supply: the components, then the assembly.

Each component (drive, motor, shaft, pump, pipeline, nozzles, flowmeter) is a private module
with its physics functions (SI) and its section of the plant file; the package exports:

- :class:`PlantConfig`: the whole plant's TOML file (:func:`load_plant_config`,
  :func:`plant_config_from_dict`, :func:`reference_plant_text`), with its ``[calibration]``
  record (:class:`CalibrationLog`, :class:`CalibrationRecord`);
- its numeric parameters by dotted name (:func:`parameter_names`, :func:`plant_parameters`,
  :class:`PlantParameter`), read with :func:`get_parameter` and set in a new config with
  :func:`with_parameters`;
- the assembly: the temperature-dependent coefficients (:func:`plant_coefficients`), the
  nonlinear ODE (:func:`plant_rhs`, :func:`plant_jacobian`) and its :func:`operating_point`;
- :func:`linearise`: linearisation (:class:`LinearPlant`) and reduction to the model family
  (:class:`EquivalentModel`);
- :func:`prediction_uncertainty`: the calibration's covariance propagated to K, T, settling;
- :func:`measure_flow`: what the PLC reads of the flow (the meter's lag and dead time, noise,
  quantisation);
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
