"""The fleet page's rows: one per loop, status chips, sorted by what needs attention first.

Each loop gets the chips below, each at a level: ``alarm`` (act now), ``warn`` (look today),
``unknown`` (not measured, or no longer: the measurement is missing), ``info`` (worth knowing,
nothing to do), ``ok``. The thresholds are the constants of this module.

- **service**: alarm when the service is stopped (its beat is stale) or the link is down;
  warn when a central loop's site has not been heard from for a few send intervals
  ("no contact": the site may well run on, but what the page shows is as of its last sync and
  an action waits for it; look at its network today); unknown before the first sample, and
  while the link is "up" but its newest sample is older than the page's freshness bound
  (``fuelid.dashboard._views.FRESH_SAMPLE_S``, 5 s of wall time, or three sampling periods when
  longer: "no new sample for 9.3 s", where "link up (newest sample 9.3 s ago)" would mislead in
  the seconds before a killed service is judged stopped); ok when up with a fresh sample.
- **oscillation**: alarm when the last window oscillates.
- **last write**: alarm when the last write failed, a write is held or a revert is requested.
- **proposals**: warn while a proposal waits for a person (pending) or for its write (approved);
  info when the service's ``write_back`` is "off" (propose only: nothing is written, a proposal
  is advice and waiting is its normal state), and for proposals out of date (the service would
  not write them: "1 out of date, not written"); the states are those of the loop page's cards
  (``fuelid.dashboard._views.proposal_state``), so the chip and the cards say the same.
- **drift**: warn when K now / K the gains were tuned for is off 1 by more than `DRIFT_WARN`
  (10 %) and by more than two standard errors; info while K is tracked but the gains in force
  have no model of their own (as commissioned, or reverted to them: the model is known once a
  proposal's gains are written and verified).
- **limits**: warn when the drive sat at its limits more than `LIMITS_WARN` (5 %) of the last
  window.
- **IAE**: warn when the IAE per unit setpoint step is more than `IAE_WARN` (2) times its own
  median over the recent windows.
- **mode**: warn when the last window was in MAN or spent less than `AUTO_WARN` (90 %) of its
  time in AUTO.

**The test signal** (issue 40) is a note, not a chip: while a loop's service runs a test signal,
its row says so beside its chips ("exciting: ±0.15 V, 2 of 5 windows, cost +0.08 L/min sd", the
line ``fuelid online status`` prints; ``excitation`` in the row, with ``state``, ``exciting``,
``text`` and ``started``: :func:`fuelid.dashboard._excitation_view.excitation_note`). A signal
is the service doing its work, nothing to act on: the note changes neither the loop's level
nor its place in the order. A service stopped during a burst shows no "exciting": the PLC
zeroes the signal when the service's heartbeat stops.

**A stopped service** (state "stopped"): the chips about the running loop (oscillation, drift,
limits, IAE, mode: `LIVE_CHIPS`) turn unknown, "unknown since the stop at 08:15:03 CET (last:
…)", the time that of the newest sample (plant time, the pages' only clock, in the site's zone);
the service chip stays an alarm. What the store still proves keeps its colour: the last write
and the proposals.

**A restarted service**: the same chips stay unknown until the service has judged a window
of its own, one that starts at or after its start, "unknown since the restart at 08:25:10 CET:
no window of its own yet (last before: …)": until then the newest window (whose health they
show) holds the previous run's samples and the outage. The rule compares plant times, like with
like: the newest window's start (``last_window`` ``start``) against the service record's
``started_plant`` (the plant time of the running service's first sample, newer than every
sample the store held at its start; null until that sample is committed, and then no window
of its own was judged either). A window judged after the restart but opened before it (a
10-minute window judged 2 minutes after the restart) keeps the chips grey; the restart's time
shown is ``started_plant`` in the site's
zone. The record's ``started`` is wall time, never compared with a plant time (an
accelerated virtual PLC runs its plant clock hours ahead); only a record written before
``started_plant`` existed is judged on its ``started`` against the window's ``wall_time``,
the service host's two wall stamps.

**Severity order** (``severity_key``): loops with an alarm first, then with a warning, then
those with something unknown, then those with only something to know (a propose-only loop's
waiting proposals, an out-of-date proposal, a drift not measurable yet), then the healthy ones;
within a level, the loop with more chips at that level first; then by the first chip at that
level in the list's order above (``CHIP_ORDER``: a stopped service before an oscillation before
a failed write); then by loop id. A loop with no contact is a warning led by its service chip:
it sorts after every alarm and before the other warnings of as many chips (the service chip is
first in the order). A stopped loop is an alarm of one chip (its service) unless its last write
failed too: its greyed chips no longer add alarms.
"""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from fuelid.dashboard._excitation_view import excitation_note
from fuelid.dashboard._views import link_text, proposal_state, quiet_sample_age, stop_time_text
from fuelid.io import format_time

