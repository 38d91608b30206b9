"""Modbus TCP: the site file's tags in as few requests as possible, through pymodbus's async client.

The read tags are grouped by register area (input registers, holding registers, coils, discrete
inputs) and each area is read in one request spanning its lowest to its highest address, as long
as the span fits the protocol's limit (125 registers, 2000 bits); a wider map is split into
several spans. One request per area is also what keeps the values of one area from the same PLC
scan (values across areas are not scan-consistent: only the ring buffer is).

32-bit values are decoded with :mod:`fuelid.plc._codec` (word order and byte swap of ``[plc]``)
and scaled with :meth:`~fuelid.plc.site.Tag.to_engineering`.

:meth:`ModbusSource.read_write_side` reads write-side roles back the same way (one request per
area): the staged gains, apply and heartbeat from holding registers, and the PLC's ``echo`` of the
apply number, which is read-only and usually an input register (``ir:16`` on the virtual PLC).

Errors (the recorder retries a :class:`~fuelid.plc.adapters._base.LinkError`; a
:class:`~fuelid.errors.ConfigError` stops it, since retrying cannot help):

* no TCP connection, a dropped link or no answer within the timeout → ``LinkError`` naming
  ``host:port`` and the timeout; a timeout is a link's trouble (a blip the next poll recovers
  from, as often as not), so it gives no advice about the device id: only a device that answers
  says its unit is wrong (below);
* Modbus exception 2 (illegal data address) → ``ConfigError`` naming the site-file key and
  address, e.g. ``tags.flow: ir:20 does not exist on the PLC (Modbus exception 2)``;
* exceptions 4, 10 and 11 (device failure, gateway path unavailable, gateway target failed to
  respond: what a wrong ``device_id`` gives behind a gateway, and on pymodbus's own server) →
  ``ConfigError`` naming ``plc.device_id``.

pymodbus's own background reconnect is switched off (``reconnect_delay=0``): the recorder owns
the connect loop and its backoff, so a link state is never changed behind its back.
"""

from __future__ import annotations

import contextlib
import logging
import re
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from pymodbus.client import AsyncModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException

from fuelid.errors import ConfigError
from fuelid.plc import _codec as codec
from fuelid.plc._site_addresses import REGISTERS_OF
from fuelid.plc.adapters._base import LinkError, PlcSource, Reading, RingRecord
from fuelid.plc.site import SiteConfig, Tag

# a library does not print: pymodbus logs every failed connect and a server's tracebacks, which
# would scatter over the recorder's status line; the application may still configure "pymodbus"
logging.getLogger("pymodbus").addHandler(logging.NullHandler())

MAX_REGISTERS = 125
"""Registers per read request (Modbus: 125 for function codes 3 and 4)."""
MAX_BITS = 2000
"""Bits per read request (function codes 1 and 2)."""
MAX_WRITE_REGISTERS = 123
"""Registers per write request (function code 16)."""
TIMEOUT_S = 1.0
"""Time to wait for an answer [s] (loopback answers in < 1 ms, a plant network in a few ms)."""

_ADDRESS = re.compile(r"^(ir|hr|coil|di):(\d+)$")
_AREA_NAMES = {
    "ir": "input registers",
    "hr": "holding registers",
    "coil": "coils",
    "di": "discrete inputs",
}
_EXCEPTIONS = {
    1: "illegal function",
    2: "illegal data address",
    3: "illegal data value",
    4: "device failure",
    5: "acknowledge",
    6: "device busy",
    10: "gateway path unavailable",
    11: "gateway target device failed to respond",
}


def parse_address(address: str) -> tuple[str, int]:
    """The area and 0-based address of a Modbus tag address (``"ir:20"`` → ``("ir", 20)``).

    Examples
    --------
    >>> parse_address("hr:100")
    ('hr', 100)
    """
    match = _ADDRESS.match(address)
    if match is None:  # the site file is validated, so this is a caller's mistake
        raise ConfigError(f"{address!r} is not a Modbus address (ir:N, hr:N, coil:N, di:N)")
    return match.group(1), int(match.group(2))


@dataclass(frozen=True)
class _Item:
    """One tag in a read plan: its site-file key, role, tag and first address."""

    key: str
    role: str
    tag: Tag
    start: int

    @property
    def size(self) -> int:
        return 1 if self.tag.type == "bool" else REGISTERS_OF[self.tag.type]


@dataclass
class _Block:
    """One read request: an area, a start address and a count, and the tags it carries."""

    area: str
    start: int
    count: int
    items: list[_Item]


