"""The one interface between the virtual PLC's engine and a protocol server.

The runner (:mod:`fuelid.plc.virtual._runner`) owns the clock: each tick it collects what clients
wrote (:meth:`Frontend.collect`), hands it to the engine, advances the plant and publishes the new
values and ring records (:meth:`Frontend.publish`). A front end is a real server of its protocol
on a real socket (pymodbus, asyncua, python-snap7), laid out as :mod:`fuelid.plc.virtual._points`
says; it holds no plant logic.

:class:`ReplyTiming` says when a server answers (Modbus only): at once by default, or in the PLC's
cycle, with jitter and an occasional late reply, as a PLC whose server block runs in its cyclic
task answers; the client's receipt times then follow the PLC's clock.
"""

from __future__ import annotations

import math
import socket
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import ConfigError
from fuelid.plc._codec import WordOrder
from fuelid.plc.virtual._points import DEFAULT_RING_SIZE


@dataclass(frozen=True)
class ReplyTiming:
    """When the virtual PLC's server answers a request; the default: at once.

    A real PLC whose Modbus server block (an S7's ``MB_SERVER``) is called in its cyclic task
    answers once per cycle, when the block runs: a client that polls faster than the PLC's
    cycle gets its replies at the PLC's cycle, on the PLC's clock (a clock 2 % slow: 20.4 ms
    apart for a 20 ms cycle), and a busy network or CPU now and then delays one.

    Attributes
    ----------
    in_cycle : bool
        Answer each request at the end of the PLC's next cycle (after the cycle has published its
        values; a write is taken at the scan after), not at once.
    jitter_s : float
        Each reply leaves a further random delay after it was made, uniform in
        [0, ``jitter_s``) [s] (seeded). The values are those of the cycle that made it.
    late_every : int
        Every ``late_every``-th reply (counting from the first request served) leaves ``late_s``
        later still: a delayed poll; 0: none.
    late_s : float
        The extra delay of a late reply [s].
    seed : int, optional
        Seed of the jitter (None: fresh entropy).

    Raises
    ------
    ConfigError
        If a delay is negative or not finite, or ``late_every`` negative.

    Examples
    --------
    >>> ReplyTiming().immediate
    True
    >>> ReplyTiming(in_cycle=True, jitter_s=0.002, late_every=250, late_s=0.0172).immediate
    False
    """

    in_cycle: bool = False
    jitter_s: float = 0.0
    late_every: int = 0
    late_s: float = 0.0
    seed: int | None = 0

    def __post_init__(self) -> None:
        for name in ("jitter_s", "late_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ConfigError(f"reply timing: {name} must be zero or positive, got {value!r}")
        if self.late_every < 0:
            raise ConfigError(f"reply timing: late_every must be 0 or more, got {self.late_every}")

    @property
    def immediate(self) -> bool:
        """True when every reply leaves at once (the default)."""
        late = self.late_every > 0 and self.late_s > 0.0
        return not (self.in_cycle or self.jitter_s > 0.0 or late)


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

        ``ring`` maps a slot to its record ``[seq, command, flow, setpoint, excitation]``; the head
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
