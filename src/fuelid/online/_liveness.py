"""Is the loop's service running, is its link up: :func:`loop_state` (:func:`link_json` of a store).

The running service keeps a record under the ``online_state`` key ``"service"`` (see
:func:`service_record`): who it is (pid, host, version), when it started, its settings, and its
``beat``, refreshed every :data:`SERVICE_BEAT_S` of wall time. (Not to be confused with the PLC's
heartbeat register, the write-back's watchdog.) A reader judges the loop from that record and
from the wall clock alone: the samples' own ``time`` is plant time, which an accelerated virtual
PLC runs far ahead of the wall clock, so nothing here is inferred from it.

- ``stopped``: no record, its ``stopped`` set (a clean stop), or a beat older than
  :data:`SERVICE_STALE_S` (a killed service, kill -9 included: nothing else it left is trusted);
- ``link_down``: the service is live, and the newest link event is ``link_down`` or the newest
  sample was written more than :data:`LINK_FRESH_S` of wall time ago (or when unknown: a store
  from before schema 3 has no ``wall_time``);
- ``up``: live, and the newest sample was written within :data:`LINK_FRESH_S`;
- ``no_data``: live, no sample yet.

All times here are on the wall clock [s UTC since the epoch].
"""

from __future__ import annotations

import hashlib
import math
import os
import socket
import time as _time
from collections.abc import Mapping
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fuelid.io import format_age, format_time

if TYPE_CHECKING:
    from fuelid.store import LoopStore

__all__ = [
    "LINK_FRESH_S",
    "SERVICE_BEAT_S",
    "SERVICE_STALE_S",
    "link_json",
    "loop_state",
    "plant_hash",
    "service_record",
]

SERVICE_BEAT_S = 2.0
"""Wall time between two beats of the running service [s]."""
SERVICE_STALE_S = 10.0
"""A beat older than this (five beats) means the service is not running [s of wall time]."""
LINK_FRESH_S = 30.0
"""A sample written (wall clock) no longer ago than this means a live link [s]."""
LINK_EVENTS = ("link_down", "link_up")
"""The events that say the link's state."""


def plant_hash(path: str | Path | None) -> str | None:
    """SHA-256 hex of the plant file's bytes, or of the built-in reference plant's.

    None when the plant file cannot be read (the record is written anyway).
    """
    if path is not None:
        try:
            return hashlib.sha256(Path(path).read_bytes()).hexdigest()
        except OSError:
            return None
    from fuelid.plant import reference_plant_text

    return hashlib.sha256(reference_plant_text().encode("utf-8")).hexdigest()


def service_record(
    site: Any, plant_file: str | Path | None, now: float | None = None
) -> dict[str, Any]:
    """The record a starting service writes under :data:`SERVICE_KEY`.

    Keys: ``pid``, ``host``, ``version`` (fuelid's), ``started`` and ``beat`` [wall s UTC],
    ``started_plant`` [plant s UTC: the plant time of this run's first sample, newer than any the
    store held at the start and than its newest window's analysis time; None until the service
    records it, at its first beat after that sample is committed], ``beat_every_s`` [s],
    ``stopped`` (None while running) and ``settings``: every ``[online]`` setting
    (``write_back``, ``rule``, ``ms_target``, ``move_fraction``, ``hysteresis``,
    ``gain_bounds``, the gates' thresholds, …), ``timezone``, ``loop_id``, ``plant_hash``,
    ``plant_file`` (absolute path; None for the reference plant), ``controller`` (``form``,
    ``gain_units``, ``integral_unit``, ``u_span_V``, ``y_span_Lpm``, ``kc``, ``ti``; None
    without a ``[controller]``) and ``gain_units`` (``{"Kc", "Ti"}``, see
    :func:`fuelid.tuning._block.block_units`) and ``sampling`` (``period_s``,
    ``control_period_s`` [s]) and ``excitation`` (the ``[excitation]`` table and ``possible``:
    whether the site maps ``[write.excitation]`` and gives an amplitude).
    """
    import fuelid
    from fuelid.store import default_loop_id
    from fuelid.tuning import BlockForm, block_units

    wall = _time.time() if now is None else float(now)
    c = site.controller
    controller = (
        None
        if c is None
        else {
            "form": c.form,
            "gain_units": c.gain_units,
            "integral_unit": c.integral_unit,
            "u_span_V": c.u_span_V,
            "y_span_Lpm": c.y_span_Lpm,
            "kc": c.kc,  # the commissioning gains as the block holds them (None: not given)
            "ti": c.ti,
        }
    )
    online = site.online
    settings = online.model_dump(mode="json") if hasattr(online, "model_dump") else asdict(online)
    settings.update(
        {
            "timezone": site.site.timezone,
            "loop_id": site.site.loop_id or default_loop_id(site.site.name),
            "plant_hash": plant_hash(plant_file),
            "plant_file": None if plant_file is None else str(Path(plant_file).resolve()),
            "controller": controller,
            "gain_units": None if c is None else block_units(BlockForm.of(c)),
            # the re-identification of archived history (fuelid.fleet) rebuilds the window
            # analysis from these: the sampling and control periods [s]
            "sampling": {
                "period_s": site.sampling.period_s,
                "control_period_s": site.sampling.control_period_s,
            },
            # the test signal (issue 40): its settings, and whether the site can carry one
            # (a [write.excitation] register and an amplitude; a request is refused without)
            "excitation": _excitation_settings(site),
        }
    )
    return {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "version": fuelid.__version__,
        "started": wall,
        "started_plant": None,
        "beat": wall,
        "beat_every_s": SERVICE_BEAT_S,
        "stopped": None,
        "settings": settings,
    }


