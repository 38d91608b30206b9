"""Reading the write side back (``PlcSource.read_write_side``): the PLC's echo of a gain write.

Against the real virtual PLC on loopback for each protocol (Modbus TCP, also with the CDAB/BADC
layout, OPC UA, S7), through fuelid's adapters and the virtual PLC's own site file: before any
write the echo reads 0; after a fresh heartbeat and one staged write of kc, ti and a new apply
number, a few control periods of plant time later the echo is that number and the read tags kc
and ti are the written gains (as float32). Waits are on the PLC's sequence counter (plant time),
not on wall time, so a slow machine makes them slower, not wrong; each test is bounded.

Without a PLC: a role the write side does not map is a ConfigError naming ``write.<role>``
(before any request), an unconnected source a LinkError, and a replayed log refuses (it has no
write side).
"""

from __future__ import annotations

import asyncio
import importlib.util
import tomllib
from collections.abc import Coroutine
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import pytest

from fuelid.errors import ConfigError
from fuelid.plc.adapters import LinkError, PlcSource, open_source
from fuelid.plc.site import SiteConfig
from support.waiting import await_until

# xdist: one worker runs every module that drives a PLC at speed, one after another
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("real-time")

T = TypeVar("T")

LIMIT_S = 15.0
"""Wall-time bound of each test body [s] (a run takes well under 1 s at 20×)."""
SPEED = 20.0
"""Plant time per wall time of the virtual PLC."""
N_CONTROL = 50
"""Samples per control period (1 s / 0.02 s): the PLC takes a staged set at a control scan."""
APPLY = 70_001
"""The apply number written: above 65535, so both 16-bit words of the uint32 must be right."""

_LIBRARY = {"modbus": "pymodbus", "opcua": "asyncua", "s7": "snap7"}
MISSING = {"modbus": "ir:500", "opcua": "ns=2;s=FuelLoop.NoSuchEcho", "s7": "DB9.DBD0"}
"""An echo address the virtual PLC does not have, per protocol."""


def _protocol(protocol: str, **options: Any) -> Any:
    """A test parameter: the protocol and VirtualPlcThread options, skipped without its library."""
    library = _LIBRARY[protocol]
    missing = importlib.util.find_spec(library) is None
    suffix = "-" + "-".join(f"{k}={v}" for k, v in options.items()) if options else ""
    return pytest.param(
        protocol,
        options,
        id=protocol + suffix,
        marks=pytest.mark.skipif(missing, reason=f"needs {library}: pip install 'fuelid[plc]'"),
    )


LINKS = [
    _protocol("modbus"),
    _protocol("modbus", word_order="little", byte_swap=True),
    _protocol("opcua"),
    _protocol("s7"),
]


def run(coro: Coroutine[Any, Any, T]) -> T:
    """Run a test body in a fresh event loop, bounded in wall time."""
    return asyncio.run(asyncio.wait_for(coro, LIMIT_S))


def f32(value: float) -> float:
    """``value`` as the PLC stores it (float32)."""
    return float(np.float32(value))


def _site(protocol: str, drop: tuple[str, ...] = ()) -> SiteConfig:
    """The virtual PLC's generated site file (for a port nobody serves), less write roles."""
    from fuelid.plc.virtual import site_text

    data = tomllib.loads(site_text(protocol, "127.0.0.1", 9))
    for role in drop:
        del data["write"][role]
    return SiteConfig.model_validate(data)


async def _seq(source: PlcSource) -> int:
    """The PLC's sample counter now (read tag ``seq``)."""
    return int((await source.read()).values["seq"])


async def _wait_samples(source: PlcSource, samples: int) -> None:
    """Wait until ``samples`` more samples of plant time have passed on the PLC."""
    start = await _seq(source)

    async def passed() -> bool:
        return await _seq(source) >= start + samples

    # within the body's bound (LIMIT_S), so that this message, not a bare timeout, says why
    await await_until(passed, 10.0, f"{samples} samples of plant time", every=0.01)


