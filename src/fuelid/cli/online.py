"""``fuelid online``: the online service at the command line, and what it has done.

``fuelid online --config SITE.toml`` runs the service in the foreground (records as ``fuelid
record``, identifies a gated window every ``identify_every_s`` of data time, tracks K(T),
proposes PI gains, writes them when the site allows), with structured log lines and a status
line on stderr; Ctrl-C or SIGTERM stop it cleanly. ``--virtual`` starts the virtual PLC in the
same command (AUTO, wind-tunnel runs, the fuel cycling −10…+45 °C over a day) at a speed-up, so
the whole adaptive story plays in minutes.

``status``, ``history``, ``approve``, ``reject`` and ``revert`` read or mark the store (its
SQLite file is shared with a running service: every change is committed at once). Every failure
is one line on stderr and exit code 2.
"""

from __future__ import annotations

import getpass
import json
import math
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from fuelid.cli._common import check_figure_path, emit_json, guarded, provenance
from fuelid.cli.serve import ServeProtocol
from fuelid.errors import ConfigError

if TYPE_CHECKING:
    from fuelid.online.service import OnlineService
    from fuelid.plc.site import SiteConfig
    from fuelid.store.online import OnlineHistory
    from fuelid.store.sqlite import SQLiteStore

app = typer.Typer(
    invoke_without_command=True,
    rich_markup_mode=None,
)

VIRTUAL_STORE = Path("fuelid-online-virtual.db")
"""The store of ``fuelid online --virtual`` without ``--store`` (in the current folder)."""
PLC_HEARTBEAT_TIMEOUT_S = 10.0
"""The virtual PLC's heartbeat timeout [s of plant time]."""
QUIET_STATUS_EVERY_S = 10.0
"""Status line interval when stderr is not a terminal [s]."""
RECENT_WINDOWS = 20
"""Windows listed by ``fuelid online history`` without ``--json``."""

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


# --- running the service --------------------------------------------------------------------


class _Console:
    """Log lines and the live status line on stderr (the status redrawn in place on a terminal)."""

    def __init__(self, json_log: bool) -> None:
        self.json_log = json_log
        self.tty = sys.stderr.isatty() and not json_log
        self._shown = False
        self._last = -math.inf

    def message(self, line: str) -> None:
        self._clear()
        if self.json_log:
            typer.echo(json.dumps(log_record(line), ensure_ascii=False), err=True)
        else:
            typer.echo(f"online: {' '.join(line.split())}", err=True)

    def status(self, line: str) -> None:
        if self.tty:
            sys.stderr.write("\r\x1b[2K" + line)
            sys.stderr.flush()
            self._shown = True
        elif time.monotonic() - self._last >= QUIET_STATUS_EVERY_S:
            self._last = time.monotonic()
            self.message(f"status line={json.dumps(line)}" if self.json_log else line)

    def _clear(self) -> None:
        if self._shown:
            sys.stderr.write("\r\x1b[2K")
            self._shown = False

    def close(self) -> None:
        self._clear()


def log_record(line: str) -> dict[str, Any]:
    """A service log line (``word key=value …``) as a JSON object with ``time`` and ``event``.

    Examples
    --------
    >>> r = log_record('window id=3 accepted=True reason="passed every gate"')
    >>> r["event"], r["id"], r["reason"]
    ('window', '3', 'passed every gate')
    """
    import shlex

    record: dict[str, Any] = {"time": time.time()}
    try:
        parts = shlex.split(line)
    except ValueError:
        word, _, rest = line.partition(" ")
        return record | {"event": word, "message": rest}
    if not parts:
        return record | {"event": ""}
    record["event"] = parts[0]
    for part in parts[1:]:
        key, sep, value = part.partition("=")
        if sep:
            record[key] = value
        else:
            record.setdefault("message", "")
            record["message"] = f"{record['message']} {part}".strip()
    return record


