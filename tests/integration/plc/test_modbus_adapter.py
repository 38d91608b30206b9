"""The Modbus adapter (issue 14, item 2) against a pymodbus server written here, word by word.

The server is pymodbus's SimDevice (../shared/docs/online.md) in a thread of its own, with the
registers as hand-computed numbers: 3.5 = 0x4060_0000 (float32), 74565 = 0x0001_2345 (uint32),
13824 counts = half of 27648 = 60 L/min on a 0…120 L/min span.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("pymodbus", reason="the [plc] extra (pymodbus) is not installed")

from fuelid.errors import ConfigError
from fuelid.plc.adapters import LinkError, ModbusSource, open_source
from fuelid.plc.adapters._modbus import plan_reads
from fuelid.plc.site import SiteConfig
from support.modbus import FakePlc, free_port

# xdist: one worker runs every module that drives a PLC at speed, one after another
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("real-time")


def site_for(port: int, tags: str, *, word_order: str = "big", byte_swap: bool = False,
             device_id: int = 1, extra: str = "") -> SiteConfig:  # fmt: skip
    import tomllib

    text = f"""
[site]
name = "test loop"
[plc]
protocol = "modbus"
host = "127.0.0.1"
port = {port}
device_id = {device_id}
word_order = "{word_order}"
byte_swap = {"true" if byte_swap else "false"}
[sampling]
period_s = 0.01
control_period_s = 1.0
{tags}
{extra}
"""
    return SiteConfig.model_validate(tomllib.loads(text))


TAGS = """
[tags.flow]
address = "ir:20"
type = "int16"
raw = [0, 27648]
eng = [0.0, 120.0]
unit = "L/min"
[tags.fuel_temperature]
address = "ir:21"
type = "int16"
raw = [0, 27648]
eng = [-40.0, 80.0]
unit = "degC"
[tags.mode]
address = "ir:30"
type = "uint16"
[tags.seq]
address = "ir:24"
type = "uint32"
[tags.command]
address = "hr:10"
type = "float32"
unit = "V"
[tags.setpoint]
address = "hr:12"
type = "float32"
unit = "L/min"
[write.kc]
address = "hr:40"
type = "float32"
[write.ti]
address = "hr:42"
type = "float32"
[write.apply]
address = "hr:44"
type = "uint32"
[write.heartbeat]
address = "hr:50"
type = "uint16"
"""


@pytest.fixture
def plc() -> Iterator[FakePlc]:
    server = FakePlc()
    try:
        yield server
    finally:
        server.close()


def read(site: SiteConfig, plc: FakePlc | None = None) -> tuple[Any, ModbusSource]:
    async def go() -> tuple[Any, ModbusSource]:
        source = open_source(site)
        assert isinstance(source, ModbusSource)
        async with source:
            return await source.read(), source

    return asyncio.run(go())


# 3.5 = 0x40600000 and 74565 = 0x00012345, as each layout puts them in two registers
LAYOUTS = [
    ("big", False, [0x4060, 0x0000], [0x0001, 0x2345]),
    ("little", False, [0x0000, 0x4060], [0x2345, 0x0001]),
    ("big", True, [0x6040, 0x0000], [0x0100, 0x4523]),
    ("little", True, [0x0000, 0x6040], [0x4523, 0x0100]),
]


@pytest.mark.parametrize(("order", "swap", "float_words", "seq_words"), LAYOUTS)
def test_word_order_byte_swap_and_scaling_against_hand_computed_registers(
    plc: FakePlc, order: str, swap: bool, float_words: list[int], seq_words: list[int]
) -> None:
    counts = 13824  # half of 27648
    word = ((counts & 0xFF) << 8) | (counts >> 8) if swap else counts
    plc.set_ir(20, [word, word])  # flow, fuel temperature: both half scale
    plc.set_ir(24, seq_words)
    mode = 0x0100 if swap else 0x0001
    plc.set_ir(30, [mode])
    plc.stop_link()
    plc.hr[10:14] = float_words + float_words  # command 3.5 V, setpoint 3.5 L/min
    plc.start_link()
    reading, source = read(site_for(plc.port, TAGS, word_order=order, byte_swap=swap))
    assert reading.values["flow"] == pytest.approx(60.0)  # 0…27648 → 0…120 L/min
    assert reading.values["fuel_temperature"] == pytest.approx(20.0)  # → −40…80 °C
    assert reading.raw["flow"] == counts
    assert reading.values["command"] == 3.5
    assert reading.values["setpoint"] == 3.5
    assert reading.raw["seq"] == 74565
    assert reading.values["mode"] == 1.0
    # one request per area: ir 20…31 and hr 10…13
    assert source.blocks == [("ir", 20, 11), ("hr", 10, 4)]
    assert source.requests == 2


def test_negative_int16_counts_and_siemens_over_range_decode() -> None:
    from fuelid.plc import decode

    assert decode([0xED00], "int16") == -4864  # Siemens under-range limit
    assert decode([0x7EFF], "int16") == 32511  # over-range limit


def test_reads_are_grouped_per_area_and_split_past_125_registers() -> None:
    site = site_for(
        1,
        """
