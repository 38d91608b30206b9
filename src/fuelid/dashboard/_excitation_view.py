"""The test signal (issue 40) as the dashboard shows it: the loop page's part and the fleet's note.

Everything here is read from the loop's status (``status["excitation"]``, the exciter's state
record as :func:`fuelid.online.excitation._status.excitation_json` gives it, and the service
record's ``settings.excitation``); the one line is
:func:`~fuelid.online.excitation._status.excitation_line`'s, the text ``fuelid online status``
prints, so the page, the fleet and the command say the same.

- **The loop page** ("Test signal", in the "Now" part: re-read with it, greyed with it): the
  line; while a burst runs, its amplitude, mean hold, how long it has run of its ``burst_s``
  (the newest sample's plant time less its start, advanced by the page at every status event),
  the expected standard errors and fit, the expected cost, and the reason with who started it;
  the last bursts with how each ended. A service stopped mid-burst is said: the PLC's heartbeat
  rule zeroes the signal, whatever the record last said.
- **The actions** (an engineer's session): "start a test signal" while the site can carry one
  (``settings.excitation.possible``: a ``[write.excitation]`` register and an amplitude), the
  service runs and no signal runs; "stop the signal" while one runs. A central loop offers the
  same, judged on what the site's last send told (its service record, and the exciter's record
  in the liveness row's ``site_state``): the request is relayed like a revert (central schema
  version 4), and while one of its kind waits for the site the button gives way to a line that
  says so (one at a time, as :meth:`~fuelid.dashboard._central_source.CentralLoop.file_request`
  enforces).
- **The fleet's note** (:func:`excitation_note`): the line while a signal runs, on the loop's
  row beside its chips; it is not a chip, so it changes no loop's severity or order. Its value
  is also what the live stream compares between two status events (the ``excitation`` topic).

Times are plant time [s UTC]; amplitudes [V]; flows [L/min].
"""

from __future__ import annotations

import math
import time as _time
from typing import Any

from fuelid.dashboard._views import is_waiting
from fuelid.io import format_age, format_time
from fuelid.online.excitation import INTERRUPTED, excitation_line

__all__ = ["CUT_TEXT", "LAST_BURSTS", "excitation_note", "excitation_view"]

CUT_TEXT = INTERRUPTED
"""What a stopped service's burst is said to be (the record cannot say it ended): the status's
own words (:data:`fuelid.online.excitation._status.INTERRUPTED`)."""

LAST_BURSTS = 5
"""Bursts listed on the loop page (the newest)."""


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        return None
    return float(value)


def _pct(value: Any) -> str:
    number = _number(value)
    return "-" if number is None else f"{100.0 * number:.1f} %"


def _stopped(status: dict[str, Any]) -> bool:
    """The service is not running (stopped, never started): nothing carries a signal."""
    return (status.get("link") or {}).get("service") != "running"


def excitation_note(status: dict[str, Any]) -> dict[str, Any] | None:
    """The fleet row's note on the test signal; None when no exciter ever ran on the loop.

    ``state`` ("running", "idle"), ``exciting`` (a signal runs and the service with it),
    ``text`` (the one line; a stopped service's burst is said cut), ``started`` [plant s UTC].

    >>> running = {"state": "running", "windows_with_signal": 1, "windows_counted": 5,
    ...            "running": {"started": 10.0, "design": {"amplitude_V": 0.15,
    ...                                                    "added_flow_sd_Lpm": 0.08}}}
    >>> note = excitation_note({"excitation": running, "link": {"service": "running"}})
    >>> note["exciting"], note["text"]
    (True, 'exciting: ±0.15 V, 1 of 5 windows, cost +0.08 L/min sd')
    >>> excitation_note({"excitation": running, "link": {"service": "stopped"}})["exciting"]
    False
    >>> excitation_note({}) is None
    True
    """
    excitation = status.get("excitation")
    if not isinstance(excitation, dict):
        return None
    running = excitation.get("state") == "running" and bool(excitation.get("running"))
    text = excitation_line(excitation) or ""
    if running and _stopped(status):
        text = CUT_TEXT
    return {
        "state": excitation.get("state") or "idle",
        "exciting": running and not _stopped(status),
        "text": text,
        "started": (excitation.get("running") or {}).get("started") if running else None,
    }


