"""The virtual PLC on Modbus TCP: a pymodbus server laid out as :mod:`~.points` says.

A pymodbus (≥3.15, <3.17) :class:`~pymodbus.server.ModbusTcpServer` with one device (unit id 1)
whose holding and input registers are separate blocks (``SimDevice`` with a 4-tuple,
../shared/docs/online.md §1):

- input registers 0…102: the read points (``ir:0`` seq … ``ir:22`` run, ``ir:100`` ring head,
  ``ir:102`` ring size; unused registers in between read 0);
- input registers 1000…1000 + 10·size − 1: the ring, record of sample ``seq`` in slot
  ``seq % size``, each ``seq`` (uint32) then command, flow, setpoint, excitation (float32);
- holding registers 0…23: the write points (``hr:22`` excitation request the last).

Any other address answers with Modbus exception 2 (illegal data address); the server goes on.
32-bit values follow the word order and byte swap asked for (:mod:`fuelid.plc._codec`).

pymodbus copies the datastore into the server, so values are written through the server's own
``async_setValues`` (writing into a context of one's own changes nothing). The front end keeps a
mirror of every register, so a stopped and restarted server (a link drop) comes back with the
PLC's memory: the ring and what clients last wrote.

**Reply timing** (:class:`~fuelid.plc.virtual._frontend.ReplyTiming`, off by default): with
``in_cycle`` a request waits for the end of the PLC's next cycle (the next :meth:`publish`) and
is answered then, from that cycle's values; jitter and late replies delay the reply's sending
after it was made. A server of its own class (:class:`_PacedServer`) gives each connection a
request handler that waits and delays so (pymodbus's ``ServerRequestHandler`` with
``handle_request`` and ``server_send`` wrapped).
"""

from __future__ import annotations

import asyncio
import random
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid.plc._codec import WordOrder, decode, encode
from fuelid.plc.virtual._frontend import Frontend, ReplyTiming, bound_port
from fuelid.plc.virtual._points import (
    DEFAULT_RING_SIZE,
    POINTS,
    RING_FIELDS,
    RING_FIRST_REGISTER,
    RING_RECORD_REGISTERS,
)

try:
    from pymodbus.server import ModbusTcpServer
    from pymodbus.server.requesthandler import ServerRequestHandler
    from pymodbus.simulator import DataType, SimData, SimDevice
except ImportError as exc:  # pragma: no cover - the plc extra is installed for the tests
    raise ImportError(
        "the virtual PLC's Modbus server needs pymodbus: pip install 'fuelid[plc]'"
    ) from exc

DEVICE_ID = 1
"""The unit id the virtual PLC answers to."""
FC_HOLDING, FC_INPUT = 3, 4

_READ = {name: p for name, p in POINTS.items() if p.access == "read"}
_WRITE = {name: p for name, p in POINTS.items() if p.access == "write"}
_SIZE = {"float32": 2, "uint32": 2, "int16": 1, "uint16": 1}
IR_POINTS_COUNT = max(p.register + _SIZE[p.type] for p in _READ.values())
"""Input registers 0 … IR_POINTS_COUNT − 1 hold the read points (103)."""
HR_COUNT = max(p.register + _SIZE[p.type] for p in _WRITE.values())
"""Holding registers 0 … HR_COUNT − 1 hold the write points (24)."""


def ring_registers(
    records: NDArray[np.float64], word_order: WordOrder = "big", byte_swap: bool = False
) -> NDArray[np.int64]:
    """The registers of ring records ``[seq, command, flow, setpoint, excitation]``, shape (m, 10).

    Vectorised: the same words :func:`fuelid.plc._codec.encode` gives field by field (a uint32,
    then four float32), at thousands of records a second.

    Examples
    --------
    >>> ring_registers(np.array([[1.0, 3.5, 0.0, 0.0, -0.25]]))[0].tolist()
    [0, 1, 16480, 0, 0, 0, 0, 0, 48768, 0]
    >>> ring_registers(np.array([[1.0, 3.5, 0.0, 0.0, 0.0]]), "little")[0, :4].tolist()
    [1, 0, 0, 16480]
    """
    m = records.shape[0]
    width = len(RING_FIELDS)
    raw = np.empty((m, width), dtype=">u4")
    raw[:, 0] = records[:, 0].astype(np.uint64).astype(np.uint32)
    raw[:, 1:] = records[:, 1:width].astype(">f4").view(">u4")
    words = raw.view(">u2").reshape(m, width, 2).astype(np.int64)
    if word_order == "little":
        words = words[:, :, ::-1]
    if byte_swap:
        words = ((words & 0xFF) << 8) | (words >> 8)
    out: NDArray[np.int64] = words.reshape(m, RING_RECORD_REGISTERS)
    return out


