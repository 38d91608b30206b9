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
    from fuelid.online._central_link import CentralLink, origin_of
    from fuelid.online._context import RECENT_WINDOWS_SPAN, model_of, observation_of, stale_reason
    from fuelid.online._gains import Gains
    from fuelid.online._liveness import SERVICE_BEAT_S, SERVICE_STALE_S, link_json, plant_hash
    from fuelid.online._logs import (
        LOGGER_NAME,
        JsonLineFormatter,
        KeyValueFormatter,
        Quoted,
        log_event,
        log_record,
    )
    from fuelid.online._report import (
        decision_json,
        health_line,
        held_line,
        history_json,
        proposal_json,
        status_json,
        window_json,
    )
    from fuelid.online._requests import consume_requests, submit_request
    from fuelid.online._service import OnlineService
    from fuelid.online._settings import Online, ServiceSite, load_service_site
    from fuelid.online._tracking import (
        GainObservation,
        KTracker,
        PlantGain,
        TrackingError,
        plant_gain_function,
    )
    from fuelid.online._window import WindowAnalyser, WindowResult, check_site_plant, window_priors
    from fuelid.online._writeback import GOOD_TUNED_FOR
    from fuelid.online.gates import WindowVerdict, postfit_gates, prefit_gates
    from fuelid.online.health import LoopHealth, loop_health

_HOMES = {
    "CentralLink": "fuelid.online._central_link",
    "check_site_plant": "fuelid.online._window",
    "consume_requests": "fuelid.online._requests",
    "decision_json": "fuelid.online._report",
    "GainObservation": "fuelid.online._tracking",
    "Gains": "fuelid.online._gains",
    "GOOD_TUNED_FOR": "fuelid.online._writeback",
    "health_line": "fuelid.online._report",
    "held_line": "fuelid.online._report",
    "history_json": "fuelid.online._report",
    "JsonLineFormatter": "fuelid.online._logs",
    "KeyValueFormatter": "fuelid.online._logs",
    "KTracker": "fuelid.online._tracking",
    "link_json": "fuelid.online._liveness",
    "load_service_site": "fuelid.online._settings",
    "log_event": "fuelid.online._logs",
    "log_record": "fuelid.online._logs",
    "LOGGER_NAME": "fuelid.online._logs",
    "loop_health": "fuelid.online.health",
    "LoopHealth": "fuelid.online.health",
    "model_of": "fuelid.online._context",
    "observation_of": "fuelid.online._context",
    "Online": "fuelid.online._settings",
    "OnlineService": "fuelid.online._service",
    "origin_of": "fuelid.online._central_link",
    "plant_gain_function": "fuelid.online._tracking",
    "plant_hash": "fuelid.online._liveness",
    "PlantGain": "fuelid.online._tracking",
    "postfit_gates": "fuelid.online.gates",
    "prefit_gates": "fuelid.online.gates",
    "proposal_json": "fuelid.online._report",
    "Quoted": "fuelid.online._logs",
    "RECENT_WINDOWS_SPAN": "fuelid.online._context",
    "SERVICE_BEAT_S": "fuelid.online._liveness",
    "SERVICE_STALE_S": "fuelid.online._liveness",
    "ServiceSite": "fuelid.online._settings",
    "stale_reason": "fuelid.online._context",
    "status_json": "fuelid.online._report",
    "submit_request": "fuelid.online._requests",
    "TrackingError": "fuelid.online._tracking",
    "window_json": "fuelid.online._report",
    "window_priors": "fuelid.online._window",
    "WindowAnalyser": "fuelid.online._window",
    "WindowResult": "fuelid.online._window",
    "WindowVerdict": "fuelid.online.gates",
}


def __getattr__(name: str) -> Any:
    # imported on use: the CLI reads fuelid.online._logs without loading numpy and scipy
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "GOOD_TUNED_FOR",
    "LOGGER_NAME",
    "RECENT_WINDOWS_SPAN",
    "SERVICE_BEAT_S",
    "SERVICE_STALE_S",
    "CentralLink",
    "GainObservation",
    "Gains",
    "JsonLineFormatter",
    "KTracker",
    "KeyValueFormatter",
    "LoopHealth",
    "Online",
    "OnlineService",
    "PlantGain",
    "Quoted",
    "ServiceSite",
    "TrackingError",
    "WindowAnalyser",
    "WindowResult",
    "WindowVerdict",
    "check_site_plant",
    "consume_requests",
    "decision_json",
    "health_line",
    "held_line",
    "history_json",
    "link_json",
    "load_service_site",
    "log_event",
    "log_record",
    "loop_health",
    "model_of",
    "observation_of",
    "origin_of",
    "plant_gain_function",
    "plant_hash",
    "postfit_gates",
    "prefit_gates",
    "proposal_json",
    "stale_reason",
    "status_json",
    "submit_request",
    "window_json",
    "window_priors",
]
