"""PI tuning: rules, robustness margins, closed-loop simulation, fuel-temperature schedules.

- :mod:`~fuelid.tuning.rules`: the tuning rules in a registry (SIMC, improved SIMC, lambda,
  AMIGO) and the PLC forms of the gains;
- :mod:`~fuelid.tuning.frequency`: loop frequency responses with the dead time exact and the
  sampled controller included; gain and phase margins, Ms;
- :mod:`~fuelid.tuning.closedloop`: the discrete PI with limits and anti-windup, closed-loop
  simulation on the linear model and on the nonlinear plant, step metrics;
- :mod:`~fuelid.tuning.schedule`: plant models over fuel temperature and flow, one fixed PI over
  all of them, a gain schedule, the uncertainty sweep.
"""

from __future__ import annotations

from fuelid.tuning.frequency import Robustness, robustness
from fuelid.tuning.rules import TUNING_RULES, PISettings, list_rules, tune

__all__ = ["TUNING_RULES", "PISettings", "Robustness", "list_rules", "robustness", "tune"]
