"""What ``fuelid online status`` and ``fuelid online history`` print: plain JSON from the store.

Pure functions of an open store and its :class:`~fuelid.store.OnlineHistory`: they read, never
write, and need no running service (the service commits every window, proposal and write before
it goes on, so a reader sees what it did).

:func:`status_json` answers "how is the loop now": the link, the last window and its gate
verdict, the current model, the K(T) trend, the proposals waiting for a person, the loop's
health, the write-back state. :func:`history_json` gives everything over time: every window (with
the model, standard errors and 95 % intervals shaped as ``fuelid identify --json``'s), every
proposal with its history, every event of the recording and every write of gains.

Units (:data:`ONLINE_UNITS`): times are UTC seconds since the Unix epoch [s]; the fuel
temperature in °C; the command u in V; the flow, setpoint and noise in L/min; K in (L/min)/V;
T, T2, T_f and the delay θ in s; the gains ``Kc`` and ``Ti`` in the controller's units (as the
site's ``[controller]`` table says its registers hold them; ``gains_units`` when known).
"""

from __future__ import annotations

import math
import time as _time
from typing import Any

from fuelid.io.jsonsafe import json_ready
from fuelid.online.context import TRACKER_OBSERVATIONS, observation_of
from fuelid.online.tracking import KTracker, TrackingError
from fuelid.store.online import OnlineHistory
from fuelid.store.sqlite import SQLiteStore

ONLINE_UNITS: dict[str, str] = {
    "time": "s (UTC since the epoch)",
    "start": "s (UTC since the epoch)",
    "end": "s (UTC since the epoch)",
    "newest_sample": "s (UTC since the epoch)",
    "age_s": "s",
    "fuel_temperature": "degC",
    "u_mean": "V",
    "K": "(L/min)/V",
    "T": "s",
    "T2": "s",
    "delay": "s",
    "T_f": "s",
    "plant_K": "(L/min)/V",
    "fit_percent": "%",
    "Kc": "controller units (see gains_units)",
    "Ti": "controller units (see gains_units)",
    "Ms": "-",
    "health": "units in the key names (_s, _Lpm, _percent); shares 0-1",
}
"""Units of the numbers in :func:`status_json` and :func:`history_json` (by key name)."""

LINK_FRESH_S = 30.0
"""The newest sample no older than this counts as a live link [s] (otherwise "unknown")."""
ACTIVE_STATUSES = ("pending", "approved")
"""Proposals that wait for a person or for the service's write."""
LINK_EVENTS = ("link_down", "link_up")


def _window_model(detail: dict[str, Any]) -> dict[str, Any]:
    """``model``, ``stderr``, ``ci95`` of a window's detail (None each when nothing was fitted)."""
    return {key: detail.get(key) for key in ("model", "stderr", "ci95")}


def window_json(row: dict[str, Any]) -> dict[str, Any]:
    """One stored window as the JSON prints it.

    Returns
    -------
    dict
        ``id``, ``start``, ``end``, ``time`` (when analysed) [s UTC], ``accepted``, ``reason``,
        ``mode``, ``fuel_temperature`` [°C], ``u_mean`` [V], ``method``, ``fit_percent`` [%],
        ``plant_K``, and ``model``, ``stderr``, ``ci95`` as ``identify --json`` (None when the
        window was not fitted), ``model_id``, ``method_reason`` (why that estimator) and
        ``step_ls`` (the article's step-ls model of the same samples, reported beside, never
        gated on: ``model``, ``stderr``, ``fit_percent``, or ``reason`` when it failed).
    """
    detail = row.get("detail") or {}
    out = {
        "id": row["id"],
        "start": row["t_from"],
        "end": row["t_to"],
        "time": row["time"],
        "accepted": bool(row["accepted"]),
        "reason": row["reason"],
        "mode": detail.get("mode"),
        "fuel_temperature": row.get("T_fuel"),
        "u_mean": row.get("u_mean"),
        "method": detail.get("method") or None,
        "fit_percent": detail.get("fit_percent"),
        "plant_K": detail.get("plant_K"),
        "model_id": row.get("model_id"),
        **_window_model(detail),
        "method_reason": detail.get("method_reason") or None,
        "step_ls": detail.get("step_ls"),
    }
    return out