__all__ = [
    "AUTO_WARN",
    "CHIP_ORDER",
    "DRIFT_WARN",
    "IAE_WARN",
    "LEVELS",
    "LIMITS_WARN",
    "LIVE_CHIPS",
    "Chip",
    "fleet_row",
    "loop_chips",
    "severity_key",
]

LEVELS = ("alarm", "warn", "unknown", "info", "ok")
"""Chip levels, the most severe first."""
CHIP_ORDER = (
    "service",
    "oscillation",
    "last write",
    "proposals",
    "drift",
    "limits",
    "IAE",
    "mode",
)
"""Ties within a level are broken by the first chip at that level in this order."""
LIVE_CHIPS = ("oscillation", "drift", "limits", "IAE", "mode")
"""Chips about the running loop: unknown while the service is stopped, and after a restart until
it judged a window (module docstring)."""
AUTO_WARN = 0.9
"""A window with less than this share of its time in AUTO warns [0-1]."""
LIMITS_WARN = 0.05
"""A window with more than this share of its time at the drive's limits warns [0-1]."""
IAE_WARN = 2.0
"""IAE per unit step more than this many times its own recent median warns [-]."""
DRIFT_WARN = 0.10
"""|K now / K tuned − 1| above this (and above 2 standard errors) warns [-]."""


@dataclass(frozen=True)
class Chip:
    """One status chip: its name, level (:data:`LEVELS`) and the text shown."""

    name: str
    level: str
    text: str

    def to_json(self) -> dict[str, str]:
        """``{"name", "level", "text"}``."""
        return {"name": self.name, "level": self.level, "text": self.text}


def _pct(x: float) -> str:
    return f"{100.0 * x:.0f} %"


def _service_chip(status: dict[str, Any]) -> Chip:
    state = (status.get("link") or {}).get("state")
    text = link_text(status, status.get("timezone") or "UTC")
    if state in ("stopped", "link_down", "down"):
        return Chip("service", "alarm", text)
    if state == "up" and quiet_sample_age(status) is None:
        return Chip("service", "ok", text)
    if state == "no_contact":
        return Chip("service", "warn", text)
    return Chip("service", "unknown", text)  # no sample yet, or none fresh


def _health_chips(status: dict[str, Any], recent_iae: list[float]) -> list[Chip]:
    health = status.get("loop_health") or {}
    window = status.get("last_window") or {}
    chips = []
    auto = health.get("time_in_auto")
    mode = window.get("mode")
    if auto is None and mode is None:
        chips.append(Chip("mode", "unknown", "mode not measured yet"))
    else:
        text = f"{mode or '-'}" + ("" if auto is None else f" ({_pct(auto)} of the window in AUTO)")
        low = mode == "MAN" or (auto is not None and auto < AUTO_WARN)
        chips.append(Chip("mode", "warn" if low else "ok", text))
    limits = health.get("time_at_limits")
    if limits is None:
        chips.append(Chip("limits", "unknown", "not measured yet"))
    else:
        level = "warn" if limits > LIMITS_WARN else "ok"
        chips.append(Chip("limits", level, f"{_pct(limits)} of the window at the drive's limits"))
    osc = health.get("oscillation") or {}
    if "oscillating" not in osc:
        chips.append(Chip("oscillation", "unknown", "not measured yet"))
    elif osc.get("oscillating"):
        period = osc.get("period_s")
        text = "oscillating" + ("" if period is None else f" (period {period:.3g} s)")
        chips.append(Chip("oscillation", "alarm", text))
    else:
        chips.append(Chip("oscillation", "ok", "none"))
    iae = health.get("iae_per_unit_step_s")
    if iae is None or not recent_iae:
        chips.append(Chip("IAE", "unknown", "no setpoint step yet"))
    else:
        median = statistics.median(recent_iae)
        ratio = iae / median if median > 0 else 1.0
        level = "warn" if ratio > IAE_WARN else "ok"
        chips.append(Chip("IAE", level, f"{iae:.3g} s per unit step, {ratio:.2f}× its median"))
    return chips


