"""``fuelid online [--virtual]``: run the service in the foreground, log lines and a live status.

The log lines are the ``fuelid.online`` logger's records (:mod:`fuelid.online._logs`), printed
on stderr by a handler with the key=value or the JSON formatter; the live status line on a
terminal is a :class:`rich.live.Live` redrawn in place under them, into a file or a pipe a
status line every ``QUIET_STATUS_EVERY_S``.
"""

from __future__ import annotations

import logging
import math
import sys
import time
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from fuelid.cli._common import guarded
from fuelid.cli._serve import ServeProtocol
from fuelid.errors import ConfigError, validation_reason

if TYPE_CHECKING:
    from fuelid.online import OnlineService, ServiceSite

from fuelid.cli.online._app import ConfigFile, StoreFile, app
from fuelid.online import (
    LOGGER_NAME,
    JsonLineFormatter,
    KeyValueFormatter,
    Quoted,
    log_event,
)

if TYPE_CHECKING:
    from rich.live import Live

# --- running the service --------------------------------------------------------------------


VIRTUAL_STORE = Path("fuelid-online-virtual.db")
"""The store of ``fuelid online --virtual`` without ``--store`` (in the current folder)."""
PLC_HEARTBEAT_TIMEOUT_S = 10.0
"""The virtual PLC's heartbeat timeout [s of plant time]."""
QUIET_STATUS_EVERY_S = 10.0
"""Status line interval when stderr is not a terminal [s]."""


class _Console(logging.Handler):
    """The service's log records and the live status line on stderr.

    The records are formatted by :class:`~fuelid.online._logs.KeyValueFormatter` (``online:
    word key=value …``) or, with ``--json-log``, :class:`~fuelid.online._logs.JsonLineFormatter`.
    On a terminal the status line is a :class:`rich.live.Live` display redrawn under the log
    lines; otherwise it is logged every :data:`QUIET_STATUS_EVERY_S` (``{"event": "status",
    "line": …}`` with ``--json-log``, the bare line after ``online:`` without).
    """

    def __init__(self, json_log: bool) -> None:
        super().__init__(logging.INFO)
        self.json_log = json_log
        self.tty = sys.stderr.isatty() and not json_log
        self.setFormatter(JsonLineFormatter() if json_log else KeyValueFormatter("online: "))
        self.logger = logging.getLogger(LOGGER_NAME)
        self._level = self.logger.level
        self._last = -math.inf
        self._live: Live | None = None
        self.logger.addHandler(self)
        self.logger.setLevel(logging.INFO)

    def emit(self, record: logging.LogRecord) -> None:
        """Print one record on stderr (above the live status line, if shown)."""
        try:
            text = self.format(record)
            if self._live is not None:
                self._live.console.print(text, markup=False, highlight=False, soft_wrap=True)
            else:
                typer.echo(text, err=True)
        except Exception:  # a handler must not raise into the service: logging's own policy
            self.handleError(record)

    def status(self, line: str) -> None:
        """Show the status line: redrawn in place on a terminal, else logged now and then."""
        if self.tty:
            from rich.console import Console
            from rich.live import Live
            from rich.text import Text

            text = Text(line, no_wrap=True, overflow="ellipsis")  # one line, redrawn in place
            if self._live is None:
                self._live = Live(
                    text, console=Console(stderr=True), auto_refresh=False, transient=True
                )
                self._live.start()
            self._live.update(text, refresh=True)
        elif time.monotonic() - self._last >= QUIET_STATUS_EVERY_S:
            self._last = time.monotonic()
            if self.json_log:
                log_event(self.logger, "status", line=line)
            else:
                self.logger.info(line)

    def close(self) -> None:
        """Remove the status line and stop handling the service's records."""
        if self._live is not None:
            self._live.stop()
            self._live = None
        self.logger.removeHandler(self)
        self.logger.setLevel(self._level)
        super().close()


VIRTUAL_SITE_KEYS = ("name", "loop_id", "plant", "timezone")
"""The ``[site]`` keys --virtual takes from --config (the PLC's address and tags are its own)."""


