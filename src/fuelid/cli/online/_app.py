"""The ``fuelid online`` command group, and the options its commands share."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from fuelid.errors import ConfigError

if TYPE_CHECKING:
    from fuelid.online import ServiceSite
    from fuelid.store import OnlineHistory, SQLiteStore

app = typer.Typer(
    invoke_without_command=True,
    rich_markup_mode=None,
)

ConfigFile = Annotated[
    Path | None,
    typer.Option(
        "--config",
        "-c",
        metavar="SITE.toml",
        help="The site file (its [store] url is the store unless --store is given).",
        show_default=False,
    ),
]
StoreFile = Annotated[
    Path | None,
    typer.Option(
        "--store",
        metavar="FILE.db",
        help="The store (an SQLite file); default the site file's [store] url.",
        show_default=False,
    ),
]
JsonFlag = Annotated[bool, typer.Option("--json", help="Print one JSON object.")]
ProposalId = Annotated[int, typer.Argument(metavar="ID", help="The proposal's id.")]
WhoOption = Annotated[
    str | None,
    typer.Option("--who", metavar="NAME", help="Who decides (default: the OS user name).",
                 show_default=False),
]  # fmt: skip
WhyOption = Annotated[
    str, typer.Option("--why", metavar="TEXT", help="Why, one line (kept in the history).")
]


def _store_path(url: str) -> Path:
    _, sep, location = url.partition(":///")
    return Path(location if sep else url)


@contextmanager
def _opened(
    config: Path | None, store: Path | None
) -> Iterator[tuple[SQLiteStore, OnlineHistory, dict[str, Any]]]:
    """The store and its history (read from --store, or the site file's), and the settings."""
    from fuelid.store import OnlineHistory, SQLiteStore, StoreError

    if config is None and store is None:
        raise ConfigError("give --config SITE.toml or --store FILE.db")
    settings: dict[str, Any] = {}
    identity: dict[str, Any] | None = None
    path = store
    if config is not None:
        from fuelid.online import load_service_site
        from fuelid.plc import site_identity

        site = load_service_site(config)
        identity = site_identity(site)
        settings = _settings(site)
        if path is None:
            path = _store_path(site.store.url)
    assert path is not None
    if not path.is_file():
        raise StoreError(f"{path}: no such store (run fuelid online --config SITE.toml first)")
    opened = SQLiteStore(path)
    try:
        if identity is not None and (opened.site_name, opened.tag_map_hash) != (
            identity["site_name"],
            identity["tag_map_hash"],
        ):
            raise StoreError(
                f"{path}: the store belongs to site {opened.site_name!r} (tag map "
                f"{opened.tag_map_hash[:12]}), not {identity['site_name']!r} (tag map "
                f"{str(identity['tag_map_hash'])[:12]})"
            )
        with OnlineHistory(opened) as history:
            yield opened, history, settings
    finally:
        opened.close()


def _settings(site: ServiceSite) -> dict[str, Any]:
    from fuelid.tuning import BlockForm, block_units

    out: dict[str, Any] = {"write_back": site.online.write_back, "timezone": site.site.timezone}
    c = site.controller
    if c is not None:
        out["gains_units"] = block_units(BlockForm.of(c))
        out["controller"] = c
    return out


def _options(config: Path | None, store: Path | None, **more: Any) -> dict[str, Any]:
    return {
        "config": None if config is None else str(config),
        "store": None if store is None else str(store),
        **more,
    }
