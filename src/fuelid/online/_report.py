"""What ``fuelid online status`` and ``fuelid online history`` print: plain JSON from the store.

Pure functions of a loop's history and store (:class:`~fuelid.store.LoopHistory` and
:class:`~fuelid.store.LoopStore`: a store file's :class:`~fuelid.store.OnlineHistory` and
:class:`~fuelid.store.SQLiteStore`, or a loop of the central database): they read, never
write, and need no running service (the service commits every window, proposal and write before
it goes on, so a reader sees what it did).

:func:`status_json` answers "how is the loop now": the link, the last window and its gate
verdict, the current model, the K(T) trend, the proposals waiting for a person, the loop's
health, the write-back state. :func:`history_json` gives everything over time: every window (with
the model, standard errors and 95 % intervals shaped as ``fuelid identify --json``'s), every
proposal with its history, every event of the recording and every write of gains.

Units (:data:`ONLINE_UNITS`): times are UTC seconds since the Unix epoch [s] on two clocks:
``time`` (and ``start``, ``end``, ``finished``, ``newest_sample``) is plant time, the samples'
time base (an accelerated virtual PLC runs it 20–50 times faster than the wall clock);
``wall_time`` (and ``finished_wall``, ``newest_sample_wall``, the service record's times) the
wall clock when written. The link and the service are judged on the wall clock alone
(:func:`fuelid.online._liveness.loop_state`). The fuel
temperature in °C; the command u in V; the flow, setpoint and noise in L/min; K in (L/min)/V;
T, T2, T_f and the delay θ in s; the gains ``Kc`` and ``Ti`` in the controller's units (as the
site's ``[controller]`` table says its registers hold them; ``gain_units`` when known, see
:func:`fuelid.tuning._block.block_units`).
"""

from __future__ import annotations

import math
from typing import Any

from fuelid.errors import FuelidError
from fuelid.io import format_time
from fuelid.io.jsonsafe import json_ready
from fuelid.online._context import TRACKER_OBSERVATIONS, observation_of, stale_while_stopped
from fuelid.online._liveness import LINK_FRESH_S, link_json
from fuelid.online._plc_gains import plc_gains_json
from fuelid.online._requests import stale_of
from fuelid.online._tracking import KTracker, TrackingError
from fuelid.online.excitation._status import excitation_json
from fuelid.plc import PLC_GAINS_KEY
from fuelid.store import SERVICE_KEY, LoopHistory, LoopStore
from fuelid.tuning import BlockForm, block_units, to_block

ONLINE_UNITS: dict[str, str] = {
    "time": "s (plant time: the samples' time base, UTC since the epoch)",
    "wall_time": "s (wall clock when written, UTC since the epoch)",
    "start": "s (plant time, UTC since the epoch)",
    "end": "s (plant time, UTC since the epoch)",
    "finished": "s (plant time, UTC since the epoch)",
    "finished_wall": "s (wall clock, UTC since the epoch)",
    "done_wall": "s (wall clock, UTC since the epoch)",
    "newest_sample": "s (plant time, UTC since the epoch)",
    "newest_sample_wall": "s (wall clock when written, UTC since the epoch)",
    "since": "s (wall clock, UTC since the epoch)",
    "started": "s (wall clock, UTC since the epoch)",
    "started_plant": "s (plant time, UTC since the epoch)",
    "beat": "s (wall clock, UTC since the epoch)",
    "stopped": "s (wall clock, UTC since the epoch)",
    "age_s": "s (wall clock)",
    "beat_age_s": "s (wall clock)",
    "fuel_temperature": "degC",
    "u_mean": "V",
    "K": "(L/min)/V",
    "T": "s",
    "T2": "s",
    "delay": "s",
    "T_f": "s",
    "plant_K": "(L/min)/V",
    "fit_percent": "%",
    "Kc": "the PLC block's units (see gain_units)",
    "Ti": "the PLC block's units (see gain_units)",
    "decision": "Kc V per L/min, Ti s (the ideal form, whatever the block's); control_period_s s",
    "ideal": "Kc V per L/min, Ti s (the ideal form, whatever the block's)",
    "Ms": "-",
    "health": "units in the key names (_s, _Lpm, _percent); shares 0-1",
}
"""Units of the numbers in :func:`status_json` and :func:`history_json` (by key name)."""

ACTIVE_STATUSES = ("pending", "approved")
"""Proposals that wait for a person or for the service's write."""


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
        gated on: ``model``, ``stderr``, ``fit_percent``, or ``reason`` when it failed) and
        ``excitation`` (a test signal's cost measured on the window's samples:
        :func:`~fuelid.online.excitation._cost.measured_cost`; None when none ran in it).
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
        "excitation": detail.get("excitation"),
        "wall_time": row.get("wall_time"),
    }
    return out


