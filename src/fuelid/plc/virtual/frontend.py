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
from typing import Any

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
        TCP port; 0 lets the OS pick a free one as the server binds, and :attr:`port` says which
        once :meth:`start` returns (a later :meth:`start` binds the same one).
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
        """Bind and serve in the background (returns once clients can connect).

        With port 0 asked for, :attr:`port` is the bound port when this returns.
        """

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
    """A TCP port free on ``host`` now (the OS picks it).

    Another process may take it before it is bound again: a server that can bind port 0 itself
    (every front end can) should, and report the port it got.
    """
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as sock:
        sock.bind((host, 0))
        port: int = sock.getsockname()[1]
        return port


def bound_port(server: Any, asked: int) -> int:
    """The TCP port an asyncio server (``loop.create_server``) is bound to; ``asked`` if unknown.

    Parameters
    ----------
    server : asyncio.Server or None
        The listening server (its ``sockets``).
    asked : int
        The port asked for.

    Examples
    --------
    >>> bound_port(None, 5020)
    5020
    """
    for sock in getattr(server, "sockets", None) or ():
        port = int(sock.getsockname()[1])
        if port:
            return port
    return asked