def _drift_chip(status: dict[str, Any]) -> Chip:
    trend = status.get("k_trend") or {}
    drift = trend.get("drift")
    if not isinstance(drift, dict) or drift.get("ratio") is None:
        if trend.get("available"):  # the drift's reference is set when a proposal is written
            text = (
                "K tracked; the gains in force have no model of their own (as commissioned, or "
                "reverted to): drift is measured from the next proposal written and verified"
            )
            return Chip("drift", "info", text)
        return Chip("drift", "unknown", "K not tracked yet")
    ratio, se = float(drift["ratio"]), float(drift.get("se") or 0.0)
    off = abs(ratio - 1.0)
    level = "warn" if off > DRIFT_WARN and off > 2.0 * se else "ok"
    return Chip("drift", level, f"K now / K tuned for {ratio:.3f} ± {se:.3f}")


def _proposal_chip(status: dict[str, Any], windows: Sequence[dict[str, Any]]) -> Chip:
    states = [proposal_state(p, status, windows) for p in status.get("pending_proposals") or []]
    count = {name: sum(s.state == name for s in states) for name in ("waiting", "approved")}
    late = sum(s.state == "out_of_date" for s in states)
    propose_only = (status.get("write_back") or {}).get("setting") == "off"
    parts = []
    if count["waiting"]:
        parts.append(
            f"{count['waiting']} (propose only: nothing is written)"
            if propose_only
            else f"{count['waiting']} {'waits' if count['waiting'] == 1 else 'wait'} for approval"
        )
    if count["approved"]:
        parts.append(
            f"{count['approved']} approved (propose only: not written)"
            if propose_only
            else f"{count['approved']} approved, waiting for the write"
        )
    if late:
        parts.append(f"{late} out of date, not written")
    held = (status.get("held_proposal") or {}).get("id")
    if held is not None and not count["waiting"] and not count["approved"]:
        # the evidence points at turned-down gains: nothing will come until it moves
        parts.append(f"none filed: the gains of #{held} are held back")
        return Chip("proposals", "info", "; ".join(parts))
    if not parts:
        return Chip("proposals", "ok", "none waiting")
    # the states' own levels: warn while one waits for a person or a write, info otherwise
    level = min((s.level for s in states), key=LEVELS.index)
    return Chip("proposals", level, "; ".join(parts))


def _write_chip(status: dict[str, Any]) -> Chip:
    wb = status.get("write_back") or {}
    last = status.get("last_write")
    if wb.get("revert_requested"):
        return Chip("last write", "alarm", "revert requested")
    if wb.get("write_held"):
        return Chip("last write", "alarm", f"writes held: {wb['write_held']}")
    if last is None:
        return Chip("last write", "ok", "none yet")
    what = (
        f"proposal #{last['proposal_id']}"
        if last.get("kind") == "proposal" and last.get("proposal_id") is not None
        else str(last.get("kind"))
    )
    text = f"write #{last['id']} ({what}) {last['status']}"
    level = "alarm" if last.get("status") in ("failed", "not_applied") else "ok"
    return Chip("last write", level, text)


def _grey_when_stopped(chips: list[Chip], status: dict[str, Any]) -> list[Chip]:
    """The :data:`LIVE_CHIPS` unknown while the service is stopped, their last text kept."""
    link = status.get("link") or {}
    if link.get("state") != "stopped":
        return chips
    since = (
        "unknown: the service never ran"
        if link.get("service") == "never started"
        else f"unknown since the stop at {stop_time_text(status)}"
    )
    return [
        Chip(c.name, "unknown", f"{since} (last: {c.text})") if c.name in LIVE_CHIPS else c
        for c in chips
    ]


