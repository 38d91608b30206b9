"""PI tuning: rules, robustness margins, closed-loop simulation, fuel-temperature schedules.

- the rules: :func:`tune` with a rule of the registry :data:`TUNING_RULES` (SIMC, improved
  SIMC, lambda, AMIGO; :func:`list_rules`) on the model reduced by :func:`half_rule`, giving
  :class:`PISettings`;
- the PLC's PI block: its form and units (:class:`BlockForm`, :func:`block_units`) and the one
  conversion of the gains to and from it (:func:`to_block`, :func:`from_block`);
- :func:`check_tunable`, :func:`check_sweep_size`: what fuelid tunes, and the guards that refuse
  the rest;
- :func:`robustness`: gain and phase margins and Ms, from loop frequency responses with the dead
  time exact and the sampled controller included (:func:`loop_function`,
  :func:`frequency_grid`);
- :class:`DiscretePI`: the PLC's discrete PI with limits and anti-windup;
- :func:`linear_closed_loop`: the sampled closed loop on the process model (fast, exact): its
  setpoint and load-disturbance steps with their overshoot, settling time and IAE
  (:class:`LinearResponse`);
- :func:`~fuelid.tuning.closedloop.simulate_closed_loop` (at :mod:`fuelid.tuning.closedloop`):
  the closed loop on the nonlinear plant, the standard runs;
- :func:`evaluate_tuning`: one tuning with its evidence and its JSON (:class:`TuningResult`);
- :func:`plant_cases`, :func:`evaluate_fixed`: plant models over fuel temperature and flow, one
  fixed PI over all of them; :func:`band_check` the gains with K at the 95 % interval ends of
  each command band a log visited;
- :func:`gain_schedule`: the gain schedule (:class:`GainSchedule`, its bands from
  :func:`band_edges`);
- :func:`uncertainty_sweep`: the uncertainty sweep.

Inside, the fuel temperature is in kelvin (``T_fuel``); °C appears only in JSON and messages.
The tuning parameter of the rules is the closed-loop time constant (τc or λ, ``closed_loop_time``
[s]): larger is slower. See docs/explanation/tuning.md.

The public API
--------------
The names in ``__all__``, and :func:`~fuelid.tuning.closedloop.simulate_closed_loop` at
:mod:`fuelid.tuning.closedloop`.
"""

from __future__ import annotations

from fuelid.tuning._bands import BandCheck, CommandBand, band_check
from fuelid.tuning._block import BlockForm, block_units, from_block, to_block
from fuelid.tuning._cases import (
    DEFAULT_T_RANGE,
    Anchor,
    CaseCache,
    FixedPIEvaluation,
    evaluate_fixed,
    plant_cases,
)
from fuelid.tuning._controller import DiscretePI
from fuelid.tuning._frequency import (
    Robustness,
    RobustPeak,
    StateSpacePlant,
    TransferFunctionPlant,
    frequency_grid,
    loop_function,
    robust_peak,
    robustness,
)
from fuelid.tuning._limits import check_sweep_size, check_tunable
from fuelid.tuning._linearloop import (
    LinearResponse,
    full_order_closed_loop,
    input_sensitivity,
    linear_closed_loop,
    misfit_overshoot,
    step_duration,
)
from fuelid.tuning._result import UNITS, TuningResult, evaluate_tuning
from fuelid.tuning._rules import (
    TUNING_RULES,
    PISettings,
    ReducedModel,
    half_rule,
    list_rules,
    simc,
    tune,
)
from fuelid.tuning._schedule import GainSchedule, band_edges, gain_schedule
from fuelid.tuning._sweep import SweepResult, uncertainty_sweep

__all__ = [
    "DEFAULT_T_RANGE",
    "TUNING_RULES",
    "UNITS",
    "Anchor",
    "BandCheck",
    "BlockForm",
    "CaseCache",
    "CommandBand",
    "DiscretePI",
    "FixedPIEvaluation",
    "GainSchedule",
    "LinearResponse",
    "PISettings",
    "ReducedModel",
    "RobustPeak",
    "Robustness",
    "StateSpacePlant",
    "SweepResult",
    "TransferFunctionPlant",
    "TuningResult",
    "band_check",
    "band_edges",
    "block_units",
    "check_sweep_size",
    "check_tunable",
    "evaluate_fixed",
    "evaluate_tuning",
    "frequency_grid",
    "from_block",
    "full_order_closed_loop",
    "gain_schedule",
    "half_rule",
    "input_sensitivity",
    "linear_closed_loop",
    "list_rules",
    "loop_function",
    "misfit_overshoot",
    "plant_cases",
    "robust_peak",
    "robustness",
    "simc",
    "step_duration",
    "to_block",
    "tune",
    "uncertainty_sweep",
]
