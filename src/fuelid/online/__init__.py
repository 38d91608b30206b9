"""The online service beside the PLC (issue 15): loop health, re-identification, retuning.

- :mod:`~fuelid.online.health`: loop-health metrics of one window of PLC samples (time in
  AUTO and at the output limits, Hägglund's oscillation detector, setpoint-step responses, the
  Harris minimum-variance index, sensor noise, stuck readings and quantisation).
"""

from __future__ import annotations

from fuelid.online.health import LoopHealth, loop_health

__all__ = ["LoopHealth", "loop_health"]