def proposal_json(row: dict[str, Any], controller: Any = None) -> dict[str, Any]:
    """One stored proposal as the JSON prints it.

    Parameters
    ----------
    row : dict
        The proposal as :meth:`OnlineHistory.proposal` gives it.
    controller : Controller or dict, optional
        The site's ``[controller]`` (or its form, gain_units, integral_unit, u_span_V,
        y_span_Lpm as a dict): converts the target to the block's units. None: unknown.

    Returns
    -------
    dict
        ``id``, ``time`` [plant s], ``wall_time`` [wall s], ``status``, ``old`` and ``new``
        ``{"Kc", "Ti"}`` (controller units), ``target`` (the gains the rule moves toward, in
        the same units; None when unknown, with ``target_note`` saying why), ``gain_units``
        (``{"Kc", "Ti"}`` or None), ``Ms`` (the largest over the robustness checks),
        ``Ms_checks`` (check → Ms), ``reason``, ``model_id``, ``history`` (``time`` [plant
        s], ``wall_time`` [wall s], ``status``, ``who``, ``why``) and ``decision`` (what the
        gains rest on, in the ideal form: :func:`decision_json`).
    """
    detail = row.get("detail") or {}
    ms = detail.get("Ms")
    checks: dict[str, Any] | None = None
    if isinstance(ms, dict):
        checks = ms
        values = [float(v) for v in ms.values() if isinstance(v, int | float)]
        ms = max(values) if values else None
    c = _controller(controller)
    target, note = _target(detail.get("target"), c)
    return {
        "id": row["id"],
        "time": row["time"],
        "wall_time": row.get("wall_time"),
        "status": row["status"],
        "old": _gains(row.get("old")),
        "new": _gains(row.get("new")),
        "target": target,
        "target_note": note,
        "gain_units": None if c is None else block_units(BlockForm.of(c)),
        "Ms": ms,
        "Ms_checks": checks,
        "reason": detail.get("reason", ""),
        "model_id": row.get("model_id"),
        "decision": decision_json(detail),
        "history": list(row.get("history") or []),
    }


def decision_json(detail: dict[str, Any]) -> dict[str, Any] | None:
    """What a stored proposal rests on, from its detail; None when nothing was recorded.

    The gains here are in the ideal form and engineering units, Kc [V per L/min] and Ti [s],
    whatever the block's form (the proposal's ``old``, ``new`` and ``target`` are in the
    block's): what a report's gains compare with.

    Returns
    -------
    dict or None
        ``rule``, ``control_period_s`` [s], ``move_fraction``, ``hysteresis``, ``ms_target``,
        ``clipped``, ``detune_factor`` (the Kc factor the robustness check applied, 1 when
        none), ``bounds`` (``Kc``, ``Ti``: [low, high]), ``model_ids`` (the agreeing windows'
        models, newest first), ``window_gains`` (``model_id``, ``Kc``, ``Ti``: the rule on each
        of those models) and ``ideal``: ``old`` (the gains in the PLC then), ``target`` (the
        rule on the windows' weighted mean model, clipped to the bounds), ``target_unclipped``,
        ``undetuned`` (after the partial move, before the robustness check) and ``new``, each
        ``{"Kc", "Ti"}`` or None.

    Examples
    --------
    >>> decision_json({}) is None
    True
    >>> decision_json({"ideal": {"new": {"Kc": 0.05, "Ti": 2.0}}})["ideal"]["new"]
    {'Kc': 0.05, 'Ti': 2.0}
    """
    inner = detail.get("detail")
    inner = inner if isinstance(inner, dict) else {}
    ideal = detail.get("ideal")
    ideal = ideal if isinstance(ideal, dict) else {}
    if not inner and not ideal:
        return None
    return {
        "rule": inner.get("rule"),
        "control_period_s": inner.get("control_period_s"),
        "move_fraction": inner.get("move_fraction"),
        "hysteresis": inner.get("hysteresis"),
        "ms_target": inner.get("ms_target"),
        "clipped": detail.get("clipped"),
        "detune_factor": inner.get("detune_factor"),
        "bounds": inner.get("bounds"),
        "model_ids": list(detail.get("model_ids") or []),
        "window_gains": [
            {"model_id": w.get("model_id"), "Kc": w.get("Kc"), "Ti": w.get("Ti")}
            for w in inner.get("window_gains") or []
            if isinstance(w, dict)
        ],
        "ideal": {
            "old": _gains(ideal.get("old") or detail.get("old")),
            "target": _gains(detail.get("target")),
            "target_unclipped": _gains(inner.get("target_unclipped")),
            "undetuned": _gains(inner.get("undetuned")),
            "new": _gains(ideal.get("new") or detail.get("new")),
        },
    }


