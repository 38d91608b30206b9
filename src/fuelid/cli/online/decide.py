"""``fuelid online approve | reject | revert``: a person's decisions, kept in the store."""

from __future__ import annotations

import getpass
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

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
from fuelid.cli.online.show import _gains_text


def _user() -> str:
    try:
        return getpass.getuser()
    except (OSError, KeyError, ImportError):
        return "unknown"


def _decide(
    proposal_id: int,
    status: str,
    config: Path | None,
    store: Path | None,
    who: str | None,
    why: str,
    after: Callable[[dict[str, Any], dict[str, Any]], str],
) -> None:
    from fuelid.online.report import proposal_json
    from fuelid.store.base import StoreError

    name = who or _user()
    with _opened(config, store) as (_, history, settings):
        try:
            updated = history.set_proposal_status(proposal_id, status, who=name, why=why)
        except StoreError as error:
            current = history.proposal(proposal_id)
            pending = history.proposals(["pending", "approved"])
            if current is not None and current["status"] == "superseded" and pending:
                raise StoreError(
                    f"{error}; the open proposal now is #{pending[-1]['id']}"
                ) from None
            raise
        settings = {**settings, "service": history.state("service")}
    typer.echo(f"{_gains_text(proposal_json(updated))} by {name}; {after(updated, settings)}")


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
    name = who or _user()
    with _opened(config, store) as (_, history, settings):
        history.set_state(
            "revert_requested", {"who": name, "why": why or "requested", "time": time.time()}
        )
        good = history.state("last_known_good")
    target = (
        "the commissioning gains (no last-known-good kept)"
        if not good
        else f"the last-known-good gains (Kc {good['Kc']:.4g}, Ti {good['Ti']:.4g}, ideal form)"
    )
    note = ""
    if settings.get("write_back") == "off":
        note = '; write_back is "off" in the site file: the service will not write'
    typer.echo(f"revert requested by {name}: the running service writes {target}{note}")