def plan_reads(
    tags: Mapping[str, Tag], side: str = "tags", limit: int | None = None
) -> list[_Block]:
    """Group tags into as few read requests as the protocol allows.

    Each area's tags, sorted by address, are read in one span from the lowest to the highest
    register; a span longer than the limit (125 registers, 2000 bits) is split where the next tag
    would overrun it.

    Parameters
    ----------
    tags : mapping of str to Tag
        Role → tag (Modbus addresses).
    side : str
        The site-file table, for messages (``tags`` or ``write``).
    limit : int, optional
        Largest span in registers (default 125; bits 2000).

    Examples
    --------
    >>> from fuelid.plc.site import Tag
    >>> blocks = plan_reads({"flow": Tag(address="ir:20", type="int16"),
    ...                      "mode": Tag(address="ir:30", type="uint16"),
    ...                      "command": Tag(address="hr:100")})
    >>> [(b.area, b.start, b.count) for b in blocks]
    [('ir', 20, 11), ('hr', 100, 2)]
    """
    by_area: dict[str, list[_Item]] = {}
    for role, tag in tags.items():
        area, start = parse_address(tag.address)
        by_area.setdefault(area, []).append(_Item(f"{side}.{role}", role, tag, start))
    blocks: list[_Block] = []
    for area in ("ir", "hr", "coil", "di"):
        items = sorted(by_area.get(area, []), key=lambda item: item.start)
        cap = limit or (MAX_BITS if area in ("coil", "di") else MAX_REGISTERS)
        for item in items:
            end = item.start + item.size
            last = blocks[-1] if blocks and blocks[-1].area == area else None
            if last is not None and end - last.start <= cap:
                last.count = max(last.count, end - last.start)
                last.items.append(item)
            else:
                blocks.append(_Block(area, item.start, item.size, [item]))
    return blocks


