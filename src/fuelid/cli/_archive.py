"""``fuelid archive``: a store's finished days as hive-partitioned Parquet (the raw archive).

Parses, calls :func:`fuelid.archive._writer.archive_store` and prints a table or one JSON
object; every failure is one line on stderr and exit code 2.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from fuelid.cli._common import emit_json, guarded, provenance
from fuelid.errors import DataError


@guarded
def archive_command(
    store: Annotated[
        Path,
        typer.Option("--store", metavar="FILE.db", help="The store to archive (an SQLite file)."),
    ],
    to: Annotated[
        Path,
        typer.Option(
            "--to",
            metavar="DIR",
            help="The archive folder (created when absent; local or a mounted share).",
        ),
    ],
    before: Annotated[
        str | None,
        typer.Option(
            "--before",
            metavar="DATE",
            help="Archive the UTC days before this date, YYYY-MM-DD (default: every finished "
            "day, i.e. before the day of the store's newest sample).",
            show_default=False,
        ),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Write a store's raw samples and events, one Parquet file per loop and UTC day.

    Layout DIR/samples/loop=ID/date=YYYY-MM-DD/UUID.parquet (and events/, loops/ID/ with the
    loop's settings and plant file), zstd-compressed, readable by pandas, pyarrow, DuckDB and
    Dask. Each file is written whole, read back, then renamed into place, and only then is
    the day recorded in the store, so retention with an [archive] table deletes only what
    is archived. Archiving again changes nothing; a day thinned since keeps its raw rows.
    """
    from fuelid.archive import archive_store
    from fuelid.store import SQLiteStore

    if not store.exists():
        raise DataError(f"{store}: no such store")
    if store.is_dir():
        raise DataError(f"{store}: a folder, not a store file")
    with SQLiteStore(store) as opened:
        report = archive_store(opened, to, before)
    if as_json:
        options = {"store": str(store), "to": str(to), "before": before}
        emit_json(report.to_json() | provenance(options))
        return
    lines = [f"{'date':<10}  {'rows':>9}  {'MB':>8}  {'store MB':>8}  {'ratio':>6}  written"]
    for day in report.days:
        ratio = day.store_bytes / day.parquet_bytes if day.parquet_bytes else float("nan")
        lines.append(
            f"{day.date:<10}  {day.rows:>9}  {day.parquet_bytes / 1e6:>8.3f}  "
            f"{day.store_bytes / 1e6:>8.3f}  {ratio:>6.1f}  {'yes' if day.written else 'no'}"
        )
    if not report.days:
        # a trial within one UTC day: the day being recorded is not finished, so not archived
        lines = [
            f"no finished day of loop {report.loop_id} before {report.before or '-'}: nothing "
            f"archived ({report.root}); --before YYYY-MM-DD takes the days before that date, "
            "the day still being recorded as far as it goes"
        ]
    else:
        ratio = report.store_bytes / report.parquet_bytes if report.parquet_bytes else math.nan
        shrink = f", {ratio:.1f}x smaller than the store's share" if ratio == ratio else ""
        lines.append(
            f"{len(report.days)} day(s) of loop {report.loop_id} before {report.before or '-'}: "
            f"{report.rows} rows, {report.parquet_bytes / 1e6:.3f} MB of Parquet "
            f"({report.bytes_written / 1e6:.3f} MB written){shrink}, {report.seconds:.2f} s, "
            f"in {report.root}"
        )
    if report.plant_note:
        lines.append(f"plant file: {report.plant_note}")
    typer.echo("\n".join(lines))
