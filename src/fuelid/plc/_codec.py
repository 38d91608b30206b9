"""Values in 16-bit registers: the word order and byte swap of 32-bit values, as PLCs send them.

A 32-bit value's big-endian bytes A B C D travel in two registers: ``word_order="big"`` sends
[AB, CD] (Modbus's own order, Siemens), ``"little"`` sends [CD, AB] (many Schneider and
Allen-Bradley maps); ``byte_swap`` swaps the two bytes of every register (BADC or DCBA). pymodbus
has no byte-order option (../shared/docs/online.md), so the codec is here, in plain ``struct``.

Examples
--------
>>> encode(3.5, "float32", "big")            # 3.5 = 0x40600000
[16480, 0]
>>> encode(3.5, "float32", "little")
[0, 16480]
>>> decode([0x6040, 0x0000], "float32", "big", byte_swap=True)
3.5
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import Literal

from fuelid.errors import DataError

FORMATS = {"float32": ">f", "int32": ">i", "uint32": ">I", "int16": ">h", "uint16": ">H"}
WordOrder = Literal["big", "little"]


def _swap(register: int) -> int:
    return ((register & 0xFF) << 8) | (register >> 8)


def encode(
    value: float, type_: str, word_order: WordOrder = "big", byte_swap: bool = False
) -> list[int]:
    """The registers (0…65535 each) that carry ``value`` as ``type_``.

    Raises
    ------
    DataError
        If an integer type cannot hold the value.
    """
    if type_ == "bool":
        return [1 if value else 0]
    fmt = FORMATS[type_]
    try:
        data = struct.pack(fmt, value if type_ == "float32" else round(value))
    except struct.error:
        raise DataError(f"{value!r} does not fit a {type_}") from None
    registers = [int.from_bytes(data[i : i + 2], "big") for i in range(0, len(data), 2)]
    if word_order == "little":
        registers.reverse()
    return [_swap(r) for r in registers] if byte_swap else registers


def decode(
    registers: Sequence[int], type_: str, word_order: WordOrder = "big", byte_swap: bool = False
) -> float:
    """The value ``type_`` in ``registers`` (1 for 16-bit types and bool, 2 for 32-bit ones)."""
    words = [int(r) & 0xFFFF for r in registers]
    if type_ == "bool":
        return 1.0 if words[0] else 0.0
    fmt = FORMATS[type_]
    size = struct.calcsize(fmt) // 2
    if len(words) != size:
        raise DataError(f"a {type_} takes {size} register(s), got {len(words)}")
    if byte_swap:
        words = [_swap(w) for w in words]
    if word_order == "little":
        words.reverse()
    data = b"".join(w.to_bytes(2, "big") for w in words)
    return float(struct.unpack(fmt, data)[0])