def _since_the_restart(status: dict[str, Any]) -> str | None:
    """Why the live chips are unknown after a restart, or None once a window was judged since.

    "unknown since the restart at …" while the running service has judged no window since its
    start (the module docstring's rule).
    """
    service = status.get("service") or {}
    window = status.get("last_window") or {}
    if not service or not window:  # no restart, or nothing judged to grey
        return None
    if "started_plant" not in service:  # a record from before started_plant: its wall stamps
        started, written = service.get("started"), window.get("wall_time")
        if not isinstance(started, int | float) or not isinstance(written, int | float):
            return None
        return None if written >= started else "unknown since the restart"
    start, opened = service.get("started_plant"), window.get("start")
    if not isinstance(start, int | float):
        return "unknown since the restart"  # no sample of its own yet: nothing judged since
    # a window judged after the restart but opened before it holds the previous run's samples
    # and the outage: its health is not what the restarted service measured
    if isinstance(opened, int | float) and opened >= start:
        return None
    return f"unknown since the restart at {_restart_time(status, float(start))}"


def _restart_time(status: dict[str, Any], start: float) -> str:
    """The restart's plant time in the site's zone, with its date when the run is a day old."""
    text = format_time(start, status.get("timezone") or "UTC")
    service = status.get("service") or {}
    ran = (service.get("beat") or 0.0) - (service.get("started") or 0.0)
    return text if ran >= 86_400.0 else text.split(" ", 1)[1]


def _grey_after_restart(chips: list[Chip], status: dict[str, Any]) -> list[Chip]:
    """The :data:`LIVE_CHIPS` unknown until a restarted service judged a window, last text kept."""
    if (status.get("link") or {}).get("state") == "stopped":
        return chips  # the stop's own words (_grey_when_stopped)
    since = _since_the_restart(status)
    if since is None:
        return chips
    return [
        Chip(c.name, "unknown", f"{since}: no window of its own yet (last before: {c.text})")
        if c.name in LIVE_CHIPS
        else c
        for c in chips
    ]


def loop_chips(
    status: dict[str, Any], recent_iae: list[float], windows: Sequence[dict[str, Any]] = ()
) -> list[Chip]:
    """Every chip of a loop, in :data:`CHIP_ORDER`.

    Parameters
    ----------
    status : dict
        The loop's status (the shape of ``fuelid online status --json``).
    recent_iae : list of float
        IAE per unit setpoint step [s] of the recent windows that had a step (the median's
        sample).
    windows : sequence of dict, optional
        The loop's recent stored windows (``model_id``, ``t_to`` [plant s]): an open proposal's
        age is judged on its window's end (else on its filing time, see
        :func:`fuelid.dashboard._views.proposal_stale`).
    """
    chips = [
        _service_chip(status),
        *_health_chips(status, recent_iae),
        _drift_chip(status),
        _proposal_chip(status, windows),
        _write_chip(status),
    ]
    chips = _grey_when_stopped(chips, status)
    chips = _grey_after_restart(chips, status)
    return sorted(chips, key=lambda c: CHIP_ORDER.index(c.name))


def severity_key(chips: list[Chip], loop_id: str) -> tuple[Any, ...]:
    """Sort key of a loop: the module docstring's severity order (smaller sorts first)."""
    for rank, level in enumerate(LEVELS):
        at_level = [c for c in chips if c.level == level]
        if at_level:
            first = min(CHIP_ORDER.index(c.name) for c in at_level)
            return (rank, -len(at_level), first, loop_id)
    return (len(LEVELS), 0, 0, loop_id)


def fleet_row(
    loop_id: str,
    site_name: str,
    status: dict[str, Any],
    recent_iae: list[float],
    windows: Sequence[dict[str, Any]] = (),
) -> dict[str, Any]:
    """One row of the fleet page (and of ``/api/loops``); ``windows`` as :func:`loop_chips`."""
    chips = loop_chips(status, recent_iae, windows)
    worst = next((lvl for lvl in LEVELS if any(c.level == lvl for c in chips)), "ok")
    return {
        "loop_id": loop_id,
        "site_name": site_name,
        "level": worst,
        "chips": [c.to_json() for c in chips],
        "sort_key": list(severity_key(chips, loop_id)),
        # the test signal: a note beside the chips, outside the severity (module docstring)
        "excitation": excitation_note(status),
    }
