"""The online service beside the PLC (issue 15): loop health, re-identification, retuning.

- :mod:`~fuelid.online.health`: loop-health metrics of one window of PLC samples (time in
  AUTO and at the output limits, Hägglund's oscillation detector, setpoint-step responses, the
  Harris minimum-variance index, sensor noise, stuck readings and quantisation).
- :mod:`~fuelid.online.gates`: the verdict on one identification window, every gate with its
  reason (gaps and bad quality, output at a limit, excitation by mode, standard errors,
  validation fit, residual correlation by size; the plant-ratio event).
- :mod:`~fuelid.online._tracking`: the loop gain against fuel temperature from accepted windows
  (the ratio to the plant model's K, or K per command band), with prediction intervals.

The public API
--------------
The names in ``__all__``. The service that runs them (``fuelid online``) is driven through the
command line; its modules' other names are not promised yet.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from fuelid.online._tracking import GainObservation, KTracker, plant_gain_function
    from fuelid.online.gates import WindowVerdict, postfit_gates, prefit_gates
    from fuelid.online.health import LoopHealth, loop_health

_HOMES = {
    "GainObservation": "fuelid.online._tracking",
    "KTracker": "fuelid.online._tracking",
    "LoopHealth": "fuelid.online.health",
    "WindowVerdict": "fuelid.online.gates",
    "loop_health": "fuelid.online.health",
    "plant_gain_function": "fuelid.online._tracking",
    "postfit_gates": "fuelid.online.gates",
    "prefit_gates": "fuelid.online.gates",
}


def __getattr__(name: str) -> Any:
    # imported on use: the CLI reads fuelid.online._logs without loading numpy and scipy
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "GainObservation",
    "KTracker",
    "LoopHealth",
    "WindowVerdict",
    "loop_health",
    "plant_gain_function",
    "postfit_gates",
    "prefit_gates",
]
