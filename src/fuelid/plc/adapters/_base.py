"""The one small interface every PLC link implements (Modbus TCP, OPC UA, S7, a replayed log).

An adapter knows its protocol: how to reach the PLC, how to read the site file's tags in as few
requests as possible, how to decode and scale them to engineering units (V, L/min, °C) and how
to write the write side (and read it back: :meth:`PlcSource.read_write_side`, for the PLC's echo
of the apply number). It knows nothing of sampling schedules, quality flags or the store:
that is the recorder's job (:mod:`fuelid.plc._recorder`). All methods are coroutines; a
synchronous library (python-snap7) runs in a thread.

Errors: a link that cannot be reached, drops or times out raises :class:`LinkError` (the recorder
retries with backoff and records the outage); an address the PLC does not have, a wrong device
id or NodeId raises :class:`~fuelid.errors.ConfigError` naming the site-file key (retrying cannot
help).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import TracebackType
from typing import Self

from fuelid.errors import ConfigError, FuelidError
from fuelid.plc.site import SiteConfig, Tag


class LinkError(FuelidError):
    """The PLC cannot be reached, or the link dropped or timed out (one-line reason)."""


class EndOfSource(FuelidError):
    """The source has nothing more to give (a replayed log played to its end).

    Not an error: the recorder stores what it has and stops cleanly. A PLC never raises it.
    """


@dataclass(frozen=True)
class Reading:
    """One read of the site's read tags.

    Parameters
    ----------
    values : dict of str to float
        Role → engineering value (after the tag's raw → eng scaling), in the role's unit; NaN
        where the PLC answered with something that is not a number.
    raw : dict of str to float
        Role → the raw value as decoded from the wire (before scaling), for range checks.
    received : float
        When the answer arrived, UTC seconds since the epoch [s].
    """

    values: dict[str, float]
    raw: dict[str, float]
    received: float


@dataclass(frozen=True)
class RingRecord:
    """One record of the PLC's ring buffer: the PLC's sequence number and the fields' values.

    ``seq`` is the raw uint32 counter (the recorder unwraps it); ``values`` maps the ring's other
    fields (command, flow, setpoint) to engineering values.
    """

    seq: int
    values: dict[str, float] = field(default_factory=dict)


class PlcSource(ABC):
    """A connection to one PLC, as the site file describes it."""

    def __init__(self, site: SiteConfig) -> None:
        self.site = site

    @property
    def has_ring(self) -> bool:
        """Whether the site file maps a ring buffer (``[ring]``)."""
        return self.site.ring is not None

    @property
    def where(self) -> str:
        """The endpoint in words, for messages (``modbus 127.0.0.1:5020 unit 1``)."""
        plc = self.site.plc
        return f"{plc.protocol} {plc.host}:{plc.port or plc.default_port}"

    @abstractmethod
    async def connect(self) -> None:
        """Open the link (one attempt; the recorder loops with backoff).

        Raises
        ------
        LinkError
            The PLC cannot be reached.
        """

    @abstractmethod
    async def close(self) -> None:
        """Close the link (never raises)."""

    @abstractmethod
    async def read(self) -> Reading:
        """Read every read tag (``[tags.*]``), in as few requests as the protocol allows.

        Raises
        ------
        LinkError
            No answer, a dropped link or a timeout.
        ConfigError
            The PLC has no such address/node (the message names the site-file key).
        """

    async def read_ring_head(self) -> int:
        """The raw uint32 sequence number of the newest ring record (``[ring] head``)."""
        raise NotImplementedError(f"{type(self).__name__} reads no ring buffer")

    async def read_ring(self, first_slot: int, count: int) -> list[RingRecord]:
        """Records of slots ``first_slot … first_slot + count − 1`` (no wrap; the caller splits).

        Reads in blocks as large as the protocol allows (Modbus: 125 registers per request).
        """
        raise NotImplementedError(f"{type(self).__name__} reads no ring buffer")

    @abstractmethod
    async def write(self, values: Mapping[str, float]) -> None:
        """Write write-side roles (``[write.*]``: kc, ti, apply, heartbeat) in engineering units.

        Roles at contiguous addresses go in one request, so staged gains and the apply word
        arrive together (the PLC applies them as one block).

        Raises
        ------
        LinkError
            The write did not reach the PLC (it may or may not have been applied: read
            the echo with :meth:`read_write_side`).
        ConfigError
            A role the site file does not map, or an address the PLC does not have.
        """

    @abstractmethod
    async def read_write_side(self, roles: Sequence[str]) -> dict[str, float]:
        """Read roles of the write side (``[write.*]``) back from the PLC, in engineering units.

        Every write role can be read, including ``echo``, which the PLC alone writes (read-only
        on the PLC: the apply number of the set it last applied, 0 before any). This is how a
        gain write is verified: write staged kc, ti and a new apply number, then read ``echo``
        until it equals that number (the applied gains themselves are the read tags ``kc`` and
        ``ti`` of :meth:`read`). The other roles read back what the PLC holds in its write area.
        All roles asked for go in as few requests as the protocol allows.

        Parameters
        ----------
        roles : sequence of str
            Write-side roles (``kc``, ``ti``, ``apply``, ``echo``, ``heartbeat``) the site file
            maps; each at most once is read (repeats are ignored).

        Returns
        -------
        dict of str to float
            Role → engineering value, in the order asked (raw value scaled as the tag says, like
            :meth:`read`: kc in V per L/min, ti in s, the apply number, echo and heartbeat as
            plain numbers); NaN where the PLC answered with something that is not a number.

        Raises
        ------
        ConfigError
            A role the site file's write side does not map (the message names ``write.<role>``),
            an address the PLC does not have, or a source that has no write side (a replay).
        LinkError
            Not connected, no answer, a dropped link or a timeout.
        """

    def _write_side_tags(self, roles: Sequence[str]) -> dict[str, Tag]:
        """The write-side tags of ``roles``, in order and once each; unknown roles are refused.

        Checked before any request, so a wrong role is a ConfigError whatever the link's state
        (retrying cannot help).
        """
        if isinstance(roles, str):  # "echo" would be read as the roles e, c, h, o
            raise TypeError(f"roles: a sequence of roles, not the string {roles!r}")
        tags: dict[str, Tag] = {}
        for role in roles:
            tag = self.site.write.get(role)
            if tag is None:
                mapped = ", ".join(self.site.write) or "none"
                raise ConfigError(
                    f"write.{role}: the site file maps no such write tag (mapped: {mapped})"
                )
            tags[role] = tag
        return tags

    async def __aenter__(self) -> Self:
        await self.connect()
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        await self.close()