def _virtual_tables(config: Path | None) -> dict[str, Any]:
    """The tables --virtual takes from --config; without it, write_back "auto".

    ``[online]``, ``[central]``, ``[archive]``, ``[excitation]`` and the ``[site]`` keys of
    :data:`VIRTUAL_SITE_KEYS`, paths made absolute from the file's folder.
    """
    if config is None:
        return {"online": {"write_back": "auto"}, "site": {}}
    import tomllib

    from pydantic import ValidationError

    from fuelid.online import Online
    from fuelid.plc import Archive, Central
    from fuelid.plc.site import Excitation

    try:
        data = tomllib.loads(config.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"site file {str(config)!r} does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read site file {str(config)!r}: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{config}: not valid TOML ({exc})") from None
    tables: dict[str, Any] = {}
    tables_of = (
        ("online", Online), ("central", Central), ("archive", Archive), ("excitation", Excitation)
    )  # fmt: skip
    for name, model in tables_of:
        table = data.get(name, {} if name == "online" else None)
        if table is None:
            continue
        if not isinstance(table, dict):
            raise ConfigError(f"{config}: [{name}] must be a table")
        try:
            model.model_validate(table)
        except ValidationError as exc:
            first = exc.errors()[0]
            where = ".".join(str(p) for p in first["loc"])
            message = validation_reason(first)
            reason = f"{config}: {name}.{where}: {message}" if where else message
            raise ConfigError(reason) from None
        tables[name] = dict(table)
    site = data.get("site", {})
    if not isinstance(site, dict):
        raise ConfigError(f"{config}: [site] must be a table")
    tables["site"] = {key: site[key] for key in VIRTUAL_SITE_KEYS if key in site}
    _check_site_keys(config, tables["site"])
    folder = config.resolve().parent
    if "plant" in tables["site"]:
        tables["site"]["plant"] = str(folder / str(tables["site"]["plant"]))
    if "archive" in tables:
        tables["archive"]["dir"] = str(folder / str(tables["archive"]["dir"]))
    return tables


def _check_site_keys(config: Path, site: dict[str, Any]) -> None:
    """The ``[site]`` keys --virtual takes, checked here so that an error names the user's file.

    They are merged into a site file of the command's own making (in a temporary folder), whose
    name would mean nothing to the user (issue 39).
    """
    from pydantic import ValidationError

    from fuelid.plc.site import SiteInfo

    try:
        SiteInfo.model_validate({"name": "virtual fuel loop", **site})
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        raise ConfigError(f"{config}: site.{where}: {validation_reason(first)}") from None


def _virtual_site_text(base: str, tables: dict[str, Any]) -> str:
    """The virtual PLC's site file with the tables --config gives merged in."""
    import tomllib

    import tomlkit

    data = tomllib.loads(base)
    data["site"].update(tables.get("site", {}))
    for name in ("online", "central", "archive", "excitation"):
        if name in tables:
            data[name] = tables[name]
    return tomlkit.dumps(data)


def check_window_length(site: ServiceSite) -> None:
    """Refuse a missing plant file or an ``[online] window_s`` shorter than its settling time."""
    from fuelid.online import check_site_plant

    check_site_plant(site.site.plant, site.online.window_s)


def _run_service(
    service: OnlineService, duration: float | None, console: _Console
) -> tuple[Any, float]:
    import asyncio

    async def main() -> Any:
        task = asyncio.create_task(service.run(duration))
        while not task.done():
            if service.recorder is not None:
                console.status(service.stats.line())
            await asyncio.wait({task}, timeout=0.5)
        return task.result()

    started = time.monotonic()
    stats = asyncio.run(main())  # the caller closes the console, also after a failure
    return stats, time.monotonic() - started


def _summary(stats: Any, wall_s: float, target: str) -> None:
    recorder = stats.recorder
    stored = recorder.stored if recorder is not None else 0
    typer.echo(
        f"online: stopped after {wall_s:.1f} s: {stats.windows} windows ({stats.accepted} "
        f"accepted), {stats.proposals} proposals, {stats.writes} writes, {stats.reverts} "
        f"reverts; {stored} samples stored"
    )
    path = target.removeprefix("sqlite:///")  # --store takes the file, not the site's URL
    typer.echo(f"store: {path} (fuelid online status --store {path})")


def _heartbeat_s(speed: float) -> float:
    """Wall time between heartbeats: well inside the PLC's timeout at the speed-up [s]."""
    return min(1.0, 0.25 * PLC_HEARTBEAT_TIMEOUT_S / speed)


def _start(
    site: ServiceSite,
    target: str,
    duration: float | None,
    json_log: bool,
    heartbeat_s: float = 1.0,
    dashboard_port: int | None = None,
) -> None:
    import contextlib

    from fuelid.online import OnlineService

    check_window_length(site)
    for line in site.missing():
        typer.echo(f"online: the site file does not expose {line}", err=True)
    console = _Console(json_log)
    try:
        service = OnlineService(site, target, heartbeat_s=heartbeat_s)
    except BaseException:
        console.close()
        raise
    try:
        log_event(
            console.logger,
            "config",
            site=Quoted(site.site.name),
            store=Quoted(target),
            every_s=f"{site.online.identify_every_s:g}",
            window_s=f"{site.online.window_s:g}",
            write_back=site.online.write_back,
        )
        with contextlib.ExitStack() as beside:
            if dashboard_port is not None:
                from fuelid.dashboard import Beside

                beside.enter_context(Beside(service.store.path, dashboard_port))
            stats, wall = _run_service(service, duration, console)
    finally:
        console.close()
        service.close()
    _summary(stats, wall, target)