def _expected_text(design: dict[str, Any]) -> str:
    """What the design expects the windows to give (its standard errors and fit)."""
    rel = design.get("expected_rel_stderr") or {}
    fit = _number(design.get("expected_fit_percent"))
    text = f"se(K) {_pct(rel.get('K'))}, se(T) {_pct(rel.get('T'))}, fit "
    text += "-" if fit is None else f"{fit:.0f} %"
    if design.get("bound") == "amplitude":
        text += " (capped at the site's amplitude: the gates may need more than one burst)"
    return text


def _running_view(running: dict[str, Any], newest: float | None, tz: str) -> dict[str, Any]:
    """The note on the burst that runs: what it is, how long it has run, what it costs."""
    design = running.get("design") or {}
    started = _number(running.get("started"))
    burst_s = _number(design.get("burst_s"))
    elapsed = None if started is None or newest is None else max(0.0, newest - started)
    return {
        "started": started,
        "started_text": format_time(started, tz),
        "burst_s": burst_s,
        "elapsed_s": elapsed,
        "elapsed_text": (
            f"{format_age(elapsed)} of {format_age(burst_s)}"
            if elapsed is not None and burst_s is not None
            else f"since {format_time(started, tz)}"
        ),
        "amplitude_text": f"±{_number(design.get('amplitude_V')) or 0.0:.3g} V"
        + (f" ({str(design['kind']).upper()})" if design.get("kind") else ""),
        "hold_text": "-" if _number(design.get("hold_s")) is None else f"{design['hold_s']:g} s",
        "expected_text": _expected_text(design),
        "cost_text": (
            f"+{_number(design.get('added_flow_sd_Lpm')) or 0.0:.2g} L/min sd, IAE "
            f"{_number(design.get('iae_per_window')) or 0.0:.3g} (L/min)·s per window"
        ),
        "reason": str(running.get("reason") or ""),
        "who": str(running.get("who") or ""),
    }


def _bursts_view(bursts: list[dict[str, Any]], tz: str) -> list[dict[str, Any]]:
    """The last bursts, newest first: when, by whom, how large, how long, how each ended."""
    out = []
    for burst in reversed(bursts[-LAST_BURSTS:]):
        design = burst.get("design") or {}
        started, ended = _number(burst.get("started")), _number(burst.get("ended"))
        ran = None if started is None or ended is None else ended - started
        out.append(
            {
                "started_text": format_time(started, tz),
                "who": str(burst.get("who") or ""),
                "amplitude_text": f"±{_number(design.get('amplitude_V')) or 0.0:.3g} V",
                "ran_text": format_age(ran) if ran is not None else "-",
                "end_reason": str(burst.get("end_reason") or ""),
                "reason": str(burst.get("reason") or ""),
            }
        )
    return out


def _no_start_reason(settings: dict[str, Any] | None, status: dict[str, Any]) -> str:
    """Why "start a test signal" is not offered now ("" when it is)."""
    if settings is None:
        return (
            "No test signal can be started: the service has not said that the site can carry "
            "one (its record has no [excitation] settings)."
        )
    if not settings.get("possible"):
        return (
            "No test signal can be started: the site file gives no [write.excitation] register "
            "or no [excitation] amplitude."
        )
    if _stopped(status):
        return "No test signal can be started: no service runs to carry it."
    return ""


