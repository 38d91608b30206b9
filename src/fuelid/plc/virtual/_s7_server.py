"""The virtual PLC's S7 front end: a python-snap7 server with two data blocks.

DB1 holds what the PC reads (the mirror of the input registers: byte offset = 2 × register) and
the ring buffer from byte ``2 × RING_FIRST_REGISTER``, one 20-byte record per slot (the sequence
number as a UDInt, then the command, flow, setpoint and excitation as REALs; the default ring of
2048 records ends at byte 42 960, under 64 KiB); DB2 holds what the PC writes
(the mirror of the holding registers). Values are big-endian as S7 stores them: REAL float32,
UDInt uint32, Int int16, UInt/Word uint16. The DBs are not "optimised": every point has the
absolute offset :mod:`fuelid.plc.virtual._points` gives it.

python-snap7 (3.x, pure Python) serves each client from its own thread and reads a DB under the
DB's lock; :meth:`S7Frontend.publish` and :meth:`S7Frontend.collect` take the same lock for the
memory copy only, so a client never sees half an update.

Examples
--------
>>> db1_size(4), db2_size()
(2080, 48)
>>> encode_point(3.5, "float32").hex(), encode_point(27648, "int16").hex()
('40600000', '6c00')
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import socket
import struct
import threading
from collections.abc import Mapping

import numpy as np
import snap7
from numpy.typing import NDArray
from snap7 import SrvArea

from fuelid.plc._codec import WordOrder
from fuelid.plc.virtual._frontend import Frontend
from fuelid.plc.virtual._points import (
    DEFAULT_RING_SIZE,
    POINTS,
    RING_FIELDS,
    RING_FIRST_REGISTER,
    RING_RECORD_REGISTERS,
    S7_READ_DB,
    S7_WRITE_DB,
    Point,
)

# a library does not print: snap7's server logs each refused request (an unknown DB, an offset
# past the end), which would scatter over a console; the application may configure "snap7"
logging.getLogger("snap7").addHandler(logging.NullHandler())

_FORMATS = {"float32": ">f", "uint32": ">I", "int16": ">h", "uint16": ">H"}
_INT_RANGE = {"int16": (-32768, 32767), "uint16": (0, 65535)}
RING_FIRST_BYTE = 2 * RING_FIRST_REGISTER
"""Byte offset of ring slot 0 in DB1."""
RECORD_BYTES = 2 * RING_RECORD_REGISTERS
"""Bytes per ring record: seq UDInt + command, flow, setpoint, excitation REAL."""
_RECORD = struct.Struct(">I" + "f" * (len(RING_FIELDS) - 1))


def _end(point: Point) -> int:
    return 2 * point.register + struct.calcsize(_FORMATS[point.type])


def db1_size(ring_size: int = DEFAULT_RING_SIZE) -> int:
    """Bytes of DB1: the read points and a ring of ``ring_size`` records."""
    points = max(_end(p) for p in POINTS.values() if p.access == "read")
    return max(points, RING_FIRST_BYTE + RECORD_BYTES * ring_size)


def db2_size() -> int:
    """Bytes of DB2: the write points."""
    return max(_end(p) for p in POINTS.values() if p.access == "write")


def encode_point(value: float, type_: str) -> bytes:
    """The big-endian S7 bytes of an engineering value of a point's type.

    REALs carry NaN and inf as they are; a UDInt counter wraps modulo 2³²; Int and UInt saturate
    (as an analog input card does) and NaN becomes 0.
    """
    fmt = _FORMATS[type_]
    if type_ == "float32":
        return struct.pack(fmt, value)
    if not math.isfinite(value):
        value = 0.0 if math.isnan(value) else math.copysign(1e12, value)
    if type_ == "uint32":
        return struct.pack(fmt, int(value) % 2**32)
    low, high = _INT_RANGE[type_]
    return struct.pack(fmt, min(max(round(value), low), high))


class _Server(snap7.Server):
    """snap7's server that also drops its clients' connections when it stops.

    python-snap7 3.3's ``stop()`` closes the listening socket but leaves each client's thread
    waiting up to 5 s for its next request, which it then still answers: a client would not see
    the link drop. Here the client sockets are shut down first, as a PLC going away does.
    """

    def __init__(self) -> None:
        super().__init__(log=False)
        self._sockets: set[socket.socket] = set()
        self._sockets_lock = threading.Lock()

    def _handle_client(self, client_socket: socket.socket, address: tuple[str, int]) -> None:
        with self._sockets_lock:
            self._sockets.add(client_socket)
        try:
            super()._handle_client(client_socket, address)
        finally:
            with self._sockets_lock:
                self._sockets.discard(client_socket)

    def _drop_clients(self) -> None:
        with self._sockets_lock:
            sockets = list(self._sockets)
        for sock in sockets:
            with contextlib.suppress(OSError):  # already closed by its handler
                sock.shutdown(socket.SHUT_RDWR)

    def stop(self) -> int:
        self._drop_clients()
        code = super().stop()
        self._drop_clients()  # any client accepted while stopping
        return code


class S7Frontend(Frontend):
    """The virtual PLC's points as S7 data blocks DB1 (read) and DB2 (write).

    Parameters
    ----------
    host : str
        Address to bind (127.0.0.1 unless the user allows remote clients).
    port : int
        TCP port (S7's own is 102, which needs root; 0 picks a free one, then :attr:`port`).
    ring_size : int
        Records in the ring buffer.
    word_order, byte_swap
        Ignored: S7 data blocks are big-endian.
    """

    protocol = "s7"

    def __init__(
        self,
        host: str,
        port: int,
        *,
        ring_size: int = DEFAULT_RING_SIZE,
        word_order: WordOrder = "big",
        byte_swap: bool = False,
    ) -> None:
        super().__init__(
            host, port, ring_size=ring_size, word_order=word_order, byte_swap=byte_swap
        )
        self.db1 = bytearray(db1_size(ring_size))
        self.db2 = bytearray(db2_size())
        self._server: _Server | None = None

    async def start(self) -> None:
        """Bind ``host:port`` and serve (the DBs keep their contents across restarts)."""
        if self._server is not None:
            return
        server = _Server()
        server.register_area(SrvArea.DB, S7_READ_DB, self.db1)
        server.register_area(SrvArea.DB, S7_WRITE_DB, self.db2)
        server.start_to(self.host, self.port)
        if server.server_socket is not None:
            self.port = int(server.server_socket.getsockname()[1])
        self._server = server

    async def stop(self) -> None:
        """Drop the clients, stop serving and release the port."""
        server, self._server = self._server, None
        if server is not None:
            await asyncio.to_thread(server.stop)

    def _locked_write(self, db: int, updates: list[tuple[int, bytes]]) -> None:
        target = self.db1 if db == S7_READ_DB else self.db2
        server = self._server
        if server is not None:
            server.lock_area(SrvArea.DB, db)
        try:
            for offset, data in updates:
                target[offset : offset + len(data)] = data
        finally:
            if server is not None:
                server.unlock_area(SrvArea.DB, db)

    async def publish(
        self, values: Mapping[str, float], ring: Mapping[int, NDArray[np.float64]]
    ) -> None:
        """Write new ring records and the read points into DB1, the head last, in one lock.

        Parameters
        ----------
        values : mapping of str to float
            Point name → engineering value (V, L/min, °C, s; counters as numbers); names that
            are not read points of :data:`~fuelid.plc.virtual._points.POINTS` are ignored.
        ring : mapping of int to array
            Slot → record ``[seq, command [V], flow [L/min], setpoint [L/min], excitation [V]]``.
        """
        updates: list[tuple[int, bytes]] = []
        width = len(RING_FIELDS)
        for slot, record in ring.items():
            seq, *fields = (float(x) for x in record[:width])
            data = _RECORD.pack(int(seq) % 2**32, *fields)
            updates.append((RING_FIRST_BYTE + RECORD_BYTES * (int(slot) % self.ring_size), data))
        head: tuple[int, bytes] | None = None
        for name, value in values.items():
            point = POINTS.get(name)
            if point is None or point.access != "read":
                continue
            item = (2 * point.register, encode_point(float(value), point.type))
            if name == "ring_head":
                head = item
            else:
                updates.append(item)
        if head is not None:
            updates.append(head)
        self._locked_write(S7_READ_DB, updates)

    async def collect(self) -> dict[str, float]:
        """The write points as clients last left them in DB2 (engineering values)."""
        server = self._server
        if server is not None:
            server.lock_area(SrvArea.DB, S7_WRITE_DB)
        try:
            data = bytes(self.db2)
        finally:
            if server is not None:
                server.unlock_area(SrvArea.DB, S7_WRITE_DB)
        out: dict[str, float] = {}
        for point in POINTS.values():
            if point.access == "write":
                (value,) = struct.unpack_from(_FORMATS[point.type], data, 2 * point.register)
                out[point.name] = float(value)
        return out