def _controller(value: Any) -> Any:
    """A Controller from a Controller, its dict, or None."""
    if value is None:
        return None
    if isinstance(value, dict):
        from fuelid.plc.site import Controller

        try:
            return Controller(**{k: v for k, v in value.items() if v is not None})
        except ValueError:
            return None
    return value


def _target(ideal: Any, controller: Any) -> tuple[dict[str, float] | None, str | None]:
    """The target in the block's units, or None and why."""
    if not isinstance(ideal, dict) or ideal.get("Kc") is None or ideal.get("Ti") is None:
        return None, "no target recorded"
    if controller is None:
        return None, "the controller is unknown (give --config): the target is in ideal form"
    try:
        kc, ti = to_block(float(ideal["Kc"]), float(ideal["Ti"]), BlockForm.of(controller))
    except (ValueError, FuelidError) as error:
        return None, str(error)
    return {"Kc": kc, "Ti": ti}, None


def _held(value: Any) -> dict[str, Any] | None:
    """The held proposal's record (``id``, ``status``, ``Kc``, ``Ti``); None when none is held.

    A store from before the record had fields kept the id alone: that one is said as it is.

    >>> _held(3), _held(None)
    ({'id': 3, 'status': None, 'Kc': None, 'Ti': None}, None)
    """
    if value is None:
        return None
    if not isinstance(value, dict):
        return {"id": value, "status": None, "Kc": None, "Ti": None}
    return {key: value.get(key) for key in ("id", "status", "Kc", "Ti")}


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
        "wall_time": row.get("wall_time"),
        "finished_wall": row.get("finished_wall"),
        "detail": row.get("detail"),
    }


_OUTCOME_WORDS = {"verified": "verified", "failed": "failed", "not_applied": "found not applied"}
"""A finished write's status as said before its time (:func:`write_times_text`)."""


def write_times_text(write: dict[str, Any], tz: str | None = "UTC") -> str:
    """A write's two instants, each labelled: issued (its intent) and its outcome.

    ``time`` is when the service issued the write (its intent, committed just before the PLC is
    written), ``finished`` when the PLC's echo verified it (or it failed, or was found not
    applied); both plant time in the zone ``tz``. The outcome's date is left out when it is the
    issue's. ``fuelid online status`` and ``history`` and the dashboard say a write's times with
    this one function, so the command and the page name the same instants.

    Examples
    --------
    >>> write_times_text({"status": "verified", "time": 1_795_767_203.4,
    ...                   "finished": 1_795_767_207.4}, "Europe/Zurich")
    'issued at 2026-11-27 09:13:23 CET, verified at 09:13:27 CET'
    >>> write_times_text({"status": "intent", "time": 1_795_767_203.4, "finished": None})
    'issued at 2026-11-27 08:13:23 UTC, no echo yet'
    """
    issued = format_time(write.get("time"), tz)
    text = f"issued at {issued}"
    outcome = _OUTCOME_WORDS.get(str(write.get("status")))
    if outcome is None or write.get("finished") is None:
        return text + ", no echo yet"
    finished = format_time(write.get("finished"), tz)
    day, _, clock = finished.partition(" ")
    if issued.startswith(day + " "):
        finished = clock
    return f"{text}, {outcome} at {finished}"


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


