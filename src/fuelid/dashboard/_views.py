"""Words and numbers the pages print: times in the site's zone, gains with their units, next steps.

Pure functions of the status and history objects (the shapes ``fuelid online status --json`` and
``history --json`` print), so the pages, the fleet's chips and the tests read the same sentences.
Times on the pages are plant time (the samples' time base) in the site's zone.

**A proposal's state** (``proposal_state``, one classification for the fleet's "proposals"
chip and the loop page's cards), from its stored status and the service's own rules:

- **waiting** (pending: a person must approve or reject it): warn, info when ``write_back`` is
  "off" (propose only: it is advice); actions approve, reject.
- **approved** (waiting for its write): warn, info when ``write_back`` is "off"; action reject.
- **out_of_date** (pending or approved, but the service would not write it: its newest window
  ended more than ``RECENT_WINDOWS_SPAN`` (6) window lengths of data before the newest sample,
  ``fuelid.online._context.stale_reason``, the rule by which the service supersedes it and
  refuses its approval): info, said "out of date, not written: …"; action reject.
- **writing** (its write under way, or it was when the service stopped): info; no action.
- **written** (its write verified by the PLC's echo: "written and verified at …"): ok.
- **reverted** (written, then reverted), **failed** (its write got no echo): info.
- **rejected**, **superseded** (a person rejected it; a newer proposal or its age replaced it): ok.

The chip counts the waiting and approved ones; out-of-date ones are said ("1 out of date, not
written") at level info, never as a warning: nothing waits for anyone.

**Decided proposals** (``decided_views``): the newest :data:`DECIDED_CARDS` (3) proposals no one
has to act on (being written, written, reverted, failed, rejected, superseded), newest first,
and the last one sent to the PLC when it is older, each once, stay on the page as cards. Each
says who approved it and why, then what became of it with who and why ("approved at T by ana:
why; written and verified at T, reverted at T by bob: why", "rejected at T by ana: why",
"superseded at T by service: why"), plant times in the site's zone. People's approvals,
rejections and reverts are also rows of the events table (``decision_events``, kind
"proposal"), read from the proposals' history: nothing more is stored.

**The gains in force** (``gains_in_force``), the first of:

1. the PLC's own kc and ti tags as the recorder last read them (the status' ``plc_gains``, when
   the site file reads ``[tags.kc]`` and ``[tags.ti]``): "the PLC's kc and ti tags as read at
   …". A reading newer than the last verified write whose gains are not that write's (to
   :data:`READ_BACK_RTOL`) is a change at the PLC (the panel, another tool) that no write
   explains, and the text says so. A reading older than the write that disagrees has not seen
   it yet: the PLC's echo of the write's apply number is its newer word, so 2. applies;
2. the last write of gains the PLC's echo verified (a revert's included: a reverted proposal's
   gains are never shown as current), said "last verified write #n: issued at …, verified at
   …" (and, when the tags were last read before it, that they do not show it yet);
3. the gains the service found in the PLC when it filed its newest open proposal;
4. the site file's ``[controller]`` kc and ti ("as commissioned");
5. else not known.

A card's "from" gains are these, not the gains the proposal was filed against (kept as
``filed_old``).

**A stopped service** (link state "stopped") does nothing, so what it would do is said as of
its last run (``write_back_text``): "Write-back: approve when the service last ran (stopped at
08:15:03 CET); nothing is written while it is stopped." (the time: the newest sample's, plant
time in the site's zone, as on the chips), in the "Now" table too; an out-of-date proposal's
reason promises new windows "when the service runs again"
(``fuelid.online._context.stale_while_stopped``).

**A write's times** (``fuelid.online.write_times_text``, the same words as ``fuelid online
status`` and ``history``): "issued at 2026-11-27 08:15:03 CET, verified at 08:15:07 CET", the
write's intent and the PLC's echo, both plant time in the site's zone.

**A fresh sample** (``FRESH_SAMPLE_S``, 5 s of wall time, or three sampling periods when
longer): the link is said "up" only while the newest sample is younger than the bound; past it
the page says "no new sample for 9.3 s", grey (unknown), in the seconds before the service's own
state catches up (stopped after 10 s without a beat, ``SERVICE_STALE_S``; link down after 30 s
without a sample, ``LINK_FRESH_S``). ``online status`` keeps its states: only the page's words
and colours change.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from fuelid.io import format_age, format_time
from fuelid.online import health_line, stale_while_stopped, write_times_text

__all__ = [
    "DECIDED_CARDS",
    "FRESH_PERIODS",
    "FRESH_SAMPLE_S",
    "PROPOSAL_STATES",
    "READ_BACK_RTOL",
    "STATE_LABELS",
    "ProposalState",
    "central_waiting",
    "decided_cards",
    "decided_proposals",
    "decided_views",
    "decision_events",
    "fmt_num",
    "fresh_bound_s",
    "gains_agree",
    "gains_in_force",
    "is_waiting",
    "last_written_view",
    "link_line_state",
    "link_text",
    "now_rows",
    "proposal_next",
    "proposal_stale",
    "proposal_state",
    "proposal_views",
    "quiet_sample_age",
    "stop_time_text",
    "write_back_of",
    "write_back_state",
    "write_back_text",
]

FRESH_SAMPLE_S = 5.0
"""Newest sample older than this: the page no longer says "link up" [s of wall time].