def _online_table(config: Path | None) -> str:
    """The ``[online]`` table for the virtual site: --config's, else write_back "auto"."""
    if config is None:
        return '[online]\nwrite_back = "auto"\n'
    import tomllib

    from pydantic import ValidationError

    from fuelid.plc.site import Online

    try:
        data = tomllib.loads(config.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"site file {str(config)!r} does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read site file {str(config)!r}: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{config}: not valid TOML ({exc})") from None
    table = data.get("online", {})
    if not isinstance(table, dict):
        raise ConfigError(f"{config}: [online] must be a table")
    try:
        Online.model_validate(table)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        message = str(first["msg"]).removeprefix("Value error, ")
        raise ConfigError(f"{config}: online.{where}: {message}" if where else message) from None
    lines = ["[online]"]
    for key, value in table.items():
        lines.append(f"{key} = {json.dumps(value)}")
    return "\n".join(lines) + "\n"


def check_window_length(site: SiteConfig) -> None:
    """Refuse a missing plant file or an ``[online] window_s`` shorter than its settling time."""
    from fuelid.online.window import check_site_plant

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
    try:
        stats = asyncio.run(main())
    finally:
        console.close()
    return stats, time.monotonic() - started


def _summary(stats: Any, wall_s: float, target: str) -> None:
    recorder = stats.recorder
    stored = recorder.stored if recorder is not None else 0
    typer.echo(
        f"online: stopped after {wall_s:.1f} s: {stats.windows} windows ({stats.accepted} "
        f"accepted), {stats.proposals} proposals, {stats.writes} writes, {stats.reverts} "
        f"reverts; {stored} samples stored"
    )
    typer.echo(f"store: {target} (fuelid online status --store {target})")


def _heartbeat_s(speed: float) -> float:
    """Wall time between heartbeats: well inside the PLC's timeout at the speed-up [s]."""
    return min(1.0, 0.25 * PLC_HEARTBEAT_TIMEOUT_S / speed)


def _start(
    site: SiteConfig,
    target: str,
    duration: float | None,
    json_log: bool,
    heartbeat_s: float = 1.0,
) -> None:
    from fuelid.online.service import OnlineService

    check_window_length(site)
    for line in site.missing():
        typer.echo(f"online: the site file does not expose {line}", err=True)
    console = _Console(json_log)
    service = OnlineService(site, target, on_message=console.message, heartbeat_s=heartbeat_s)
    try:
        console.message(
            f"config site={json.dumps(site.site.name)} store={json.dumps(target)} "
            f"every_s={site.online.identify_every_s:g} window_s={site.online.window_s:g} "
            f"write_back={site.online.write_back}"
        )
        stats, wall = _run_service(service, duration, console)
    finally:
        service.close()
    _summary(stats, wall, target)


def _run_virtual(
    config: Path | None,
    store: Path | None,
    duration: float | None,
    json_log: bool,
    speed: float,
    hours: float,
    protocol: ServeProtocol,
) -> None:
    import tempfile
    from importlib import resources

    from fuelid.plc.site import load_site
    from fuelid.plc.virtual.runner import VirtualPlcThread
    from fuelid.profiles.runs import demo_run_profile, demo_temperature

    if not (math.isfinite(speed) and 0.0 < speed <= 1000.0):
        raise ConfigError(f"--speed must be within (0, 1000], got {speed:g}")
    if not (math.isfinite(hours) and hours > 0.0):
        raise ConfigError(f"--hours must be a positive number of hours, got {hours:g}")
    online = _online_table(config)
    plant_s = hours * 3600.0
    wall = plant_s / speed if duration is None else duration
    path = VIRTUAL_STORE if store is None else store
    if store is None and path.exists():
        typer.echo(f"online: replacing the demo store {path}", err=True)
        for suffix in ("", "-wal", "-shm"):
            Path(f"{path}{suffix}").unlink(missing_ok=True)
    target = str(path.resolve())
    plant = resources.files("fuelid.data").joinpath("reference_plant.toml")
    plant_path = str(plant) if Path(str(plant)).is_file() else None
    times, temperatures = demo_temperature(plant_s)
    with (
        VirtualPlcThread(
            protocol.value,
            speed=speed,
            seed=1,
            setpoint_profile=demo_run_profile(),
            fuel_temp_profile=(times, temperatures),
        ) as virtual,
        tempfile.TemporaryDirectory(prefix="fuelid-online-") as folder,
    ):
        text = virtual.site_text(store_url=f"sqlite:///{target}", plant=plant_path)
        site_path = Path(folder) / "virtual-site.toml"
        site_path.write_text(f"{text}\n{online}", encoding="utf-8")
        site = load_site(site_path)
        typer.echo(
            f"online: virtual PLC ({protocol.value} on {virtual.host}:{virtual.port}), "
            f"{speed:g}x real time, {hours:g} h of plant time in {wall:.1f} s",
            err=True,
        )
        _start(site, target, wall, json_log, heartbeat_s=_heartbeat_s(speed))


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
            "fuel −10…+45 °C over 24 h); --config then only gives the [online] table.",
        ),
    ] = False,
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
    if virtual:
        _run_virtual(config, store, duration, json_log, speed, hours, protocol)
        return
    if config is None:
        raise ConfigError(
            "give --config SITE.toml (the site file of the loop), or --virtual for the demo; "
            "subcommands: status, history, approve, reject, revert"
        )
    from fuelid.plc.site import load_site

    site = load_site(config)
    target = str(store) if store is not None else site.store.url
    _start(site, target, duration, json_log)