def _excitation_settings(site: Any) -> dict[str, Any] | None:
    table = getattr(site, "excitation", None)
    if table is None:
        return None
    settings: dict[str, Any] = table.model_dump(mode="json")
    possible = "excitation" in getattr(site, "write", {}) and table.amplitude is not None
    return settings | {"possible": possible}


def loop_state(
    service: Mapping[str, Any] | None,
    newest_sample_wall: float | None,
    last_link_event: tuple[str, float] | None,
    now_wall: float,
    tz: str | None = "UTC",
    newest_sample: float | None = None,
) -> dict[str, Any]:
    """The loop's state now, from the service record and the wall clock (module docstring).

    Parameters
    ----------
    service : dict or None
        The ``"service"`` record of ``online_state`` (None when there is none).
    newest_sample_wall : float or None
        ``wall_time`` of the newest sample [s UTC]; None without samples, NaN when there are
        samples but their wall time is unknown (a store from before schema 3).
    last_link_event : (str, float) or None
        The newest ``link_down``/``link_up`` event: its kind and its wall time [s UTC].
    now_wall : float
        The wall clock now [s UTC].
    tz : str, optional
        The time zone of the times in ``text``.
    newest_sample : float, optional
        The newest sample's plant time [s UTC]: a stopped service's ``text`` names it, labelled
        plant time beside the stop's wall age (never used to judge the state).

    Returns
    -------
    dict
        ``state`` ("stopped", "link_down", "up", "no_data"), ``text`` (one line: "service
        stopped (no beat for 12 s of wall time; newest sample at 08:15:03 UTC plant time)"),
        ``service`` ("running", "stopped", "never started"), ``beat_age_s`` and
        ``sample_age_s`` [s] (None when unknown), ``since`` [wall s UTC]: since when the state
        holds, as far as known (the stop, the last beat, the link event, the newest sample).

    Examples
    --------
    >>> loop_state(None, None, None, 100.0)["text"]
    'service never started'
    >>> record = {"beat": 99.0, "stopped": None}
    >>> loop_state(record, 99.4, ("link_up", 50.0), 100.0)["state"]
    'up'
    >>> loop_state(record, 99.4, ("link_up", 50.0), 111.0)["state"]  # beat 12 s old
    'stopped'
    """
    now = float(now_wall)
    beat = _number(service.get("beat")) if service else None
    if beat is None and service:
        beat = _number(service.get("started"))
    beat_age = None if beat is None else now - beat
    sample_age = None if newest_sample_wall is None else now - float(newest_sample_wall)
    if sample_age is not None and not math.isfinite(sample_age):
        sample_age = None
    out: dict[str, Any] = {"beat_age_s": beat_age, "sample_age_s": sample_age}
    if not service:
        return {
            **out,
            "state": "stopped",
            "service": "never started",
            "since": None,
            "text": "service never started",
        }
    stopped = _number(service.get("stopped"))
    if stopped is not None or beat_age is None or beat_age > SERVICE_STALE_S:
        since = stopped if stopped is not None else beat
        return {
            **out,
            "state": "stopped",
            "service": "stopped",
            "since": since,
            "text": _stopped_text(now, stopped, beat_age, newest_sample, tz),
        }
    out["service"] = "running"
    if last_link_event is not None and last_link_event[0] == "link_down":
        since = float(last_link_event[1])
        text = f"link down (for {format_age(now - since)})"
        return {**out, "state": "link_down", "since": since, "text": text}
    if newest_sample_wall is None:
        return {
            **out,
            "state": "no_data",
            "since": _number(service.get("started")),
            "text": "service running, no sample yet",
        }
    if sample_age is None or not math.isfinite(sample_age) or sample_age > LINK_FRESH_S:
        known = sample_age is not None and math.isfinite(sample_age)
        since = float(newest_sample_wall) if known else None
        last = f"{format_age(sample_age)} ago" if known else "not known"
        return {
            **out,
            "state": "link_down",
            "since": since,
            "text": f"link down (no fresh sample: the newest written {last})",
        }
    return {
        **out,
        "state": "up",
        "since": None if last_link_event is None else float(last_link_event[1]),
        "text": f"up (newest sample {format_age(sample_age)} ago)",
    }