def proposal_json(row: dict[str, Any]) -> dict[str, Any]:
    """One stored proposal as the JSON prints it.

    Returns
    -------
    dict
        ``id``, ``time`` [s UTC], ``status``, ``old`` and ``new`` ``{"Kc", "Ti"}`` (controller
        units), ``Ms`` (the largest over the robustness checks), ``Ms_checks`` (check → Ms),
        ``reason``, ``model_id`` and ``history`` (``time``, ``status``, ``who``, ``why``).
    """
    detail = row.get("detail") or {}
    ms = detail.get("Ms")
    checks: dict[str, Any] | None = None
    if isinstance(ms, dict):
        checks = ms
        values = [float(v) for v in ms.values() if isinstance(v, int | float)]
        ms = max(values) if values else None
    return {
        "id": row["id"],
        "time": row["time"],
        "status": row["status"],
        "old": _gains(row.get("old")),
        "new": _gains(row.get("new")),
        "Ms": ms,
        "Ms_checks": checks,
        "reason": detail.get("reason", ""),
        "model_id": row.get("model_id"),
        "history": list(row.get("history") or []),
    }


def _gains(value: Any) -> dict[str, Any] | None:
    if not isinstance(value, dict):
        return None
    return {"Kc": value.get("Kc"), "Ti": value.get("Ti")}


def write_json(row: dict[str, Any]) -> dict[str, Any]:
    """One write of gains as the JSON prints it (the gains in controller units)."""
    return {
        "id": row["id"],
        "time": row["time"],
        "kind": row["kind"],
        "proposal_id": row.get("proposal_id"),
        "Kc": row["kc"],
        "Ti": row["ti"],
        "apply_seq": row["apply_seq"],
        "status": row["status"],
        "who": row["who"],
        "why": row["why"],
        "finished": row.get("finished"),
        "detail": row.get("detail"),
    }


def link_json(store: SQLiteStore, now: float | None = None) -> dict[str, Any]:
    """The link as the store saw it last.

    ``state`` is "down" when the newest link event is ``link_down``; otherwise "up" when the
    newest sample is at most :data:`LINK_FRESH_S` old (an accelerated virtual PLC's samples may
    run ahead of the wall clock: a negative age counts as fresh), "unknown" when there is no
    sample or the newest is older (no recorder running).
    """
    now = _time.time() if now is None else float(now)
    newest = store.last_time()
    last_event = None
    for event in store.read_events():
        if event.kind in LINK_EVENTS:
            last_event = event
    age = None if newest is None else now - newest
    if last_event is not None and last_event.kind == "link_down":
        state = "down"
    elif age is not None and age <= LINK_FRESH_S:
        state = "up"
    else:
        state = "unknown"
    return {
        "state": state,
        "newest_sample": newest,
        "age_s": age,
        "last_event": None
        if last_event is None
        else {"time": last_event.time, "kind": last_event.kind, "detail": last_event.detail},
        "fresh_within_s": LINK_FRESH_S,
    }


def _current_model(row: dict[str, Any] | None) -> dict[str, Any] | None:
    if row is None:
        return None
    m = row.get("model") or {}
    return {
        "model_id": row["id"],
        "window_id": row.get("window_id"),
        "time": row.get("t_to"),
        "start": row.get("t_from"),
        "end": row.get("t_to"),
        "fuel_temperature": row.get("T_fuel"),
        "u_mean": m.get("u_mean"),
        "model": m.get("model"),
        "stderr": m.get("stderr"),
        "ci95": m.get("ci95"),
        "method": m.get("method"),
        "fit_percent": m.get("fit_percent"),
        "plant_K": m.get("plant_K"),
    }


def k_trend_json(history: OnlineHistory) -> dict[str, Any]:
    """The K(T) tracker over the accepted models, with K predicted at the newest temperature.

    Returns
    -------
    dict
        ``available`` (bool); with a fit the tracker's ``to_dict()`` (``mode`` "ratio" with a
        plant model, else "band"; the line(s) and their units) and ``at_newest``
        (``fuel_temperature`` [°C], ``u`` [V], ``K`` and ``se`` [(L/min)/V], ``K_plant``), and
        ``drift`` (K now / K of the model the current gains were tuned for, with its se) when
        that model is known; without one ``reason`` and ``n`` (observations).
    """
    rows = history.accepted_models(limit=TRACKER_OBSERVATIONS)
    observations = [obs for obs in (observation_of(row) for row in rows) if obs is not None]
    try:
        tracker = KTracker(max_observations=TRACKER_OBSERVATIONS).fit(observations)
    except TrackingError as error:
        return {"available": False, "reason": str(error), "n": len(observations)}
    newest = observations[-1]
    out: dict[str, Any] = {"available": True, **tracker.to_json()}
    try:
        K, se = tracker.predict(newest.T_fuel_C, newest.u, K_plant=newest.K_plant)
    except TrackingError as error:
        out["at_newest"] = {"reason": str(error)}
        return json_ready(out)  # type: ignore[no-any-return]
    out["at_newest"] = {
        "fuel_temperature": newest.T_fuel_C,
        "u": newest.u,
        "K": K,
        "se": se,
        "K_plant": newest.K_plant,
    }
    tuned = history.state("tuned_for")
    K_tuned = tuned.get("K") if isinstance(tuned, dict) else None
    if isinstance(K_tuned, int | float) and K_tuned > 0 and math.isfinite(K):
        out["drift"] = {"K_tuned": float(K_tuned), "ratio": K / K_tuned, "se": se / K_tuned}
    else:
        out["drift"] = None
    return json_ready(out)  # type: ignore[no-any-return]