@pytest.mark.parametrize(("protocol", "options"), LINKS)
def test_the_echo_verifies_a_staged_gain_write(protocol: str, options: dict[str, Any]) -> None:
    from fuelid.plc.virtual import VirtualPlcThread

    with VirtualPlcThread(protocol=protocol, speed=SPEED, seed=31, **options) as virtual:
        site = SiteConfig.model_validate(tomllib.loads(virtual.site_text()))
        source = open_source(site)
        kc0, ti0 = virtual.plc.kc0, virtual.plc.ti0
        kc, ti = 1.5 * kc0, 0.75 * ti0  # within the PLC's limits (0.1–10 × commissioning)

        async def body() -> tuple[dict[str, float], dict[str, float], dict[str, float]]:
            async with source:
                before = await source.read_write_side(["echo"])
                with pytest.raises(ConfigError, match=r"^write\.flow: .*no such write tag"):
                    await source.read_write_side(["echo", "flow"])  # a read role, not a write one
                with pytest.raises(ConfigError, match=r"^write\.bogus: "):
                    await source.read_write_side(["bogus"])
                # a fresh heartbeat (stale until it first changes), then the staged set with a
                # new apply number and another heartbeat change, in one request
                await source.write({"heartbeat": 1})
                await source.write({"kc": kc, "ti": ti, "apply": APPLY, "heartbeat": 2})
                # collected at the next tick (20 samples at 20×), taken at the next control
                # scan: three control periods of plant time leave room for both
                await _wait_samples(source, 3 * N_CONTROL)
                echo = await source.read_write_side(["echo"])
                applied = (await source.read()).values
                every = await source.read_write_side(["heartbeat", "echo", "kc", "ti", "apply"])
                return before, echo | {"kc": applied["kc"], "ti": applied["ti"]}, every

        before, after, every = run(body())

        # an echo mapped where the PLC has nothing: a ConfigError naming the key, not NaN or a
        # retry (OPC UA refuses the unknown NodeId at connect already)
        data = tomllib.loads(virtual.site_text())
        data["write"]["echo"]["address"] = MISSING[protocol]
        wrong = open_source(SiteConfig.model_validate(data))

        async def refused() -> None:
            async with wrong:
                await wrong.read_write_side(["echo"])

        with pytest.raises(ConfigError, match=r"^write\.echo: ") as error:
            run(refused())
        assert MISSING[protocol].split(";")[-1].removeprefix("s=") in str(error.value)

    assert before == {"echo": 0.0}  # no set applied yet
    assert after["echo"] == APPLY
    assert after["kc"] == pytest.approx(f32(kc), rel=1e-7)
    assert after["ti"] == pytest.approx(f32(ti), rel=1e-7)
    # the staged area reads back as written (float32), the echo among them, all in one call,
    # in the order asked
    assert list(every) == ["heartbeat", "echo", "kc", "ti", "apply"]
    assert every["echo"] == every["apply"] == APPLY
    assert every["heartbeat"] == 2.0
    assert (every["kc"], every["ti"]) == pytest.approx((f32(kc), f32(ti)), rel=1e-7)


def test_modbus_reads_the_write_side_in_one_request_per_area() -> None:
    pytest.importorskip("pymodbus", reason="needs pymodbus: pip install 'fuelid[plc]'")
    from fuelid.plc.adapters import ModbusSource
    from fuelid.plc.virtual import VirtualPlcThread

    with VirtualPlcThread(protocol="modbus", speed=SPEED, seed=32) as virtual:
        source = ModbusSource(SiteConfig.model_validate(tomllib.loads(virtual.site_text())))

        async def body() -> tuple[int, int]:
            async with source:
                first = source.requests
                await source.read_write_side(["echo", "kc", "ti", "apply", "heartbeat"])
                return first, source.requests

        first, last = run(body())
    # ir:16 (echo) and hr:10…20 (kc, ti, apply, heartbeat): the two areas, no more
    assert last - first == 2


@pytest.mark.parametrize(("protocol", "options"), LINKS)
def test_a_role_the_write_side_does_not_map_is_named(
    protocol: str, options: dict[str, Any]
) -> None:
    source = open_source(_site(protocol, drop=("echo",)))

    async def body() -> None:
        # refused before any request: the source is not even connected
        with pytest.raises(ConfigError, match=r"^write\.echo: .*mapped: kc, ti, apply, heartbeat"):
            await source.read_write_side(["apply", "echo"])
        with pytest.raises(TypeError, match="not the string 'apply'"):
            await source.read_write_side("apply")
        assert await source.read_write_side([]) == {}

    run(body())


@pytest.mark.parametrize(("protocol", "options"), LINKS)
def test_an_unconnected_source_is_a_link_error(protocol: str, options: dict[str, Any]) -> None:
    source = open_source(_site(protocol))

    async def body() -> None:
        with pytest.raises(LinkError):
            await source.read_write_side(["echo"])

    run(body())


def test_a_replayed_log_has_no_write_side(tmp_path: Path) -> None:
    log = tmp_path / "log.csv"
    log.write_text("u,y\n2.0,40.0\n2.1,41.0\n", encoding="utf-8")
    site = SiteConfig.model_validate(
        {
            "site": {"name": "replay"},
            "plc": {"protocol": "replay", "path": str(log)},
            "tags": {
                "command": {"address": "u", "unit": "V"},
                "flow": {"address": "y", "unit": "L/min"},
            },
            "write": {"apply": {"address": "apply", "type": "uint32"}},
        }
    )
    source = open_source(site)

    async def body() -> None:
        async with source:
            await source.write({"apply": 3})  # kept, never echoed
            with pytest.raises(ConfigError, match=r"^write\.echo: .*replayed log has no write"):
                await source.read_write_side(["echo"])
            with pytest.raises(ConfigError, match=r"^write\.apply: .*no write side"):
                await source.read_write_side(["apply"])

    run(body())