def _stopped_text(
    now: float,
    stopped: float | None,
    beat_age: float | None,
    newest_sample: float | None,
    tz: str | None,
) -> str:
    """A stopped service's line: "service stopped (no beat for 12 s of wall time; …)".

    The stop as an age on the wall clock (the pages and the commands show plant time, which a PLC
    at X times real time runs ahead of the wall clock: a wall-clock stamp beside them would read
    as one of theirs), the newest sample as a plant time in the site's zone, each labelled; its
    date only when the stop is a day old or more.
    """
    age = now - stopped if stopped is not None else beat_age
    how = (
        f"{format_age(age)} ago in wall time"
        if stopped is not None
        else f"no beat for {format_age(beat_age)} of wall time"
    )
    sample = _number(newest_sample)
    if sample is None or not math.isfinite(sample):
        return f"service stopped ({how})"
    stamp = format_time(sample, tz)
    if age is not None and age < 86_400.0:
        stamp = stamp.split(" ", 1)[1]
    return f"service stopped ({how}; newest sample at {stamp} plant time)"


def link_json(
    store: LoopStore,
    now: float | None = None,
    service: dict[str, Any] | None = None,
    tz: str | None = "UTC",
) -> dict[str, Any]:
    """The loop's state: the service and its link, judged on the wall clock.

    ``state`` is :func:`loop_state`'s ("stopped", "link_down", "up",
    "no_data"), with its ``text``, ``service`` ("running", "stopped", "never started"),
    ``beat_age_s``, ``sample_age_s`` and ``since``; ``newest_sample`` is the newest sample's
    plant time, ``newest_sample_wall`` the wall clock it was written at (None before schema
    3), ``age_s`` its wall age; ``last_event`` the newest link event.
    """
    now = _time.time() if now is None else float(now)
    newest = store.newest_sample_clocks()
    event = store.last_event(LINK_EVENTS)
    event_wall = None
    if event is not None:
        event_wall = event[3] if event[3] is not None else event[0]
    state = loop_state(
        service,
        None if newest is None else newest[1],
        None if event is None or event_wall is None else (event[1], float(event_wall)),
        now,
        tz,
        None if newest is None else newest[0],
    )
    newest_wall = None if newest is None or math.isnan(newest[1]) else newest[1]
    return {
        **state,
        "newest_sample": None if newest is None else newest[0],
        "newest_sample_wall": newest_wall,
        "age_s": None if newest_wall is None else now - newest_wall,
        "last_event": None
        if event is None
        else {"time": event[0], "wall_time": event[3], "kind": event[1], "detail": event[2]},
        "fresh_within_s": LINK_FRESH_S,
    }


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value)