# --- the store ------------------------------------------------------------------------------


def _store_path(url: str) -> Path:
    _, sep, location = url.partition(":///")
    return Path(location if sep else url)


@contextmanager
def _opened(
    config: Path | None, store: Path | None
) -> Iterator[tuple[SQLiteStore, OnlineHistory, dict[str, Any]]]:
    """The store and its history (read from --store, or the site file's), and the settings."""
    from fuelid.store.base import StoreError
    from fuelid.store.online import OnlineHistory
    from fuelid.store.sqlite import SQLiteStore

    if config is None and store is None:
        raise ConfigError("give --config SITE.toml or --store FILE.db")
    settings: dict[str, Any] = {}
    identity: dict[str, Any] | None = None
    path = store
    if config is not None:
        from fuelid.plc.recorder import site_identity
        from fuelid.plc.site import load_site

        site = load_site(config)
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


def _settings(site: SiteConfig) -> dict[str, Any]:
    out: dict[str, Any] = {"write_back": site.online.write_back}
    c = site.controller
    if c is not None:
        kc = "V per L/min" if c.gain_units == "engineering" else "% per %"
        out["gains_units"] = {"Kc": kc, "Ti": c.integral_unit}
    return out


def _options(config: Path | None, store: Path | None, **more: Any) -> dict[str, Any]:
    return {
        "config": None if config is None else str(config),
        "store": None if store is None else str(store),
        **more,
    }


def _stamp(t: float | None) -> str:
    if t is None:
        return "-"
    from datetime import UTC, datetime

    return datetime.fromtimestamp(t, tz=UTC).strftime("%Y-%m-%d %H:%M:%S UTC")


def _pm(values: dict[str, Any] | None, errors: dict[str, Any] | None, key: str, unit: str) -> str:
    value = (values or {}).get(key)
    if value is None:
        return f"{key} -"
    se = (errors or {}).get(key)
    text = f"{value:.4g}" + ("" if se is None else f" ± {se:.2g}")
    return f"{text} {unit}".rstrip()


def _model_text(entry: dict[str, Any]) -> str:
    model, se = entry.get("model"), entry.get("stderr")
    parts = [
        "K = " + _pm(model, se, "K", "(L/min)/V"),
        "T = " + _pm(model, se, "T", "s"),
        "θ = " + _pm(model, se, "delay", "s"),
    ]
    return ", ".join(parts)


def _gains_text(p: dict[str, Any]) -> str:
    old, new = p.get("old") or {}, p.get("new") or {}

    def g(d: dict[str, Any], k: str) -> str:
        return "-" if d.get(k) is None else f"{d[k]:.4g}"

    ms = p.get("Ms")
    return (
        f"#{p['id']} {p['status']}: Kc {g(old, 'Kc')} → {g(new, 'Kc')}, Ti {g(old, 'Ti')} → "
        f"{g(new, 'Ti')}" + ("" if ms is None else f" (Ms {ms:.2f})")
    )


def _percent(x: Any) -> str:
    return "-" if x is None else f"{100.0 * x:.1f} %"


