"""``fuelid plant serve``: the virtual PLC, the plant with its PLC emulated, on a real protocol.

Only typer and the CLI's light foundation at the top; the engine, numpy and the protocol library
are imported when the command runs.
"""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from fuelid.cli._common import ConfigOption, guarded
from fuelid.errors import FuelidError
from fuelid.units import DEFAULT_FUEL_TEMPERATURE_C

if TYPE_CHECKING:
    from fuelid.plc import WordOrder
    from fuelid.profiles.runs import Profile


class ServeProtocol(StrEnum):
    """The protocols the virtual PLC speaks."""

    modbus = "modbus"
    opcua = "opcua"
    s7 = "s7"


class WordOrderChoice(StrEnum):
    """32-bit word order on Modbus: big = ABCD, little = CDAB."""

    big = "big"
    little = "little"


def is_loopback(host: str) -> bool:
    """True for ``localhost`` and loopback addresses (127.0.0.0/8, ::1).

    Examples
    --------
    >>> is_loopback("127.0.0.1"), is_loopback("localhost"), is_loopback("0.0.0.0")
    (True, True, False)
    """
    import ipaddress

    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def parse_run_windows(texts: list[str]) -> list[tuple[float, float]]:
    """The ``--run START:END`` options as (start, end) pairs [s].

    Raises
    ------
    FuelidError
        If one is not two finite numbers with START < END.

    Examples
    --------
    >>> parse_run_windows(["60:180", "300.5:420"])
    [(60.0, 180.0), (300.5, 420.0)]
    """
    import math

    windows = []
    for text in texts:
        start_text, sep, end_text = text.partition(":")
        try:
            start, end = float(start_text), float(end_text)
        except ValueError:
            start = end = math.nan
        if not (sep and math.isfinite(start) and math.isfinite(end) and start < end):
            raise FuelidError(
                f"--run {text}: give START:END in seconds of plant time, with START < END"
            )
        windows.append((start, end))
    return windows


