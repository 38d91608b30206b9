"""The virtual PLC's clock: the engine on a protocol front end, in real time or X times faster.

:func:`serve` ticks on an absolute wall-clock schedule (every ``plant_period_s/min(speed, 1)`` of
wall time, never drifting: each deadline is the start plus a whole number of ticks). Each tick it
collects what clients wrote, hands it to the engine, advances plant time by every sample now due
(``floor(wall elapsed · speed / plant_period_s)`` minus those done, so at speed X the sequence
counter advances X times faster than wall time, several samples a tick) and publishes the new
values and ring records. ``plant_period_s`` is the engine's ``period_s`` unless its clock runs
slow or fast (``clock_slow``, :mod:`fuelid.plc.virtual._engine`): a PLC whose clock is 2 % slow
takes 20.4 ms of wall time for each 20 ms sample at real time. A late tick is not skipped but
caught up: the samples it owes are all produced, so plant time keeps pace with X × wall time and
no sample is lost.

:class:`VirtualPlcThread` runs engine and front end in a background thread with its own event
loop, for tests, benchmarks and the command line; :func:`site_text` (in
:mod:`fuelid.plc.virtual._sitefile`, re-exported here) writes the site file that points at a
virtual PLC.
"""

from __future__ import annotations

import asyncio
import importlib
import math
import socket
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import TracebackType
from typing import Any, Self

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import ConfigError
from fuelid.plc._codec import WordOrder
from fuelid.plc.virtual._engine import VirtualPLC
from fuelid.plc.virtual._frontend import Frontend, ReplyTiming, free_port
from fuelid.plc.virtual._sitefile import site_text

__all__ = [
    "DEFAULT_PORTS",
    "FRONTENDS",
    "MAX_SPEED",
    "ReplyTiming",
    "ServeStats",
    "VirtualPlcThread",
    "check_port",
    "free_port",
    "frontend_class",
    "frontend_kwargs",
    "serve",
    "serve_until_stopped",
    "site_text",
]

FRONTENDS = {
    "modbus": ("fuelid.plc.virtual._modbus_server", "ModbusFrontend"),
    "opcua": ("fuelid.plc.virtual._opcua_server", "OpcUaFrontend"),
    "s7": ("fuelid.plc.virtual._s7_server", "S7Frontend"),
}
"""Protocol → (module, class) of its front end, imported when the protocol is used."""
DEFAULT_PORTS = {"modbus": 5020, "opcua": 4840, "s7": 1102}
"""The virtual PLC's default ports: above 1024, so no privileges are needed."""
MAX_SPEED = 1000.0
"""Fastest plant time the runner accepts, times real time."""


def frontend_kwargs(protocol: str, reply: ReplyTiming | None) -> dict[str, Any]:
    """The front end's keyword for a reply timing: ``reply`` on Modbus, nothing by default.

    Raises
    ------
    ConfigError
        A reply timing other than the default on a protocol other than Modbus.
    """
    if reply is None or reply.immediate:
        return {}
    if protocol != "modbus":
        raise ConfigError(
            f"the virtual PLC's reply timing (in cycle, jitter, late replies) is a Modbus "
            f"option; its {protocol} server answers at once"
        )
    return {"reply": reply}


def frontend_class(protocol: str) -> type[Frontend]:
    """The front-end class of ``protocol``, imported now.

    Raises
    ------
    ConfigError
        If the protocol is unknown, or its library (the ``plc`` extra) is not installed.
    """
    if protocol not in FRONTENDS:
        raise ConfigError(f"protocol {protocol!r}: the virtual PLC speaks {', '.join(FRONTENDS)}")
    module_name, class_name = FRONTENDS[protocol]
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ConfigError(
            f"the {protocol} server needs {exc.name or 'its library'}: pip install 'fuelid[plc]'"
        ) from None
    cls: type[Frontend] = getattr(module, class_name)
    return cls


@dataclass
class ServeStats:
    """How the clock kept up (filled in by :func:`serve` when passed)."""

    ticks: int = 0
    samples: int = 0
    """Samples advanced (plant time = samples × period_s)."""
    wall_s: float = 0.0
    """Wall time served [s]."""
    busy_s: float = 0.0
    """Wall time spent in ticks (collect, advance, publish) [s]."""
    max_lag_s: float = 0.0
    """Largest lateness of a tick behind its deadline [s of wall time]."""
    max_batch: int = 0
    """Most samples advanced in one tick."""
    lags: list[float] = field(default_factory=list, repr=False)
    """Lateness of every tick [s] (kept only when ``keep_lags``)."""
    keep_lags: bool = False


