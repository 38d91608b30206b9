"""``fuelid online approve | reject | revert | excite``: a person's decisions, kept in the store.

Each files a request (origin "cli", :mod:`fuelid.online._requests`). With a live service (per
:func:`~fuelid.online._liveness.loop_state`) the service applies it at its next beat: the command
waits up to two beats for the outcome, and says when the service has not taken it yet. With no
live service it applies the request at once itself, with the same function.
"""

from __future__ import annotations

import getpass
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from fuelid.cli._common import guarded

if TYPE_CHECKING:
    pass

from fuelid.cli.online._app import (
    ConfigFile,
    ProposalId,
    StoreFile,
    WhoOption,
    WhyOption,
    _opened,
    app,
)
from fuelid.cli.online._show import _gains_text


def _user() -> str:
    try:
        return getpass.getuser()
    except (OSError, KeyError, ImportError):
        return "unknown"


def _submit(
    opened: Any,
    history: Any,
    kind: str,
    proposal_id: int | None,
    name: str,
    why: str,
    write_back: str | None,
) -> dict[str, Any]:
    """File a request; applied here when no service is live, else by the service."""
    from fuelid.online import submit_request

    return submit_request(opened, history, kind, proposal_id, name, why, "cli", write_back)


def _waiting(request: dict[str, Any]) -> str:
    return (
        f"request #{request['id']} ({request['kind']}) filed: waiting for the service "
        "(it applies it at its next beat; fuelid online status lists it)"
    )


def _decide(
    proposal_id: int,
    status: str,
    config: Path | None,
    store: Path | None,
    who: str | None,
    why: str,
    after: Callable[[dict[str, Any], dict[str, Any]], str],
) -> None:
    from fuelid.online import proposal_json
    from fuelid.store import StoreError

    name = who or _user()
    kind = {"approved": "approve", "rejected": "reject"}[status]
    with _opened(config, store) as (opened, history, settings):
        if history.proposal(proposal_id) is None:
            raise StoreError(f"no proposal {proposal_id}")
        request = _submit(opened, history, kind, proposal_id, name, why, settings.get("write_back"))
        updated = history.proposal(proposal_id)
        from fuelid.online import link_json

        record = history.state("service")
        running = link_json(opened, service=record)["service"] == "running"
        settings = {**settings, "service": record if running else None}
    if request["status"] == "waiting":
        typer.echo(_waiting(request))
        return
    if request["status"] != "done":
        raise StoreError(str(request["outcome"]))
    assert updated is not None
    controller = settings.get("controller")
    if controller is None and isinstance(record, dict):  # the service's, without --config
        controller = (record.get("settings") or {}).get("controller")
    typer.echo(
        f"{_gains_text(proposal_json(updated, controller))} by {name}; {after(updated, settings)}"
    )


@app.command("approve")
@guarded
def approve_command(
    proposal_id: ProposalId,
    config: ConfigFile = None,
    store: StoreFile = None,
    who: WhoOption = None,
    why: WhyOption = "",
) -> None:
    """Mark a pending proposal approved: the running service writes it when write-back allows."""

    def after(_: dict[str, Any], settings: dict[str, Any]) -> str:
        service = settings.get("service") or {}
        if service and not service.get("stopped"):  # what the running service does
            running = service.get("write_back")
            if running == "off":
                return 'the running service has write_back "off": it does not write'
            return (
                f'the running service (write_back "{running}") writes it when the loop '
                "allows (AUTO, no limit, link up)"
            )
        mode = settings.get("write_back")
        if mode == "off":
            return 'write_back is "off" in the site file: nothing is written (set "approve")'
        if mode is None:
            return 'the running service writes it if its site has write_back "approve" or "auto"'
        return "the running service writes it when the loop allows (AUTO, no limit, link up)"

    _decide(proposal_id, "approved", config, store, who, why, after)


@app.command("reject")
@guarded
def reject_command(
    proposal_id: ProposalId,
    config: ConfigFile = None,
    store: StoreFile = None,
    who: WhoOption = None,
    why: WhyOption = "",
) -> None:
    """Mark a pending or approved proposal rejected: it is never written."""
    _decide(proposal_id, "rejected", config, store, who, why, lambda *_: "it will not be written")


@app.command("revert")
@guarded
def revert_command(
    config: ConfigFile = None,
    store: StoreFile = None,
    who: WhoOption = None,
    why: WhyOption = "",
) -> None:
    """Ask the running service to write the last-known-good gains back (one command).

    The request is kept in the store; the service writes the last-known-good gains (the
    commissioning gains when it has none) at its next chance, and records who asked and why.
    """
    from fuelid.store import StoreError

    name = who or _user()
    with _opened(config, store) as (opened, history, settings):
        # applied here, the CLI does not judge the write-back: a service that cannot write
        # drops the request when it starts (and says so)
        request = _submit(opened, history, "revert", None, name, why, None)
        good = history.state("last_known_good")
    if request["status"] == "waiting":
        typer.echo(_waiting(request))
        return
    if request["status"] != "done":
        raise StoreError(str(request["outcome"]))
    target = (
        "the commissioning gains (no last-known-good kept)"
        if not good
        else f"the last-known-good gains (Kc {good['Kc']:.4g}, Ti {good['Ti']:.4g}, ideal form)"
    )
    note = ""
    if settings.get("write_back") == "off":
        note = '; write_back is "off" in the site file: the service will not write'
    typer.echo(f"revert requested by {name}: the running service writes {target}{note}")


@app.command("excite")
@guarded
def excite_command(
    start: Annotated[
        bool, typer.Option("--start", help="Start a test signal now (within the site's limits).")
    ] = False,
    stop: Annotated[bool, typer.Option("--stop", help="Stop the running test signal.")] = False,
    config: ConfigFile = None,
    store: StoreFile = None,
    who: WhoOption = None,
    why: WhyOption = "",
) -> None:
    """Ask the running service to start or stop a test signal on the PI's output.

    The service designs the signal from the loop's model within the site file's [excitation]
    limits (amplitude, one burst of max_share of a window per window) and starts it where the
    next window starts, if the loop allows it then (AUTO, no run, off the drive's limits, link
    up); a stop writes 0 to the register at once. fuelid online status shows the signal, or
    why none began.
    """
    from fuelid.errors import ConfigError
    from fuelid.store import StoreError

    if start == stop:
        raise ConfigError("give one of --start and --stop")
    kind = "excite_start" if start else "excite_stop"
    name = who or _user()
    with _opened(config, store) as (opened, history, _):
        request = _submit(opened, history, kind, None, name, why, None)
    if request["status"] == "waiting":
        typer.echo(_waiting(request))
        return
    if request["status"] != "done":
        raise StoreError(str(request["outcome"]))
    typer.echo(f"{request['outcome']} (by {name})")