[tags.flow]
address = "ir:0"
type = "float32"
unit = "L/min"
[tags.setpoint]
address = "ir:124"
type = "float32"
unit = "L/min"
[tags.command]
address = "ir:300"
type = "float32"
unit = "V"
[tags.mode]
address = "ir:123"
type = "uint16"
""",
    )
    blocks = [(b.area, b.start, b.count) for b in plan_reads(site.tags)]
    # 0…123 fits in 124 registers; ir:124 (2 registers) would make 126: a new request
    assert blocks == [("ir", 0, 124), ("ir", 124, 2), ("ir", 300, 2)]


def test_a_register_the_plc_does_not_have_names_the_key_and_address(plc: FakePlc) -> None:
    tags = TAGS.replace('address = "ir:30"', 'address = "ir:5000"')
    with pytest.raises(ConfigError, match=r"tags\.mode: ir:5000 does not exist on the PLC"):
        read(site_for(plc.port, tags))


def test_a_wrong_device_id_names_device_id(plc: FakePlc) -> None:
    with pytest.raises(ConfigError, match=r"plc\.device_id = 7.*exception 4"):
        read(site_for(plc.port, TAGS, device_id=7))


def test_an_unreachable_plc_is_a_link_error_naming_host_and_port() -> None:
    port = free_port()
    with pytest.raises(LinkError, match=rf"127\.0\.0\.1:{port}"):
        read(site_for(port, TAGS))


def test_no_answer_within_the_timeout_gives_no_device_id_advice() -> None:
    # issue 39: a 0.09 s blip asked "is plc.device_id = 1 right?"; a timeout is the link's
    # trouble, and only a device that answers (a Modbus exception) can say its unit is wrong
    import socket
    import threading

    listener = socket.create_server(("127.0.0.1", 0))
    accepted: list[socket.socket] = []

    def accept() -> None:  # accepts the connection, never answers a request
        with contextlib.suppress(OSError):
            accepted.append(listener.accept()[0])

    threading.Thread(target=accept, daemon=True).start()
    site = site_for(listener.getsockname()[1], TAGS)

    async def go() -> None:
        source = ModbusSource(site, timeout_s=0.2)
        await source.connect()
        try:
            await source.read()
        finally:
            await source.close()

    try:
        with pytest.raises(LinkError) as caught:
            asyncio.run(go())
    finally:
        listener.close()
        for connection in accepted:
            connection.close()
    message = str(caught.value)
    assert "no answer from modbus 127.0.0.1" in message
    assert "within 0.2 s" in message
    assert "device_id" not in message


def test_a_dropped_link_is_a_link_error_and_a_reconnect_works(plc: FakePlc) -> None:
    site = site_for(plc.port, TAGS)

    async def go() -> float:
        source = open_source(site)
        await source.connect()
        await source.read()
        plc.stop_link()
        with pytest.raises(LinkError):
            await source.read()
        plc.start_link()
        await source.connect()
        value = (await source.read()).values["flow"]
        await source.close()
        return value

    assert math.isfinite(asyncio.run(go()))


def test_staged_gains_and_apply_go_in_one_write(plc: FakePlc) -> None:
    site = site_for(plc.port, TAGS)

    async def go() -> int:
        source = open_source(site)
        assert isinstance(source, ModbusSource)
        async with source:
            await source.write({"kc": 3.5, "ti": 3.5, "apply": 74565})
            return source.requests

    assert asyncio.run(go()) == 1
    assert plc.read_hr(40, 6) == [0x4060, 0, 0x4060, 0, 0x0001, 0x2345]


def test_ring_records_are_read_in_blocks_of_whole_records(plc: FakePlc) -> None:
    ring = '[ring]\nhead = "ir:100"\naddress = "ir:1000"\nsize = 40\n'
    site = site_for(plc.port, TAGS, extra=ring)
    for slot in range(40):
        # record: seq (uint32), command 3.5 V, flow 3.5 L/min, setpoint 3.5
        plc.set_ir(1000 + 8 * slot, [0, slot + 100] + [0x4060, 0] * 3)
    plc.set_ir(100, [0, 139])

    async def go() -> tuple[int, list[Any], int]:
        source = open_source(site)
        assert isinstance(source, ModbusSource)
        async with source:
            head = await source.read_ring_head()
            records = await source.read_ring(0, 40)
            return head, records, source.requests

    head, records, requests = asyncio.run(go())
    assert head == 139
    assert [r.seq for r in records] == list(range(100, 140))
    assert records[7].values == {"command": 3.5, "flow": 3.5, "setpoint": 3.5}
    assert requests == 1 + 3  # 40 records of 8 registers: 15 + 15 + 10 per request
