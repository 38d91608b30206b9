"""``fuelid record``, ``fuelid export`` and ``fuelid store info``: the sample stream at the CLI.

``record`` reads a PLC as its site file says and stores the samples (foreground, a live status
line on stderr, Ctrl-C or SIGTERM stop after a final commit); ``export`` writes a store's ok
samples as a log ``fuelid identify`` reads without options; ``store info`` says what a store
holds. Every failure is one line on stderr and exit code 2.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from fuelid.cli._common import emit_json, guarded, provenance
from fuelid.errors import DataError, FuelidError

if TYPE_CHECKING:
    from fuelid.plc import RecorderStats

store_app = typer.Typer(help="The sample store: what it holds.", rich_markup_mode=None)

StoreFile = Annotated[
    Path,
    typer.Option("--store", metavar="FILE.db", help="The store (an SQLite file)."),
]

QUIET_STATUS_EVERY_S = 10.0
"""Status line interval when stderr is not a terminal [s] (a log file gets a line now and then)."""


class _StatusLine:
    """The live status line on stderr: redrawn in place on a terminal, a line every 10 s else."""

    def __init__(self) -> None:
        self.tty = sys.stderr.isatty()
        self._shown = False
        self._last = -float("inf")

    def message(self, text: str) -> None:
        self._clear()
        typer.echo(f"record: {' '.join(text.split())}", err=True)

    def status(self, stats: RecorderStats) -> None:
        if self.tty:
            sys.stderr.write("\r\x1b[2K" + stats.line())
            sys.stderr.flush()
            self._shown = True
        elif time.monotonic() - self._last >= QUIET_STATUS_EVERY_S:
            self._last = time.monotonic()
            typer.echo(f"record: {stats.line()}", err=True)

    def _clear(self) -> None:
        if self._shown:
            sys.stderr.write("\r\x1b[2K")
            self._shown = False

    def close(self) -> None:
        self._clear()


@guarded
def record_command(
    config: Annotated[
        Path,
        typer.Option("--config", "-c", metavar="SITE.toml", help="The site file of the loop."),
    ],
    store: Annotated[
        Path | None,
        typer.Option(
            "--store",
            metavar="FILE.db",
            help="Store to append to (default: the site file's [store] url).",
            show_default=False,
        ),
    ] = None,
    duration: Annotated[
        float | None,
        typer.Option(
            metavar="SECONDS",
            help="Stop after this long [s] (default: until Ctrl-C or SIGTERM).",
            show_default=False,
        ),
    ] = None,
    give_up_after: Annotated[
        float | None,
        typer.Option(
            "--give-up-after",
            metavar="SECONDS",
            help="Exit with code 2 after this long [s] without a link to the PLC (default: "
            "keep retrying with backoff up to 5 s).",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Record a PLC's samples into the store, with a live status line on stderr.

    Sample times come from the PLC's ring buffer or sequence counter when the site file maps
    them, else from the receipt time; lost samples, link drops, restarts, bad values and gain
    changes are stored as events. Ctrl-C or SIGTERM stops after a final commit.
    """
    from fuelid.online import load_service_site
    from fuelid.plc import record_site

    for name, value in (("--duration", duration), ("--give-up-after", give_up_after)):
        if value is not None and not value > 0.0:
            raise typer.BadParameter(f"{name} must be a positive number of seconds")
    site = load_service_site(config)
    for line in site.missing():
        typer.echo(f"record: the site file does not expose {line}", err=True)
    target = str(store) if store is not None else site.store.url
    archiver = None
    if site.archive is not None and site.archive.auto:
        from fuelid.archive import archiver as site_archiver

        archiver = site_archiver(site.archive.dir)
    status = _StatusLine()
    status.message(f"recording {site.site.name!r} into {target} (Ctrl-C stops)")
    try:
        stats = record_site(
            site,
            target,
            duration_s=duration,
            give_up_after_s=give_up_after,
            on_message=status.message,
            on_status=status.status,
            archiver=archiver,
        )
    finally:
        status.close()
    if stats.stored == 0:  # a store with nothing in it is no recording: say why, exit 2
        why = (
            f"the link to the PLC never came up ({stats.last_error})"
            if stats.last_error and stats.link != "up"
            else "the PLC answered but gave no new sample (is its sample counter running?)"
            if stats.link == "up"
            else "no link to the PLC within the time given"
        )
        raise FuelidError(f"recorded no sample into {target}: {why}")
    typer.echo(
        f"recorded {stats.stored} samples into {target}: {stats.lost} lost, {stats.flagged} "
        f"flagged, {stats.drops} link drop(s), {stats.restarts} PLC restart(s)"
    )


