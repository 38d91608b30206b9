"""The PLC's side of fuelid's writes: the heartbeat, the staged block and its echo, the signal.

A write is one request carrying the block (Kc, Ti, a new apply number) in the ``[controller]``
form and units; the PLC takes the block when the apply number changes and echoes that number
back. The writer waits ``timeout_s`` for the echo; whether to revert when it does not come is
the caller's decision (:mod:`fuelid.online._writeback`). The heartbeat word tells the PLC a
writer is alive (any change counts).

The writer keeps a connection of its own (the recorder keeps another) and puts one request at
a time on it. Nothing here knows about proposals or the online history.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time

from fuelid.errors import FuelidError
from fuelid.plc.adapters._base import LinkError, PlcSource

HEARTBEAT_MODULUS = 65536
"""The heartbeat word is a uint16: it wraps at this value."""


class GainWriter:
    """Writes one gain block and checks the PLC's echo, on a connection of its own.

    Parameters
    ----------
    source : PlcSource
        A second connection to the PLC (the recorder keeps its own).
    timeout_s : float
        How long to wait for the echo [s of wall time].
    """

    def __init__(self, source: PlcSource, timeout_s: float) -> None:
        self.source = source
        self.timeout_s = float(timeout_s)
        self._connected = False
        self._heartbeat = 0
        self._lock: asyncio.Lock | None = None

    async def _ensure(self) -> None:
        if not self._connected:
            await self.source.connect()
            self._connected = True

    async def close(self) -> None:
        """Close the write connection (also after a link error, so no socket is left open)."""
        with contextlib.suppress(Exception):
            await self.source.close()
        self._connected = False

    def _guard(self) -> asyncio.Lock:
        # one request at a time on this link: the heartbeat task and a write must not race
        # (two connects of one client leave a transport open)
        if self._lock is None:
            self._lock = asyncio.Lock()
        return self._lock

    async def beat(self) -> None:
        """Change the heartbeat word (any change counts; the uint16 wraps)."""
        async with self._guard():
            try:
                await self._ensure()
                self._heartbeat = (self._heartbeat + 1) % HEARTBEAT_MODULUS
                await self.source.write({"heartbeat": float(self._heartbeat)})
            except LinkError:
                await self.close()
                raise

    async def heartbeat(self, stopping: asyncio.Event, every_s: float) -> None:
        """Beat every ``every_s`` of wall time until ``stopping`` is set (link errors pass)."""
        while not stopping.is_set():
            with contextlib.suppress(LinkError, FuelidError):
                await self.beat()
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(stopping.wait(), every_s)

    async def echo(self) -> int | None:
        """The PLC's echo of the last apply number taken; None when it cannot be read."""
        async with self._guard():
            return await self._echo()

    async def _echo(self) -> int | None:
        try:
            await self._ensure()
            values = await self.source.read_write_side(["echo"])
        except LinkError:
            await self.close()
            return None
        value = values.get("echo", math.nan)
        return round(value) if math.isfinite(value) else None

    async def write_block(self, kc: float, ti: float, apply_seq: int) -> bool:
        """Write (kc, ti, apply) in one request and wait for the echo; True when echoed.

        Parameters
        ----------
        kc, ti : float
            The gains in the ``[controller]`` form and units.
        apply_seq : int
            The new apply number (the PLC takes the block when it changes).

        Returns
        -------
        bool
            True when the PLC echoed ``apply_seq`` within ``timeout_s`` [s of wall time].
        """
        async with self._guard():
            try:
                await self._ensure()
                await self.source.write({"kc": kc, "ti": ti, "apply": float(apply_seq)})
            except LinkError:
                await self.close()
                # it may or may not have arrived: the echo says
        deadline = time.monotonic() + self.timeout_s
        while time.monotonic() < deadline:
            if await self.echo() == apply_seq:
                return True
            await asyncio.sleep(min(0.05, self.timeout_s / 20.0))
        return False

    async def set_excitation(self, value: float) -> None:
        """Write the test signal's register (``[write.excitation]``) [V].

        No echo: the PLC's read-back of the applied signal (``tags.excitation``) comes with
        every sample, and the PLC zeroes the signal itself when the heartbeat goes stale.

        Raises
        ------
        LinkError
            When the write did not go through (the connection is closed for the next try).
        """
        async with self._guard():
            try:
                await self._ensure()
                await self.source.write({"excitation": float(value)})
            except LinkError:
                await self.close()
                raise


__all__ = ["HEARTBEAT_MODULUS", "GainWriter"]