def _health_text(h: dict[str, Any] | None) -> str:
    if not h:
        return "not measured yet"
    osc = (h.get("oscillation") or {}).get("oscillating")
    iae = h.get("iae_per_unit_step_s")
    harris = (h.get("harris") or {}).get("index")
    sensor = h.get("sensor") or {}
    noise = sensor.get("noise_Lpm")
    return (
        f"AUTO {_percent(h.get('time_in_auto'))}, at limits {_percent(h.get('time_at_limits'))}, "
        f"oscillating {'yes' if osc else 'no'}, IAE/step "
        + ("-" if iae is None else f"{iae:.3g} s")
        + ", Harris "
        + ("-" if harris is None else f"{harris:.2f}")
        + ", sensor "
        + ("stuck" if sensor.get("stuck") else "ok")
        + ("" if noise is None else f" (noise {noise:.3g} L/min)")
    )


def _trend_text(trend: dict[str, Any]) -> str:
    if not trend.get("available"):
        return f"not yet ({trend.get('reason', '')})"
    at = trend.get("at_newest") or {}
    n = trend.get("n")
    text = f"{trend.get('mode')} fit over {n} windows"
    ratio = trend.get("ratio")
    if isinstance(ratio, dict):
        text += f", K/K_plant {ratio['intercept']:.3f} ± {ratio['se_intercept']:.2g}"
        text += f" at {ratio['T_ref']:.1f} °C"
        if ratio.get("slope") is not None:
            text += f", slope {ratio['slope']:.2e} ± {ratio['se_slope']:.1e} /°C"
    if at.get("K") is not None:
        text += (
            f"; K at {at['fuel_temperature']:.1f} °C, {at['u']:.2f} V: "
            f"{at['K']:.4g} ± {at['se']:.2g} (L/min)/V"
        )
    drift = trend.get("drift")
    if isinstance(drift, dict):
        text += f"; drift from the tuned model {drift['ratio']:.3f} ± {drift['se']:.2g}"
    return text


def status_lines(status: dict[str, Any]) -> list[str]:
    """The human form of :func:`~fuelid.online.report.status_json`, a few aligned lines."""
    link = status["link"]
    age = link.get("age_s")
    if age is None:
        when = ""
    elif age >= 0.0:
        when = f", {age:.1f} s ago"
    else:  # an accelerated (virtual) PLC's clock runs ahead of the wall clock
        when = f", {-age:.1f} s ahead of this clock"
    link_text = f"{link['state']} (newest sample {_stamp(link.get('newest_sample'))}{when})"
    w = status.get("last_window")
    if w is None:
        window_text = "none yet"
    else:
        verdict = "accepted" if w["accepted"] else "rejected"
        fuel = w.get("fuel_temperature")
        window_text = (
            f"#{w['id']} ending {_stamp(w['end'])}, {w.get('mode') or '-'}, "
            + ("" if fuel is None else f"fuel {fuel:.1f} °C, ")
            + f"{verdict}: {w['reason']}"
        )
    m = status.get("current_model")
    if m is None:
        model_text = "none accepted yet"
    else:
        fuel = m.get("fuel_temperature")
        model_text = (
            _model_text(m)
            + f" (window ending {_stamp(m.get('end'))}"
            + ("" if fuel is None else f", fuel {fuel:.1f} °C")
            + ")"
        )
    pending = status.get("pending_proposals") or []
    proposals_text = "none" if not pending else "; ".join(_gains_text(p) for p in pending)
    wb = status.get("write_back") or {}
    last_write = status.get("last_write")
    write_text = f"write_back {wb.get('setting') or 'unknown (give --config)'}"
    if wb.get("write_held"):
        write_text += f", held: {wb['write_held']}"
    if wb.get("revert_requested"):
        write_text += ", revert requested"
    write_text += "; last write " + (
        "none"
        if last_write is None
        else f"#{last_write['id']} {last_write['kind']} {last_write['status']} "
        f"(Kc {last_write['Kc']:.4g}, Ti {last_write['Ti']:.4g}) at {_stamp(last_write['time'])}"
    )
    c = status.get("counts") or {}
    last = status.get("last_window") or {}
    step = last.get("step_ls") or {}
    step_text = (
        "-"
        if not step
        else (
            _model_text(step)
            if step.get("model")
            else f"not fitted: {step.get('reason', 'no reason given')}"
        )
        + " (the article's method, reported beside, not gated)"
    )
    rows = [
        ("site", f"{status['site']['name']} (store {status['site']['store']})"),
        ("link", link_text),
        ("window", window_text),
        ("model", model_text),
        ("step-ls", step_text),
        ("K(T)", _trend_text(status.get("k_trend") or {})),
        ("proposals", proposals_text),
        ("health", _health_text(status.get("loop_health"))),
        ("writes", write_text),
        (
            "counts",
            f"{c.get('windows', 0)} windows, {c.get('accepted', 0)} accepted, "
            f"{c.get('proposals', 0)} proposals, {c.get('writes', 0)} writes",
        ),
    ]
    return [f"{name:<10} {text}" for name, text in rows]