class ModbusSource(PlcSource):
    """A Modbus TCP PLC as the site file maps it (pymodbus's asyncio client).

    Parameters
    ----------
    site : SiteConfig
        The site file (``plc.protocol = "modbus"``).
    timeout_s : float
        Time to wait for each answer [s].
    """

    def __init__(self, site: SiteConfig, timeout_s: float = TIMEOUT_S) -> None:
        super().__init__(site)
        plc = site.plc
        self.host = plc.host
        self.port = plc.port or plc.default_port
        self.device_id = plc.device_id
        self.word_order: codec.WordOrder = plc.word_order
        self.byte_swap = plc.byte_swap
        self.timeout_s = float(timeout_s)
        self._blocks = plan_reads(site.tags)
        # read plans of the write side, by the roles asked for: kept, so that a hole in the PLC's
        # map found once (see _read_block) is not probed again at every echo poll
        self._write_plans: dict[tuple[str, ...], list[_Block]] = {}
        self._client: AsyncModbusTcpClient | None = None
        self.requests = 0
        """Read and write requests sent (for tests and benchmarks)."""

    @property
    def where(self) -> str:
        """``modbus 127.0.0.1:5020 device 1``, for messages."""
        return f"modbus {self.host}:{self.port} device {self.device_id}"

    @property
    def blocks(self) -> list[tuple[str, int, int]]:
        """The read requests of one :meth:`read`: (area, first address, count)."""
        return [(block.area, block.start, block.count) for block in self._blocks]

    async def connect(self) -> None:
        """Open the TCP connection (one attempt).

        Raises
        ------
        LinkError
            Nothing listens at host:port, or the host cannot be reached.
        """
        await self.close()
        client = AsyncModbusTcpClient(
            self.host,
            port=self.port,
            timeout=self.timeout_s,
            retries=0,  # one attempt per request: the recorder decides what a failure means
            reconnect_delay=0,  # no background reconnect: the recorder owns the connect loop
        )
        try:
            connected = await client.connect()
        except (OSError, ModbusException) as error:
            client.close()
            raise LinkError(f"cannot reach {self.where} ({error})") from None
        if not connected:
            client.close()
            raise LinkError(
                f"cannot reach {self.where}: connection refused or no route "
                "(is the PLC on, the address and port right?)"
            )
        self._client = client

    async def close(self) -> None:
        """Close the connection (never raises)."""
        client, self._client = self._client, None
        if client is not None:
            with contextlib.suppress(Exception):  # a broken socket: nothing left to do
                client.close()

    def _require(self) -> AsyncModbusTcpClient:
        if self._client is None or not self._client.connected:
            raise LinkError(f"link to {self.where} lost (connection closed)")
        return self._client

    async def _request(self, kind: str, address: int, count: int, keys: str) -> list[int]:
        """One read request; the registers (or bits as 0/1) it returns."""
        client = self._require()
        call = {
            "ir": client.read_input_registers,
            "hr": client.read_holding_registers,
            "coil": client.read_coils,
            "di": client.read_discrete_inputs,
        }[kind]
        self.requests += 1
        try:
            response = await call(address, count=count, device_id=self.device_id)
        except ModbusIOException as error:
            raise LinkError(
                f"no answer from {self.where} within {self.timeout_s:g} s ({error})"
            ) from None
        except (ConnectionException, ModbusException, OSError) as error:
            raise LinkError(f"link to {self.where} lost ({error})") from None
        if response.isError():
            raise self._exception(response, kind, address, count, keys)
        if kind in ("coil", "di"):
            return [1 if bit else 0 for bit in list(response.bits)[:count]]
        registers = list(response.registers)
        if len(registers) != count:
            raise LinkError(
                f"{self.where} answered {len(registers)} registers for {count} at {kind}:{address}"
            )
        return registers

    def _exception(
        self, response: Any, kind: str, address: int, count: int, keys: str
    ) -> Exception:
        code = int(getattr(response, "exception_code", 0) or 0)
        name = _EXCEPTIONS.get(code, "unknown exception")
        where = f"{kind}:{address}" if count <= 2 else f"{kind}:{address}…{address + count - 1}"
        if code == 2:
            return ConfigError(
                f"{keys}: {where} does not exist on the PLC (Modbus exception 2, {name})"
            )
        if code in (4, 10, 11):
            return ConfigError(
                f"plc.device_id = {self.device_id}: {self.where} answers with Modbus exception "
                f"{code} ({name}) at {where}: is the device id right?"
            )
        return LinkError(f"{self.where}: Modbus exception {code} ({name}) at {where} ({keys})")

    async def _read_block(self, block: _Block, plan: list[_Block]) -> list[int]:
        """The registers (or bits) of one block of ``plan``; a refused span is split in ``plan``."""
        keys = ", ".join(item.key for item in block.items)
        try:
            return await self._request(block.area, block.start, block.count, keys)
        except ConfigError:
            if len(block.items) == 1:
                raise
        # the span failed: find the tag the PLC does not have (each alone), or a hole in the
        # PLC's map between tags that exist, in which case read them one by one from now on
        words = [0] * block.count
        for item in block.items:
            part = await self._request(block.area, item.start, item.size, item.key)
            offset = item.start - block.start
            words[offset : offset + item.size] = part
        index = plan.index(block)
        plan[index : index + 1] = [
            _Block(block.area, item.start, item.size, [item]) for item in block.items
        ]
        return words

    def _decode(self, tag: Tag, words: Sequence[int]) -> float:
        if tag.type == "bool":
            return 1.0 if words[0] else 0.0
        return codec.decode(words, tag.type, self.word_order, self.byte_swap)

    async def read(self) -> Reading:
        """Read every read tag, one request per register area (see :func:`plan_reads`).

        Raises
        ------
        LinkError
            No answer, a dropped link or a timeout.
        ConfigError
            Modbus exception 2 (the key and address named) or a wrong device id.
        """
        values, raw = await self._read_plan(self._blocks)
        return Reading(values=values, raw=raw, received=time.time())

    async def _read_plan(self, plan: list[_Block]) -> tuple[dict[str, float], dict[str, float]]:
        """Read every block of a plan: role → engineering value, and role → raw value."""
        values: dict[str, float] = {}
        raw: dict[str, float] = {}
        for block in list(plan):  # a copy: a refused span is split in the plan meanwhile
            words = await self._read_block(block, plan)
            for item in block.items:
                offset = item.start - block.start
                value = self._decode(item.tag, words[offset : offset + item.size])
                raw[item.role] = value
                values[item.role] = item.tag.to_engineering(value)
        return values, raw

    async def read_write_side(self, roles: Sequence[str]) -> dict[str, float]:
        """Read write-side roles back (e.g. ``echo``), one request per register area.

        Planned as :meth:`read` plans the read tags (:func:`plan_reads`): all four areas are
        readable, so the read-only ``echo`` in input registers and the staged gains, apply word
        and heartbeat in holding registers (or coils) each go in one request per area.

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
            A role the write side does not map (``write.<role>``), Modbus exception 2 (the key
            and address named) or a wrong device id.
        LinkError
            Not connected, no answer, a dropped link or a timeout.
        """
        tags = self._write_side_tags(roles)
        if not tags:
            return {}
        key = tuple(tags)
        plan = self._write_plans.get(key)
        if plan is None:
            plan = self._write_plans[key] = plan_reads(tags, side="write")
        values, _ = await self._read_plan(plan)
        return {role: values[role] for role in tags}  # in the order asked, not by address

    def _ring_area(self) -> tuple[str, int, int]:
        ring = self.site.ring
        if ring is None:
            raise NotImplementedError("the site file maps no ring buffer ([ring])")
        area, start = parse_address(ring.address)
        return area, start, ring.record_registers

    async def read_ring_head(self) -> int:
        """The raw uint32 sequence number of the newest record (``[ring] head``)."""
        ring = self.site.ring
        if ring is None:
            raise NotImplementedError("the site file maps no ring buffer ([ring])")
        area, start = parse_address(ring.head)
        words = await self._request(area, start, 2, "ring.head")
        return int(codec.decode(words, "uint32", self.word_order, self.byte_swap))

    async def read_ring(self, first_slot: int, count: int) -> list[RingRecord]:
        """Records of slots ``first_slot … first_slot + count − 1``, whole records per request.

        A request carries at most ``125 // record_registers`` records (15 of 8 registers).
        """
        ring = self.site.ring
        area, start, size = self._ring_area()
        assert ring is not None  # _ring_area checked it
        if first_slot < 0 or count < 0 or first_slot + count > ring.size:
            raise ValueError(f"slots {first_slot}…{first_slot + count - 1} outside the ring")
        per_request = MAX_REGISTERS // size
        records: list[RingRecord] = []
        slot = first_slot
        while slot < first_slot + count:
            n = min(per_request, first_slot + count - slot)
            words = await self._request(area, start + slot * size, n * size, "ring.address")
            for k in range(n):
                record = words[k * size : (k + 1) * size]
                seq = int(codec.decode(record[0:2], "uint32", self.word_order, self.byte_swap))
                fields = {
                    name: codec.decode(
                        record[2 * i : 2 * i + 2], "float32", self.word_order, self.byte_swap
                    )
                    for i, name in enumerate(ring.fields)
                    if i > 0
                }
                records.append(RingRecord(seq=seq, values=fields))
            slot += n
        return records

    async def write(self, values: Mapping[str, float]) -> None:
        """Write write-side roles; roles at contiguous holding registers go in one request.

        Staged ``kc``, ``ti`` and the ``apply`` word mapped one after the other thus arrive in
        one ``write_registers`` (the PLC applies them as a block).

        Raises
        ------
        ConfigError
            A role the site file does not map, a tag not in holding registers or coils, or an
            address the PLC does not have.
        LinkError
            The write did not reach the PLC.
        """
        client = self._require()
        unknown = sorted(set(values) - set(self.site.write))
        if unknown:
            raise ConfigError(f"write.{unknown[0]}: the site file maps no such write tag")
        runs: list[tuple[int, list[int], list[str]]] = []
        for role in sorted(values, key=lambda r: parse_address(self.site.write[r].address)[1]):
            tag = self.site.write[role]
            area, start = parse_address(tag.address)
            key = f"write.{role}"
            if area == "coil":
                self.requests += 1
                try:
                    response = await client.write_coil(
                        start, bool(values[role]), device_id=self.device_id
                    )
                except (ModbusException, OSError) as error:
                    raise LinkError(f"write to {self.where} failed ({error})") from None
                if response.isError():
                    raise self._exception(response, "coil", start, 1, key)
                continue
            if area != "hr":
                raise ConfigError(f"{key}: {tag.address} cannot be written (use hr:N or coil:N)")
            raw = tag.to_raw(values[role])
            words = codec.encode(raw, tag.type, self.word_order, self.byte_swap)
            last = runs[-1] if runs else None
            if (
                last is not None
                and last[0] + len(last[1]) == start
                and len(last[1]) + len(words) <= MAX_WRITE_REGISTERS
            ):
                last[1].extend(words)
                last[2].append(key)
            else:
                runs.append((start, list(words), [key]))
        for start, words, keys in runs:
            self.requests += 1
            try:
                response = await client.write_registers(start, words, device_id=self.device_id)
            except (ModbusException, OSError) as error:
                raise LinkError(f"write to {self.where} failed ({error})") from None
            if response.isError():
                raise self._exception(response, "hr", start, len(words), ", ".join(keys))
