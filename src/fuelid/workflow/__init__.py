"""The whole chain as library calls: identify → tune → check over temperature → runs → schedule.

What the command line, the demo and (next) the online service run, with plain arguments and
result objects whose ``to_json()`` is the documented JSON (docs/reference/json.md); nothing here
prints, draws or writes files. Fuel temperatures are in kelvin throughout (``T_fuel``, ``T_range``).

- ``fuelid identify``: :func:`identify_log` (its outcome :class:`IdentifyOutcome`);
- ``fuelid tune``: :class:`TuneRequest`, :func:`tune_model` (:class:`TuneOutcome`), the check
  over temperature :func:`check_over_temperature` and, for ``--schedule``,
  :func:`schedule_gains` (:class:`ScheduleOutcome`);
- ``fuelid report``: :class:`AnalysisSettings`, :func:`analyse_log` (:class:`LogAnalysis`);
- what every number rests on: :class:`PlantSource` (a user's plant file or the built-in
  reference plant), :class:`OperatingPoint`, the plant file's priors (:func:`plant_priors`, at
  :data:`T_REF` unless told), the signal check :func:`check_signals`, and the figures the data
  leave undetermined (:func:`undetermined`);
- ``fuelid plant info``: :func:`plant_info` (:class:`PlantInfo`);
- ``fuelid simulate``: :class:`SimulationRequest`, :func:`simulate_log` and the profile-file
  reader :func:`read_profile`;
- ``fuelid greybox``: :func:`fit_greybox` (:class:`GreyBoxFit`), a user's ODE model file fitted
  to logs: the model with its fixed and free parameters (:func:`greybox_model`), the logs as
  records (:func:`read_record`), the validation, the warnings and the JSON object.

See docs/explanation/architecture.md for where this layer sits.

The public API
--------------
The names in ``__all__``, at ``fuelid.workflow`` itself (each loads its stage on first use).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

# Each stage is imported when first used, so `fuelid identify` does not load the tuning layer
# and `fuelid tune` does not load the log reader: see docs/explanation/architecture.md, lazy
# imports.
# Each name is imported from its private module on first use (lazy_loader, SPEC 1), so
# that importing the package stays cheap.
__getattr__ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "_analysis": ["AnalysisSettings", "LogAnalysis", "METHODS", "analyse_log"],
        "_assumptions": [
            "OperatingPoint",
            "PlantSource",
            "REFERENCE_PLANT_NOTICE",
            "T_REF",
            "check_signals",
            "gain_unit",
            "plant_knowledge",
            "plant_priors",
        ],
        "_greybox_fit": [
            "GreyBoxFit",
            "data_columns",
            "fit_greybox",
            "fit_warnings",
            "greybox_estimator",
            "greybox_model",
            "greybox_result",
            "read_record",
            "validation_head_end",
        ],
        "_identification": [
            "IDENTIFY_UNITS",
            "IdentifyOutcome",
            "identify_log",
            "identify_step_ls",
        ],
        "_plant_info": ["PLANT_INFO_UNITS", "PlantInfo", "plant_info"],
        "_progress": ["IDENTIFY_STAGES"],
        "_simulation": [
            "ProfileTable",
            "SIMULATION_UNITS",
            "SimulationInputs",
            "SimulationOutcome",
            "SimulationRequest",
            "read_profile",
            "simulate_log",
            "simulation_inputs",
        ],
        "_trust": [
            "LEADING_RESPONSE",
            "control_period_from",
            "overridden",
            "undetermined",
            "undetermined_refusal",
            "undetermined_refusal_line",
        ],
        "_tune": [
            "ScheduleOutcome",
            "TuneOutcome",
            "TuneRequest",
            "check_over_temperature",
            "model_file_fields",
            "operating_command",
            "schedule_gains",
            "tune_model",
            "tune_notices",
        ],
    },
)[0]

if TYPE_CHECKING:
    from fuelid.workflow._analysis import METHODS, AnalysisSettings, LogAnalysis, analyse_log
    from fuelid.workflow._assumptions import (
        REFERENCE_PLANT_NOTICE,
        T_REF,
        OperatingPoint,
        PlantSource,
        check_signals,
        gain_unit,
        plant_knowledge,
        plant_priors,
    )
    from fuelid.workflow._greybox_fit import (
        GreyBoxFit,
        data_columns,
        fit_greybox,
        fit_warnings,
        greybox_estimator,
        greybox_model,
        greybox_result,
        read_record,
        validation_head_end,
    )
    from fuelid.workflow._identification import (
        IDENTIFY_UNITS,
        IdentifyOutcome,
        identify_log,
        identify_step_ls,
    )
    from fuelid.workflow._plant_info import PLANT_INFO_UNITS, PlantInfo, plant_info
    from fuelid.workflow._progress import IDENTIFY_STAGES
    from fuelid.workflow._simulation import (
        SIMULATION_UNITS,
        ProfileTable,
        SimulationInputs,
        SimulationOutcome,
        SimulationRequest,
        read_profile,
        simulate_log,
        simulation_inputs,
    )
    from fuelid.workflow._trust import (
        LEADING_RESPONSE,
        control_period_from,
        overridden,
        undetermined,
        undetermined_refusal,
        undetermined_refusal_line,
    )
    from fuelid.workflow._tune import (
        ScheduleOutcome,
        TuneOutcome,
        TuneRequest,
        check_over_temperature,
        model_file_fields,
        operating_command,
        schedule_gains,
        tune_model,
        tune_notices,
    )

__all__ = [
    "IDENTIFY_STAGES",
    "IDENTIFY_UNITS",
    "LEADING_RESPONSE",
    "METHODS",
    "PLANT_INFO_UNITS",
    "REFERENCE_PLANT_NOTICE",
    "SIMULATION_UNITS",
    "T_REF",
    "AnalysisSettings",
    "GreyBoxFit",
    "IdentifyOutcome",
    "LogAnalysis",
    "OperatingPoint",
    "PlantInfo",
    "PlantSource",
    "ProfileTable",
    "ScheduleOutcome",
    "SimulationInputs",
    "SimulationOutcome",
    "SimulationRequest",
    "TuneOutcome",
    "TuneRequest",
    "analyse_log",
    "check_over_temperature",
    "check_signals",
    "control_period_from",
    "data_columns",
    "fit_greybox",
    "fit_warnings",
    "gain_unit",
    "greybox_estimator",
    "greybox_model",
    "greybox_result",
    "identify_log",
    "identify_step_ls",
    "model_file_fields",
    "operating_command",
    "overridden",
    "plant_info",
    "plant_knowledge",
    "plant_priors",
    "read_profile",
    "read_record",
    "schedule_gains",
    "simulate_log",
    "simulation_inputs",
    "tune_model",
    "tune_notices",
    "undetermined",
    "undetermined_refusal",
    "undetermined_refusal_line",
    "validation_head_end",
]