@app.command("status")
@guarded
def status_command(
    config: ConfigFile = None, store: StoreFile = None, as_json: JsonFlag = False
) -> None:
    """Link, last window and its verdict, current model, K(T) trend, proposals, loop health.

    Read from the store; a running service need not be stopped. --json prints one object
    (keys site, link, last_window, current_model, k_trend, pending_proposals, loop_health,
    counts, write_back, last_write, units).
    """
    from fuelid.online.report import status_json

    with _opened(config, store) as (opened, history, settings):
        status = status_json(history, opened, settings=settings)
    if as_json:
        emit_json(status | provenance(_options(config, store)))
        return
    typer.echo("\n".join(status_lines(status)))


@app.command("history")
@guarded
def history_command(
    config: ConfigFile = None,
    store: StoreFile = None,
    as_json: JsonFlag = False,
    plot: Annotated[
        Path | None,
        typer.Option(
            "--plot",
            metavar="FILE.png",
            help="Draw K over time and against fuel temperature with 95 % intervals, the gains "
            "and the proposals.",
            show_default=False,
        ),
    ] = None,
    force: Annotated[bool, typer.Option("--force", help="Overwrite an existing --plot.")] = False,
) -> None:
    """Every window, proposal, event and write of the service, oldest first.

    --json prints one object with windows (start, end, accepted, reason, fuel_temperature,
    model, stderr, ci95 as fuelid identify's), proposals (id, time, status, old, new, Ms, reason,
    history), events, writes, k_trend.
    """
    from fuelid.online.report import history_json

    check_figure_path(plot, overwrite=force)
    with _opened(config, store) as (opened, history, settings):
        data = history_json(history, opened, settings=settings)
    if plot is not None:
        from fuelid.plots import plot_online_history

        plot_online_history(data, plot)
    if as_json:
        emit_json(data | provenance(_options(config, store, plot=plot and str(plot))))
        return
    windows = data["windows"]
    lines = [f"{len(windows)} windows, {sum(w['accepted'] for w in windows)} accepted"]
    if len(windows) > RECENT_WINDOWS:
        lines.append(f"(the newest {RECENT_WINDOWS}; --json for all)")
    for w in windows[-RECENT_WINDOWS:]:
        fitted = "" if w.get("model") is None else " " + _model_text(w)
        fuel = w.get("fuel_temperature")
        lines.append(
            f"  #{w['id']:<5} {_stamp(w['end'])} {'ok ' if w['accepted'] else 'no '}"
            + ("" if fuel is None else f"{fuel:6.1f} °C")
            + f"{fitted} | {w['reason']}"
        )
    lines.append(f"{len(data['proposals'])} proposals")
    lines += [f"  {_gains_text(p)} at {_stamp(p['time'])}" for p in data["proposals"]]
    kinds: dict[str, int] = {}
    for e in data["events"]:
        kinds[e["kind"]] = kinds.get(e["kind"], 0) + 1
    lines.append(
        f"{len(data['events'])} events"
        + ("" if not kinds else ": " + ", ".join(f"{k} {n}" for k, n in sorted(kinds.items())))
    )
    lines.append(f"{len(data['writes'])} writes")
    lines += [
        f"  #{w['id']} {w['kind']} {w['status']} Kc {w['Kc']:.4g} Ti {w['Ti']:.4g} by {w['who']}"
        for w in data["writes"]
    ]
    if plot is not None:
        lines.append(f"figure: {plot}")
    typer.echo("\n".join(lines))


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


def __getattr__(name: str) -> Any:
    # the virtual run's profiles live in fuelid.profiles.runs (numpy: imported on use,
    # so `fuelid --help` stays light); kept importable from here
    if name in ("demo_run_profile", "demo_temperature"):
        from fuelid.profiles import runs as profiles

        return getattr(profiles, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["app", "check_window_length", "log_record"]
