"""Words and numbers the pages print: times in the site's zone, gains with their units, next steps.

Pure functions of the status and history objects (the shapes ``fuelid online status --json`` and
``history --json`` print), so the pages and the tests read the same sentences.
"""

from __future__ import annotations

import math
from typing import Any

from fuelid.io.clock import format_time
from fuelid.online.report import health_line

__all__ = [
    "central_waiting",
    "fmt_num",
    "gains_now",
    "is_waiting",
    "link_text",
    "now_rows",
    "proposal_next",
    "proposal_views",
    "write_back_of",
]


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
    ``warning`` (:func:`site_warning`, None when the site is in contact and running).
    """
    out: dict[Any, dict[str, Any]] = {}
    for r in (status.get("central") or {}).get("requests") or []:
        if not is_waiting(r, now):
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


def link_text(status: dict[str, Any], tz: str) -> str:
    """The link line: the service's and the link's state in words."""
    link = status.get("link") or {}
    if link.get("text"):
        text = str(link["text"])
        # the command prints it after the word "link"; a page shows it alone
        return f"link {text}" if link.get("state") == "up" else text
    newest = link.get("newest_sample")
    return f"{link.get('state', 'unknown')} (newest sample {format_time(newest, tz)})"


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


def proposal_views(status: dict[str, Any], windows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The pending and approved proposals, each with ``next``, ``window_id`` and ``stale``.

    ``stale`` says why the service would no longer write it (the service's own rule), else None.
    """
    from fuelid.online.context import stale_reason
    from fuelid.plc.site import Online

    by_model = {w.get("model_id"): w for w in windows if w.get("model_id") is not None}
    settings = (status.get("service") or {}).get("settings") or {}
    window_s = float(settings.get("window_s") or Online().window_s)
    newest = (status.get("link") or {}).get("newest_sample")
    out = []
    for p in status.get("pending_proposals") or []:
        window = by_model.get(p.get("model_id"))
        end = None if window is None else window.get("t_to")
        stale = stale_reason(end, newest, window_s)
        out.append(
            {
                **p,
                "old": p.get("old") or {},
                "new": p.get("new") or {},
                "next": (
                    f"out of date, not written: {stale}" if stale else proposal_next(p, status)
                ),
                "stale": stale,
                "window_id": None if window is None else window["id"],
            }
        )
    return out


def gains_now(status: dict[str, Any]) -> tuple[dict[str, Any], str]:
    """The gains in force in the block's units, and where they come from (a note, or "")."""
    wb = status.get("write_back") or {}
    if wb.get("current_gains_block"):
        return dict(wb["current_gains_block"]), ""
    pending = status.get("pending_proposals") or []
    if pending and pending[-1].get("old"):  # no write yet: the gains the proposals start from
        return dict(pending[-1]["old"]), " (as commissioned: no write yet)"
    settings = (status.get("service") or {}).get("settings") or {}
    controller = settings.get("controller") or {}
    if controller.get("kc") is not None and controller.get("ti") is not None:
        gains = {"Kc": controller["kc"], "Ti": controller["ti"]}
        return gains, " (the site file's [controller] gains: no write yet)"
    return {}, " (not known: no write yet, no [controller] kc and ti)"


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
    units = status.get("gain_units") or status.get("gains_units") or {}
    gains, whence = gains_now(status)
    rows.append(
        (
            "write-back",
            f"{write_back_of(status) or 'unknown'}; gains now Kc {fmt_num(gains.get('Kc'))} "
            f"{units.get('Kc', '')}, Ti {fmt_num(gains.get('Ti'))} {units.get('Ti', '')}"
            f"{whence}",
        )
    )
    last = status.get("last_write")
    if last:
        when = format_time(last["time"], tz)
        rows.append(("last write", f"#{last['id']} {last['kind']} {last['status']} at {when}"))
    else:
        rows.append(("last write", "none"))
    counts = status.get("counts") or {}
    rows.append(
        (
            "counts",
            f"{counts.get('windows', 0)} windows, {counts.get('accepted', 0)} accepted, "
            f"{counts.get('proposals', 0)} proposals, {counts.get('writes', 0)} writes",
        )
    )
    return rows
