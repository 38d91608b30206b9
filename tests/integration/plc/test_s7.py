"""S7 on loopback: the virtual PLC's S7 front end and the S7 adapter (python-snap7).

(a) a plain snap7 client against :class:`S7Frontend` with hand-computed bytes; (b)
:class:`S7Source` against :class:`S7Frontend`: scaling, bits, the ring, one-request reads and
writes, refusals and link drops; (c) end to end against the virtual PLC.
"""

from __future__ import annotations

import asyncio
import socket
import struct
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

snap7 = pytest.importorskip(
    "snap7", reason="the S7 tests need python-snap7 (pip install 'fuelid[plc]')"
)

from snap7.client import Client  # noqa: E402

from fuelid.errors import ConfigError  # noqa: E402
from fuelid.plc.adapters import LinkError, S7Source, open_source  # noqa: E402
from fuelid.plc.adapters._s7 import plan_spans  # noqa: E402
from fuelid.plc.site import SiteConfig  # noqa: E402
from fuelid.plc.virtual._s7_server import S7Frontend  # noqa: E402
from support.waiting import wait_until  # noqa: E402

# xdist: one worker runs every module that drives a PLC at speed, one after another
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("real-time")

HOST = "127.0.0.1"

# Every read point of the virtual PLC with a value whose big-endian bytes are easy to check
# (points.py: DB1 byte offset = 2 x register).
VALUES = {
    "seq": 123456789,  # DBD0  UDInt 07 5B CD 15
    "flow": 3.5,  # DBD4  REAL 40 60 00 00
    "command": 2.5,  # DBD8  REAL 40 20 00 00
    "setpoint": -1.0,  # DBD12 REAL BF 80 00 00
    "fuel_temperature": 20.0,  # DBD16 REAL 41 A0 00 00
    "mode": 1,  # DBW20 UInt 00 01
    "status": 5,  # DBW22 UInt 00 05
    "kc": 0.125,  # DBD24 REAL 3E 00 00 00
    "ti": 8.0,  # DBD28 REAL 41 00 00 00
    "echo": 42,  # DBD32 UDInt 00 00 00 2A
    "flow_counts": 13824,  # DBW36 Int 36 00 (half of 27648: 60 L/min)
    "fuel_temperature_counts": 27648,  # DBW38 Int 6C 00 (80 °C)
    "excitation": 0.25,  # DBD40 REAL 3E 80 00 00
    "run": 1,  # DBW44 UInt 00 01
    "ring_head": 39,  # DBD200 UDInt 00 00 00 27
    "ring_size": 64,  # DBW204 UInt 00 40
}
DB1_HEAD = bytes.fromhex(
    "075BCD15 40600000 40200000 BF800000 41A00000 0001 0005 3E000000 41000000 0000002A 3600 6C00"
    "3E800000 0001"
)
RING_SIZE = 64


def _ring(count: int = 40) -> dict[int, np.ndarray]:
    """Slots 0..count-1: seq 1000+slot, command 1+slot/100 V, flow 2*slot, setpoint 50, −0.5 V."""
    return {
        slot: np.array([1000.0 + slot, 1.0 + slot / 100.0, 2.0 * slot, 50.0, -0.5])
        for slot in range(count)
    }


def _run(coroutine: Any) -> Any:
    return asyncio.run(asyncio.wait_for(coroutine, timeout=10.0))


@pytest.fixture
def frontend() -> Iterator[S7Frontend]:
    """A running S7 front end on a free high port (S7's 102 needs root), fed known values."""
    server = S7Frontend(HOST, 0, ring_size=RING_SIZE)

    async def start() -> None:
        await server.start()
        await server.publish(VALUES, _ring())

    _run(start())
    try:
        yield server
    finally:
        _run(server.stop())


@pytest.fixture
def client(frontend: S7Frontend) -> Iterator[Client]:
    """A plain snap7 client connected to the front end (rack 0, slot 1)."""
    plain = Client()
    plain.connect(HOST, 0, 1, tcp_port=frontend.port)
    try:
        yield plain
    finally:
        plain.disconnect()