The service's writer commits the samples about once a second
(:class:`~fuelid.store.SampleWriter`'s ``commit_interval_s``, 1 s), so on a live link the
newest sample is at most a commit interval plus a read old; five intervals leave room for a slow
commit. The service itself is judged stopped only after
:data:`~fuelid.online._liveness.SERVICE_STALE_S` (10 s) without a beat and its link down after
:data:`~fuelid.online._liveness.LINK_FRESH_S` (30 s): between the two a killed service would
otherwise read "link up (newest sample 9.3 s ago)".
"""
FRESH_PERIODS = 3.0
"""A slow sampling period stretches the bound to this many periods [-] (:func:`fresh_bound_s`)."""
READ_BACK_RTOL = 1e-3
"""The PLC's kc and ti tags agree with a write within this, relative [-].

A float32 tag reads back a written float32 to about 1e-7, but a scaled integer tag (raw → eng)
only to its resolution: an int16 over 0…1 is 4e-5 absolute, about 1e-3 of a gain of 0.05."""
PROPOSAL_STATES = (
    "waiting",
    "approved",
    "out_of_date",
    "writing",
    "written",
    "reverted",
    "failed",
    "rejected",
    "superseded",
)
"""A proposal's states on the pages (the module docstring's list)."""
STATE_LABELS = {
    "waiting": "waits for approval",
    "approved": "approved, waits for its write",
    "out_of_date": "out of date, not written",
    "writing": "being written",
    "written": "written and verified",
    "reverted": "reverted",
    "failed": "write failed",
    "rejected": "rejected",
    "superseded": "superseded",
}
"""A state in a few words (a card's heading)."""
_STATE_OF_STATUS = {
    "writing": "writing",
    "applied": "written",
    "reverted": "reverted",
    "failed": "failed",
    "rejected": "rejected",
    "superseded": "superseded",
}
"""The page's state of a proposal's stored final (or in-flight) status."""
_CLOSED_LEVEL = {
    "writing": "info",
    "written": "ok",
    "reverted": "info",
    "failed": "info",
    "rejected": "ok",
    "superseded": "ok",
}
"""The chip level of a proposal no one has to act on (the "last write" chip carries failures)."""
DECIDED_CARDS = 3
"""Decided proposals the loop page keeps as cards, the newest (:func:`decided_views`)."""
_SENT = ("writing", "applied", "reverted", "failed")
"""The stored statuses of a proposal sent to the PLC."""
_DECIDED = (*_SENT, "rejected", "superseded")
"""The stored statuses of a proposal no one has to act on."""
_PERSON_STEPS = ("approved", "rejected", "reverted")
"""The steps of a proposal's history a person takes (the events table shows them)."""


@dataclass(frozen=True)
class ProposalState:
    """What a proposal is now, as the pages say it.

    Attributes
    ----------
    state : str
        One of :data:`PROPOSAL_STATES`.
    text : str
        One line: what happens next, or what happened.
    level : str
        A chip level (:data:`fuelid.dashboard._fleet.LEVELS`).
    actions : tuple of str
        What a person can really do now: "approve" and/or "reject" (none once it is closed).
    """

    state: str
    text: str
    level: str
    actions: tuple[str, ...]

    def to_json(self) -> dict[str, Any]:
        """``{"state", "text", "level", "actions"}``."""
        return {
            "state": self.state,
            "text": self.text,
            "level": self.level,
            "actions": list(self.actions),
        }


def is_waiting(request: dict[str, Any], now: float) -> bool:
    """A central request still waits: fetched by the site (being carried out) or unexpired.

    >>> is_waiting({"status": "waiting", "fetched": None, "expires": 10.0}, 5.0)
    True
    >>> is_waiting({"status": "waiting", "fetched": None, "expires": 10.0}, 11.0)
    False
    """
    if request.get("status") != "waiting":
        return False
    expires = request.get("expires")
    return request.get("fetched") is not None or expires is None or float(expires) > now


def site_warning(status: dict[str, Any], expires: float | None, tz: str) -> str | None:
    """Why a central request may expire unapplied (the site's service stopped, no contact).

    >>> site_warning({"link": {"state": "stopped"}}, 0.0, "UTC")[-60:]
    'unless it starts before 1970-01-01 00:00:00 UTC (wall clock)'
    >>> site_warning({"link": {"state": "up"}}, 0.0, "UTC") is None
    True
    """
    state = (status.get("link") or {}).get("state")
    before = f"before {format_time(expires, tz)} (wall clock)"
    if state == "stopped":
        return f"the site's service is stopped: the request will expire unless it starts {before}"
    if state == "no_contact":
        return (
            "no contact with the site: the request will expire unless the site syncs again "
            + before
        )
    return None


def central_waiting(status: dict[str, Any], tz: str, now: float) -> dict[Any, dict[str, Any]]:
    """The loop's waiting central requests by proposal id (None: a revert), for the page.

    Each: ``text`` ("approve filed by ana, waiting for the site's next sync, expires …") and
    ``warning`` (:func:`site_warning`, None when the site is in contact and running). A start
    or stop of the test signal is not among them: the signal's own part shows it
    (:mod:`fuelid.dashboard._excitation_view`).
    """
    out: dict[Any, dict[str, Any]] = {}
    for r in (status.get("central") or {}).get("requests") or []:
        if not is_waiting(r, now) or r.get("kind") in ("excite_start", "excite_stop"):
            continue
        if r.get("fetched") is not None:
            text = f"{r['kind']} filed by {r.get('who')}, fetched by the site, being carried out"
            warning = None
        else:
            text = (
                f"{r['kind']} filed by {r.get('who')}, waiting for the site's next sync, expires "
                f"{format_time(r.get('expires'), tz)} (wall clock)"
            )
            warning = site_warning(status, r.get("expires"), tz)
        out[r.get("proposal_id")] = {"id": r.get("id"), "text": text, "warning": warning}
    return out


def fmt_num(value: Any, digits: int = 4) -> str:
    """A number with ``digits`` significant digits; "-" for None, NaN or a non-number.

    >>> fmt_num(0.049241555), fmt_num(None), fmt_num(1.4831393, 3)
    ('0.04924', '-', '1.48')
    """
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        return "-" if not isinstance(value, str) else value
    return f"{value:.{digits}g}"


def write_back_of(status: dict[str, Any]) -> str | None:
    """The write-back setting in force (``status`` already takes the running service's)."""
    return (status.get("write_back") or {}).get("setting")


def write_back_state(status: dict[str, Any]) -> str:
    """The write-back setting as true now: while the service is stopped, as of its last run.

    >>> write_back_state({"write_back": {"setting": "approve"}, "link": {"state": "up"}})
    'approve'
    >>> write_back_state({"write_back": {"setting": "approve"},
    ...                   "link": {"state": "stopped", "service": "stopped",
    ...                            "newest_sample": 1_795_767_303.4, "beat_age_s": 12.0}})[:59]
    'approve when the service last ran (stopped at 08:15:03 UTC)'
    """
    setting = write_back_of(status) or "unknown"
    link = status.get("link") or {}
    if link.get("state") != "stopped":
        return setting
    if link.get("service") == "never started":
        return f"{setting}; no service ran: nothing is written"
    return (
        f"{setting} when the service last ran (stopped at {stop_time_text(status)}); nothing is "
        "written while it is stopped"
    )


def write_back_text(status: dict[str, Any]) -> str:
    """The page's write-back line: "Write-back: approve." (:func:`write_back_state`)."""
    return f"Write-back: {write_back_state(status)}."


def fresh_bound_s(status: dict[str, Any]) -> float:
    """The freshness bound of the newest sample for this loop [s of wall time].

    :data:`FRESH_SAMPLE_S`, or :data:`FRESH_PERIODS` sampling periods when the site samples
    slower than that allows (``service.settings.sampling.period_s``, up to 10 s).

    >>> fresh_bound_s({}), fresh_bound_s({"service": {"settings": {"sampling": {"period_s": 4}}}})
    (5.0, 12.0)
    """
    settings = (status.get("service") or {}).get("settings") or {}
    period = (settings.get("sampling") or {}).get("period_s")
    if isinstance(period, int | float) and math.isfinite(period) and period > 0:
        return max(FRESH_SAMPLE_S, FRESH_PERIODS * float(period))
    return FRESH_SAMPLE_S


def quiet_sample_age(status: dict[str, Any]) -> float | None:
    """The newest sample's age [s] when the link is "up" but that sample is past the bound.

    None otherwise (not "up", the age unknown, or the sample fresh): the link's state from
    ``online status`` (a contract) is kept; only what the page says of it changes.

    >>> quiet_sample_age({"link": {"state": "up", "sample_age_s": 9.3}})
    9.3
    >>> quiet_sample_age({"link": {"state": "up", "sample_age_s": 0.4}}) is None
    True
    """
    link = status.get("link") or {}
    age = link.get("sample_age_s")
    if link.get("state") != "up" or not isinstance(age, int | float) or not math.isfinite(age):
        return None
    return float(age) if age > fresh_bound_s(status) else None


def link_line_state(status: dict[str, Any]) -> str:
    """The link line's state (its colour): "unknown" while :func:`link_text` says no new sample.

    A link "up" whose newest sample is past the freshness bound is not shown in the colour of a
    healthy link (the chip beside it is grey then too).

    >>> link_line_state({"link": {"state": "up", "sample_age_s": 0.4}})
    'up'
    >>> link_line_state({"link": {"state": "up", "sample_age_s": 9.3}})
    'unknown'
    """
    if quiet_sample_age(status) is not None:
        return "unknown"
    return str((status.get("link") or {}).get("state") or "unknown")


def link_text(status: dict[str, Any], tz: str) -> str:
    """The link line: the service's and the link's state in words.

    "link up (newest sample 0.4 s ago)" only while that sample is fresh
    (:func:`quiet_sample_age`); past the bound "no new sample for 9.3 s".
    """
    link = status.get("link") or {}
    quiet = quiet_sample_age(status)
    if quiet is not None:
        text = f"no new sample for {format_age(quiet)}"
        contact = link.get("contact_age_s")  # a central loop: as of the site's last sync
        if isinstance(contact, int | float):
            text += f", as of the site's last sync {format_age(contact)} ago"
        return text
    if link.get("text"):
        text = str(link["text"])
        # the command prints it after the word "link"; a page shows it alone
        return f"link {text}" if link.get("state") == "up" else text
    newest = link.get("newest_sample")
    return f"{link.get('state', 'unknown')} (newest sample {format_time(newest, tz)})"


def stop_time_text(status: dict[str, Any]) -> str:
    """When the loop's data stopped: the newest sample's plant time, in the site's zone.

    ``HH:MM:SS ZONE``, with the date when the stop is a day old or more (wall age); "unknown"
    without a sample.

    >>> stop_time_text({"link": {"newest_sample": 1_795_767_303.4, "beat_age_s": 60.0}})
    '08:15:03 UTC'
    >>> stop_time_text({"link": {"newest_sample": 1_795_767_303.4, "beat_age_s": 2e5}})
    '2026-11-27 08:15:03 UTC'
    """
    link = status.get("link") or {}
    newest = link.get("newest_sample")
    if not isinstance(newest, int | float):
        return "unknown"
    text = format_time(float(newest), status.get("timezone") or "UTC")
    age = link.get("stopped_age_s", link.get("beat_age_s"))
    recent = isinstance(age, int | float) and age < 86_400.0
    return text.split(" ", 1)[1] if recent else text


def proposal_next(proposal: dict[str, Any], status: dict[str, Any]) -> str:
    """What happens to a proposal next, or why it waits."""
    state = (status.get("link") or {}).get("state")
    write_back = write_back_of(status)
    held = (status.get("write_back") or {}).get("write_held")
    if proposal.get("status") == "pending":
        text = "waits for an engineer to approve or reject it"
        if write_back == "off":
            text += '; write_back is "off": an approval is recorded, nothing is written'
        return text
    if proposal.get("status") != "approved":
        return str(proposal.get("status"))
    if state == "stopped":
        return "approved; the service is stopped: written when it runs again and write-back allows"
    if state == "no_contact":
        return "approved; no contact with the site now: its service writes it on its own rules"
    if write_back == "off":
        return 'approved; write_back is "off": the service does not write it'
    if held:
        return f"approved; writes are held: {held}"
    if state in ("link_down", "down"):
        return "approved; the link is down: written when it is back"
    return (
        "approved; written at the service's next write check (AUTO, drive off its limits, link "
        "up), then verified by the PLC's echo"
    )


def _window_s(status: dict[str, Any]) -> float:
    """The service's window length [s] (``[online] window_s``, its default when unknown)."""
    from fuelid.online import Online

    settings = (status.get("service") or {}).get("settings") or {}
    return float(settings.get("window_s") or Online().window_s)


def proposal_stale(
    proposal: dict[str, Any], status: dict[str, Any], windows: Sequence[dict[str, Any]] = ()
) -> str | None:
    """Why the service would not write ``proposal`` (too old), else None: its own rule.

    :func:`fuelid.online._context.stale_reason` on the end of the proposal's window (found in
    ``windows`` by its ``model_id``) and the newest sample's plant time. A proposal whose window
    is not among ``windows`` is judged on its own filing time: its window ended before it was
    filed, so a proposal filed too long ago is out of date too ("at least" so long).

    Parameters
    ----------
    proposal : dict
        A proposal as the status and history objects give it.
    status : dict
        The loop's status (``link.newest_sample`` [plant s], the service's ``window_s``).
    windows : sequence of dict
        Stored windows (``model_id``, ``t_to`` [plant s]), e.g. the recent ones.
    """
    reason = _stale_reason(proposal, status, windows)
    if (status.get("link") or {}).get("state") == "stopped":  # no new window while stopped
        return stale_while_stopped(reason)
    return reason


def _stale_reason(
    proposal: dict[str, Any], status: dict[str, Any], windows: Sequence[dict[str, Any]]
) -> str | None:
    """:func:`proposal_stale` as the service words it, running."""
    from fuelid.online import stale_reason

    if "stale" in proposal:  # the status' own answer (fuelid.online._requests.stale_of): one truth
        return proposal["stale"]  # type: ignore[no-any-return]
    model_id = proposal.get("model_id")
    if model_id is None:  # no window to judge: the service writes it
        return None
    newest = (status.get("link") or {}).get("newest_sample")
    end = next((w.get("t_to") for w in windows if w.get("model_id") == model_id), None)
    if end is not None:
        return stale_reason(float(end), newest, _window_s(status))
    filed = proposal.get("time")
    if not isinstance(filed, int | float):
        return None
    reason = stale_reason(float(filed), newest, _window_s(status))
    return None if reason is None else reason.replace(" ended ", " ended at least ", 1)


def _entry(proposal: dict[str, Any], status: str) -> dict[str, Any]:
    """The newest entry of the proposal's history that moved it to ``status`` (or {})."""
    for entry in reversed(proposal.get("history") or []):
        if entry.get("status") == status:
            return dict(entry)
    return {}


def _step_text(entry: dict[str, Any], verb: str, tz: str) -> str:
    """A person's (or the service's) step: "approved at T by NAME: why", plant time in ``tz``."""
    why = f": {entry['why']}" if entry.get("why") else ""
    return f"{verb} at {format_time(entry.get('time'), tz)} by {entry.get('who', 'unknown')}{why}"


def _closed_text(proposal: dict[str, Any], status: dict[str, Any]) -> str:
    """What happened to a proposal no one has to act on, with plant times in the site's zone.

    Who approved it and why comes first when it was approved ("approved at T by ana: why; "),
    then what became of it: "written and verified at T", "reverted at T by NAME: why",
    "rejected at T by NAME: why", "superseded at T by service: why", the write failed.
    """
    tz = status.get("timezone") or "UTC"
    approval = _entry(proposal, "approved")
    approved = f"{_step_text(approval, 'approved', tz)}; " if approval else ""
    return approved + _outcome_text(proposal, status, tz)


def _outcome_text(proposal: dict[str, Any], status: dict[str, Any], tz: str) -> str:
    """What became of a closed (or in-flight) proposal, its step's who and why included."""
    kind = proposal.get("status")
    entry = _entry(proposal, str(kind))
    at = format_time(entry.get("time"), tz)
    why = f": {entry['why']}" if entry.get("why") else ""
    if kind == "writing":
        if (status.get("link") or {}).get("state") == "stopped":
            return (
                "being written when the service stopped: settled from the PLC's echo at its start"
            )
        return "being written: waiting for the PLC's echo"
    written = f"written and verified at {format_time(_entry(proposal, 'applied').get('time'), tz)}"
    if kind == "applied":
        return written
    if kind == "reverted":
        return f"{written}, {_step_text(entry, 'reverted', tz)}"
    if kind == "failed":
        return f"not written: the write failed at {at}{why}"
    return _step_text(entry, str(kind), tz)  # rejected, superseded


def proposal_state(
    proposal: dict[str, Any], status: dict[str, Any], windows: Sequence[dict[str, Any]] = ()
) -> ProposalState:
    """The proposal's state, its one line, its chip level and the actions open to a person.

    The module docstring's table; ``windows`` as :func:`proposal_stale`.

    Examples
    --------
    >>> status = {"link": {"state": "up", "newest_sample": 1000.0}}
    >>> proposal_state({"id": 1, "status": "pending"}, status).actions
    ('approve', 'reject')
    >>> proposal_state({"id": 1, "status": "superseded"}, status).level
    'ok'
    """
    kind = proposal.get("status")
    if kind not in ("pending", "approved"):
        state = _STATE_OF_STATUS.get(str(kind), str(kind))
        level = _CLOSED_LEVEL.get(state, "unknown")
        return ProposalState(state, _closed_text(proposal, status), level, ())
    stale = proposal_stale(proposal, status, windows)
    if stale is not None:
        return ProposalState(
            "out_of_date", f"out of date, not written: {stale}", "info", ("reject",)
        )
    # propose only: nothing is written, so an open proposal is advice and holds nothing up
    level = "info" if write_back_of(status) == "off" else "warn"
    text = proposal_next(proposal, status)
    if kind == "pending":
        return ProposalState("waiting", text, level, ("approve", "reject"))
    return ProposalState("approved", text, level, ("reject",))


def _gains_json(
    status: dict[str, Any], kc: Any, ti: Any, source: str, text: str, write_id: Any = None
) -> dict[str, Any]:
    """The shape :func:`gains_in_force` returns."""
    return {
        "Kc": kc,
        "Ti": ti,
        "source": source,
        "text": text,
        "write_id": write_id,
        "units": _units(status),
    }


def _units(status: dict[str, Any]) -> dict[str, Any]:
    """The block's units of Kc and Ti: the status', else the PLC reading's (None each)."""
    reading = status.get("plc_gains") or {}
    units = status.get("gain_units") or status.get("gains_units") or reading.get("units") or {}
    return {"Kc": units.get("Kc"), "Ti": units.get("Ti")}


def _verified_write(
    status: dict[str, Any], writes: Sequence[dict[str, Any]] | None
) -> tuple[dict[str, Any] | None, dict[str, Any] | None]:
    """The newest verified write of gains, and the newest write when it is a later one.

    From ``writes`` (the history's, any order) when given, else from the status' ``last_write``.
    """
    rows = list(writes) if writes is not None else [status.get("last_write") or {}]
    rows = sorted((w for w in rows if w.get("id") is not None), key=lambda w: int(w["id"]))
    verified = [w for w in rows if w.get("status") == "verified"]
    last = verified[-1] if verified else None
    newest = rows[-1] if rows else None
    later = newest if newest is not None and newest is not last else None
    return last, later


def _from_write(
    status: dict[str, Any], write: dict[str, Any] | None, later: dict[str, Any] | None
) -> dict[str, Any] | None:
    """The gains of the last verified write (a revert's included); None without one."""
    tz = status.get("timezone") or "UTC"
    after = (
        ""
        if later is None
        else f"; write #{later['id']} after it is {later.get('status')}: the PLC may differ"
    )
    if write is not None:
        what = f"write #{write['id']}" + (" (a revert)" if write.get("kind") == "revert" else "")
        text = f"last verified {what}: {write_times_text(write, tz)}{after}"
        reading = status.get("plc_gains") or {}
        if reading.get("Kc") is not None and _read_before_write(reading, write):
            text += (
                "; the PLC's kc and ti tags, last read at "
                f"{format_time(reading.get('time'), tz)} before it, do not show it yet"
            )
        return _gains_json(status, write.get("Kc"), write.get("Ti"), "write", text, write["id"])
    block = (status.get("write_back") or {}).get("current_gains_block")
    if block and block.get("Kc") is not None:  # verified, but not among the writes given
        text = "last verified write" + after
        return _gains_json(status, block["Kc"], block.get("Ti"), "write", text)
    return None


def _versus_write(reading: dict[str, Any], write: dict[str, Any], status: dict[str, Any]) -> str:
    """What the PLC's reading is to the last verified write: "" when newer and the same.

    Read before the write with the same gains, or read after it with other gains (changed at the
    PLC): said, with the write's gains when they differ. A reading before the write with other
    gains never comes here: the write's echo is the newer word from the PLC (:func:`_from_plc`).
    """
    tz = status.get("timezone") or "UTC"
    units = _units(status)
    what = f"the last verified write #{write['id']}"
    what += " (a revert)" if write.get("kind") == "revert" else ""
    at = write.get("finished") or write.get("time")
    what += f" at {format_time(at, tz)}"
    if gains_agree(reading, write, READ_BACK_RTOL):
        return f", before {what} (the same gains)" if _read_before_write(reading, write) else ""
    written = f"Kc {fmt_num(write.get('Kc'))} {units['Kc'] or ''}".rstrip()
    written += f", Ti {fmt_num(write.get('Ti'))} {units['Ti'] or ''}".rstrip()
    return f"; not the gains of {what} ({written}): changed at the PLC, not by a write"


def _read_before_write(reading: dict[str, Any], write: dict[str, Any]) -> bool:
    """True when the PLC's gain tags were last read before the write finished (plant time)."""
    read_at = reading.get("time")
    at = write.get("finished") or write.get("time")
    return isinstance(read_at, int | float) and isinstance(at, int | float) and read_at < at


def _from_plc(
    status: dict[str, Any], writes: Sequence[dict[str, Any]] | None
) -> dict[str, Any] | None:
    """The PLC's kc and ti tags as the recorder last read them; None without a reading."""
    reading = status.get("plc_gains") or {}
    if reading.get("Kc") is None or reading.get("Ti") is None:
        return None
    tz = status.get("timezone") or "UTC"
    text = f"the PLC's kc and ti tags as read at {format_time(reading.get('time'), tz)}"
    write, _ = _verified_write(status, writes)
    if write is None:
        return _gains_json(status, reading["Kc"], reading["Ti"], "plc", text)
    if _read_before_write(reading, write) and not gains_agree(reading, write, READ_BACK_RTOL):
        # the PLC echoed the write's apply number after its tags were last read: the echo is
        # the newer word from the PLC, so the write's gains are in force (said so)
        return None
    text += _versus_write(reading, write, status)
    return _gains_json(status, reading["Kc"], reading["Ti"], "plc", text)


def gains_in_force(
    status: dict[str, Any], writes: Sequence[dict[str, Any]] | None = None
) -> dict[str, Any]:
    """The gains in force now (the block's units) and where that comes from.

    The module docstring's order: the PLC's kc and ti tags as read (``plc_gains``), else the
    last verified write (a revert's too), else the gains the service found in the PLC when it
    filed its newest open proposal, else the site file's ``[controller]`` kc and ti, else not
    known.

    Parameters
    ----------
    status : dict
        The loop's status (``plc_gains``, ``last_write``, ``write_back``,
        ``pending_proposals``, the service's ``settings.controller``, ``timezone``,
        ``gain_units``).
    writes : sequence of dict, optional
        The history's writes (``id``, ``kind``, ``status``, ``Kc``, ``Ti``, ``time``,
        ``finished``); None: the status' ``last_write`` alone.

    Returns
    -------
    dict
        ``Kc``, ``Ti`` (None each when not known), ``source`` ("plc", "write", "proposal",
        "commissioning", "unknown"), ``text`` (where they come from, in words: "the PLC's kc
        and ti tags as read at …", "last verified write #3: issued at 2026-11-27 08:15:02 CET,
        verified at 08:15:03 CET", "as commissioned …"), ``write_id`` (None unless a write) and
        ``units`` (``{"Kc", "Ti"}``: the block's).

    Examples
    --------
    >>> status = {"last_write": {"id": 4, "kind": "revert", "status": "verified", "Kc": 0.04,
    ...                          "Ti": 1.5, "time": 0.0, "finished": 0.0}}
    >>> force = gains_in_force(status)
    >>> force["Kc"], force["Ti"], force["text"][:58]
    (0.04, 1.5, 'last verified write #4 (a revert): issued at 1970-01-01 00')
    >>> status["plc_gains"] = {"Kc": 0.04, "Ti": 1.5, "time": 5.0}
    >>> gains_in_force(status)["text"]
    "the PLC's kc and ti tags as read at 1970-01-01 00:00:05 UTC"
    """
    echo = _from_plc(status, writes)
    if echo is not None:
        return echo
    written = _from_write(status, *_verified_write(status, writes))
    if written is not None:
        return written
    tz = status.get("timezone") or "UTC"
    filed = [p for p in status.get("pending_proposals") or [] if (p.get("old") or {}).get("Kc")]
    if filed:
        p = max(filed, key=lambda q: int(q["id"]))
        text = f"as the service found them when it filed proposal #{p['id']} at "
        text += format_time(p.get("time"), tz)
        return _gains_json(status, p["old"]["Kc"], p["old"].get("Ti"), "proposal", text)
    settings = (status.get("service") or {}).get("settings") or {}
    controller = settings.get("controller") or {}
    if controller.get("kc") is not None and controller.get("ti") is not None:
        text = "as commissioned (the site file's [controller] kc and ti; no write yet)"
        return _gains_json(status, controller["kc"], controller["ti"], "commissioning", text)
    text = "not known: no write yet, no proposal, no [controller] kc and ti"
    return _gains_json(status, None, None, "unknown", text)


def gains_agree(a: dict[str, Any], b: dict[str, Any], rel_tol: float = 1e-6) -> bool:
    """True when both gains are known and equal to ``rel_tol`` (relative)."""
    try:
        return all(math.isclose(float(a[k]), float(b[k]), rel_tol=rel_tol) for k in ("Kc", "Ti"))
    except (KeyError, TypeError, ValueError):
        return False


def _card(
    proposal: dict[str, Any],
    status: dict[str, Any],
    windows: Sequence[dict[str, Any]],
    start: dict[str, Any],
    start_text: str,
) -> dict[str, Any]:
    """One proposal card: the proposal's keys, its state, and the gains it moves from."""
    state = proposal_state(proposal, status, windows)
    model_id = proposal.get("model_id")
    window = next(
        (w for w in windows if model_id is not None and w.get("model_id") == model_id), None
    )
    filed_old = proposal.get("old") or {}
    return {
        **proposal,
        "from": start,
        "from_text": start_text,
        "old": start,
        "filed_old": filed_old,
        "from_changed": bool(start) and bool(filed_old) and not gains_agree(start, filed_old),
        "new": proposal.get("new") or {},
        "state": state.state,
        "state_label": STATE_LABELS.get(state.state, state.state),
        "state_text": state.text,
        "level": state.level,
        "actions": list(state.actions),
        "next": state.text,
        "stale": (
            proposal_stale(proposal, status, windows) if state.state == "out_of_date" else None
        ),
        "window_id": None if window is None else window.get("id"),
    }


def proposal_views(
    status: dict[str, Any],
    windows: Sequence[dict[str, Any]],
    writes: Sequence[dict[str, Any]] | None = None,
) -> list[dict[str, Any]]:
    """The open (pending and approved) proposals as the loop page's cards.

    Parameters
    ----------
    status : dict
        The loop's status (its ``pending_proposals``).
    windows : sequence of dict
        Stored windows (``id``, ``model_id``, ``t_to``): the evidence link and the age rule.
    writes : sequence of dict, optional
        The history's writes, for :func:`gains_in_force` (None: the status' ``last_write``).

    Returns
    -------
    list of dict
        Each proposal's keys, and: ``from`` (also ``old``) the gains in force now, what a
        write would move from, with ``from_text`` saying where they come from; ``filed_old``
        the gains it was filed against and ``from_changed`` whether they differ (a write or a
        revert since); ``state``, ``state_label``, ``state_text``, ``level``, ``actions``
        (:func:`proposal_state`); ``next`` (= ``state_text``), ``stale`` (why it is out of
        date, else None) and ``window_id`` (its window, None when not among ``windows``).
    """
    force = gains_in_force(status, writes)
    start = {"Kc": force["Kc"], "Ti": force["Ti"]} if force["Kc"] is not None else {}
    return [
        _card(p, status, windows, start, force["text"])
        for p in status.get("pending_proposals") or []
    ]


def last_written_view(
    status: dict[str, Any], history: dict[str, Any], windows: Sequence[dict[str, Any]] = ()
) -> dict[str, Any] | None:
    """The card of the proposal written last, so a write stays on the page once it is made.

    The newest proposal (by the time of its newest step) that went to the PLC: being written
    ("writing"), verified by the PLC's echo ("applied": state "written", "written and verified
    at …", plant time in the site's zone), "reverted" since, or "failed" (:func:`proposal_state`).
    Its ``from`` are the gains it was filed against, those before its write. None when none
    went to the PLC.

    Parameters
    ----------
    status : dict
        The loop's status (the time zone).
    history : dict
        The loop's history (its ``proposals``).
    windows : sequence of dict
        Stored windows, for the evidence link.
    """
    sent = ("writing", "applied", "reverted", "failed")
    written = [p for p in history.get("proposals") or [] if p.get("status") in sent]
    if not written:
        return None
    p = max(written, key=lambda q: (_entry(q, str(q["status"])).get("time") or 0.0, int(q["id"])))
    return _card(p, status, windows, p.get("old") or {}, "the gains before its write")


def _decided_at(proposal: dict[str, Any]) -> tuple[float, int]:
    """When a proposal took its status (the newest step that moved it there), and its id."""
    return (_entry(proposal, str(proposal["status"])).get("time") or 0.0, int(proposal["id"]))


def decided_views(
    status: dict[str, Any],
    history: dict[str, Any],
    windows: Sequence[dict[str, Any]] = (),
    shown: Sequence[Any] = (),
    limit: int = DECIDED_CARDS,
) -> list[dict[str, Any]]:
    """The cards of the proposals decided last, newest first: what people decided stays shown.

    The newest ``limit`` proposals no one has to act on (being written, written, reverted,
    failed, rejected, superseded; by the time of the step that closed them), and the last one
    sent to the PLC when it is older than those (a write stays on the page once it is made),
    each once. Each card's ``state_text`` says who approved it and why, then what became of it
    with who and why (:func:`proposal_state`), plant times in the site's zone; its ``from`` are
    the gains it was filed against.

    Parameters
    ----------
    status : dict
        The loop's status (the time zone, the link's state).
    history : dict
        The loop's history (its ``proposals``, with their ``history``).
    windows : sequence of dict
        Stored windows, for the evidence link.
    shown : sequence of int
        Ids already shown as open cards (a status read a moment before the history): left out.
    limit : int
        How many of the newest decided proposals.
    """
    return decided_cards(status, decided_proposals(history, shown, limit), windows)


def decided_proposals(
    history: dict[str, Any], shown: Sequence[Any] = (), limit: int = DECIDED_CARDS
) -> list[dict[str, Any]]:
    """The proposals :func:`decided_views` shows, newest first (its parameters)."""
    skip = {int(pid) for pid in shown}
    closed = sorted(
        (
            p
            for p in history.get("proposals") or []
            if p.get("status") in _DECIDED and int(p["id"]) not in skip
        ),
        key=_decided_at,
        reverse=True,
    )
    picked = closed[: max(int(limit), 0)]
    sent = next((p for p in closed if p.get("status") in _SENT), None)
    if sent is not None and all(p["id"] != sent["id"] for p in picked):
        picked.append(sent)  # older than the newest decided ones: the last write stays
    return picked


def decided_cards(
    status: dict[str, Any], decided: Sequence[dict[str, Any]], windows: Sequence[dict[str, Any]]
) -> list[dict[str, Any]]:
    """The cards of ``decided`` (:func:`decided_proposals`), each from its filed-against gains."""
    return [
        _card(p, status, windows, p.get("old") or {}, "the gains it was filed against")
        for p in decided
    ]


def _is_service(who: Any) -> bool:
    """True for the service's own steps ("service", "online", "service (write_back = auto)")."""
    name = str(who or "")
    return name in ("service", "online") or name.startswith("service ")


def decision_events(history: dict[str, Any]) -> list[dict[str, Any]]:
    """People's decisions on proposals as rows of the events table, oldest first.

    Each approval, rejection and revert a person made (the proposals' history entries whose
    ``who`` is not the service): ``time`` [plant s], ``kind`` "proposal", ``detail`` ("#4
    rejected by ana: not before the run"). Read from the proposals, not stored as events.

    >>> decision_events({"proposals": [{"id": 4, "history": [
    ...     {"time": 5.0, "status": "rejected", "who": "ana", "why": "not now"}]}]})
    [{'time': 5.0, 'kind': 'proposal', 'detail': '#4 rejected by ana: not now'}]
    """
    rows = []
    for proposal in history.get("proposals") or []:
        for step in proposal.get("history") or []:
            if step.get("status") not in _PERSON_STEPS or _is_service(step.get("who")):
                continue
            why = f": {step['why']}" if step.get("why") else ""
            detail = f"#{proposal['id']} {step['status']} by {step.get('who')}{why}"
            rows.append({"time": step.get("time"), "kind": "proposal", "detail": detail})
    return sorted(rows, key=lambda row: float(row["time"] or 0.0))


def now_rows(status: dict[str, Any], tz: str) -> list[tuple[str, str]]:
    """The "Now" table: the model, K(T), health, write-back, counts."""
    rows: list[tuple[str, str]] = []
    model = status.get("current_model")
    if model and model.get("model"):
        m, se = model["model"], model.get("stderr") or {}
        parts = [
            f"{key} {fmt_num(m.get(key))}"
            + (f" ± {fmt_num(se.get(key), 2)}" if se.get(key) else "")
            for key in ("K", "T", "T2", "delay")
            if m.get(key) is not None
        ]
        rows.append(
            (
                "model",
                ", ".join(parts)
                + f" (window ending {format_time(model.get('end'), tz)}; K [(L/min)/V], times [s])",
            )
        )
    else:
        rows.append(("model", "none accepted yet"))
    trend = status.get("k_trend") or {}
    drift = trend.get("drift")
    at = trend.get("at_newest") or {}
    if trend.get("available"):
        text = f"{trend.get('mode')} fit over {trend.get('n')} windows"
        if at.get("K") is not None:
            text += f"; K at {fmt_num(at.get('fuel_temperature'), 3)} °C: {fmt_num(at['K'])}"
        if isinstance(drift, dict):
            text += f"; K now / K tuned for {fmt_num(drift.get('ratio'), 3)}"
        rows.append(("K(T)", text))
    else:
        rows.append(("K(T)", f"not yet ({trend.get('reason', '')})"))
    rows.append(("health", health_line(status.get("loop_health"))))
    force = gains_in_force(status)
    units = force["units"]
    rows.append(
        (
            "write-back",
            f"{write_back_state(status)}; gains in force Kc {fmt_num(force['Kc'])} "
            f"{units['Kc'] or ''}, Ti {fmt_num(force['Ti'])} {units['Ti'] or ''} "
            f"({force['text']})",
        )
    )
    last = status.get("last_write")
    if last:
        times = write_times_text(last, tz)
        rows.append(("last write", f"#{last['id']} {last['kind']} {last['status']}: {times}"))
    else:
        rows.append(("last write", "none"))
    counts = status.get("counts") or {}
    rows.append(
        (
            "counts",
            f"{_counted(counts.get('windows', 0), 'window')}, {counts.get('accepted', 0)} "
            f"accepted, {_counted(counts.get('proposals', 0), 'proposal')}, "
            f"{_counted(counts.get('writes', 0), 'write')}",
        )
    )
    return rows


def _counted(n: int, noun: str) -> str:
    """``n`` and the noun, plural unless one.

    >>> _counted(1, "proposal"), _counted(0, "write")
    ('1 proposal', '0 writes')
    """
    return f"{n} {noun}" + ("" if n == 1 else "s")
