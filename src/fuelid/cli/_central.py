"""``fuelid central …``: the central PostgreSQL store every loop's service sends to.

``migrate`` creates or upgrades its schema (the database owner's command), ``status`` lists the
loops it knows, ``sync`` runs one sync cycle of a store by hand (a backfill without a service),
``retention`` drops the monthly partitions older than N months. The URL carries no password:
libpq reads ``PGPASSWORD``, ``~/.pgpass`` or a service file. A bad URL, an unreachable server or
a schema newer than this fuelid's: one line on stderr, exit code 2.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from fuelid.cli._common import emit_json, guarded, provenance

app = typer.Typer(
    help="The central PostgreSQL store of many loops: migrate, status, sync, retention.",
    rich_markup_mode=None,
    no_args_is_help=True,
)

UrlOption = Annotated[
    str,
    typer.Option(
        "--url",
        metavar="postgresql://ROLE@HOST/DB",
        help="The central store (no password: PGPASSWORD, ~/.pgpass or a service file).",
    ),
]
JsonOption = Annotated[bool, typer.Option("--json", help="Print one JSON object.")]


def _shown(url: str) -> str:
    """The URL as printed: any password typed into it masked."""
    from fuelid.central import redact

    return redact(url)


@app.command("migrate")
@guarded
def migrate_command(url: UrlOption, as_json: JsonOption = False) -> None:
    """Create or upgrade the central schema (run as the database's owner)."""
    from fuelid.central import connect, migrate

    with connect(url) as con:
        before, after = migrate(con)
    if as_json:
        emit_json({"version_before": before, "version": after} | provenance({"url": _shown(url)}))
        return
    if before == after:
        typer.echo(f"central schema at version {after}: nothing to do")
    else:
        typer.echo(f"central schema migrated from version {before} to {after}")


@app.command("status")
@guarded
def status_command(url: UrlOption, as_json: JsonOption = False) -> None:
    """The loops the central store knows: last seen, backlog, open proposals, requests.

    --json prints one object: schema_version and loops (each loop_id, site_name, stores,
    last_seen, last_seen_age_s, backlog_rows, backlog_oldest_wall, service_beat,
    service_stopped, last_window_time, open_proposals, waiting_requests).
    """
    from fuelid.central import check_schema, connect, fleet_status
    from fuelid.io import format_age

    with connect(url) as con:
        version = check_schema(con)
        loops = fleet_status(con)
    if as_json:
        emit_json({"schema_version": version, "loops": loops} | provenance({"url": _shown(url)}))
        return
    if not loops:
        typer.echo(f"central schema version {version}: no loop has sent yet")
        return
    typer.echo(
        f"{'loop':<20} {'service':<10} {'last seen':>10} {'backlog':>8} {'proposals':>9} "
        f"{'requests':>8}  site"
    )
    for row in loops:
        seen = format_age(row["last_seen_age_s"]) if row["last_seen"] is not None else "never"
        typer.echo(
            f"{row['loop_id']:<20} {_service(row):<10} {seen:>10} {row['backlog_rows'] or 0:>8} "
            f"{row['open_proposals']:>9} {row['waiting_requests']:>8}  {row['site_name']}"
        )


def _service(row: dict[str, Any]) -> str:
    """The service as the centre last heard of it: stopped (cleanly), running, none."""
    if row.get("service_stopped") is not None:
        return "stopped"
    if row.get("service_beat") is not None:
        return "running"  # as of its last sync ("last seen" says how long ago)
    return "none"  # a store synced by hand: no service ever ran on it


@app.command("sync")
@guarded
def sync_command(
    store: Annotated[
        Path, typer.Option("--store", metavar="FILE.db", help="The loop's SQLite store.")
    ],
    url: UrlOption,
    batch_rows: Annotated[
        int, typer.Option("--batch-rows", min=1, help="Outbox entries per batch.")
    ] = 5000,
    as_json: JsonOption = False,
) -> None:
    """Send a store's outbox now (switching it on; the first time, its whole history).

    Also files and applies the store's central requests (a revert and a start of the test
    signal are refused: no service carries them out; a stop of the signal is done: without a
    service the PLC holds it at 0). A store whose service runs is refused: the service sends it.
    """
    from fuelid.central import CentralError
    from fuelid.online import CentralLink, link_json
    from fuelid.plc import Central
    from fuelid.store import SERVICE_KEY, OnlineHistory, SQLiteStore

    with SQLiteStore(store) as opened, OnlineHistory(opened) as history:
        live = link_json(opened, service=history.state(SERVICE_KEY))["service"] == "running"
        if live:  # two senders of one store: the service's cycles would race this one
            raise CentralError(
                f"a running service sends {store}: stop it or let it sync (`fuelid online "
                "status` shows its backlog)"
            )
        link = CentralLink(opened.path, Central(url=url, batch_rows=batch_rows), history)
        try:
            result = link.cycle(apply_now=True, max_batches=None)
        finally:
            link.close()
    if result.error is not None:
        raise CentralError(result.error)
    sync = result.sync
    if as_json:
        emit_json(
            {
                **sync.to_json(),
                "requests_filed": len(result.filed),
                "requests_reported": len(result.reported),
            }
            | provenance({"store": str(store), "url": _shown(url)})
        )
        return
    typer.echo(
        f"sent {sync.sent_rows} rows in {sync.batches} batches"
        + (f" (backfill queued {sync.backfilled})" if sync.backfilled else "")
        + f"; backlog {sync.backlog_rows}; central requests filed {len(result.filed)}, "
        f"reported {len(result.reported)}"
    )


@app.command("retention")
@guarded
def retention_command(
    url: UrlOption,
    months: Annotated[
        int, typer.Option("--months", min=1, help="Keep this many months of windows and KPIs.")
    ],
    as_json: JsonOption = False,
) -> None:
    """Drop the monthly window and KPI partitions older than --months (a cron job)."""
    from fuelid.central import check_schema, connect, drop_old_partitions

    with connect(url) as con:
        check_schema(con)
        dropped = drop_old_partitions(con, months)
    if as_json:
        emit_json({"dropped": dropped} | provenance({"url": _shown(url)}))
        return
    typer.echo(
        f"dropped {len(dropped)} partitions" + (f": {', '.join(dropped)}" if dropped else "")
    )
