"""What the loop page shows, computed once for its first view and for each live refresh.

The page's live parts (proposals, "Now" with the test signal, the windows and events tables) are
rendered by the same templates (``part_*.html.j2``) from the same context, on the first view and
whenever the stream says the store changed (``GET /loops/{id}/parts``): a part never says
something another part contradicts, and a refreshed page never differs from a reloaded one.

Only bounded reads: the newest :data:`PART_WINDOWS` windows and :data:`PART_EVENTS` events,
whatever the store holds (a year of windows is no slower to show than a day), and the window of
each proposal shown, looked up by its model (:func:`with_evidence`). The events table shows the
store's events and, among them in time order, people's decisions on proposals (approve, reject,
revert, with who and why), read from the proposals' history: nothing more is stored.
"""

from __future__ import annotations

import time
from typing import Any

from fuelid.dashboard._excitation_view import excitation_view
from fuelid.dashboard._source import LoopReader
from fuelid.dashboard._views import (
    READ_BACK_RTOL,
    central_waiting,
    decided_cards,
    decided_proposals,
    decision_events,
    gains_agree,
    gains_in_force,
    link_text,
    now_rows,
    proposal_views,
    write_back_of,
    write_back_text,
)

__all__ = [
    "PARTS",
    "PART_EVENTS",
    "PART_WINDOWS",
    "events_table",
    "link_bands",
    "loop_context",
    "revert_offer",
    "with_evidence",
]

PART_WINDOWS = 30
"""Windows in the page's table (the newest)."""
PART_EVENTS = 50
"""Events in the page's table (the newest)."""
BAND_EVENTS = 400
"""Events read for the link-down bands on the trend (the newest)."""
PARTS = ("proposals", "now", "windows", "events")
"""The live parts, each a template ``part_<name>.html.j2`` and an element ``<name>-part``."""


def link_bands(events: list[dict[str, Any]], newest: float | None) -> list[list[float]]:
    """The link-down stretches [plant s] (link_down to the next link_up; open ones to ``newest``).

    >>> link_bands([{"kind": "link_down", "time": 5.0}, {"kind": "link_up", "time": 7.0}], 9.0)
    [[5.0, 7.0]]
    >>> link_bands([{"kind": "link_down", "time": 5.0}], 9.0)
    [[5.0, 9.0]]
    """
    bands: list[list[float]] = []
    down: float | None = None
    for event in events:
        if event["kind"] == "link_down" and down is None:
            down = float(event["time"])
        elif event["kind"] == "link_up" and down is not None:
            bands.append([down, float(event["time"])])
            down = None
    if down is not None:
        bands.append([down, down if newest is None else max(down, float(newest))])
    return bands


def revert_offer(
    status: dict[str, Any], write_back: str | None, gains: dict[str, Any]
) -> tuple[bool, dict[str, Any], str]:
    """Whether a revert can happen now, the gains it would write, and why not when it cannot."""
    good = (status.get("write_back") or {}).get("last_known_good_block") or {}
    if write_back in (None, "off"):
        return False, good, 'No revert: write-back is "off", the service writes nothing.'
    if not good:
        return False, good, "No revert yet: no verified write, so no last-known-good gains."
    if gains_agree(good, gains, READ_BACK_RTOL):  # the PLC's tags round the gains
        return False, good, "No revert: the gains in force are the last-known-good ones."
    return True, good, ""


def with_evidence(
    loop: LoopReader, windows: list[dict[str, Any]], proposals: list[dict[str, Any]]
) -> list[dict[str, Any]]:
    """``windows`` and the window of each proposal's model that is not among them.

    Looked up by model id (one bounded read, a row per proposal at most): a card's evidence
    row and its age rule do not depend on how many windows came since it was filed.
    """
    have = {w.get("model_id") for w in windows}
    wanted = {
        int(p["model_id"])
        for p in proposals
        if p.get("model_id") is not None and p["model_id"] not in have
    }
    return [*windows, *loop.windows_of_models(sorted(wanted))] if wanted else windows


