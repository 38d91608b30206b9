"""The test signal in the status (``online status``, ``--json``, the dashboard): one home.

:func:`excitation_json` reads the exciter's state record and the newest windows; the one line
people read is :func:`excitation_line`:
``exciting: ±0.15 V, 2 of 5 windows, cost +0.08 L/min sd`` while a burst runs, else the mode,
what holds a signal off, and how the last burst ended.
"""

from __future__ import annotations

from typing import Any

from fuelid.store import LoopHistory

STATE_KEY = "excitation"
"""``online_state`` key of the exciter's record (:mod:`fuelid.online.excitation._exciter`)."""
RECENT_WINDOWS = 5
"""Windows the status counts the signal over [-]."""


INTERRUPTED = "the service stopped mid-burst: the PLC zeroes the signal (its heartbeat rule)"
"""How a burst ends that a killed service left "running" in its record."""


def excitation_json(history: LoopHistory, service_running: bool = True) -> dict[str, Any] | None:
    """The signal's state; None when the service never ran an exciter on this store.

    With ``service_running`` False a burst the record still calls running (a service killed
    mid-burst writes nothing more) is reported as ended, with :data:`INTERRUPTED`: no fuelid
    runs it, and the PLC's heartbeat rule has zeroed it.

    Returns
    -------
    dict or None
        ``mode``, ``amplitude_V`` (the site's cap), ``state`` ("running" or "idle"),
        ``running`` (the burst: ``started`` [plant s UTC], ``reason``, ``who``, ``design``),
        ``held`` (why none may run now, or None), ``next_start`` (plant time [s UTC] a burst
        waits for: the next window start; None), ``bursts`` (the last few, each with
        ``ended`` and ``end_reason``), ``windows_with_signal`` of ``windows_counted`` (the
        newest :data:`RECENT_WINDOWS`), ``measured`` (the newest window's measured cost:
        :func:`~fuelid.online.excitation._cost.measured_cost`, with its window ``id``).
    """
    record = history.state(STATE_KEY)
    if not isinstance(record, dict):
        return None
    windows = history.windows(limit=RECENT_WINDOWS)
    with_signal = [w for w in windows if (w.get("detail") or {}).get("excitation")]
    measured = None
    if with_signal:
        newest = with_signal[-1]
        measured = {"id": newest["id"], **newest["detail"]["excitation"]}
    bursts = list(record.get("bursts") or [])
    state, running = record.get("state", "idle"), record.get("running")
    if state == "running" and not service_running:
        if running:
            bursts.append({**running, "ended": None, "end_reason": INTERRUPTED})
        state, running = "idle", None
    return {
        "mode": record.get("mode"),
        "amplitude_V": record.get("amplitude_V"),
        "state": state,
        "running": running,
        "held": record.get("held"),
        "next_start": record.get("next_start") if service_running else None,
        "bursts": bursts[-RECENT_WINDOWS:],
        "windows_with_signal": len(with_signal),
        "windows_counted": len(windows),
        "measured": measured,
    }


def excitation_line(excitation: dict[str, Any] | None) -> str | None:
    """The signal in one line; None when there is none to tell.

    Examples
    --------
    >>> running = {"state": "running", "windows_with_signal": 2, "windows_counted": 5,
    ...            "running": {"design": {"amplitude_V": 0.15, "added_flow_sd_Lpm": 0.08}}}
    >>> excitation_line(running)
    'exciting: ±0.15 V, 2 of 5 windows, cost +0.08 L/min sd'
    >>> excitation_line({"state": "idle", "mode": "when_unidentified",
    ...                  "held": "the loop is not in AUTO", "bursts": []})
    'when_unidentified, idle (held: the loop is not in AUTO)'
    """
    if not excitation:
        return None
    counted = (
        f"{excitation.get('windows_with_signal', 0)} of {excitation.get('windows_counted', 0)} "
        "windows"
    )
    running = excitation.get("running")
    if excitation.get("state") == "running" and running:
        design = running.get("design") or {}
        return (
            f"exciting: ±{design.get('amplitude_V', 0.0):.3g} V, {counted}, cost "
            f"+{design.get('added_flow_sd_Lpm', 0.0):.2g} L/min sd"
        )
    text = f"{excitation.get('mode') or 'off'}, idle"
    if excitation.get("held"):
        text += f" (held: {excitation['held']})"
    elif excitation.get("next_start") is not None:
        text += " (a burst starts where the next window starts)"
    bursts = excitation.get("bursts") or []
    if bursts:
        last = bursts[-1]
        text += f"; last burst ±{(last.get('design') or {}).get('amplitude_V', 0.0):.3g} V"
        if last.get("end_reason"):
            text += f", ended: {last['end_reason']}"
    measured = excitation.get("measured") or {}
    if measured.get("added_flow_sd_Lpm") is not None:
        text += (
            f"; measured +{measured['added_flow_sd_Lpm']:.2g} L/min sd in window {measured['id']}"
        )
    return text