async def serve(
    plc: VirtualPLC,
    frontend: Frontend,
    *,
    speed: float = 1.0,
    duration_s: float | None = None,
    stop: asyncio.Event | None = None,
    stats: ServeStats | None = None,
) -> None:
    """Run the virtual PLC on ``frontend`` (already started) until stopped.

    Parameters
    ----------
    plc : VirtualPLC
        The engine.
    frontend : Frontend
        A started protocol server.
    speed : float
        Plant time per wall time (1 = real time).
    duration_s : float, optional
        Wall time to serve [s]; None: until ``stop`` is set (or the task is cancelled).
    stop : asyncio.Event, optional
        Set it to stop after the current tick.
    stats : ServeStats, optional
        Filled in with how the clock kept up.

    Raises
    ------
    ConfigError
        If the speed is not within (0, 1000].
    """
    if not (math.isfinite(speed) and 0.0 < speed <= MAX_SPEED):
        raise ConfigError(f"speed must be within (0, {MAX_SPEED:g}], got {speed!r}")
    loop = asyncio.get_running_loop()
    tick = plc.plant_period_s / min(speed, 1.0)  # wall time between ticks [s]
    samples_per_wall_s = speed / plc.plant_period_s
    start = loop.time()
    done = 0
    ticks = 0
    # the engine's first sample is published before the first tick: a client connecting now
    # reads a valid head and record
    first = {plc.seq % plc.ring_size: plc.ring[plc.seq % plc.ring_size].copy()}
    await frontend.publish(plc.read_points(), first)
    while stop is None or not stop.is_set():
        ticks += 1
        deadline = start + ticks * tick
        now = loop.time()
        if deadline > now:
            await asyncio.sleep(deadline - now)
            now = loop.time()
        if stop is not None and stop.is_set():
            break
        began = time.perf_counter()
        elapsed = now - start
        if duration_s is not None and elapsed >= duration_s:
            elapsed = duration_s
        due = math.floor(elapsed * samples_per_wall_s + 1e-9) - done
        plc.write_points(await frontend.collect())
        ring = plc.advance(due) if due > 0 else {}
        done += max(due, 0)
        await frontend.publish(plc.read_points(), ring)
        if stats is not None:
            lag = max(0.0, now - deadline)
            stats.ticks = ticks
            stats.samples = done
            stats.wall_s = elapsed
            stats.busy_s += time.perf_counter() - began
            stats.max_lag_s = max(stats.max_lag_s, lag)
            stats.max_batch = max(stats.max_batch, due)
            if stats.keep_lags:
                stats.lags.append(lag)
        if duration_s is not None and elapsed >= duration_s:
            break


async def serve_until_stopped(
    plc: VirtualPLC,
    frontend: Frontend,
    *,
    speed: float = 1.0,
    duration_s: float | None = None,
    on_ready: Callable[[], None] | None = None,
) -> None:
    """Serve in the foreground until the duration ends, SIGINT or SIGTERM (``plant serve``).

    The port is checked first and released in any case; ``on_ready`` is called once clients can
    connect.

    Raises
    ------
    ConfigError
        The port cannot be bound (one line: in use, or not allowed).
    """
    import contextlib
    import signal

    check_port(frontend.host, frontend.port)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):  # not on every platform
            loop.add_signal_handler(sig, stop.set)
    try:
        await frontend.start()
    except (OSError, RuntimeError) as exc:  # pymodbus says RuntimeError when it cannot listen
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise ConfigError(
            f"cannot serve on {frontend.host}:{frontend.port} (port in use?): {reason}"
        ) from None
    if on_ready is not None:
        on_ready()
    try:
        await serve(plc, frontend, speed=speed, duration_s=duration_s, stop=stop)
    finally:
        await frontend.stop()


def check_port(host: str, port: int) -> None:
    """Refuse a port that cannot be bound, in one line (before a server library logs it).

    Raises
    ------
    ConfigError
        The port is in use or not allowed.
    """
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as sock:
        # as the servers bind: a port in TIME_WAIT after a restart is free
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((host, port))
        except OSError as exc:
            raise ConfigError(
                f"cannot serve on {host}:{port}: {exc.strerror or exc} (another server there?)"
            ) from None