def events_table(
    events: list[dict[str, Any]], decisions: list[dict[str, Any]]
) -> list[dict[str, Any]]:
    """The events table's rows, newest first: the store's events and people's decisions.

    Both oldest first; merged in time order, the newest :data:`PART_EVENTS` kept.

    >>> events_table([{"time": 1.0, "kind": "restart"}], [{"time": 2.0, "kind": "proposal"}])
    [{'time': 2.0, 'kind': 'proposal'}, {'time': 1.0, 'kind': 'restart'}]
    """
    merged = sorted([*events, *decisions], key=lambda row: float(row.get("time") or 0.0))
    return list(reversed(merged[-PART_EVENTS:]))


def _proposal_cards(
    loop: LoopReader,
    status: dict[str, Any],
    history: dict[str, Any],
    windows: list[dict[str, Any]],
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """The open proposals' cards and the recently decided ones', their windows looked up."""
    pending = status.get("pending_proposals") or []
    decided = decided_proposals(history, [p["id"] for p in pending])
    evidence = with_evidence(loop, windows, [*pending, *decided])
    return (
        proposal_views(status, evidence, history["writes"]),
        decided_cards(status, decided, evidence),
    )


def _approve_effect(status: dict[str, Any]) -> str:
    """What an approval leads to, as true now (a stopped service writes nothing until it runs)."""
    if write_back_of(status) == "off":
        return 'write-back is "off": recorded, nothing is written'
    if (status.get("link") or {}).get("state") == "stopped":
        return (
            "the service is stopped: written when it runs again, at its first write check, "
            "verified by the PLC's echo"
        )
    return "the service writes it at its next write check, verified by the PLC's echo"


def loop_context(loop: LoopReader, *, engineer: bool) -> dict[str, Any]:
    """The template context of the loop page and its parts (module docstring)."""
    from fuelid.online import held_line, window_json

    status = loop.status()
    tz = status.get("timezone") or "UTC"
    units = status.get("gain_units") or status.get("gains_units") or {}
    settings = (status.get("service") or {}).get("settings") or {}
    write_back = write_back_of(status)
    identity = loop.identity()
    windows = loop.recent_windows(PART_WINDOWS)
    # the proposals and writes (a handful a day): every one; the windows: none beyond these
    history = loop.history(windows=1)
    gains = gains_in_force(status, history["writes"])
    can_revert, last_good, no_revert = revert_offer(status, write_back, gains)
    events = loop.recent_events(BAND_EVENTS)
    proposals, decided = _proposal_cards(loop, status, history, windows)
    newest = (status.get("link") or {}).get("newest_sample")
    return {
        "tz": tz,
        "lp": identity,
        "status": status,
        "engineer": engineer,
        "units": {"Kc": units.get("Kc", ""), "Ti": units.get("Ti", "")},
        "ms_target": settings.get("ms_target", "the site's ms_target"),
        "write_back_text": write_back_text(status),
        "approve_effect": _approve_effect(status),
        "proposals": proposals,
        # the proposals decided last, newest first: what people decided stays on the page
        "decided": decided,
        "held_text": held_line(status.get("held_proposal")),
        "gains": {"Kc": gains["Kc"], "Ti": gains["Ti"]},
        "gains_source": gains["text"],
        "can_revert": can_revert,
        "last_good": last_good,
        "no_revert_reason": no_revert,
        "now_rows": now_rows(status, tz),
        "link_text": link_text(status, tz),
        # the test signal (issue 40): in the "Now" part, so re-read and greyed with it
        "excitation": excitation_view(
            status, tz, engineer=engineer, central=identity.get("source") == "central"
        ),
        "windows": [window_json(row) for row in reversed(windows)],
        "window_count": (status.get("counts") or {}).get("windows", len(windows)),
        # the store's events and people's decisions on proposals (read from the proposals)
        "events": events_table(events, decision_events(history)),
        "link_bands": link_bands(events, newest),
        # a proposal with a central request waiting: said on it, its buttons disabled
        "waiting": (
            central_waiting(status, tz, time.time()) if identity.get("source") == "central" else {}
        ),
    }
