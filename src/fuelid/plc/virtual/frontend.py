"""The one interface between the virtual PLC's engine and a protocol server.

The runner (:mod:`fuelid.plc.virtual.runner`) owns the clock: each tick it collects what clients
wrote (:meth:`Frontend.collect`), hands it to the engine, advances the plant and publishes the new
values and ring records (:meth:`Frontend.publish`). A front end is a real server of its protocol
on a real socket (pymodbus, asyncua, python-snap7), laid out as :mod:`fuelid.plc.virtual.points`
says; it holds no plant logic.
"""

from __future__ import annotations

import socket
from abc import ABC, abstractmethod
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from fuelid.plc.codec import WordOrder
from fuelid.plc.virtual.points import DEFAULT_RING_SIZE


class Frontend(ABC):
    """A protocol server exposing the virtual PLC's points.

    Parameters
    ----------
    host : str
        Address to bind (127.0.0.1 unless the user allows remote clients).
    port : int
        TCP port.
    ring_size : int
        Records in the ring buffer.
    word_order, byte_swap
        How 32-bit values are laid out in registers (Modbus only).
    """

    protocol: str = ""

    def __init__(
        self,
        host: str,
        port: int,
        *,
        ring_size: int = DEFAULT_RING_SIZE,
        word_order: WordOrder = "big",
        byte_swap: bool = False,
    ) -> None:
        self.host = host
        self.port = port
        self.ring_size = ring_size
        self.word_order: WordOrder = word_order
        self.byte_swap = byte_swap

    @abstractmethod
    async def start(self) -> None:
        """Bind and serve in the background (returns once clients can connect)."""

    @abstractmethod
    async def stop(self) -> None:
        """Stop serving and release the port (clients see the link drop)."""

    @abstractmethod
    async def publish(
        self, values: Mapping[str, float], ring: Mapping[int, NDArray[np.float64]]
    ) -> None:
        """Write the read points (name → engineering value) and new ring records.

        ``ring`` maps a slot to its record ``[seq, command, flow, setpoint]``; the head
        (``ring_head`` in ``values``) is published after the records, so a client never sees a
        head that points at a record not yet written.
        """

    @abstractmethod
    async def collect(self) -> dict[str, float]:
        """The write points (name → engineering value) as clients last left them."""


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port free on ``host`` now (the OS picks it)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as sock:
        sock.bind((host, 0))
        port: int = sock.getsockname()[1]
        return port