def _whole_ring(plc: VirtualPLC) -> dict[int, NDArray[np.float64]]:
    """Every slot of the engine's ring (the PLC's memory survives a link drop)."""
    return {slot: plc.ring[slot].copy() for slot in range(plc.ring_size)}


class _LinkGate(Frontend):
    """The front end as the clock sees it: while the link is down, nothing goes through.

    Clients cannot write while the server is stopped, so :meth:`collect` returns what they last
    left; :meth:`publish` is dropped (the engine keeps its ring, republished on reconnect).
    """

    def __init__(self, frontend: Frontend | None) -> None:
        self.inner = frontend
        self.up = frontend is not None
        self._last: dict[str, float] = {}

    async def start(self) -> None:  # the thread starts the inner front end itself
        """Nothing: the link is raised by :meth:`VirtualPlcThread.start_link`."""

    async def stop(self) -> None:
        """Nothing: the link is dropped by :meth:`VirtualPlcThread.stop_link`."""

    async def publish(
        self, values: Mapping[str, float], ring: Mapping[int, NDArray[np.float64]]
    ) -> None:
        """Publish through the inner front end while the link is up."""
        if self.up and self.inner is not None:
            await self.inner.publish(values, ring)

    async def collect(self) -> dict[str, float]:
        """What clients wrote (the last values seen while the link was down)."""
        if self.up and self.inner is not None:
            self._last = await self.inner.collect()
        return dict(self._last)


