"""``fuelid reidentify``: the online service's window analysis over archived history, on Dask.

Parses the options, calls :func:`fuelid.fleet._run.reidentify` and prints the per-loop summary
table (or, with ``--json``, one JSON object). A progress bar on stderr while the loop-days run
(on a terminal, unless ``--quiet`` or ``--json``).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from fuelid.cli._common import emit_json, guarded, provenance

if TYPE_CHECKING:
    from collections.abc import Callable, Iterator


def _progress(quiet: bool) -> Any:
    """A context manager yielding the run's progress callback (a rich bar on a terminal)."""
    from contextlib import contextmanager

    from rich.console import Console

    @contextmanager
    def bar() -> Iterator[Callable[[int, int, dict[str, Any] | None], None]]:
        console = Console(stderr=True)
        if quiet or not console.is_terminal:
            yield lambda done, total, summary: None
            return
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        display = Progress(
            TextColumn("loop-days"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            console=console,
        )
        task = display.add_task("loop-days", total=None)

        def update(done: int, total: int, summary: dict[str, Any] | None) -> None:
            display.update(task, completed=done, total=total)

        with display:
            yield update

    return bar()


def _number(value: float | None, fmt: str) -> str:
    return "-" if value is None else format(value, fmt)


def _table(loops: list[dict[str, Any]]) -> list[str]:
    lines = [
        f"{'loop':<16} {'days':>5} {'windows':>8} {'accepted':>9} {'K drift':>18}  "
        "K(T) slope [95 % interval]"
    ]
    for s in loops:
        share = _number(None if s["accepted_share"] is None else 100 * s["accepted_share"], ".1f")
        drift = (
            "-"
            if s["k_drift"] is None
            else f"{100 * s['k_drift']:+.2f} ± {100 * s['k_drift_se']:.2f} %"
        )
        slope = "-"
        if s["k_slope"] is not None:
            lo, hi = s["k_slope_ci95"]
            slope = f"{s['k_slope']:+.4g} [{lo:+.4g}, {hi:+.4g}] {s['k_slope_unit']}"
        lines.append(
            f"{s['loop_id']:<16} {s['loop_days']:>5} {s['windows']:>8} {share + ' %':>9} "
            f"{drift:>18}  {slope}"
        )
    return lines


@guarded
def reidentify_command(
    archive: Annotated[
        Path,
        typer.Argument(metavar="DIR", help="The archive (samples/loop=…/date=…/*.parquet)."),
    ],
    loops: Annotated[
        str | None,
        typer.Option(
            "--loops", metavar="ID,ID", help="Comma-separated loop ids (default: every loop)."
        ),
    ] = None,
    date_from: Annotated[
        str | None,
        typer.Option("--from", metavar="DATE", help="First UTC date, YYYY-MM-DD (inclusive)."),
    ] = None,
    date_to: Annotated[
        str | None,
        typer.Option("--to", metavar="DATE", help="Last UTC date, YYYY-MM-DD (inclusive)."),
    ] = None,
    settings: Annotated[
        Path | None,
        typer.Option(
            "--settings",
            metavar="ONLINE.toml",
            help="A TOML file whose [online] table replaces every loop's archived settings.",
        ),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(
            "--scheduler",
            metavar="ADDRESS",
            help="A running Dask scheduler (tcp://host:8786); default a local cluster.",
        ),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(
            "--workers",
            min=1,
            metavar="N",
            help="Worker processes of the local cluster (default: cores).",
        ),
    ] = None,
    out: Annotated[
        Path,
        typer.Option("--out", metavar="RESULT", help="The result folder (resumable)."),
    ] = Path("reidentified"),
    central: Annotated[
        str | None,
        typer.Option(
            "--central",
            metavar="URL",
            help="Also send the results to the central store (postgresql://…; no password: "
            "PGPASSWORD, ~/.pgpass or a service file).",
        ),
    ] = None,
    json_output: Annotated[
        bool, typer.Option("--json", help="Print the summary as one JSON object.")
    ] = False,
    quiet: Annotated[bool, typer.Option("--quiet", help="No progress bar.")] = False,
) -> None:
    """Re-identify archived history with the online service's gates and estimators, on Dask.

    One task per loop-day (the windows looped inside, each day starting cold), results to
    RESULT/windows/loop=<id>/date=<d>/part.parquet (a finished loop-day is skipped when run
    again), the K(T) tracker per loop to RESULT/tracking/<id>.json, and a summary per loop:
    accepted share, K drift over the period, K(T) slope with its 95 % interval.
    """
    from fuelid.errors import FuelidError
    from fuelid.fleet import online_from_toml, reidentify

    if scheduler is not None and workers is not None:
        raise FuelidError("give --scheduler or --workers, not both")
    online = None if settings is None else online_from_toml(settings)
    loop_ids = None if loops is None else [x.strip() for x in loops.split(",") if x.strip()]
    with _progress(quiet or json_output) as progress:
        run = reidentify(
            archive,
            out,
            loops=loop_ids,
            date_from=date_from,
            date_to=date_to,
            online=online,
            settings_source="" if settings is None else f"--settings {settings}",
            scheduler=scheduler,
            workers=workers,
            progress=progress,
            central=central,
        )
    if json_output:
        options = {
            "loops": loop_ids,
            "from": date_from,
            "to": date_to,
            "settings": None if settings is None else str(settings),
            "scheduler": scheduler,
            "workers": workers,
            "central": None if run.central is None else run.central["url"],
        }
        emit_json({**run.to_json(), "provenance": provenance(options)})
        return
    typer.echo(
        f"{run.loop_days} loop-day(s): {run.computed} computed, {run.skipped} already done; "
        f"{run.windows} window(s) in {run.seconds:.1f} s on {run.workers} worker(s) "
        f"({run.scheduler}); results in {run.out}"
    )
    for line in _table(run.loops):
        typer.echo(line)
    if run.central is not None:
        typer.echo(
            f"sent to {run.central['url']}: {run.central['loop_days']} loop-day(s), "
            f"{run.central['windows']} window(s)"
        )