def _site(port: int, **tags: dict[str, Any]) -> SiteConfig:
    """A site file for the front end: flow and fuel temperature as analog counts, mode a bit."""
    table: dict[str, Any] = {
        "command": {"address": "DB1.DBD8", "type": "float32", "unit": "V"},
        "flow": {
            "address": "DB1.DBW36",
            "type": "int16",
            "raw": [0, 27648],
            "eng": [0.0, 120.0],
            "unit": "L/min",
        },
        "fuel_temperature": {
            "address": "DB1.DBW38",
            "type": "int16",
            "raw": [0, 27648],
            "eng": [-40.0, 80.0],
            "unit": "degC",
        },
        "mode": {"address": "DB1.DBX21.0", "type": "bool"},  # low byte of the UInt at DBW20
        "seq": {"address": "DB1.DBD0", "type": "uint32"},
        "kc": {"address": "DB1.DBD24", "type": "float32"},
        "ti": {"address": "DB1.DBD28", "type": "float32"},
        "setpoint": {"address": "DB2.DBD4", "type": "float32", "unit": "L/min"},  # another DB
    }
    table.update(tags)
    return SiteConfig.model_validate(
        {
            "site": {"name": "s7 test loop"},
            "plc": {"protocol": "s7", "host": HOST, "port": port, "rack": 0, "slot": 1},
            "tags": table,
            "write": {
                "kc": {"address": "DB2.DBD20", "type": "float32"},
                "ti": {"address": "DB2.DBD24", "type": "float32"},
                "apply": {"address": "DB2.DBD28", "type": "uint32"},
                "heartbeat": {"address": "DB2.DBW40", "type": "uint16"},
            },
            "ring": {
                "head": "DB1.DBD200",
                "address": "DB1.DBD2000",
                "size": RING_SIZE,
                "fields": ["seq", "command", "flow", "setpoint", "excitation"],
            },
        }
    )


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind((HOST, 0))
        return int(probe.getsockname()[1])


