"""Siemens S7 (S7-300/400/1200/1500, ISO-on-TCP port 102) through python-snap7.

Tags are absolute data-block addresses: ``DB1.DBD0`` (4 bytes: float32, int32, uint32),
``DB1.DBW4`` (2 bytes: int16, uint16), ``DB1.DBX8.3`` (bit 3 of byte 8: bool), big-endian as S7
stores them. On an S7-1200/1500 the DB must not use "optimized block access" (absolute offsets
exist only then) and the CPU must allow PUT/GET communication.

Requests: the read tags are grouped by DB and each DB's span (first to last byte) is read as one
block; spans longer than the negotiated PDU allows (PDU − 18 bytes: 222 for a 240-byte PDU, 462
for 480) are cut between tags, and several blocks (other DBs, or a cut span) travel together in
one multi-item request as far as the PDU holds them (python-snap7's ``read_multi_vars``), so a
typical site file is read in one request. Write-side roles are read back the same way
(:meth:`S7Source.read_write_side`, for the PLC's ``echo`` of the apply number, which usually
lives in the DB the PC reads, not in the one it writes). Ring slices are one ``db_read`` that
python-snap7 cuts into PDU-sized requests. Write roles at contiguous addresses go in one
``db_write``.

python-snap7's client is synchronous: each call runs in a worker thread
(:func:`asyncio.to_thread`), one at a time. Its own reconnection is off: a dropped link raises
:class:`~fuelid.plc.adapters._base.LinkError` and the recorder calls :meth:`S7Source.connect`
again.

Examples
--------
>>> parse_address("DB1.DBD4")
S7Address(db=1, kind='D', byte=4, bit=None)
>>> parse_address("DB2.DBX8.3").length, parse_address("DB2.DBW10").length
(1, 2)
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import re
import struct
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TypeVar

from snap7 import Area, Client, WordLen
from snap7.error import S7Error, S7PacketLostError, S7ProtocolError, S7StalePacketError

from fuelid.errors import ConfigError, DataError
from fuelid.plc.adapters._base import LinkError, PlcSource, Reading, RingRecord
from fuelid.plc.site import SiteConfig, Tag

# a library does not print: snap7 logs connects, failures and reconnects, which would scatter
# over the recorder's status line; the application may still configure "snap7"
logging.getLogger("snap7").addHandler(logging.NullHandler())

_T = TypeVar("_T")

_ADDRESS = re.compile(r"^DB(\d+)\.DB([XBWD])(\d+)(?:\.([0-7]))?$")
_LENGTH = {"X": 1, "B": 1, "W": 2, "D": 4}
_FORMATS = {"float32": ">f", "int32": ">i", "uint32": ">I", "int16": ">h", "uint16": ">H"}
_REFUSED = re.compile(r"failed(: .*\(0x[0-9a-f]{2}\)$| with S7 error code)")
READ_OVERHEAD = 18
"""Bytes of a read reply's PDU that are not data (12 header, 2 parameter, 4 item header)."""
_MULTI_MAX = 20  # python-snap7's Client.MAX_VARS: items per multi-item request
_HINT = (
    "check that the DB exists and is long enough, that it is not 'optimized' (S7-1200/1500: "
    "absolute offsets need optimized block access off) and that the CPU permits PUT/GET"
)


@dataclass(frozen=True)
class S7Address:
    """An absolute data-block address.

    Parameters
    ----------
    db : int
        Data block number.
    kind : str
        ``X`` bit, ``B`` byte, ``W`` word (2 bytes), ``D`` double word (4 bytes).
    byte : int
        Byte offset in the DB.
    bit : int or None
        Bit 0–7 of a ``DBX`` address.
    """

    db: int
    kind: str
    byte: int
    bit: int | None

    @property
    def length(self) -> int:
        """Bytes the value occupies (a bit is read as its byte)."""
        return _LENGTH[self.kind]

    @property
    def end(self) -> int:
        """The byte after the value."""
        return self.byte + self.length


def parse_address(text: str) -> S7Address:
    """The parts of an S7 address ``DB<n>.DB<X|B|W|D><byte>[.<bit>]``.

    Raises
    ------
    ConfigError
        Not an S7 data-block address.
    """
    match = _ADDRESS.match(text)
    if match is None:
        raise ConfigError(f"{text!r} is not an S7 address such as DB1.DBD0")
    bit = match.group(4)
    return S7Address(
        int(match.group(1)), match.group(2), int(match.group(3)), None if bit is None else int(bit)
    )


@dataclass(frozen=True)
class _Item:
    """One tag of the site file, located."""

    key: str
    role: str
    tag: Tag
    address: S7Address