def status_json(
    history: OnlineHistory,
    store: SQLiteStore,
    now: float | None = None,
    *,
    settings: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The service's state now, from its store (``fuelid online status --json``).

    Parameters
    ----------
    history : OnlineHistory
        The online history in ``store``'s file.
    store : SQLiteStore
        The store (samples and events).
    now : float, optional
        Reference time for the link's age [s UTC]; the wall clock by default.
    settings : dict, optional
        The site's ``[online]`` and ``[controller]`` as known to the caller (``write_back``,
        ``gains_units``); None with a bare store.

    Returns
    -------
    dict
        ``site``, ``link``, ``last_window``, ``current_model``, ``k_trend``,
        ``pending_proposals``, ``loop_health``, ``counts``, ``write_back``, ``last_write``,
        ``units`` (see the module docstring).
    """
    last = history.last_window()
    last_window = None
    health = None
    if last is not None:
        detail = last.get("detail") or {}
        last_window = {**window_json(last), "gates": detail.get("gates")}
        health = detail.get("health")
    models = history.accepted_models(limit=1)
    writes = history.writes(limit=1)
    settings = dict(settings or {})
    out = {
        "site": _site(store),
        "link": link_json(store, now),
        "last_window": last_window,
        "current_model": _current_model(models[0] if models else None),
        "k_trend": k_trend_json(history),
        "pending_proposals": [proposal_json(p) for p in history.proposals(list(ACTIVE_STATUSES))],
        "loop_health": health,
        "counts": history.counts(),
        "write_back": {
            "setting": settings.get("write_back"),
            "current_gains": history.state("current_gains"),
            "last_known_good": history.state("last_known_good"),
            "write_held": history.state("write_held"),
            "revert_requested": history.state("revert_requested"),
        },
        "last_write": write_json(writes[0]) if writes else None,
        "gains_units": settings.get("gains_units"),
        "units": ONLINE_UNITS,
    }
    return json_ready(out)  # type: ignore[no-any-return]


def history_json(
    history: OnlineHistory,
    store: SQLiteStore,
    *,
    settings: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Everything the service did, oldest first (``fuelid online history --json``).

    Returns
    -------
    dict
        ``site``, ``windows`` (:func:`window_json`), ``proposals`` (:func:`proposal_json`),
        ``events`` (``time``, ``kind``, ``detail`` of the recording's and the service's events),
        ``writes`` (:func:`write_json`), ``k_trend`` (:func:`k_trend_json`), ``counts``,
        ``gains_units``, ``units``.
    """
    settings = dict(settings or {})
    out = {
        "site": _site(store),
        "windows": [window_json(row) for row in history.windows()],
        "proposals": [proposal_json(row) for row in history.proposals()],
        "events": [
            {"time": e.time, "kind": e.kind, "detail": e.detail} for e in store.read_events()
        ],
        "writes": [write_json(row) for row in history.writes()],
        "k_trend": k_trend_json(history),
        "counts": history.counts(),
        "gains_units": settings.get("gains_units"),
        "units": ONLINE_UNITS,
    }
    return json_ready(out)  # type: ignore[no-any-return]


def _site(store: SQLiteStore) -> dict[str, Any]:
    return {"name": store.site_name, "tag_map_hash": store.tag_map_hash, "store": store.path}


__all__ = [
    "LINK_FRESH_S",
    "ONLINE_UNITS",
    "history_json",
    "k_trend_json",
    "link_json",
    "proposal_json",
    "status_json",
    "window_json",
    "write_json",
]
