"""A person's requests (approve, reject, revert), filed in the store and applied in one place.

The CLI (``fuelid online approve|reject|revert``, origin "cli") and the dashboard (origin
"dashboard") file a request with :func:`file_request`; the running service consumes the
waiting ones at every beat (:data:`~fuelid.online._liveness.SERVICE_BEAT_S`) with
:func:`apply_request`, and records the outcome with
:meth:`~fuelid.store._online.OnlineHistory.finish_request`. When no service runs (per
:func:`~fuelid.online._liveness.loop_state`), the CLI applies its request at once itself, with
the same function.

What a request does: approve and reject move the proposal along its transitions (with the
request's who and why) or are refused with the reason (a proposal superseded meanwhile names
the open one); a revert leaves the ``revert_requested`` state that the service's write-back
turns into a write of the last-known-good gains at its next chance.
"""

from __future__ import annotations

import time as _time
from typing import Any

from fuelid.store import LoopHistory, OnlineHistory, StoreError

__all__ = ["EXCITE_KINDS", "apply_request", "consume_requests", "file_request", "submit_request"]

_STATUS_OF = {"approve": "approved", "reject": "rejected"}


def file_request(
    history: OnlineHistory,
    kind: str,
    proposal_id: int | None,
    who: str,
    why: str,
    origin: str,
) -> dict[str, Any]:
    """File a request (status "waiting"); the row as :meth:`OnlineHistory.add_request` gives it."""
    return history.add_request(kind, proposal_id, who, why, origin)


def apply_request(
    history: OnlineHistory, request: dict[str, Any], write_back_setting: str | None
) -> tuple[str, str]:
    """Apply one request; ``(status, outcome)``: "done" or "refused" and one line.

    Parameters
    ----------
    history : OnlineHistory
        The store's online history.
    request : dict
        A request row (:meth:`OnlineHistory.requests`).
    write_back_setting : str or None
        The write-back of whoever applies it ("off", "approve", "auto"; None when unknown): a
        revert is refused when it is "off" (nothing would ever write it).

    The request row itself is not changed (the caller records the outcome with
    :meth:`OnlineHistory.finish_request`).
    """
    kind = request["kind"]
    who, why = str(request["who"]), str(request["why"])
    if kind in EXCITE_KINDS:
        return _excite(history, request)
    if kind == "revert":
        if write_back_setting == "off":
            return "refused", 'write_back is "off": nothing writes the revert'
        history.set_state(
            "revert_requested",
            {
                "who": who,
                "why": why or "requested",
                "time": _time.time(),
                "request_id": request["id"],
            },
        )
        return "done", "revert requested: the service writes the last-known-good gains"
    status = _STATUS_OF.get(kind)
    if status is None:
        return "refused", f"unknown request kind {kind!r}"
    proposal_id = request["proposal_id"]
    if kind == "approve":
        stale = stale_of(history, proposal_id)
        if stale is not None:  # the service would supersede it instead of writing it
            return "refused", f"proposal {proposal_id} is out of date ({stale})"
    try:
        updated = history.set_proposal_status(int(proposal_id), status, who=who, why=why)
    except StoreError as error:
        reason = str(error)
        current = history.proposal(int(proposal_id))
        pending = history.proposals(["pending", "approved"])
        if current is not None and current["status"] == "superseded" and pending:
            reason = f"{reason}; the open proposal now is #{pending[-1]['id']}"
        return "refused", reason
    return "done", f"proposal {updated['id']} {updated['status']} by {who}"


EXCITE_KINDS = {"excite_start": "start", "excite_stop": "stop"}
"""Request kinds of the test signal (``fuelid online excite``) and their action."""