@dataclass(frozen=True)
class _Span:
    """A block of one DB read in one piece, and the tags in it."""

    db: int
    start: int
    length: int
    items: tuple[_Item, ...]


class _Refused(Exception):
    """The PLC answered but refused an address (wrapped S7 error)."""


def plan_spans(items: Sequence[_Item], max_bytes: int) -> list[_Span]:
    """Group tags by DB into blocks from the first to the last byte, none over ``max_bytes``."""
    spans: list[_Span] = []
    ordered = sorted(items, key=lambda it: (it.address.db, it.address.byte, it.address.end))
    current: list[_Item] = []
    for item in ordered:
        if current:
            first = current[0].address
            end = max(it.address.end for it in [*current, item])
            if item.address.db != first.db or end - first.byte > max_bytes:
                spans.append(_span(current))
                current = []
        current.append(item)
    if current:
        spans.append(_span(current))
    return spans


def _span(items: list[_Item]) -> _Span:
    start = items[0].address.byte
    end = max(it.address.end for it in items)
    return _Span(items[0].address.db, start, end - start, tuple(items))


def decode_value(data: bytes | bytearray, offset: int, address: S7Address, type_: str) -> float:
    """The raw value of a tag of type ``type_`` at ``offset`` in ``data`` (big-endian).

    Examples
    --------
    >>> decode_value(bytes.fromhex("40600000"), 0, parse_address("DB1.DBD0"), "float32")
    3.5
    >>> decode_value(bytes([0b1000]), 0, parse_address("DB1.DBX0.3"), "bool")
    1.0
    """
    if type_ == "bool":
        return float((data[offset] >> (address.bit or 0)) & 1)
    (value,) = struct.unpack_from(_FORMATS[type_], data, offset)
    return float(value)


def encode_value(raw: float, type_: str, key: str) -> bytes:
    """The big-endian bytes of a raw value of type ``type_`` (integers rounded).

    Raises
    ------
    DataError
        The value does not fit the type (the message names ``key``).
    """
    if type_ == "bool":
        return bytes([1 if raw else 0])
    fmt = _FORMATS[type_]
    try:
        return struct.pack(fmt, raw if type_ == "float32" else round(raw))
    except (struct.error, ValueError, OverflowError):
        raise DataError(f"{key}: {raw!r} does not fit a {type_}") from None


def _refused(exc: S7Error) -> bool:
    """Whether the PLC answered with a refusal (no such DB/address, access denied)."""
    if not isinstance(exc, S7ProtocolError):
        return False
    if isinstance(exc, (S7StalePacketError, S7PacketLostError)):
        return False
    return bool(exc.error_code) or _REFUSED.search(str(exc)) is not None