class _ReplyPacer:
    """Holds requests until the PLC's cycle ends and delays replies, as a :class:`ReplyTiming` says.

    Lives on the server's event loop (the runner's): every method is called from it.
    """

    def __init__(self, timing: ReplyTiming) -> None:
        self.timing = timing
        self._waiting: list[asyncio.Future[bool]] = []
        self._timers: set[asyncio.TimerHandle] = set()
        self._replies = 0
        self._rng = random.Random(timing.seed)

    async def wait_for_cycle(self) -> bool:
        """Until the end of the PLC's next cycle (at once without ``in_cycle``); False: stopped."""
        if not self.timing.in_cycle:
            return True
        future: asyncio.Future[bool] = asyncio.get_running_loop().create_future()
        self._waiting.append(future)
        return await future

    def cycle_ended(self) -> None:
        """The PLC published a cycle: the requests waiting for it go on."""
        waiting, self._waiting = self._waiting, []
        for future in waiting:
            if not future.done():
                future.set_result(True)

    def next_delay(self) -> float:
        """How long the next reply waits after it was made [s]."""
        self._replies += 1
        timing = self.timing
        delay = self._rng.uniform(0.0, timing.jitter_s) if timing.jitter_s > 0.0 else 0.0
        if timing.late_every > 0 and self._replies % timing.late_every == 0:
            delay += timing.late_s
        return delay

    def later(self, delay: float, send: Callable[..., None], *args: Any) -> None:
        """Call ``send(*args)`` after ``delay`` [s] (dropped if the server stops first)."""
        loop = asyncio.get_running_loop()

        def fire() -> None:
            self._timers.discard(handle)
            send(*args)

        handle = loop.call_later(delay, fire)
        self._timers.add(handle)

    def close(self) -> None:
        """The server stopped: waiting requests get no answer, delayed replies are dropped."""
        waiting, self._waiting = self._waiting, []
        for future in waiting:
            if not future.done():
                future.set_result(False)
        for handle in self._timers:
            handle.cancel()
        self._timers.clear()


class _PacedHandler(ServerRequestHandler):
    """A connection's request handler that answers as the server's :class:`_ReplyPacer` says."""

    async def handle_request(self) -> None:
        """Wait for the end of the PLC's cycle, then answer from its values."""
        if await self.server.pacer.wait_for_cycle():
            await super().handle_request()  # type: ignore[no-untyped-call]

    def server_send(self, pdu: Any, addr: Any) -> None:
        """Send the reply after the pacer's delay."""
        delay = self.server.pacer.next_delay()
        if delay > 0.0:
            self.server.pacer.later(delay, super().server_send, pdu, addr)
        else:
            super().server_send(pdu, addr)  # type: ignore[no-untyped-call]


