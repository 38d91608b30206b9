"""``fuelid dashboard user …``: who may log in to the dashboard, and with which role.

``add`` and ``rotate`` print a new token once: only its SHA-256 is stored, so it cannot be shown
again (rotate it if it is lost). The users file is JSON with mode 0600
(docs/how-to/dashboard-security.md). Only the standard library is needed here, not the
``dashboard`` extra.
"""

from __future__ import annotations

import enum
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated

import typer

from fuelid.cli._common import emit_json, guarded

DEFAULT_USERS_FILE = Path("dashboard-users.json")
"""The users file when ``--users`` is not given: in the current folder."""


class Role(enum.StrEnum):
    """A dashboard role."""

    viewer = "viewer"
    engineer = "engineer"


UsersOption = Annotated[
    Path,
    typer.Option(
        "--users",
        metavar="FILE",
        help="The users file (JSON, mode 0600) [default: dashboard-users.json in the current "
        "folder].",
        show_default=False,
    ),
]
NameArgument = Annotated[
    str, typer.Argument(metavar="NAME", help="The user's name: 1-64 letters, digits, . _ -.")
]

user_app = typer.Typer(
    help="Dashboard users: add, remove, rotate a token, list.",
    no_args_is_help=True,
    rich_markup_mode=None,
)


def _show_token(name: str, token: str, what: str) -> None:
    typer.echo(f"{what} {name}; their token (give it to them now):")
    typer.echo(token)
    typer.echo("The token is not stored (only its SHA-256) and cannot be shown again.")


@user_app.command("add")
@guarded
def add(
    name: NameArgument,
    role: Annotated[
        Role, typer.Option("--role", help="viewer: sees every page; engineer: also acts.")
    ],
    users: UsersOption = DEFAULT_USERS_FILE,
) -> None:
    """Add a user with a new random token (the file is created if missing)."""
    from fuelid.dashboard import UsersFile

    token = UsersFile(users).add(name, role.value)
    _show_token(name, token, f"added {role.value}")


@user_app.command("remove")
@guarded
def remove(name: NameArgument, users: UsersOption = DEFAULT_USERS_FILE) -> None:
    """Remove a user: their token stops working, their open sessions end."""
    from fuelid.dashboard import UsersFile

    UsersFile(users).remove(name)
    typer.echo(f"removed {name}")


@user_app.command("rotate")
@guarded
def rotate(name: NameArgument, users: UsersOption = DEFAULT_USERS_FILE) -> None:
    """Give a user a new token: the old one stops working, their open sessions end."""
    from fuelid.dashboard import UsersFile

    token = UsersFile(users).rotate(name)
    _show_token(name, token, "rotated the token of")


@user_app.command("list")
@guarded
def list_users(
    users: UsersOption = DEFAULT_USERS_FILE,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """List the users with their roles and when their token was made (never a token)."""
    from fuelid.dashboard import UsersFile

    records = UsersFile(users).records()
    if as_json:
        emit_json(
            {
                "users": [
                    {
                        "name": r.name,
                        "role": r.role,
                        "created": r.created,
                        "rotated": r.rotated,
                    }
                    for r in records
                ],
                "units": {"created": "s since 1970-01-01 UTC", "rotated": "s since 1970-01-01 UTC"},
            }
        )
        return
    if not records:
        typer.echo(f"no users in {users}")
        return
    width = max(len("name"), *(len(r.name) for r in records))
    typer.echo(f"{'name':<{width}}  {'role':<8}  {'created (UTC)':<16}  rotated (UTC)")
    for r in records:
        rotated = _utc(r.rotated) if r.rotated is not None else "-"
        typer.echo(f"{r.name:<{width}}  {r.role:<8}  {_utc(r.created):<16}  {rotated}")


def _utc(t: float) -> str:
    """A wall-clock time [s UTC] as ``YYYY-MM-DD HH:MM``."""
    return datetime.fromtimestamp(t, UTC).strftime("%Y-%m-%d %H:%M")