class VirtualPlcThread:
    """Engine and front end in a background thread with their own event loop.

    Parameters
    ----------
    protocol : {"modbus", "opcua", "s7"}
        The front end.
    host : str
        Address to bind.
    port : int, optional
        TCP port; None (or 0) lets the OS pick a free one as the server binds, and :attr:`port`
        says which once started (a restart of the PLC or its link keeps it).
    speed : float
        Plant time per wall time.
    word_order, byte_swap
        32-bit layout (Modbus).
    reply : ReplyTiming, optional
        When the server answers (Modbus only; default: at once). With ``clock_slow`` among the
        engine's arguments and ``ReplyTiming(in_cycle=True)``, replies come on the PLC's slow
        clock.
    **engine_kwargs
        Passed to :class:`~fuelid.plc.virtual._engine.VirtualPLC` (``ring_size`` to the front end
        too), e.g. ``excitation_limit_V`` (the PLC's clamp of the test signal [V]) and
        ``run_windows`` (((start, end), …) [s] on the PLC's clock: the read point ``run`` is 1).

    Examples
    --------
    ::

        with VirtualPlcThread(speed=20.0) as virtual:
            site = virtual.site_text()          # points at virtual.port
    """

    def __init__(
        self,
        protocol: str = "modbus",
        host: str = "127.0.0.1",
        port: int | None = None,
        *,
        speed: float = 1.0,
        word_order: WordOrder = "big",
        byte_swap: bool = False,
        reply: ReplyTiming | None = None,
        **engine_kwargs: Any,
    ) -> None:
        self.protocol = protocol
        self.reply = reply
        self._frontend_kwargs = frontend_kwargs(protocol, reply)
        self.host = host
        # 0: bound by the server itself, so no other process can take the port in between
        self.port = 0 if port is None else int(port)
        self.speed = float(speed)
        self.word_order: WordOrder = word_order
        self.byte_swap = byte_swap
        self._engine_kwargs = engine_kwargs
        self._frontend_cls = frontend_class(protocol)
        self.plc = VirtualPLC(**engine_kwargs)
        self.stats = ServeStats()
        self.frontend: Frontend | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._stop: asyncio.Event | None = None
        self._task: asyncio.Task[None] | None = None
        self._resume = asyncio.Event()
        self._gate = _LinkGate(None)

    # -- life cycle --------------------------------------------------------------------------

    def start(self) -> Self:
        """Start serving; returns once clients can connect.

        Raises
        ------
        ConfigError
            If the server cannot bind (the port taken, …) or its library is missing.
        """
        if self._thread is not None:
            return self
        ready = threading.Event()
        failure: list[BaseException] = []

        def run() -> None:
            loop = asyncio.new_event_loop()
            self._loop = loop
            asyncio.set_event_loop(loop)
            try:
                loop.run_until_complete(self._main(ready, failure))
            finally:
                loop.run_until_complete(loop.shutdown_asyncgens())
                loop.close()

        self._thread = threading.Thread(
            target=run, name=f"virtual-plc-{self.protocol}", daemon=True
        )
        self._thread.start()
        ready.wait(30.0)
        if failure:
            self._thread.join(5.0)
            self._thread = None
            exc = failure[0]
            raise ConfigError(
                f"the virtual PLC's {self.protocol} server cannot start on "
                f"{self.host}:{self.port}: {exc}"
            ) from None
        return self

    async def _main(self, ready: threading.Event, failure: list[BaseException]) -> None:
        self._stop = asyncio.Event()
        try:
            await self._start_frontend()
        except Exception as exc:
            failure.append(exc)
            ready.set()
            return
        ready.set()
        try:
            while not self._stop.is_set():
                self._resume = asyncio.Event()
                self._task = asyncio.create_task(self._serve())
                try:
                    await self._task
                except asyncio.CancelledError:
                    if self._stop.is_set():
                        break
                    # a PLC restart cancelled the clock: wait for the new engine, go round
                    await self._resume.wait()
        finally:
            if self.frontend is not None and self._gate.up:
                self._gate.up = False
                await self.frontend.stop()

    async def _serve(self) -> None:
        assert self._stop is not None
        await serve(self.plc, self._gate, speed=self.speed, stop=self._stop, stats=self.stats)

    async def _start_frontend(self) -> None:
        self.frontend = self._frontend_cls(
            self.host,
            self.port,
            ring_size=self.plc.ring_size,
            word_order=self.word_order,
            byte_swap=self.byte_swap,
            **self._frontend_kwargs,
        )
        await self.frontend.start()
        self.port = self.frontend.port  # the bound one, when 0 was asked for
        self._gate = _LinkGate(self.frontend)

    def _call(self, coro: Any, timeout: float = 30.0) -> Any:
        if self._loop is None or self._thread is None:
            raise ConfigError("the virtual PLC is not running")
        return asyncio.run_coroutine_threadsafe(coro, self._loop).result(timeout)

    def stop(self) -> None:
        """Stop the clock and the server, release the port, join the thread."""
        if self._thread is None or self._loop is None:
            return
        stop = self._stop
        if stop is not None:
            self._loop.call_soon_threadsafe(stop.set)
        self._thread.join(30.0)
        self._thread = None
        self._loop = None

    def stop_link(self) -> None:
        """Stop the protocol server only (clients see the link drop; the plant runs on)."""

        async def down() -> None:
            if self.frontend is not None and self._gate.up:
                self._gate.up = False
                await self.frontend.stop()

        self._call(down())

    def start_link(self) -> None:
        """Serve again on the same port after :meth:`stop_link`, the whole ring republished."""

        async def up() -> None:
            if self.frontend is not None and not self._gate.up:
                await self.frontend.start()
                await self.frontend.publish(self.plc.read_points(), _whole_ring(self.plc))
                self._gate.up = True

        self._call(up())

    def restart_plc(self) -> None:
        """A PLC restart: the link drops, a new engine starts (seq from seq0, the ring empty)."""

        async def restart() -> None:
            if self._task is not None:
                self._task.cancel()
            if self.frontend is not None and self._gate.up:
                self._gate.up = False
                await self.frontend.stop()
            self.plc = VirtualPLC(**self._engine_kwargs)
            await self._start_frontend()  # a fresh front end: the write area back to zeros
            self._resume.set()

        self._call(restart())

    def set_run(self, flag: bool) -> None:
        """Raise or lower the engine's run flag by hand.

        As :meth:`~fuelid.plc.virtual._engine.VirtualPLC.set_run`, on the clock's own thread,
        between two ticks. A PLC restart (:meth:`restart_plc`) starts a new engine with the flag
        lowered (its ``run_windows`` kept).
        """

        async def set_flag() -> None:
            self.plc.set_run(flag)

        self._call(set_flag())

    def site_text(self, store_url: str | None = None, plant: str | None = None) -> str:
        """The site file that points at this virtual PLC (``plant``: its ``[site] plant``)."""
        return site_text(
            self.protocol,
            self.host,
            self.port,
            period_s=self.plc.period_s,
            control_period_s=self.plc.control_period_s,
            word_order=self.word_order,
            byte_swap=self.byte_swap,
            ring_size=self.plc.ring_size,
            store_url=store_url,
            kc=self.plc.kc0,
            ti=self.plc.ti0,
            plant=plant,
        )

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()
