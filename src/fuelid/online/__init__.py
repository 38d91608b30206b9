"""The online service beside the PLC (issue 15): loop health, re-identification, retuning.

- :mod:`~fuelid.online.health`: loop-health metrics of one window of PLC samples (time in
  AUTO and at the output limits, Hägglund's oscillation detector, setpoint-step responses, the
  Harris minimum-variance index, sensor noise, stuck readings and quantisation).
- :mod:`~fuelid.online.gates`: the verdict on one identification window, every gate with its
  reason (gaps and bad quality, output at a limit, excitation by mode, standard errors,
  validation fit, residual correlation by size; the plant-ratio event).
- :class:`KTracker`: the loop gain against fuel temperature from accepted windows (the ratio to
  the plant model's K, or K per command band), with prediction intervals.
- :class:`WindowAnalyser`: one window gated, fitted and assessed (:class:`WindowResult`).
- :class:`OnlineService`: the service itself (recorder, schedule, history, tracker, proposals,
  write-back), set up by the site file's ``[online]`` table (:class:`Online`, read with the rest
  of the site by :func:`load_service_site`); :class:`Gains` the PI gains it proposes and writes.

The public API
--------------
The names in ``__all__``. The service that runs them (``fuelid online``) is driven through the
command line; its modules' other names are not promised yet.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

if TYPE_CHECKING:
    from fuelid.online._central_link import CentralLink, origin_of
    from fuelid.online._context import (
        RECENT_WINDOWS_SPAN,
        model_of,
        observation_of,
        stale_reason,
        stale_while_stopped,
    )
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
        write_times_text,
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

# Each name is imported from its private module on first use (lazy_loader, SPEC 1), so
# that importing the package stays cheap.
__getattr__ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "_central_link": ["CentralLink", "origin_of"],
        "_context": [
            "RECENT_WINDOWS_SPAN",
            "model_of",
            "observation_of",
            "stale_reason",
            "stale_while_stopped",
        ],
        "_gains": ["Gains"],
        "_liveness": ["SERVICE_BEAT_S", "SERVICE_STALE_S", "link_json", "plant_hash"],
        "_logs": [
            "JsonLineFormatter",
            "KeyValueFormatter",
            "LOGGER_NAME",
            "Quoted",
            "log_event",
            "log_record",
        ],
        "_report": [
            "decision_json",
            "health_line",
            "held_line",
            "history_json",
            "proposal_json",
            "status_json",
            "window_json",
            "write_times_text",
        ],
        "_requests": ["consume_requests", "submit_request"],
        "_service": ["OnlineService"],
        "_settings": ["Online", "ServiceSite", "load_service_site"],
        "_tracking": [
            "GainObservation",
            "KTracker",
            "PlantGain",
            "TrackingError",
            "plant_gain_function",
        ],
        "_window": ["WindowAnalyser", "WindowResult", "check_site_plant", "window_priors"],
        "_writeback": ["GOOD_TUNED_FOR"],
        "gates": ["WindowVerdict", "postfit_gates", "prefit_gates"],
        "health": ["LoopHealth", "loop_health"],
    },
)[0]


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
    "stale_while_stopped",
    "status_json",
    "submit_request",
    "window_json",
    "window_priors",
    "write_times_text",
]