class S7Source(PlcSource):
    """A link to a Siemens S7 CPU, as the site file describes it (``protocol = "s7"``)."""

    def __init__(self, site: SiteConfig) -> None:
        super().__init__(site)
        self._client: Client | None = None
        self._lock = asyncio.Lock()
        self._read_items = [
            _Item(f"tags.{role}", role, tag, parse_address(tag.address))
            for role, tag in site.tags.items()
        ]
        self._write_items = {
            role: _Item(f"write.{role}", role, tag, parse_address(tag.address))
            for role, tag in site.write.items()
        }

    @property
    def where(self) -> str:
        """The endpoint in words: ``s7 127.0.0.1:102 rack 0 slot 1``."""
        plc = self.site.plc
        return f"{super().where} rack {plc.rack} slot {plc.slot}"

    @property
    def pdu_length(self) -> int:
        """The PDU length negotiated with the CPU (240 or 480 typically; 240 before connect)."""
        return self._client.pdu_length if self._client is not None else 240

    @property
    def max_read(self) -> int:
        """Data bytes one read request returns (PDU − 18)."""
        return self.pdu_length - READ_OVERHEAD

    async def connect(self) -> None:
        """Open the link (one attempt, no background reconnection).

        Raises
        ------
        LinkError
            The CPU cannot be reached or refuses the connection (wrong rack/slot).
        """
        await self.close()
        plc = self.site.plc
        port = plc.port or plc.default_port
        client = Client()
        try:
            await asyncio.to_thread(client.connect, plc.host, plc.rack, plc.slot, tcp_port=port)
        except (S7Error, OSError) as exc:
            await asyncio.to_thread(_disconnect, client)
            raise LinkError(f"{self.where}: cannot connect ({exc})") from None
        self._client = client

    async def close(self) -> None:
        """Close the link (never raises)."""
        client, self._client = self._client, None
        if client is not None:
            await asyncio.to_thread(_disconnect, client)

    async def _call(self, work: Callable[[Client], _T]) -> _T:
        """Run ``work(client)`` in a thread; a link failure closes the link and raises LinkError.

        Raises
        ------
        LinkError
            Not connected, or the link dropped or timed out.
        _Refused
            The CPU answered with a refusal.
        """
        async with self._lock:
            client = self._client
            if client is None:
                raise LinkError(f"{self.where}: not connected")
            try:
                return await asyncio.to_thread(work, client)
            except (S7Error, OSError) as exc:
                if isinstance(exc, S7Error) and _refused(exc):
                    raise _Refused(str(exc)) from None
                self._client = None
                await asyncio.to_thread(_disconnect, client)
                raise LinkError(f"{self.where}: link lost ({exc})") from None

    async def _read_spans(self, spans: Sequence[_Span]) -> list[bytearray]:
        def work(client: Client) -> list[bytearray]:
            if len(spans) == 1:
                span = spans[0]
                return [client.db_read(span.db, span.start, span.length)]
            blocks: list[bytearray] = []
            for first in range(0, len(spans), _MULTI_MAX):
                group = spans[first : first + _MULTI_MAX]
                request = [
                    {"area": Area.DB, "db_number": s.db, "start": s.start, "size": s.length}
                    for s in group
                ]
                if len(request) == 1:
                    blocks.append(client.db_read(group[0].db, group[0].start, group[0].length))
                else:
                    _code, data = client.read_multi_vars(request)
                    blocks.extend(bytearray(d) for d in data)
            return blocks

        return await self._call(work)

    async def _probe(self, items: Sequence[_Item], reason: str) -> ConfigError:
        """The ConfigError naming the first tag the CPU refuses (each read on its own)."""
        for item in items:
            span = _span([item])
            try:
                await self._read_spans([span])
            except _Refused as exc:
                return _refusal(item, str(exc))
        keys = ", ".join(f"{it.key} ({it.tag.address})" for it in items)
        return ConfigError(f"{self.where}: the PLC refuses {keys}: {reason}; {_HINT}")

    async def read(self) -> Reading:
        """Read every read tag, one block per DB span (usually one request in all).

        Raises
        ------
        LinkError
            Not connected, no answer, a dropped link or a timeout.
        ConfigError
            The CPU has no such DB or offset, or refuses access (names the site-file key).
        """
        values, raw, received = await self._read_tags(self._read_items)
        return Reading(values=values, raw=raw, received=received)

    async def read_write_side(self, roles: Sequence[str]) -> dict[str, float]:
        """Read write-side roles back (e.g. ``echo``), a block per DB span, scaled as :meth:`read`.

        The spans of all roles travel in one multi-item request as far as the PDU holds them: on
        the virtual PLC ``echo`` (``DB1.DBD32``) and the staged set (DB2) are one request.

        Parameters
        ----------
        roles : sequence of str
            Roles of ``[write.*]`` (``kc``, ``ti``, ``apply``, ``echo``, ``heartbeat``).

        Returns
        -------
        dict of str to float
            Role → engineering value (the tag's raw → eng scaling applied).

        Raises
        ------
        ConfigError
            A role the write side does not map (``write.<role>``), or the CPU has no such DB or
            offset, or refuses access (names the site-file key).
        LinkError
            Not connected, no answer, a dropped link or a timeout.
        """
        tags = self._write_side_tags(roles)
        if not tags:
            return {}
        values, _, _ = await self._read_tags([self._write_items[role] for role in tags])
        return {role: values[role] for role in tags}  # in the order asked, not by address

    async def _read_tags(
        self, items: Sequence[_Item]
    ) -> tuple[dict[str, float], dict[str, float], float]:
        """Read tags in DB spans: role → engineering value, role → raw value, and when [s].

        Raises
        ------
        LinkError, ConfigError
            As :meth:`read` (a refusal is probed tag by tag to name the key).
        """
        spans = plan_spans(items, self.max_read)
        try:
            blocks = await self._read_spans(spans)
        except _Refused as exc:
            raise await self._probe(items, str(exc)) from None
        received = time.time()
        values: dict[str, float] = {}
        raw: dict[str, float] = {}
        for span, block in zip(spans, blocks, strict=True):
            for item in span.items:
                value = decode_value(
                    block, item.address.byte - span.start, item.address, item.tag.type
                )
                raw[item.role] = value
                values[item.role] = item.tag.to_engineering(value)
        return values, raw, received

    def _ring_item(self, key: str) -> _Item:
        ring = self.site.ring
        if ring is None:
            raise NotImplementedError(f"{self.where}: the site file maps no [ring]")
        text = ring.head if key == "ring.head" else ring.address
        return _Item(key, key, Tag(address=text, type="uint32"), parse_address(text))

    async def read_ring_head(self) -> int:
        """The raw uint32 sequence number of the newest ring record (``[ring] head``).

        Raises
        ------
        LinkError, ConfigError
            As :meth:`read`.
        """
        item = self._ring_item("ring.head")
        try:
            (block,) = await self._read_spans([_span([item])])
        except _Refused as exc:
            raise _refusal(item, str(exc)) from None
        return int(struct.unpack_from(">I", block, 0)[0])

    async def read_ring(self, first_slot: int, count: int) -> list[RingRecord]:
        """Records of slots ``first_slot … first_slot + count − 1`` (no wrap; the caller splits).

        One ``db_read``, which python-snap7 cuts into PDU-sized requests.

        Raises
        ------
        ValueError
            The slots are not inside the ring.
        LinkError, ConfigError
            As :meth:`read`.
        """
        ring = self.site.ring
        item = self._ring_item("ring.address")
        assert ring is not None  # _ring_item raised otherwise
        if count <= 0:
            return []
        if first_slot < 0 or first_slot + count > ring.size:
            raise ValueError(
                f"slots {first_slot}…{first_slot + count - 1} outside 0…{ring.size - 1}"
            )
        record = 4 * len(ring.fields)
        start = item.address.byte + first_slot * record

        def work(client: Client) -> bytearray:
            return client.db_read(item.address.db, start, count * record)

        try:
            block = await self._call(work)
        except _Refused as exc:
            raise _refusal(
                item, str(exc), extent=f"{count} records from slot {first_slot}"
            ) from None
        fmt = struct.Struct(">I" + "f" * (len(ring.fields) - 1))
        out: list[RingRecord] = []
        for n in range(count):
            seq, *fields = fmt.unpack_from(block, n * record)
            out.append(
                RingRecord(int(seq), dict(zip(ring.fields[1:], map(float, fields), strict=True)))
            )
        return out

    async def write(self, values: Mapping[str, float]) -> None:
        """Write write-side roles in engineering units; contiguous ones in one ``db_write``.

        Blocks go in address order, except that the block holding ``apply`` goes last, so the
        PLC never sees an apply number before its staged gains.

        Raises
        ------
        ConfigError
            A role the site file does not map, or an address the CPU refuses.
        DataError
            A value that does not fit its type.
        LinkError
            The write did not reach the PLC (it may or may not have been applied).
        """
        items: list[tuple[_Item, bytes]] = []
        for role, value in values.items():
            item = self._write_items.get(role)
            if item is None:
                mapped = ", ".join(self._write_items) or "none"
                raise ConfigError(f"write.{role}: not in the site file (mapped: {mapped})")
            items.append((item, encode_value(item.tag.to_raw(value), item.tag.type, item.key)))
        groups = _contiguous(items)
        groups.sort(key=lambda group: any(it.role == "apply" for it, _ in group))
        for group in groups:
            first = group[0][0].address

            def work(
                client: Client, first: S7Address = first, group: list[tuple[_Item, bytes]] = group
            ) -> None:
                if first.kind == "X":
                    start = 8 * first.byte + (first.bit or 0)
                    client.write_area(Area.DB, first.db, start, bytearray(group[0][1]), WordLen.Bit)
                else:
                    client.db_write(first.db, first.byte, bytearray(b"".join(d for _, d in group)))

            try:
                await self._call(work)
            except _Refused as exc:
                keys = ", ".join(it.key for it, _ in group)
                addresses = ", ".join(it.tag.address for it, _ in group)
                raise ConfigError(
                    f"{keys}: the PLC refuses writing {addresses} ({self.where}): {exc}; {_HINT}"
                ) from None


def _contiguous(items: list[tuple[_Item, bytes]]) -> list[list[tuple[_Item, bytes]]]:
    """Group byte-addressed writes that follow each other without a gap (bits stay alone)."""
    ordered = sorted(items, key=lambda pair: (pair[0].address.db, pair[0].address.byte))
    groups: list[list[tuple[_Item, bytes]]] = []
    for item, data in ordered:
        if groups and item.address.kind != "X":
            last = groups[-1][-1][0].address
            if last.kind != "X" and last.db == item.address.db and last.end == item.address.byte:
                groups[-1].append((item, data))
                continue
        groups.append([(item, data)])
    return groups


def _refusal(item: _Item, reason: str, extent: str = "") -> ConfigError:
    where = f"{item.tag.address}" + (f", {extent}" if extent else "")
    return ConfigError(f"{item.key}: the PLC refuses {where}: {reason}; {_HINT}")


def _disconnect(client: Client) -> None:
    with contextlib.suppress(S7Error, OSError):  # closing a dead link
        client.disconnect()
