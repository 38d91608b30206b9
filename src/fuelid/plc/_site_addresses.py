"""Addresses of a site file in each protocol's own syntax, checked before anything is read.

Modbus ``ir:N``, ``hr:N``, ``coil:N``, ``di:N`` (N the 0-based protocol address 0…65535), OPC UA
NodeIds ``ns=2;s=FuelLoop.Flow``, S7 ``DB1.DBD0``/``DB1.DBW4``/``DB1.DBX8.3``: an address must be
in its protocol's syntax, fit its tag's type, stay inside its area, and share no register (or S7
byte) with another role of the same side. Each refusal is a ``ValueError`` naming the key, which
the site file's validation (:mod:`fuelid.plc.site`) turns into a one-line
:class:`~fuelid.errors.ConfigError`.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Mapping
from typing import NamedTuple, Protocol

__all__ = [
    "REGISTERS_OF",
    "Addressed",
    "RingLayout",
    "check_address",
    "check_overlaps",
    "check_ring",
    "memory_span",
]

REGISTERS_OF = {"float32": 2, "int32": 2, "uint32": 2, "int16": 1, "uint16": 1, "bool": 1}
"""16-bit registers (Modbus) a value of each type occupies."""

_MODBUS = re.compile(r"^(ir|hr|coil|di):(\d+)$")
_OPCUA = re.compile(r"^ns=\d+;[sigb]=.+$")
_S7 = re.compile(r"^DB(\d+)\.DB([XBWD])(\d+)(?:\.([0-7]))?$")


class Addressed(Protocol):
    """What the checks read of a tag: its address and type (a :class:`~fuelid.plc.site.Tag`)."""

    @property
    def address(self) -> str:
        """The address in the protocol's syntax."""

    @property
    def type(self) -> str:
        """``float32``, ``int16``, ``uint16``, ``int32``, ``uint32`` or ``bool``."""


class RingLayout(Protocol):
    """What the checks read of a ring (a :class:`~fuelid.plc.site.Ring`)."""

    @property
    def head(self) -> str:
        """Address of the newest record's sequence number."""

    @property
    def address(self) -> str:
        """Address of slot 0."""

    @property
    def size(self) -> int:
        """Records in the ring."""

    @property
    def record_registers(self) -> int:
        """16-bit registers of one record (Modbus)."""


class _Address(NamedTuple):
    address: str
    type: str = "float32"


def check_address(protocol: str, tag: Addressed, key: str) -> None:
    """Refuse an address that is not in the protocol's syntax or does not fit the tag's type."""
    address = tag.address
    if protocol == "modbus":
        match = _MODBUS.match(address)
        if match is None or int(match.group(2)) > 65535:
            raise ValueError(
                f"{key}.address: {address!r} is not a Modbus address: ir:N, hr:N, coil:N or "
                "di:N with N the 0-based protocol address 0…65535 (not 30001/40001 numbers)"
            )
        area, start = match.group(1), int(match.group(2))
        if area in ("coil", "di") and tag.type != "bool":
            raise ValueError(f"{key}.type: {area} holds bits: the type must be bool")
        if area in ("ir", "hr") and start + REGISTERS_OF[tag.type] - 1 > 65535:
            raise ValueError(f"{key}.address: a {tag.type} at {start} runs past register 65535")
    elif protocol == "opcua":
        if _OPCUA.match(address) is None:
            raise ValueError(
                f"{key}.address: {address!r} is not an OPC UA NodeId such as ns=2;s=FuelLoop.Flow"
            )
    elif protocol == "s7":
        match = _S7.match(address)
        if match is None:
            raise ValueError(
                f"{key}.address: {address!r} is not an S7 address such as DB1.DBD0 (32-bit), "
                "DB1.DBW4 (16-bit) or DB1.DBX8.3 (a bit)"
            )
        size, bit = match.group(2), match.group(4)
        fits = {"D": ("float32", "int32", "uint32"), "W": ("int16", "uint16"), "X": ("bool",)}
        if size == "B" or tag.type not in fits[size]:
            raise ValueError(
                f"{key}.type: {tag.type} does not fit DB{size} (DBD: float32, int32, uint32; "
                "DBW: int16, uint16; DBX: bool)"
            )
        if (size == "X") != (bit is not None):
            raise ValueError(f"{key}.address: a bit address is DBX<byte>.<bit 0-7>, only for bits")


def memory_span(protocol: str, tag: Addressed) -> tuple[str, int, int] | None:
    """The memory a tag occupies: (area, first, last) in registers (Modbus) or bytes (S7).

    None for addresses that cannot overlap by position (OPC UA nodes, replay columns, bits).
    """
    if protocol == "modbus":
        match = _MODBUS.match(tag.address)
        if match is None or match.group(1) in ("coil", "di"):
            return None
        start = int(match.group(2))
        return match.group(1), start, start + REGISTERS_OF[tag.type] - 1
    if protocol == "s7":
        match = _S7.match(tag.address)
        if match is None or match.group(2) in ("X", "B"):
            return None
        start = int(match.group(3))
        size = 4 if match.group(2) == "D" else 2
        return f"DB{match.group(1)}", start, start + size - 1
    return None


def check_overlaps(protocol: str, tags: Mapping[str, Addressed], side: str) -> None:
    """Refuse two roles of one side whose values share a register (or S7 byte): a typo."""
    spans = sorted(
        (span, role)
        for role, tag in tags.items()
        if (span := memory_span(protocol, tag)) is not None
    )
    for (first, role_a), (second, role_b) in itertools.pairwise(spans):
        if first[0] == second[0] and second[1] <= first[2]:
            raise ValueError(
                f"{side}.{role_b}: {tags[role_b].address} overlaps {side}.{role_a} "
                f"({tags[role_a].address}, {tags[role_a].type}): two values cannot share memory"
            )


def check_ring(protocol: str, ring: RingLayout) -> None:
    """Refuse a ring whose addresses are not in the protocol's syntax or overrun the area."""
    if protocol == "replay":
        return
    check_address(protocol, _Address(ring.head, "uint32"), "ring.head")
    if protocol == "opcua":
        check_address(protocol, _Address(ring.address), "ring.address")
        return
    check_address(protocol, _Address(ring.address, "uint32"), "ring.address")
    if protocol == "modbus":
        match = _MODBUS.match(ring.address)
        assert match is not None  # checked just above
        if match.group(1) not in ("ir", "hr"):
            raise ValueError("ring.address: the ring lives in registers (ir:N or hr:N)")
        end = int(match.group(2)) + ring.size * ring.record_registers - 1
        if end > 65535:
            raise ValueError(
                f"ring: {ring.size} records of {ring.record_registers} registers from "
                f"{ring.address} run past register 65535"
            )
