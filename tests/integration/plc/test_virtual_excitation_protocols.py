"""Excitation on demand on the virtual PLC's three servers, each a real one on 127.0.0.1.

A plain client of each protocol (pymodbus, asyncua, python-snap7; not fuelid's adapters) writes
the heartbeat, a manual command and ``excitation_request`` at the addresses the point table gives,
then reads back the applied ``excitation``, the ``run`` flag (raised by hand) and the ring's new
``excitation`` field. The PLC runs at 20 times real time with a long heartbeat timeout, and the
checks wait on values (bounded), not on wall time.
"""

from __future__ import annotations

import asyncio
import struct
from typing import Any, TypeVar

import pytest

from fuelid.plc.virtual import VirtualPlcThread
from fuelid.plc.virtual._points import (
    POINTS,
    RING_FIELDS,
    RING_FIRST_REGISTER,
    RING_HEAD_REGISTER,
    RING_RECORD_REGISTERS,
)
from support.waiting import await_until, wait_until

# xdist: one worker runs every module that drives a PLC at speed, one after another
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("real-time")

T = TypeVar("T")
HOST = "127.0.0.1"
MANUAL_V, ASKED_V, LIMIT_V = 3.0, 0.8, 0.25  # the PLC applies 0.25 V: 3.25 V to the drive
ENGINE = {
    "speed": 20.0,
    "seed": 1,
    "ring_size": 256,
    "heartbeat_timeout_s": 600.0,  # the test writes the heartbeat once
    "excitation_limit_V": LIMIT_V,
}
EXCITATION = RING_FIELDS.index("excitation")
COMMAND = RING_FIELDS.index("command")
TIMEOUT_S = 10.0


def _f32(value: float) -> float:
    """``value`` as float32 carries it (what a REAL or a Modbus float32 reads back)."""
    return float(struct.unpack(">f", struct.pack(">f", value))[0])


def _check_record(record: list[float]) -> None:
    """A ring record of a sample after the request: the applied signal and the command."""
    assert record[EXCITATION] == _f32(LIMIT_V)
    assert record[COMMAND] == _f32(MANUAL_V + LIMIT_V)


# -- Modbus TCP --------------------------------------------------------------------------------


def _words(value: float) -> list[int]:
    return list(struct.unpack(">HH", struct.pack(">f", value)))


def test_modbus_excitation_run_and_ring() -> None:
    pytest.importorskip("pymodbus", reason="the Modbus server needs pymodbus: fuelid[plc]")
    from pymodbus.client import ModbusTcpClient

    with VirtualPlcThread("modbus", HOST, **ENGINE) as virtual:  # type: ignore[arg-type]
        client = ModbusTcpClient(HOST, port=virtual.port)
        assert client.connect()  # type: ignore[no-untyped-call]
        try:

            def ir(address: int, count: int) -> list[int]:
                reply = client.read_input_registers(address, count=count, device_id=1)
                assert not reply.isError(), reply
                return list(reply.registers)

            def hr(address: int, words: list[int]) -> None:
                reply = client.write_registers(address, words, device_id=1)
                assert not reply.isError(), reply

            def f32(words: list[int]) -> float:
                return float(struct.unpack(">f", struct.pack(">HH", *words))[0])

            excitation, run = POINTS["excitation"].register, POINTS["run"].register
            assert ir(run, 1) == [0]
            hr(POINTS["heartbeat"].register, [1])
            hr(POINTS["manual_command"].register, _words(MANUAL_V))
            hr(POINTS["excitation_request"].register, _words(ASKED_V))
            wait_until(lambda: f32(ir(excitation, 2)) == _f32(LIMIT_V), TIMEOUT_S, "the signal")
            assert f32(ir(POINTS["command"].register, 2)) == _f32(MANUAL_V + LIMIT_V)
            virtual.set_run(True)
            wait_until(lambda: ir(run, 1) == [1], TIMEOUT_S, "the run flag")

            head = ir(RING_HEAD_REGISTER, 3)
            seq, size = (head[0] << 16) | head[1], head[2]
            words = ir(RING_FIRST_REGISTER + RING_RECORD_REGISTERS * (seq % size), 10)
            record = [float((words[0] << 16) | words[1])]
            record += [f32(words[i : i + 2]) for i in range(2, RING_RECORD_REGISTERS, 2)]
            assert record[0] == seq
            _check_record(record)
            virtual.set_run(False)
            wait_until(lambda: ir(run, 1) == [0], TIMEOUT_S, "the run flag lowered")
        finally:
            client.close()  # type: ignore[no-untyped-call]


# -- OPC UA ------------------------------------------------------------------------------------