class SetpointScript(StrEnum):
    """What the virtual PLC's operator does with the setpoint."""

    runs = "runs"
    steady = "steady"


STEADY_COMMAND_V = 3.0
"""``--setpoint steady`` holds the flow the plant gives at this command and 20 °C [V]."""


@dataclass(frozen=True)
class VirtualLoop:
    """The virtual loop ``fuelid online --virtual`` runs against (its options)."""

    speed: float = 50.0
    hours: float = 24.0
    protocol: ServeProtocol = ServeProtocol.modbus
    seed: int = 1
    setpoint: SetpointScript = SetpointScript.runs
    excitation_limit_V: float = 0.5
    runs: tuple[tuple[float, float], ...] = ()


def _setpoint_profile(script: SetpointScript, plant_config: Any) -> Any:
    """The demo's wind-tunnel runs, or one setpoint held (the flow at 3 V and 20 °C)."""
    from fuelid.profiles.runs import demo_run_profile

    if script is SetpointScript.runs:
        return demo_run_profile()
    from fuelid.plant import load_plant_config
    from fuelid.tuning.closedloop import flow_at
    from fuelid.units import celsius_to_kelvin

    config = plant_config if plant_config is not None else load_plant_config()
    flow = round(flow_at(config, STEADY_COMMAND_V, celsius_to_kelvin(20.0)), 1)
    return ([0.0, 1.0], [flow, flow])


def _run_virtual(
    config: Path | None,
    store: Path | None,
    duration: float | None,
    json_log: bool,
    loop: VirtualLoop,
    dashboard_port: int | None = None,
) -> None:
    import tempfile
    from importlib import resources

    from fuelid.online import load_service_site
    from fuelid.plc.virtual import VirtualPlcThread
    from fuelid.profiles.runs import demo_temperature

    speed, hours, protocol = loop.speed, loop.hours, loop.protocol
    if not (math.isfinite(speed) and 0.0 < speed <= 1000.0):
        raise ConfigError(f"--speed must be within (0, 1000], got {speed:g}")
    if not (math.isfinite(hours) and hours > 0.0):
        raise ConfigError(f"--hours must be a positive number of hours, got {hours:g}")
    tables = _virtual_tables(config)
    plant_s = hours * 3600.0
    wall = plant_s / speed if duration is None else duration
    path = VIRTUAL_STORE if store is None else store
    if store is None and path.exists():
        typer.echo(f"online: replacing the demo store {path}", err=True)
        for suffix in ("", "-wal", "-shm"):
            Path(f"{path}{suffix}").unlink(missing_ok=True)
    target = str(path.resolve())
    plant_path = tables["site"].get("plant")
    plant_config = None
    if plant_path is None:
        plant = resources.files("fuelid.data").joinpath("reference_plant.toml")
        plant_path = str(plant) if Path(str(plant)).is_file() else None
    else:  # the virtual PLC simulates the loop's own plant file, the service anchors on it
        from fuelid.plant import load_plant_config

        plant_config = load_plant_config(plant_path)
    times, temperatures = demo_temperature(plant_s)
    with (
        VirtualPlcThread(
            protocol.value,
            speed=speed,
            seed=loop.seed,
            config=plant_config,
            setpoint_profile=_setpoint_profile(loop.setpoint, plant_config),
            fuel_temp_profile=(times, temperatures),
            excitation_limit_V=loop.excitation_limit_V,
            run_windows=list(loop.runs),
        ) as virtual,
        tempfile.TemporaryDirectory(prefix="fuelid-online-") as folder,
    ):
        text = virtual.site_text(store_url=f"sqlite:///{target}", plant=plant_path)
        site_path = Path(folder) / "virtual-site.toml"
        site_path.write_text(_virtual_site_text(text, tables), encoding="utf-8")
        site = load_service_site(site_path)
        typer.echo(
            f"online: virtual PLC ({protocol.value} on {virtual.host}:{virtual.port}), "
            f"{speed:g}x real time, {hours:g} h of plant time in {wall:.1f} s",
            err=True,
        )
        _start(
            site,
            target,
            wall,
            json_log,
            heartbeat_s=_heartbeat_s(speed),
            dashboard_port=dashboard_port,
        )


