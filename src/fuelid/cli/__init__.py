"""The ``fuelid`` command line: thin typer commands over the library.

Exit codes: 0 success; 2 bad input, refused data or usage (one-line reason on stderr);
1 unexpected internal error.
"""

from __future__ import annotations

import sys

import typer

from fuelid import __version__
from fuelid.cli import _central, _dashboard, _plant, _site, online
from fuelid.cli._archive import archive_command
from fuelid.cli._calibrate import calibrate_command
from fuelid.cli._greybox import greybox_command
from fuelid.cli._identify import identify_command
from fuelid.cli._record import export_command, record_command, store_app
from fuelid.cli._reidentify import reidentify_command
from fuelid.cli._report import report_command
from fuelid.cli._simulate import simulate_command
from fuelid.cli._tune import tune_command
from fuelid.errors import FuelidError, plain_reason

app = typer.Typer(
    name="fuelid",
    help="Gray-box modelling, identification and PI tuning of VFD-pump-pipeline fuel flow loops.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
    rich_markup_mode=None,  # help texts carry units in brackets: [s], [V] are not markup
)
app.add_typer(_plant.app, name="plant")
app.add_typer(_site.app, name="site")
app.command("simulate")(simulate_command)
app.command("identify")(identify_command)
app.command("calibrate")(calibrate_command)
app.command("greybox")(greybox_command)
app.command("tune")(tune_command)
app.command("report")(report_command)
app.command("record")(record_command)
app.command("export")(export_command)
app.command("archive")(archive_command)
app.add_typer(store_app, name="store")
app.add_typer(online.app, name="online")
app.add_typer(_dashboard.app, name="dashboard")
app.add_typer(_central.app, name="central")
app.command("reidentify")(reidentify_command)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"fuelid {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="Print the version and exit."
    ),
) -> None:
    """Gray-box modelling, identification and PI tuning of fuel flow loops."""


def main(argv: list[str] | None = None) -> int:
    """Console entry point: every failure becomes a one-line message and an exit code."""
    command = typer.main.get_command(app)
    try:
        code = command.main(args=argv, prog_name="fuelid", standalone_mode=False)
    except FuelidError as exc:  # raised outside a guarded command
        typer.echo(f"error: {' '.join(str(exc).split())}", err=True)
        return 2
    except (typer.Abort, KeyboardInterrupt):
        typer.echo("error: aborted", err=True)
        return 2
    except Exception as exc:
        # usage errors (unknown option, bad value) of the click that typer carries: they have an
        # exit code of 2 and a format_message(); recognised by shape, not by a private class
        if getattr(exc, "exit_code", None) == 2 and hasattr(exc, "format_message"):
            message = plain_reason(exc.format_message())
            typer.echo(f"error: {' '.join(message.split())}", err=True)
            return 2
        typer.echo(f"internal error: {type(exc).__name__}: {exc}", err=True)
        return 1
    return int(code) if isinstance(code, int) else 0


def run() -> None:
    """Entry point of the ``fuelid`` script."""
    sys.exit(main())


if __name__ == "__main__":  # pragma: no cover
    run()