def _central_waiting(status: dict[str, Any], kind: str, tz: str, now: float) -> str:
    """The line on a central request of ``kind`` still waiting for the site ("" when none).

    >>> row = {"kind": "excite_start", "who": "eve", "status": "waiting", "fetched": None,
    ...        "expires": 3600.0}
    >>> line = _central_waiting({"central": {"requests": [row]}}, "excite_start", "UTC", 0.0)
    >>> line.split(" (")[0]
    "A start of the test signal filed by eve waits for the site's next sync"
    >>> _central_waiting({"central": {"requests": [row]}}, "excite_stop", "UTC", 0.0)
    ''
    """
    for r in reversed((status.get("central") or {}).get("requests") or []):
        if r.get("kind") == kind and is_waiting(r, now):
            what = "A start" if kind == "excite_start" else "A stop"
            if r.get("fetched") is not None:
                return (
                    f"{what} of the test signal filed by {r.get('who')}: the site carries it out."
                )
            return (
                f"{what} of the test signal filed by {r.get('who')} waits for the site's next "
                f"sync (expires {format_time(r.get('expires'), tz)}, wall clock)."
            )
    return ""


def excitation_view(
    status: dict[str, Any],
    tz: str,
    *,
    engineer: bool,
    central: bool = False,
    now: float | None = None,
) -> dict[str, Any]:
    """The loop page's "Test signal" context (module docstring); ``central``: a central loop.

    Keys: ``line`` (one line, always), ``state`` ("running", "idle", "none": no exciter ever
    ran), ``running`` (:func:`_running_view`, None unless a burst runs and the service with
    it), ``cut`` (the service stopped during a burst), ``bursts`` (newest first), ``mode``,
    ``possible``, ``amplitude_V`` (the site's cap [V], None when unknown), ``can_start``,
    ``can_stop`` (the buttons an engineer sees), ``no_action`` (why an engineer sees no start
    button, or a central request that waits for the site; else ""). ``now`` [wall s UTC]
    judges whether a central request still waits (the clock by default).
    """
    excitation = status.get("excitation")
    excitation = excitation if isinstance(excitation, dict) else None
    settings = ((status.get("service") or {}).get("settings") or {}).get("excitation")
    settings = settings if isinstance(settings, dict) else None
    mode = (excitation or {}).get("mode") or (settings or {}).get("mode")
    possible = bool((settings or {}).get("possible"))
    running = (excitation or {}).get("running")
    running = running if isinstance(running, dict) else None
    runs = (excitation or {}).get("state") == "running" and running is not None
    cut = runs and _stopped(status)
    newest = _number((status.get("link") or {}).get("newest_sample"))
    line = excitation_line(excitation)
    if line is None:
        line = (
            "none: the site file gives no [write.excitation] register or no amplitude"
            if settings is not None and not possible
            else f"{mode or 'off'}: no test signal has run on this loop"
        )
    elif cut:  # the record still says running: the PLC's heartbeat rule zeroed it
        line = f"{CUT_TEXT} (last: {line})"
    no_action = _no_start_reason(settings, status) if not runs else ""
    # a central loop: a start or stop relayed and still waiting is said instead of its button
    # (a second one is refused while the first waits)
    wall = _time.time() if now is None else float(now)
    kind = "excite_stop" if runs else "excite_start"
    pending = _central_waiting(status, kind, tz, wall) if central else ""
    return {
        "line": line,
        "state": "none" if excitation is None else ("running" if runs else "idle"),
        "running": (
            _running_view(running, newest, tz) if running is not None and runs and not cut else None
        ),
        "cut": cut,
        "bursts": _bursts_view(list((excitation or {}).get("bursts") or []), tz),
        "mode": mode,
        "possible": possible,
        # the site's cap [V]: the confirmation names it (the design may stay below it)
        "amplitude_V": _number((excitation or {}).get("amplitude_V"))
        or _number((settings or {}).get("amplitude")),
        "can_start": engineer and not runs and not no_action and not pending,
        "can_stop": engineer and runs and not cut and not pending,
        "no_action": (pending or no_action) if engineer else "",
    }