class _PacedServer(ModbusTcpServer):
    """pymodbus's TCP server whose connections answer as a :class:`_ReplyPacer` says."""

    def __init__(self, *args: Any, pacer: _ReplyPacer, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.pacer = pacer

    def callback_new_connection(self) -> _PacedHandler:
        """A handler for a new connection."""
        return _PacedHandler(  # type: ignore[no-untyped-call]
            self, self.trace_packet, self.trace_pdu, self.trace_connect
        )


class ModbusFrontend(Frontend):
    """The virtual PLC's points on a Modbus TCP server (see the module docstring)."""

    protocol = "modbus"

    def __init__(
        self,
        host: str,
        port: int,
        *,
        ring_size: int = DEFAULT_RING_SIZE,
        word_order: WordOrder = "big",
        byte_swap: bool = False,
        reply: ReplyTiming | None = None,
    ) -> None:
        super().__init__(
            host, port, ring_size=ring_size, word_order=word_order, byte_swap=byte_swap
        )
        if not host:
            raise ValueError("bind the virtual PLC to an address (never all interfaces by '')")
        self.reply = ReplyTiming() if reply is None else reply
        """When requests are answered (at once by default)."""
        # None: pymodbus's own server, untouched (the default timing)
        self._pacer = None if self.reply.immediate else _ReplyPacer(self.reply)
        self._server: ModbusTcpServer | None = None
        # the PLC's memory, which outlives a stopped server
        self._ir = [0] * IR_POINTS_COUNT
        self._ring = [0] * (ring_size * RING_RECORD_REGISTERS)
        self._hr = [0] * HR_COUNT

    @property
    def serving(self) -> bool:
        """True while the server accepts clients."""
        return self._server is not None

    async def start(self) -> None:
        """Bind ``host:port`` and serve in the background, seeded with the PLC's memory."""
        if self._server is not None:
            return
        bits = [SimData(0, count=16, values=False, datatype=DataType.BITS)]
        holding = [SimData(0, values=list(self._hr), datatype=DataType.REGISTERS)]
        inputs = [
            SimData(0, values=list(self._ir), datatype=DataType.REGISTERS),
            SimData(RING_FIRST_REGISTER, values=list(self._ring), datatype=DataType.REGISTERS),
        ]
        device = SimDevice(id=DEVICE_ID, simdata=(bits, bits, holding, inputs))
        address = (self.host, self.port)
        server = (
            ModbusTcpServer(device, address=address)
            if self._pacer is None
            else _PacedServer(device, address=address, pacer=self._pacer)
        )
        await server.serve_forever(background=True)
        if self.port == 0:  # the OS chose it: say which (a restart binds the same one)
            self.port = bound_port(server.transport, self.port)
        self._server = server

    async def stop(self) -> None:
        """Stop serving (clients' connections close) and release the port."""
        server, self._server = self._server, None
        if server is None:
            return
        if self._pacer is not None:
            self._pacer.close()
        self._hr = [
            int(r) for r in await server.async_getValues(DEVICE_ID, FC_HOLDING, 0, HR_COUNT)
        ]
        await server.shutdown()  # type: ignore[no-untyped-call]

    async def publish(
        self, values: Mapping[str, float], ring: Mapping[int, NDArray[np.float64]]
    ) -> None:
        """Write the read points and the new ring records (the head last)."""
        order, swap = self.word_order, self.byte_swap
        for name, value in values.items():
            point = _READ.get(name)
            if point is None:
                continue
            regs = encode(value, point.type, order, swap)
            self._ir[point.register : point.register + len(regs)] = regs
        head = POINTS["ring_head"].register
        server = self._server
        if server is not None:
            await server.async_setValues(DEVICE_ID, FC_INPUT, 0, self._ir[:head])
        if ring:
            slots = np.fromiter(ring.keys(), dtype=np.int64, count=len(ring))
            records = np.array(list(ring.values()), dtype=float).reshape(-1, len(RING_FIELDS))
            by_slot = np.argsort(slots, kind="stable")
            slots, records = slots[by_slot], records[by_slot]
            words = ring_registers(records, order, swap)
            # one write per run of consecutive slots (at most two: the ring wraps once)
            breaks = np.flatnonzero(np.diff(slots) != 1) + 1
            for run_slots, run_regs in zip(
                np.split(slots, breaks), np.split(words, breaks), strict=True
            ):
                first = int(run_slots[0]) * RING_RECORD_REGISTERS
                flat = run_regs.ravel().tolist()
                self._ring[first : first + len(flat)] = flat
                if server is not None:
                    await server.async_setValues(
                        DEVICE_ID, FC_INPUT, RING_FIRST_REGISTER + first, flat
                    )
        if server is not None:
            await server.async_setValues(DEVICE_ID, FC_INPUT, head, self._ir[head:])
        if self._pacer is not None:
            self._pacer.cycle_ended()

    async def collect(self) -> dict[str, float]:
        """The write points as clients last left them (engineering units)."""
        if self._server is not None:
            regs = await self._server.async_getValues(DEVICE_ID, FC_HOLDING, 0, HR_COUNT)
            self._hr = [int(r) for r in regs]
        order, swap = self.word_order, self.byte_swap
        return {
            name: decode(
                self._hr[p.register : p.register + _SIZE[p.type]], p.type, order, byte_swap=swap
            )
            for name, p in _WRITE.items()
        }