def k_trend_json(history: LoopHistory) -> dict[str, Any]:
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
    history: LoopHistory,
    store: LoopStore,
    now: float | None = None,
    *,
    settings: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The service's state now, from its store (``fuelid online status --json``).

    Parameters
    ----------
    history : LoopHistory
        The loop's online history (a store file's :class:`~fuelid.store.OnlineHistory`).
    store : LoopStore
        Its store (identity, newest sample, events).
    now : float, optional
        Reference time for the link's age [s UTC]; the wall clock by default.
    settings : dict, optional
        The site's ``[online]`` and ``[controller]`` as known to the caller (``write_back``,
        ``gains_units``, ``controller``, ``timezone``); None with a bare store: then the
        running (or last) service's record gives them.

    Returns
    -------
    dict
        ``site``, ``link`` (:func:`~fuelid.online._liveness.link_json`), ``service`` (the
        service record with its ``state`` and ``beat_age_s``; None when no service ever ran on
        this store),
        ``timezone``, ``last_window``, ``current_model``, ``k_trend``, ``pending_proposals``
        (each with ``target``, ``gain_units`` and ``stale``: why the service would not write it,
        its promise of new windows said "when the service runs again" while none runs),
        ``requests`` (the waiting ones),
        ``loop_health``, ``counts``, ``write_back`` (``setting`` and ``setting_from``: "site
        file", "service" or None; ``current_gains`` and ``last_known_good`` in the ideal form
        [V per L/min, s], ``current_gains_block`` and ``last_known_good_block`` in the block's
        units), ``last_write``, ``plc_gains`` (the PLC's kc and ti tags as the recorder last
        read them: :func:`~fuelid.online._plc_gains.plc_gains_json`; None when the site reads
        no such tags or nothing was read yet), ``gains_units``, ``units`` (see the module
        docstring), ``central`` (the sync to the central store: :func:`central_json`),
        ``excitation`` (the test signal: :func:`~fuelid.online.excitation._status.
        excitation_json`; None when no exciter ever ran on this store).
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
    record, running = _service(history)
    merged = _merged_settings(settings, running)
    tz = merged.get("timezone") or "UTC"
    link = link_json(store, now, record, tz)
    service = (
        None
        if record is None
        else {**record, "state": link["service"], "beat_age_s": link["beat_age_s"]}
    )
    controller = merged.get("controller")
    out = {
        "site": _site(store),
        "link": link,
        "service": service,
        "timezone": tz,
        "last_window": last_window,
        "current_model": _current_model(models[0] if models else None),
        "k_trend": k_trend_json(history),
        "pending_proposals": [
            {**proposal_json(p, controller), "stale": _stale(history, p["id"], link)}
            for p in history.proposals(list(ACTIVE_STATUSES))
        ],
        # the service's newest proposal matched turned-down gains and was not filed
        "held_proposal": _held(history.state("held_proposal")),
        "requests": history.requests(status="waiting"),
        "loop_health": health,
        "counts": history.counts(),
        "write_back": _write_back_json(history, settings, merged),
        "last_write": write_json(writes[0]) if writes else None,
        "plc_gains": plc_gains_json(history.state(PLC_GAINS_KEY), _controller(controller)),
        "excitation": excitation_json(history, service_running=link["service"] == "running"),
        "central": central_json(store, now),
        "gains_units": merged.get("gains_units"),
        "units": ONLINE_UNITS,
    }
    return json_ready(out)  # type: ignore[no-any-return]


def _stale(history: LoopHistory, proposal_id: Any, link: dict[str, Any]) -> str | None:
    """Why an open proposal is too old to write, said as true now.

    Its promise of new windows holds only while a service runs
    (:func:`~fuelid.online._context.stale_while_stopped`).
    """
    reason = stale_of(history, proposal_id)
    return reason if link.get("service") == "running" else stale_while_stopped(reason)


def _write_back_json(
    history: LoopHistory, given: dict[str, Any], merged: dict[str, Any]
) -> dict[str, Any]:
    """The status' ``write_back``: the setting and where it comes from, the gains it keeps."""
    setting_from = None
    if given.get("write_back") is not None:
        setting_from = "site file"
    elif merged.get("write_back") is not None:
        setting_from = "service"
    controller = _controller(merged.get("controller"))
    current, good = history.state("current_gains"), history.state("last_known_good")
    return {
        "setting": merged.get("write_back"),
        "setting_from": setting_from,
        "current_gains": current,
        # the same gains as the PLC's block holds them (None when the controller is unknown)
        "current_gains_block": _target(current, controller)[0],
        "last_known_good": good,
        "last_known_good_block": _target(good, controller)[0],
        "write_held": history.state("write_held"),
        "revert_requested": history.state("revert_requested"),
    }


def central_json(store: LoopStore, now: float | None = None) -> dict[str, Any] | None:
    """The sync to the central store (:func:`fuelid.central._outbox.sync_status`).

    None when the store cannot say (an older schema, a locked file, no file: a central reader's
    view of a loop, which says it itself).
    """
    import sqlite3

    from fuelid.central import open_store_file, sync_status

    if store.path is None:
        return None
    try:
        con = open_store_file(store.path)
    except FuelidError:
        return None
    try:
        return sync_status(con, now)
    except sqlite3.Error:
        return None
    finally:
        con.close()


def _service(history: LoopHistory) -> tuple[dict[str, Any] | None, dict[str, Any]]:
    """The service record (None when none) and its settings (empty when none)."""
    record = history.state(SERVICE_KEY)
    if not isinstance(record, dict):
        return None, {}
    settings = record.get("settings")
    if not isinstance(settings, dict):  # a record written before 0.3: write_back only
        settings = {"write_back": record.get("write_back")}
    return record, settings