def _excite(history: OnlineHistory, request: dict[str, Any]) -> tuple[str, str]:
    """Leave a start or stop of the test signal for the running service's exciter.

    Refused when the site cannot carry a signal (no ``[write.excitation]`` or no amplitude)
    or no service runs to carry it out (without one the PLC holds the signal at 0: its
    heartbeat rule).
    """
    from fuelid.online.excitation._exciter import REQUEST_KEY
    from fuelid.store import SERVICE_KEY

    action = EXCITE_KINDS[request["kind"]]
    record = history.state(SERVICE_KEY) or {}
    settings = (record.get("settings") or {}).get("excitation") or {}
    if record.get("stopped") is not None or not record:
        if action == "stop":
            return "done", "no service runs: the PLC holds the signal at 0 (its heartbeat rule)"
        return "refused", "no service runs: nothing would carry the signal"
    if not settings.get("possible"):
        return "refused", (
            "the site file gives no [write.excitation] register or no [excitation] amplitude"
        )
    history.set_state(
        REQUEST_KEY,
        {
            "action": action,
            "who": str(request["who"]),
            "why": str(request["why"]),
            "time": _time.time(),
            "request_id": request["id"],
        },
    )
    if action == "start":
        return "done", (
            "start requested: the service starts the signal where the next window starts, if "
            "the loop allows it then (fuelid online status shows it, or why not)"
        )
    return "done", "stop requested: the service writes 0 to the register"


def stale_of(history: LoopHistory, proposal_id: Any) -> str | None:
    """Why the proposal is too old to be written (the service's own rule); None when fresh.

    The same answer for an approval (refused with it), the status (each open proposal's
    ``stale``) and the dashboard's cards.
    """
    from fuelid.online._context import stale_reason
    from fuelid.online._settings import Online
    from fuelid.store import SERVICE_KEY

    proposal = history.proposal(int(proposal_id)) if proposal_id is not None else None
    model_id = None if proposal is None else proposal.get("model_id")
    row = None if model_id is None else history.model(int(model_id))
    record = history.state(SERVICE_KEY) or {}
    settings = record.get("settings") if isinstance(record, dict) else None
    window_s = (settings or {}).get("window_s") or Online().window_s
    window_end = None if row is None else float(row["t_to"])
    return stale_reason(window_end, history.plant_now(), float(window_s))


def consume_requests(
    history: OnlineHistory, write_back_setting: str | None
) -> list[dict[str, Any]]:
    """Apply every waiting request, oldest first, and record each outcome; the rows after."""
    done = []
    for request in history.requests(status="waiting"):
        status, outcome = apply_request(history, request, write_back_setting)
        try:
            done.append(history.finish_request(request["id"], status, outcome))
        except StoreError:  # consumed meanwhile by another (the CLI with a stale view)
            continue
    return done


def submit_request(
    store: Any,
    history: OnlineHistory,
    kind: str,
    proposal_id: int | None,
    who: str,
    why: str,
    origin: str,
    write_back_setting: str | None,
    wait_s: float | None = None,
) -> dict[str, Any]:
    """File a request; apply it at once when no service is live, else wait for the service.

    What ``fuelid online approve|reject|revert`` and the dashboard's buttons both do.

    Parameters
    ----------
    store : SQLiteStore
        The loop's store (its newest sample and link events say whether a service is live).
    history : OnlineHistory
        Its online history.
    kind, proposal_id, who, why, origin
        The request (:func:`file_request`).
    write_back_setting : str or None
        The write-back the caller knows (used only when it applies the request itself).
    wait_s : float, optional
        How long to wait for a live service to apply it [s]; two beats by default.

    Returns
    -------
    dict
        The request's row after: ``status`` "done" or "refused" with its ``outcome``, or still
        "waiting" when the live service did not take it within ``wait_s``.
    """
    from fuelid.online._liveness import SERVICE_BEAT_S, link_json
    from fuelid.store import SERVICE_KEY

    live = link_json(store, service=history.state(SERVICE_KEY))["service"] == "running"
    request = file_request(history, kind, proposal_id, who, why, origin)
    if not live:
        status, outcome = apply_request(history, request, write_back_setting)
        return dict(history.finish_request(request["id"], status, outcome))
    deadline = _time.monotonic() + (2.0 * SERVICE_BEAT_S if wait_s is None else wait_s)
    while _time.monotonic() < deadline:
        _time.sleep(0.1)
        row = history.request(request["id"])
        if row is not None and row["status"] != "waiting":
            return dict(row)
    return dict(history.request(request["id"]) or request)
