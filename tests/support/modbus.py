"""A Modbus TCP PLC written in the tests (pymodbus's SimDevice in a thread) and a free port.

Shared by the Modbus adapter's and the recorder's tests; import it after
``pytest.importorskip("pymodbus")``.
"""

from __future__ import annotations

import asyncio
import socket
import threading
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any

from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from support.waiting import wait_until


def free_port() -> int:
    """A loopback port that was free a moment ago.

    One nobody listens on (an unreachable PLC's), or one :class:`FakePlc` binds again after
    :meth:`FakePlc.stop_link` (a restart on the same port, which a port-0 server cannot promise).
    """
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


class FakePlc:
    """A Modbus TCP server in a thread; the PLC's memory lives here and survives a link stop.

    ``program(plc)`` runs every ``period_s`` in the server's thread and returns the input
    register writes ``[(address, words), ...]`` of that scan, published in order (so a ring
    record goes out before the head that points at it). :meth:`stop_link` closes the server
    (clients see the link drop) while the program keeps running, :meth:`start_link` serves the
    current memory again on the same port.
    """

    def __init__(
        self,
        *,
        ir: int = 2100,
        hr: int = 64,
        device_id: int = 1,
        period_s: float = 0.01,
        program: Callable[[FakePlc], list[tuple[int, list[int]]]] | None = None,
    ) -> None:
        self.ir = [0] * ir
        self.hr = [0] * hr
        self.device_id = device_id
        self.period_s = period_s
        self.program = program
        self.scans = 0  # the program's runs so far (see wait_scans)
        self.port = free_port()
        self.server: ModbusTcpServer | None = None
        self.loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self._thread.start()
        self._task = self._call_soon(self._run())
        self.start_link()

    def _call_soon(self, coro: Any) -> Future[Any]:
        return asyncio.run_coroutine_threadsafe(coro, self.loop)

    def _call(self, coro: Any) -> Any:
        return self._call_soon(coro).result(10.0)

    async def _run(self) -> None:
        while True:
            await asyncio.sleep(self.period_s)  # the PLC's scan period: its clock, not a wait
            if self.program is None:
                continue
            for address, words in self.program(self):
                self.ir[address : address + len(words)] = words
                if self.server is not None:
                    await self.server.async_setValues(self.device_id, 4, address, words)
            self.scans += 1

    async def _start(self) -> None:
        regs = [SimData(0, values=list(self.hr), datatype=DataType.REGISTERS)]
        inputs = [SimData(0, values=list(self.ir), datatype=DataType.REGISTERS)]
        bits = [SimData(0, count=16, values=False, datatype=DataType.BITS)]
        device = SimDevice(id=self.device_id, simdata=(bits, bits, regs, inputs))
        server = ModbusTcpServer(device, address=("127.0.0.1", self.port))
        await server.serve_forever(background=True)
        self.server = server
        # a scan that ran while the server started went to memory only: publish it all again
        await server.async_setValues(self.device_id, 4, 0, list(self.ir))

    async def _stop(self) -> None:
        server, self.server = self.server, None
        if server is not None:
            self.hr = list(await server.async_getValues(self.device_id, 3, 0, len(self.hr)))
            await server.shutdown()

    def wait_scans(self, scans: int, timeout: float = 10.0) -> None:
        """Wait until the program has run ``scans`` more times (published to the server)."""
        target = self.scans + scans
        wait_until(lambda: self.scans >= target, timeout, f"{scans} scans of the test PLC")

    def start_link(self) -> None:
        self._call(self._start())

    def stop_link(self) -> None:
        self._call(self._stop())

    def set_ir(self, address: int, words: list[int]) -> None:
        async def put() -> None:
            self.ir[address : address + len(words)] = words
            if self.server is not None:
                await self.server.async_setValues(self.device_id, 4, address, words)

        self._call(put())

    def read_hr(self, address: int, count: int) -> list[int]:
        async def get() -> list[int]:
            assert self.server is not None
            return list(await self.server.async_getValues(self.device_id, 3, address, count))

        return self._call(get())  # type: ignore[no-any-return]

    def close(self) -> None:
        self._task.cancel()
        self.stop_link()
        self.loop.call_soon_threadsafe(self.loop.stop)
        self._thread.join(10.0)
        self.loop.close()