def _merged_settings(given: dict[str, Any], running: dict[str, Any]) -> dict[str, Any]:
    """The caller's settings (the site file), completed by the service record's."""
    out = {
        "write_back": running.get("write_back"),
        "timezone": running.get("timezone"),
        "controller": running.get("controller"),
        "gains_units": running.get("gain_units"),
    }
    out.update({k: v for k, v in given.items() if v is not None})
    return out


def history_json(
    history: LoopHistory,
    store: LoopStore,
    *,
    settings: dict[str, Any] | None = None,
    windows: int | None = None,
) -> dict[str, Any]:
    """Everything the service did, oldest first (``fuelid online history --json``).

    ``windows``: only the newest this many windows (the dashboard's charts page a year of them);
    every window by default. ``counts`` always counts them all.

    Returns
    -------
    dict
        ``site``, ``windows`` (:func:`window_json`), ``proposals`` (:func:`proposal_json`),
        ``events`` (``time`` [plant s], ``kind``, ``detail``, ``wall_time`` [wall s] of the
        recording's and the service's events),
        ``writes`` (:func:`write_json`), ``requests`` (every one), ``k_trend``
        (:func:`k_trend_json`), ``counts``, ``timezone``, ``gains_units`` and ``gain_units``
        (the same: the block's units of Kc and Ti), ``units``.
    """
    _, running = _service(history)
    merged = _merged_settings(dict(settings or {}), running)
    controller = merged.get("controller")
    out = {
        "site": _site(store),
        "timezone": merged.get("timezone") or "UTC",
        "windows": [window_json(row) for row in history.windows(limit=windows)],
        "proposals": [proposal_json(row, controller) for row in history.proposals()],
        "events": store.read_event_rows(),
        "requests": history.requests(),
        "writes": [write_json(row) for row in history.writes()],
        "k_trend": k_trend_json(history),
        "counts": history.counts(),
        "gains_units": merged.get("gains_units"),
        "gain_units": merged.get("gains_units"),
        "units": ONLINE_UNITS,
    }
    return json_ready(out)  # type: ignore[no-any-return]


def held_line(held: dict[str, Any] | None) -> str | None:
    """Why the service files no new proposal, in one line (``online status``, the dashboard).

    >>> held_line({"id": 1, "status": "reverted", "Kc": 0.03, "Ti": 3.0})[:68]
    'none filed: the newest evidence points at the gains of #1 (reverted)'
    >>> held_line(None) is None
    True
    """
    if not held:
        return None
    status = f" ({held['status']})" if held.get("status") else ""
    return (
        f"none filed: the newest evidence points at the gains of #{held['id']}{status}, which "
        "are not proposed again until new evidence moves them by more than the hysteresis"
    )


def health_line(health: dict[str, Any] | None) -> str:
    """The loop's health over the last window in one line (``online status`` and the dashboard).

    Examples
    --------
    >>> health_line(None)
    'not measured yet'
    >>> health_line({"time_in_auto": 0.5, "oscillation": {"oscillating": True}})[:31]
    'in AUTO 50 % of the last window'
    """
    if not health:
        return "not measured yet"

    def share(x: Any) -> str:
        return "-" if not isinstance(x, int | float) else f"{100.0 * x:.0f} %"

    def number(x: Any, spec: str) -> str:
        return "-" if not isinstance(x, int | float) else format(x, spec)

    osc = (health.get("oscillation") or {}).get("oscillating")
    harris = (health.get("harris") or {}).get("index")
    sensor = health.get("sensor") or {}
    noise = sensor.get("noise_Lpm")
    return (
        f"in AUTO {share(health.get('time_in_auto'))} of the last window, at the drive's "
        f"limits {share(health.get('time_at_limits'))}, oscillating {'yes' if osc else 'no'}, "
        f"IAE per unit step {number(health.get('iae_per_unit_step_s'), '.3g')} s, Harris index "
        f"{number(harris, '.2f')}, flowmeter {'stuck' if sensor.get('stuck') else 'ok'}"
        + ("" if noise is None else f" (noise {number(noise, '.2g')} L/min)")
    )


def _site(store: LoopStore) -> dict[str, Any]:
    return {"name": store.site_name, "tag_map_hash": store.tag_map_hash, "store": store.path}


__all__ = [
    "LINK_FRESH_S",
    "ONLINE_UNITS",
    "central_json",
    "health_line",
    "history_json",
    "k_trend_json",
    "proposal_json",
    "status_json",
    "window_json",
    "write_json",
    "write_times_text",
]