@pytest.fixture
def requests(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Counts the S7 requests every snap7 client sends (one entry per request)."""
    sent: list[int] = []
    original = Client._send_receive

    def counting(self: Client, request: bytes, max_stale_retries: int = 3) -> dict[str, Any]:
        sent.append(len(request))
        return original(self, request, max_stale_retries)

    monkeypatch.setattr(Client, "_send_receive", counting)
    return sent


# (a) a plain snap7 client against the front end ---------------------------------------------


def test_db1_bytes_as_points_say(client: Client) -> None:
    assert bytes(client.db_read(1, 0, 46)) == DB1_HEAD
    assert client.db_read(1, 200, 6).hex() == "000000270040"
    # ring slot 5 at 2000 + 20 x 5: seq 1005, 1.05 V, 10 L/min, 50 L/min, -0.5 V
    record = client.db_read(1, 2100, 20)
    assert record[:4].hex() == "000003ed"
    assert record[8:20].hex() == "4120000042480000bf000000"
    assert struct.unpack(">f", record[4:8])[0] == pytest.approx(1.05, rel=1e-7)


def test_db2_writes_are_collected(frontend: S7Frontend, client: Client) -> None:
    # mode_request UInt 1 @0, setpoint_request 55.0 @4, manual_command 3.5 @8
    client.db_write(2, 0, bytearray.fromhex("0001 0000 425C0000 40600000"))
    # staged kc 0.25 @20, ti 6.0 @24, apply 7 @28: one request, as the adapter writes them
    client.db_write(2, 20, bytearray.fromhex("3E800000 40C00000 00000007"))
    client.db_write(2, 40, bytearray.fromhex("0009"))  # heartbeat
    client.db_write(2, 44, bytearray.fromhex("BE000000"))  # excitation request -0.125 V
    got = _run(frontend.collect())
    assert got == {
        "mode_request": 1.0,
        "setpoint_request": 55.0,
        "manual_command": 3.5,
        "staged_kc": 0.25,
        "staged_ti": 6.0,
        "apply": 7.0,
        "heartbeat": 9.0,
        "excitation_request": -0.125,
    }


def test_publish_wraps_counters_saturates_counts_and_updates_in_place(
    frontend: S7Frontend, client: Client
) -> None:
    values = {"seq": 2**32 + 3, "flow_counts": 40000, "fuel_temperature_counts": float("nan")}
    _run(frontend.publish({**values, "not_a_point": 1.0, "manual_command": 9.0}, {}))
    assert client.db_read(1, 0, 4).hex() == "00000003"
    assert client.db_read(1, 36, 4).hex() == "7fff0000"  # Int saturates, NaN counts → 0
    assert client.db_read(2, 8, 4).hex() == "00000000"  # publish never writes DB2


def test_unregistered_db_and_offset_are_refused(client: Client) -> None:
    with pytest.raises(snap7.error.S7ProtocolError, match="0x0a"):
        client.db_read(3, 0, 4)
    with pytest.raises(snap7.error.S7ProtocolError, match="0x05"):
        client.db_read(1, 2000 + 20 * RING_SIZE - 2, 4)


# (b) the adapter against the front end ------------------------------------------------------


def test_open_source_gives_the_s7_adapter(frontend: S7Frontend) -> None:
    source = open_source(_site(frontend.port))
    assert isinstance(source, S7Source)
    assert source.where == f"s7 {HOST}:{frontend.port} rack 0 slot 1"


def test_read_scales_decodes_bits_in_one_request(frontend: S7Frontend, requests: list[int]) -> None:
    async def main() -> Any:
        async with S7Source(_site(frontend.port)) as source:
            await frontend.publish({}, {})
            # the client writes the setpoint that the site file reads back from DB2
            await source._call(lambda c: c.db_write(2, 4, bytearray.fromhex("425C0000")))
            requests.clear()
            return await source.read()

    reading = _run(main())
    assert len(requests) == 1  # DB1's span and DB2's in one multi-item request
    assert reading.raw["flow"] == 13824
    assert reading.values["flow"] == pytest.approx(60.0)
    assert reading.values["fuel_temperature"] == pytest.approx(80.0)
    assert reading.values["command"] == 2.5
    assert reading.values["mode"] == 1.0
    assert reading.values["seq"] == 123456789
    assert (reading.values["kc"], reading.values["ti"]) == (0.125, 8.0)
    assert reading.values["setpoint"] == 55.0


def test_read_one_db_is_one_db_read(frontend: S7Frontend, requests: list[int]) -> None:
    site = _site(
        frontend.port, setpoint={"address": "DB1.DBD12", "type": "float32", "unit": "L/min"}
    )

    async def main() -> Any:
        async with S7Source(site) as source:
            requests.clear()
            return await source.read()

    assert _run(main()).values["setpoint"] == -1.0
    assert len(requests) == 1


def test_spans_are_cut_to_the_pdu_and_still_read_in_one_request(
    frontend: S7Frontend, requests: list[int]
) -> None:
    far = {"address": "DB1.DBD2104", "type": "uint32"}  # ring slot 5's command word, 2 kB on
    source = S7Source(_site(frontend.port, seq=far))
    spans = plan_spans(source._read_items, 222)  # a 240-byte PDU
    assert [(s.db, s.start, s.length) for s in spans] == [(1, 8, 32), (1, 2104, 4), (2, 4, 4)]

    async def main() -> Any:
        async with source:
            requests.clear()
            return await source.read()

    reading = _run(main())
    assert len(requests) == 1  # three blocks, one multi-item request
    assert reading.values["seq"] == struct.unpack(">I", struct.pack(">f", 1.05))[0]
    assert reading.values["command"] == 2.5


def test_mode_bit_follows_the_word(frontend: S7Frontend) -> None:
    async def main() -> list[float]:
        async with S7Source(_site(frontend.port)) as source:
            modes = []
            for mode in (0, 1):
                await frontend.publish({"mode": mode}, {})
                modes.append((await source.read()).values["mode"])
            return modes

    assert _run(main()) == [0.0, 1.0]


def test_ring_head_and_slices(frontend: S7Frontend, requests: list[int]) -> None:
    async def main() -> Any:
        async with S7Source(_site(frontend.port)) as source:
            requests.clear()
            head = await source.read_ring_head()
            records = await source.read_ring(0, 40)
            tail = await source.read_ring(60, 4)
            return head, records, tail

    head, records, tail = _run(main())
    assert head == 39
    # 1 (head) + 800 bytes in ceil(800 / 462) = 2 PDU-sized requests + 1 (tail)
    assert len(requests) == 4
    assert [r.seq for r in records] == list(range(1000, 1040))
    assert records[7].values == pytest.approx(
        {"command": 1.07, "flow": 14.0, "setpoint": 50.0, "excitation": -0.5}
    )
    assert [r.seq for r in tail] == [0, 0, 0, 0]  # never written


def test_ring_slice_outside_the_ring_is_refused(frontend: S7Frontend) -> None:
    async def main() -> None:
        async with S7Source(_site(frontend.port)) as source:
            await source.read_ring(60, 5)

    with pytest.raises(ValueError, match="outside"):
        _run(main())


def test_staged_gains_in_one_write(frontend: S7Frontend, requests: list[int]) -> None:
    async def main() -> None:
        async with S7Source(_site(frontend.port)) as source:
            requests.clear()
            await source.write({"apply": 3, "kc": 0.2, "ti": 6.0})
            assert len(requests) == 1
            await source.write({"heartbeat": 17})

    _run(main())
    got = _run(frontend.collect())
    assert got["staged_kc"] == pytest.approx(0.2, rel=1e-7)
    assert (got["staged_ti"], got["apply"], got["heartbeat"]) == (6.0, 3.0, 17.0)
    assert frontend.db2[20:32].hex() == "3e4ccccd40c0000000000003"


def test_write_of_an_unmapped_role_names_it(frontend: S7Frontend) -> None:
    async def main() -> None:
        async with S7Source(_site(frontend.port)) as source:
            await source.write({"echo": 1})

    with pytest.raises(ConfigError, match=r"write\.echo"):
        _run(main())


@pytest.mark.parametrize(
    ("tag", "address"),
    [("flow", "DB7.DBW36"), ("kc", "DB1.DBD40000")],
    ids=["missing DB", "offset past the end"],
)
def test_refused_address_names_the_key(frontend: S7Frontend, tag: str, address: str) -> None:
    site = _site(frontend.port, **{tag: {**_site(1).tags[tag].model_dump(), "address": address}})

    async def main() -> None:
        async with S7Source(site) as source:
            await source.read()

    with pytest.raises(ConfigError, match=rf"tags\.{tag}: .*{address}.*PUT/GET"):
        _run(main())


def test_refused_write_names_the_keys(frontend: S7Frontend) -> None:
    site = _site(frontend.port)
    write = {**site.write, "kc": site.write["kc"].model_copy(update={"address": "DB9.DBD0"})}

    async def main() -> None:
        async with S7Source(site.model_copy(update={"write": write})) as source:
            await source.write({"kc": 0.2})

    with pytest.raises(ConfigError, match=r"write\.kc: the PLC refuses writing DB9\.DBD0"):
        _run(main())


def test_unreachable_plc_is_a_link_error() -> None:
    port = _free_port()

    async def main() -> None:
        source = S7Source(_site(port))
        with pytest.raises(LinkError, match="not connected"):
            await source.read()
        await source.connect()

    with pytest.raises(LinkError, match=rf"{HOST}:{port} rack 0 slot 1: cannot connect"):
        _run(main())


def test_server_restart_drops_then_reconnects(frontend: S7Frontend) -> None:
    async def main() -> None:
        async with S7Source(_site(frontend.port)) as source:
            assert (await source.read()).values["command"] == 2.5
            port = frontend.port
            await frontend.stop()
            with pytest.raises(LinkError, match="link lost"):
                await source.read()
            with pytest.raises(LinkError, match="not connected"):
                await source.read()
            with pytest.raises(LinkError, match="cannot connect"):
                await source.connect()
            await frontend.start()
            assert frontend.port == port
            await frontend.publish({"command": 4.0}, {})
            await source.connect()
            assert (await source.read()).values["command"] == 4.0

    _run(main())


# (c) end to end: the virtual PLC over S7, a plain snap7 client -------------------------------

RING_BYTE = 2000  # DB1.DBD2000: slot 0 (2 x RING_FIRST_REGISTER)


def _ring_records(plain: Client, ring_size: int) -> dict[int, tuple[float, float, float]]:
    """Every ring record by sequence number: (command [V], flow, setpoint [L/min])."""
    data = plain.db_read(1, RING_BYTE, 20 * ring_size)
    records = {}
    for slot in range(ring_size):
        seq, command, flow, setpoint, _excitation = struct.unpack_from(">Iffff", data, 20 * slot)
        records[seq] = (command, flow, setpoint)
    return records


def _head(plain: Client) -> int:
    return int(struct.unpack(">I", plain.db_read(1, 200, 4))[0])


def test_virtual_plc_manual_step_gain_and_staged_gains() -> None:
    runner = pytest.importorskip("fuelid.plc.virtual._runner", reason="the virtual PLC runner")
    from fuelid.plant import load_plant_config
    from fuelid.units import celsius_to_kelvin
    from fuelid.workflow import plant_info

    u0, u1, settle = 2.9, 3.1, 750  # V, V, samples (15 s of plant time, ~3 settling times)
    with runner.VirtualPlcThread(protocol="s7", port=None, speed=20.0, seed=1) as virtual:
        plain = Client()
        plain.connect(HOST, 0, 1, tcp_port=virtual.port)
        try:
            ring_size = int(struct.unpack(">H", plain.db_read(1, 204, 2))[0])
            # MAN (mode_request UInt 0 @ DB2.DBW0) and the manual command (REAL @ DB2.DBD8)
            plain.db_write(2, 0, bytearray(struct.pack(">H", 0)))
            plain.db_write(2, 8, bytearray(struct.pack(">f", u0)))
            start = _head(plain)
            step = wait_until(
                lambda: (h := _head(plain)) >= start + settle and h, 5.0, "u0 to settle"
            )
            plain.db_write(2, 8, bytearray(struct.pack(">f", u1)))
            wait_until(lambda: _head(plain) >= step + settle, 5.0, "u1 to settle")
            records = _ring_records(plain, ring_size)
            fuel_C = struct.unpack(">f", plain.db_read(1, 16, 4))[0]

            # staged gains: heartbeat first (a stale advisor's sets are refused), then kc, ti
            # and the apply number in one write (DB2.DBD20, DBD24, DBD28)
            kc, ti = 1.2 * virtual.plc.kc0, 0.9 * virtual.plc.ti0
            plain.db_write(2, 40, bytearray(struct.pack(">H", 1)))
            plain.db_write(2, 20, bytearray(struct.pack(">ffI", kc, ti, 5)))
            echo = wait_until(
                lambda: (
                    struct.unpack(">I", plain.db_read(1, 32, 4))[0] == 5 and plain.db_read(1, 24, 8)
                ),
                5.0,
                "the staged set's echo",
            )
            status = struct.unpack(">H", plain.db_read(1, 22, 2))[0]
        finally:
            plain.disconnect()

    window = 250  # 5 s of plant time on each side, averaged
    before = [records[s] for s in range(step - window, step) if s in records]
    after = [records[s] for s in range(step + settle - window, step + settle) if s in records]
    assert len(before) == len(after) == window
    assert {r[0] for r in before} == {struct.unpack(">f", struct.pack(">f", u0))[0]}
    assert {r[0] for r in after} == {struct.unpack(">f", struct.pack(">f", u1))[0]}
    gain = (np.mean([r[1] for r in after]) - np.mean([r[1] for r in before])) / (u1 - u0)
    K = plant_info(load_plant_config(), celsius_to_kelvin(fuel_C), 0.5 * (u0 + u1))
    assert gain == pytest.approx(K.equivalent.model.K, rel=0.02)

    assert struct.unpack(">ff", echo) == pytest.approx((kc, ti), rel=1e-6)
    assert status & 0b100 == 0  # bit 2: the set was not refused
