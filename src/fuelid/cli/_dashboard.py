"""``fuelid dashboard``: the control-room pages over the loops' stores, in a process of its own."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from fuelid.cli._common import guarded
from fuelid.cli._dashboard_users import DEFAULT_USERS_FILE, user_app

app = typer.Typer(
    help="The control-room dashboard: every loop, its model and gains over time, the proposals "
    "to approve, reject or revert (needs the dashboard extra: pip install 'fuelid[dashboard]').",
    rich_markup_mode=None,
    invoke_without_command=True,
)
app.add_typer(user_app, name="user")


TREND_MINUTES_RANGE = (1.0, 1440.0)
"""The live trend's span a page may follow [min]: a minute to a day."""


def _trend_minutes(value: float) -> float:
    """``--trend-minutes``: a number of minutes in range (NaN said as what it is, not a bound)."""
    low, high = TREND_MINUTES_RANGE
    if not (math.isfinite(value) and low <= value <= high):
        raise typer.BadParameter(f"a number of minutes from {low:g} to {high:g}, got {value:g}")
    return value


@app.callback()
@guarded
def dashboard_command(
    ctx: typer.Context,
    store: Annotated[
        list[Path] | None,
        typer.Option(
            "--store",
            metavar="FILE.db|DIR",
            help="A loop's store, or a folder of stores (watched for new ones); repeat for more.",
            show_default=False,
        ),
    ] = None,
    central: Annotated[
        str | None,
        typer.Option(
            "--central",
            metavar="URL",
            help="The central store (postgresql://user@host/db; the password from PGPASSWORD, "
            "~/.pgpass or a service file): its loops beside the local stores; an action on them "
            "is relayed to the site's service.",
            show_default=False,
        ),
    ] = None,
    archive: Annotated[
        Path | None,
        typer.Option(
            "--archive",
            metavar="DIR",
            help="The raw archive (the folder fuelid archive writes) the central loops' trends "
            "read; without it their raw samples stay at the site.",
            show_default=False,
        ),
    ] = None,
    host: Annotated[
        str, typer.Option("--host", help="Address to listen on (loopback unless --allow-remote).")
    ] = "127.0.0.1",
    port: Annotated[
        int, typer.Option("--port", min=0, max=65535, help="Port (0: a free one).")
    ] = 8050,
    users: Annotated[
        Path | None,
        typer.Option(
            "--users",
            metavar="FILE",
            help="The users file (fuelid dashboard user add); default dashboard-users.json when "
            "it exists. Without one nobody can log in: pages are read-only on loopback.",
            show_default=False,
        ),
    ] = None,
    allow_remote: Annotated[
        bool,
        typer.Option(
            "--allow-remote",
            help="Listen on a non-loopback address; every page then needs a login (put TLS in "
            "front: docs, how-to 'Secure the dashboard').",
        ),
    ] = False,
    ssl_certfile: Annotated[
        Path | None,
        typer.Option(
            "--ssl-certfile", help="TLS certificate (PEM) for uvicorn.", show_default=False
        ),
    ] = None,
    beside_service: Annotated[
        bool, typer.Option("--beside-service", hidden=True, help="Started by fuelid online.")
    ] = False,
    ssl_keyfile: Annotated[
        Path | None,
        typer.Option("--ssl-keyfile", help="TLS key (PEM) for uvicorn.", show_default=False),
    ] = None,
    trend_minutes: Annotated[
        float,
        typer.Option(
            "--trend-minutes",
            metavar="MIN",
            callback=_trend_minutes,
            help=f"The span the loop page's live trend shows and follows [min] "
            f"({TREND_MINUTES_RANGE[0]:g} to {TREND_MINUTES_RANGE[1]:g}).",
        ),
    ] = 10.0,
) -> None:
    """Serve the dashboard until Ctrl-C (fleet page, loop pages, window pages, the /api/ JSON)."""
    if ctx.invoked_subcommand is not None:
        return
    from fuelid.dashboard import serve

    if users is None and DEFAULT_USERS_FILE.exists():
        users = DEFAULT_USERS_FILE

    def ready(url: str, loop_ids: list[str]) -> None:
        shown = ", ".join(loop_ids) or "none yet"
        stops = "stops with the service" if beside_service else "Ctrl-C stops"
        typer.echo(f"dashboard: {url} (loops: {shown}; {stops})")

    serve(
        store or [],
        host=host,
        port=port,
        users=users,
        allow_remote=allow_remote,
        ssl_certfile=ssl_certfile,
        ssl_keyfile=ssl_keyfile,
        on_ready=ready,
        central=central,
        archive=archive,
        trend_minutes=trend_minutes,
    )