@app.callback()
@guarded
def online_command(
    ctx: typer.Context,
    config: ConfigFile = None,
    store: StoreFile = None,
    duration: Annotated[
        float | None,
        typer.Option(
            metavar="SECONDS",
            help="Stop after this long [s of wall time] (default: until Ctrl-C or SIGTERM; "
            "with --virtual, --hours of plant time).",
            show_default=False,
        ),
    ] = None,
    json_log: Annotated[
        bool, typer.Option("--json-log", help="Log lines on stderr as JSON objects.")
    ] = False,
    virtual: Annotated[
        bool,
        typer.Option(
            "--virtual",
            help="Run against a virtual PLC started in the same command (AUTO wind-tunnel runs, "
            "fuel −10…+45 °C over 24 h); --config then gives the [online], [central], "
            "[archive] and [excitation] tables and [site] name, loop_id, plant (the plant the "
            "virtual PLC simulates) and timezone.",
        ),
    ] = False,
    seed: Annotated[
        int, typer.Option(help="--virtual: the virtual PLC's noise seed (one per loop).")
    ] = 1,
    speed: Annotated[
        float,
        typer.Option(
            help="--virtual: plant time per wall time (≤ 1000; above ~50 a busy 2-core machine "
            "loses samples: the gaps are counted and such windows rejected)."
        ),
    ] = 50.0,
    hours: Annotated[float, typer.Option(help="--virtual: plant time to run [h].")] = 24.0,
    protocol: Annotated[
        ServeProtocol, typer.Option("--protocol", help="--virtual: the PLC's protocol.")
    ] = ServeProtocol.modbus,
    setpoint: Annotated[
        SetpointScript,
        typer.Option(
            "--setpoint",
            help="--virtual: runs: the demo's wind-tunnel runs (setpoint moves); steady: AUTO "
            "at one setpoint (the flow at 3 V), a loop that sits still (try [excitation]).",
        ),
    ] = SetpointScript.runs,
    excitation_limit: Annotated[
        float,
        typer.Option(
            "--excitation-limit",
            metavar="V",
            help="--virtual: the PLC's own clamp of the test signal [V].",
        ),
    ] = 0.5,
    run: Annotated[
        list[str] | None,
        typer.Option(
            "--run",
            metavar="START:END",
            help="--virtual: the PLC raises its run flag (tags.run) over this span of plant "
            "time [s]; repeatable.",
            show_default=False,
        ),
    ] = None,
    dashboard: Annotated[
        bool,
        typer.Option(
            "--dashboard",
            help="Also start fuelid dashboard on the store, as a process of its own, on "
            "http://127.0.0.1:8050/ (stopped with the service).",
        ),
    ] = False,
    dashboard_port: Annotated[
        int,
        typer.Option(
            "--dashboard-port", min=0, max=65535, help="--dashboard: its port (0: a free one)."
        ),
    ] = 8050,
) -> None:
    """Run the online service in the foreground (or, with a subcommand, look at its store).

    Records as fuelid record does and every [online] identify_every_s of data time identifies
    the last window_s, gates it, tracks K against fuel temperature and proposes PI gains; with
    write_back "approve" or "auto" it writes approved gains and checks the PLC's echo. Log lines
    (key=value, or JSON with --json-log) and a status line go to stderr; Ctrl-C or SIGTERM stop
    it cleanly, a summary goes to stdout. --virtual writes to fuelid-online-virtual.db (replaced)
    unless --store is given.
    """
    if ctx.invoked_subcommand is not None:
        return
    if duration is not None and not (math.isfinite(duration) and duration > 0.0):
        raise ConfigError(f"--duration must be a positive number of seconds, got {duration:g}")
    port = dashboard_port if dashboard else None
    if virtual:
        from fuelid.cli._serve import parse_run_windows

        if not (math.isfinite(excitation_limit) and excitation_limit > 0.0):
            raise ConfigError(
                f"--excitation-limit must be a positive number of V, got {excitation_limit:g}"
            )
        loop = VirtualLoop(
            speed, hours, protocol, seed, setpoint, excitation_limit,
            tuple(parse_run_windows(run or [])),
        )  # fmt: skip
        _run_virtual(config, store, duration, json_log, loop, port)
        return
    if config is None:
        raise ConfigError(
            "give --config SITE.toml (the site file of the loop), or --virtual for the demo; "
            "subcommands: status, history, approve, reject, revert"
        )
    from fuelid.online import load_service_site

    site = load_service_site(config)
    target = str(store) if store is not None else site.store.url
    _start(site, target, duration, json_log, dashboard_port=port)


# --- the store ------------------------------------------------------------------------------