def test_opcua_excitation_run_and_ring() -> None:
    pytest.importorskip("asyncua", reason="the OPC UA server needs asyncua: fuelid[plc]")
    from asyncua import ua
    from asyncua.client.client import Client

    from fuelid.plc.virtual._opcua_server import VARIANT_OF

    def node_id(name: str) -> str:
        return f"ns=2;s={POINTS[name].opcua}"

    async def body(virtual: VirtualPlcThread) -> dict[str, Any]:
        async with Client(f"opc.tcp://{HOST}:{virtual.port}/fuelid/plc/") as client:

            async def write(name: str, value: float) -> None:
                variant = VARIANT_OF[POINTS[name].type]
                number = int(value) if variant != ua.VariantType.Double else value
                await client.get_node(node_id(name)).write_value(ua.Variant(number, variant))

            async def read(name: str) -> Any:
                return await client.get_node(node_id(name)).read_value()

            async def reads(name: str, value: float) -> bool:
                return bool(await read(name) == value)

            run_before = await read("run")
            await write("heartbeat", 1)
            await write("manual_command", MANUAL_V)
            await write("excitation_request", ASKED_V)
            await await_until(lambda: reads("excitation", LIMIT_V), TIMEOUT_S, "the signal")
            await asyncio.to_thread(virtual.set_run, True)
            await await_until(lambda: reads("run", 1), TIMEOUT_S, "the run flag")
            head = await read("ring_head")
            ring = await client.get_node("ns=2;s=FuelLoop.Ring").read_value()
            return {
                "run_before": run_before,
                "run": await read("run"),
                "excitation": await read("excitation"),
                "command": await read("command"),
                "head": head,
                "size": await read("ring_size"),
                "ring": ring,
            }

    with VirtualPlcThread("opcua", HOST, **ENGINE) as virtual:  # type: ignore[arg-type]
        got = asyncio.run(asyncio.wait_for(body(virtual), 2 * TIMEOUT_S))
    assert (got["run_before"], got["run"]) == (0, 1)
    assert got["excitation"] == LIMIT_V  # Doubles on OPC UA: exact
    assert got["command"] == MANUAL_V + LIMIT_V
    width = len(RING_FIELDS)
    assert len(got["ring"]) == width * got["size"]
    slot = got["head"] % got["size"]
    record = got["ring"][width * slot : width * slot + width]
    assert record[0] == got["head"]
    assert record[EXCITATION] == LIMIT_V
    assert record[COMMAND] == MANUAL_V + LIMIT_V


# -- S7 ----------------------------------------------------------------------------------------


def test_s7_excitation_run_and_ring() -> None:
    pytest.importorskip("snap7", reason="the S7 server needs python-snap7: fuelid[plc]")
    from snap7.client import Client

    def offset(name: str) -> int:
        return 2 * POINTS[name].register

    with VirtualPlcThread("s7", HOST, **ENGINE) as virtual:  # type: ignore[arg-type]
        plain = Client()
        plain.connect(HOST, 0, 1, tcp_port=virtual.port)
        try:

            def real(name: str) -> float:
                return float(struct.unpack(">f", plain.db_read(1, offset(name), 4))[0])

            def word(name: str) -> int:
                return int(struct.unpack(">H", plain.db_read(1, offset(name), 2))[0])

            assert word("run") == 0
            plain.db_write(2, offset("heartbeat"), bytearray(struct.pack(">H", 1)))
            plain.db_write(2, offset("manual_command"), bytearray(struct.pack(">f", MANUAL_V)))
            plain.db_write(2, offset("excitation_request"), bytearray(struct.pack(">f", ASKED_V)))
            wait_until(lambda: real("excitation") == _f32(LIMIT_V), TIMEOUT_S, "the signal")
            assert real("command") == _f32(MANUAL_V + LIMIT_V)
            virtual.set_run(True)
            wait_until(lambda: word("run") == 1, TIMEOUT_S, "the run flag")

            head = int(struct.unpack(">I", plain.db_read(1, offset("ring_head"), 4))[0])
            size = word("ring_size")
            record_bytes = 2 * RING_RECORD_REGISTERS
            start = 2 * RING_FIRST_REGISTER + record_bytes * (head % size)
            data = plain.db_read(1, start, record_bytes)
            seq, *fields = struct.unpack(">I" + "f" * (len(RING_FIELDS) - 1), data)
            assert seq == head
            _check_record([float(seq), *fields])
        finally:
            plain.disconnect()


# -- fuelid plant serve ------------------------------------------------------------------------


def test_plant_serve_takes_the_excitation_limit_and_run_windows() -> None:
    pytest.importorskip("pymodbus", reason="the Modbus server needs pymodbus: fuelid[plc]")
    from typer.testing import CliRunner

    from fuelid.cli import app

    runner = CliRunner()
    options = ["--excitation-limit", "0.2", "--run", "0:3", "--run", "10:20"]
    served = runner.invoke(
        app, ["plant", "serve", "--port", "0", "--duration", "0.3", "--speed", "10", *options]
    )
    assert served.exit_code == 0, served.stderr
    for bad, reason in (
        (["--run", "5:1"], "--run 5:1: give START:END"),
        (["--run", "5"], "--run 5: give START:END"),
        (["--excitation-limit", "0"], "--excitation-limit must be a positive voltage"),
        (["--excitation-limit", "-0.1"], "--excitation-limit must be a positive voltage"),
    ):
        refused = runner.invoke(app, ["plant", "serve", "--duration", "0.1", *bad])
        assert refused.exit_code == 2, refused.stderr
        assert reason in refused.stderr