@guarded
def export_command(
    store: Annotated[
        Path,
        typer.Option(
            "--store",
            metavar="FILE.db|DIR",
            help="The store (an SQLite file) or a raw archive's folder (fuelid archive).",
        ),
    ],
    out: Annotated[
        Path,
        typer.Option("--out", "-o", metavar="LOG", help="Log to write: .csv or .parquet."),
    ],
    t_from: Annotated[
        str | None,
        typer.Option(
            "--from",
            metavar="TIME",
            help="First sample time: UTC seconds or ISO 8601 (2026-03-01T12:00:00Z).",
            show_default=False,
        ),
    ] = None,
    t_to: Annotated[
        str | None,
        typer.Option(
            "--to",
            metavar="TIME",
            help="End (exclusive): UTC seconds or ISO 8601.",
            show_default=False,
        ),
    ] = None,
    force: Annotated[bool, typer.Option("--force", help="Replace an existing log.")] = False,
    loop: Annotated[
        str | None,
        typer.Option(
            "--loop",
            metavar="ID",
            help="The loop to export from an archive folder (default: its only loop).",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Write a store's ok samples as a log that fuelid identify reads without options.

    Columns t_s [s from the first sample], u_V [V], q_Lpm [L/min], sp_Lpm, T_fuel_degC [°C],
    mode, quality, seq, time_utc. Samples that are not ok are left out, so lost or flagged
    stretches are gaps; nothing is interpolated. With --store DIR (a raw archive written by
    fuelid archive) the loop --loop ID is read from its Parquet days, with the same columns
    and the same rule: the archive exports as the store did before retention thinned it.
    """
    from fuelid.store import SQLiteStore, export_log, parse_time

    lo = None if t_from is None else parse_time(t_from)
    hi = None if t_to is None else parse_time(t_to)
    if lo is not None and hi is not None and lo >= hi:
        raise DataError(f"--from {t_from} is not before --to {t_to}: the range holds nothing")
    if store.is_dir():
        from fuelid.archive import ArchiveLoop

        result = export_log(ArchiveLoop(store, loop), out, lo, hi, overwrite=force)
    else:
        with SQLiteStore(store) as opened:
            if loop is not None and loop != opened.loop_id:
                raise DataError(f"{store}: the store is loop {opened.loop_id!r}, not {loop!r}")
            result = export_log(opened, out, lo, hi, overwrite=force)
    typer.echo(
        f"wrote {result.rows} samples ({result.t_last - result.t_first:.3f} s) to {result.path}; "
        f"{result.left_out} not ok left out"
    )


@store_app.command("info")
@guarded
def info_command(
    store: StoreFile,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Rows, time span, gaps, link events, quality counts and size of a store."""
    from fuelid.store import SQLiteStore

    with SQLiteStore(store) as opened:
        info = opened.info()
    if as_json:
        emit_json(info.to_json() | provenance({"store": str(store)}))
        return
    from datetime import UTC, datetime

    def stamp(t: float | None) -> str:
        if t is None:
            return "-"
        return datetime.fromtimestamp(t, tz=UTC).isoformat(timespec="milliseconds")

    events = ", ".join(f"{k} {n}" for k, n in sorted(info.events.items())) or "none"
    quality = ", ".join(f"{k} {n}" for k, n in sorted(info.quality.items())) or "none"
    lines = [
        f"store      {info.path} (schema {info.schema_version}, {info.size_bytes / 1e6:.3f} MB)",
        f"site       {info.site_name} (tag map {info.tag_map_hash[:12]})",
        f"rows       {info.rows} ({quality})",
        f"span       {stamp(info.t_first)} … {stamp(info.t_last)} ({info.span_s:.3f} s)",
        f"gaps       {info.gaps} ({info.missing_samples} samples missing in sequence gaps)",
        f"link       {info.events.get('link_down', 0)} down, {info.events.get('link_up', 0)} up",
        f"events     {events}",
    ]
    typer.echo("\n".join(lines))