@guarded
def serve_command(
    config: ConfigOption = None,
    protocol: Annotated[
        ServeProtocol, typer.Option("--protocol", help="Protocol of the server.")
    ] = ServeProtocol.modbus,
    host: Annotated[
        str,
        typer.Option(
            "--host", help="Address to bind; not a loopback address only with --allow-remote."
        ),
    ] = "127.0.0.1",
    port: Annotated[
        int | None,
        typer.Option(
            "--port",
            min=0,
            max=65535,
            help="TCP port (default: modbus 5020, opcua 4840, s7 1102; 0: a free port the "
            "system chooses, said in the first line on stderr).",
            show_default=False,
        ),
    ] = None,
    speed: Annotated[
        float,
        typer.Option("--speed", help="Plant time per wall time, e.g. 50 = 50× real time (≤ 1000)."),
    ] = 1.0,
    fuel_temp: Annotated[
        float | None,
        typer.Option(
            "--fuel-temp", help="Constant fuel temperature [°C] (default 20).", show_default=False
        ),
    ] = None,
    fuel_temp_profile: Annotated[
        Path | None,
        typer.Option(
            "--fuel-temp-profile",
            metavar="FILE.csv",
            help="Fuel temperature drift: CSV with columns t [s], fuel_temperature [°C].",
        ),
    ] = None,
    setpoint_profile: Annotated[
        str | None,
        typer.Option(
            "--setpoint-profile",
            metavar="FILE.csv|run",
            help="Setpoints in AUTO, repeated: 'run' (a wind-tunnel run) or a CSV with columns "
            "t [s], setpoint [L/min].",
        ),
    ] = None,
    command_profile: Annotated[
        str | None,
        typer.Option(
            "--command-profile",
            metavar="FILE.csv|steps",
            help="Commands in MAN, repeated: 'steps' (1.5–4.5 V steps, 15 s each) or a CSV "
            "with columns t [s], u [V].",
        ),
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the flowmeter noise.")] = 0,
    clock_slow: Annotated[
        float,
        typer.Option(
            "--clock-slow",
            metavar="FRACTION",
            help="The PLC's clock runs slow by this fraction (−0.5…0.5): 0.02 makes its 0.02 s "
            "cycle last 0.0204 s of real time; negative: fast. The plant runs in real time.",
        ),
    ] = 0.0,
    excitation_limit: Annotated[
        float,
        typer.Option(
            "--excitation-limit",
            metavar="V",
            help="The PLC's own clamp of the test signal a client writes to its excitation "
            "request [V], > 0: it adds at most ±this to its PI output (0 while the heartbeat "
            "is stale).",
        ),
    ] = 0.5,
    run: Annotated[
        list[str] | None,
        typer.Option(
            "--run",
            metavar="START:END",
            help="A wind-tunnel run from START to END [s of plant time, on the PLC's clock]: "
            "the read point run is 1 from START until END (repeatable).",
            show_default=False,
        ),
    ] = None,
    reply_in_cycle: Annotated[
        bool,
        typer.Option(
            "--reply-in-cycle",
            help="Modbus: answer each request at the end of the PLC's next cycle (a server "
            "block in the cyclic task), not at once: replies come on the PLC's clock.",
        ),
    ] = False,
    reply_jitter: Annotated[
        float,
        typer.Option(
            "--reply-jitter",
            min=0.0,
            metavar="SECONDS",
            help="Modbus: delay each reply by a random time up to this [s] (seeded by --seed).",
        ),
    ] = 0.0,
    late_reply_every: Annotated[
        int,
        typer.Option(
            "--late-reply-every",
            min=0,
            metavar="N",
            help="Modbus: every N-th reply leaves --late-reply seconds later (0: none).",
        ),
    ] = 0,
    late_reply: Annotated[
        float,
        typer.Option(
            "--late-reply",
            min=0.0,
            metavar="SECONDS",
            help="Modbus: the extra delay of a late reply [s].",
        ),
    ] = 0.0,
    word_order: Annotated[
        WordOrderChoice,
        typer.Option("--word-order", help="Modbus 32-bit word order: big = ABCD, little = CDAB."),
    ] = WordOrderChoice.big,
    duration: Annotated[
        float | None,
        typer.Option("--duration", min=0.0, help="Serve this long [s of wall time], then stop."),
    ] = None,
    allow_remote: Annotated[
        bool,
        typer.Option(
            "--allow-remote",
            help="Allow a non-loopback --host. The server has no authentication.",
        ),
    ] = False,
    print_site: Annotated[
        bool,
        typer.Option("--print-site", help="Print the site file that points at it, and exit."),
    ] = False,
) -> None:
    """Run the virtual PLC: the nonlinear plant with a PI, MAN/AUTO and a ring buffer.

    The plant (reference plant or --config) runs in plant time, --speed times real time, with
    the PLC emulated: a PI at the control period (1 s) with 1–5 V limits and anti-windup,
    MAN/AUTO, staged gains with apply and echo, a heartbeat, flowmeter noise and quantisation,
    and a ring buffer of (seq, u, flow, setpoint, excitation) every 0.02 s. Without a profile it
    starts in MAN at 1 V; clients write the mode, setpoint and manual command, and a test signal
    the PLC adds to its output (within ±--excitation-limit); --run marks wind-tunnel runs
    (the read point run). Ctrl-C or SIGTERM stops it.
    --clock-slow makes the PLC's clock run slow (or fast); --reply-in-cycle, --reply-jitter and
    --late-reply-every/--late-reply make its Modbus server answer as a PLC's cyclic task does.
    """
    _serve(
        config,
        protocol=protocol.value,
        host=host,
        port=port,
        speed=speed,
        fuel_temp=fuel_temp,
        fuel_temp_profile=fuel_temp_profile,
        setpoint_profile=setpoint_profile,
        command_profile=command_profile,
        seed=seed,
        clock_slow=clock_slow,
        excitation_limit=excitation_limit,
        run_windows=parse_run_windows(run or []),
        reply=(reply_in_cycle, reply_jitter, late_reply_every, late_reply),
        word_order=word_order.value,
        duration=duration,
        allow_remote=allow_remote,
        print_site=print_site,
    )


def _profiles(
    setpoint_profile: str | None, command_profile: str | None, fuel_temp_profile: Path | None
) -> tuple[Profile | str | None, Profile | str | None, Profile | None]:
    """The --setpoint-profile, --command-profile and --fuel-temp-profile as the engine takes them.

    The built-ins ("run", "steps") by name, a CSV file loaded.
    """
    from fuelid.profiles.runs import load_profile

    sp_profile = (
        setpoint_profile
        if setpoint_profile in (None, "run")
        else load_profile(str(setpoint_profile), "setpoint")
    )
    u_profile = (
        command_profile
        if command_profile in (None, "steps")
        else load_profile(str(command_profile), "u")
    )
    temperature = load_profile(fuel_temp_profile, "fuel_temperature") if fuel_temp_profile else None
    return sp_profile, u_profile, temperature


def _serve(
    config: Path | None,
    *,
    protocol: str,
    host: str,
    port: int | None,
    speed: float,
    fuel_temp: float | None,
    fuel_temp_profile: Path | None,
    setpoint_profile: str | None,
    command_profile: str | None,
    seed: int,
    clock_slow: float,
    excitation_limit: float,
    run_windows: list[tuple[float, float]],
    reply: tuple[bool, float, int, float],
    word_order: str,
    duration: float | None,
    allow_remote: bool,
    print_site: bool,
) -> None:
    import asyncio
    import math

    from fuelid.plant import load_plant_config
    from fuelid.plc.virtual import (
        DEFAULT_PORTS,
        ReplyTiming,
        VirtualPLC,
        frontend_class,
        frontend_kwargs,
        serve_until_stopped,
        site_text,
    )

    if not is_loopback(host) and not allow_remote:
        raise FuelidError(
            f"--host {host} is not a loopback address: the virtual PLC has no authentication; "
            "pass --allow-remote to serve it on the network anyway"
        )
    if fuel_temp is not None and fuel_temp_profile is not None:
        raise FuelidError("give --fuel-temp or --fuel-temp-profile, not both")
    if not 0.0 < speed <= 1000.0:
        raise FuelidError(f"--speed must be within (0, 1000], got {speed:g}")
    if not (math.isfinite(excitation_limit) and excitation_limit > 0.0):
        raise FuelidError(
            f"--excitation-limit must be a positive voltage, got {excitation_limit:g}"
        )
    sp_profile, u_profile, temperature = _profiles(
        setpoint_profile, command_profile, fuel_temp_profile
    )
    plc = VirtualPLC(
        load_plant_config(config),
        fuel_temp_C=DEFAULT_FUEL_TEMPERATURE_C if fuel_temp is None else fuel_temp,
        fuel_temp_profile=temperature,
        setpoint_profile=sp_profile,
        command_profile=u_profile,
        seed=seed,
        clock_slow=clock_slow,
        excitation_limit_V=excitation_limit,
        run_windows=run_windows,
    )
    in_cycle, jitter_s, late_every, late_s = reply
    timing = ReplyTiming(in_cycle, jitter_s, late_every, late_s, seed=seed)
    extra = frontend_kwargs(protocol, timing)
    port = DEFAULT_PORTS[protocol] if port is None else port
    order: WordOrder = "little" if word_order == "little" else "big"
    if print_site and port == 0:
        raise FuelidError(
            "--print-site needs the port the PLC will serve on: give --port N (not 0)"
        )
    if print_site:
        typer.echo(
            site_text(
                protocol,
                host,
                port,
                period_s=plc.period_s,
                control_period_s=plc.control_period_s,
                word_order=order,
                ring_size=plc.ring_size,
                kc=plc.kc0,
                ti=plc.ti0,
                plant=None if config is None else str(config.resolve()),
            ),
            nl=False,
        )
        return
    frontend = frontend_class(protocol)(
        host, port, ring_size=plc.ring_size, word_order=order, **extra
    )

    clock = (
        f" of a clock {100 * abs(plc.clock_slow):.3g} % {'slow' if plc.clock_slow > 0 else 'fast'} "
        f"({plc.plant_period_s:g} s real)"
        if plc.clock_slow
        else ""
    )

    def announce() -> None:
        # the bound port: the one asked for, or the system's choice for 0
        where = f"[{host}]:{frontend.port}" if ":" in host else f"{host}:{frontend.port}"
        typer.echo(
            f"virtual PLC: {protocol} on {where}, {speed:g}x real time, plant "
            f"{plc.config.name}, sample {plc.period_s:g} s{clock}, PI every "
            f"{plc.control_period_s:g} s (Ctrl-C stops)",
            err=True,
        )

    asyncio.run(
        serve_until_stopped(plc, frontend, speed=speed, duration_s=duration, on_ready=announce)
    )
    typer.echo(
        f"virtual PLC stopped after {plc.time_s * (1.0 + plc.clock_slow):.1f} s of plant time "
        f"(seq {plc.seq})",
        err=True,
    )
