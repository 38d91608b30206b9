"""The virtual PLC: its engine alone, and on Modbus TCP against a plain pymodbus client.

The socket tests use only pymodbus's own client (not fuelid's adapters), on loopback, at 20–50
times real time, and wait on the PLC's sequence counter (plant time), not on wall time, so a
slow machine makes them slower, not wrong. Expected values come from the plant model
(``fuelid plant info``'s linearisation, the steady state), hand-computed registers and the PI
algorithm written out here.
"""

from __future__ import annotations

import asyncio
import importlib.util
import math
import re
import struct
import time
import tomllib
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.errors import ConfigError, DataError
from fuelid.plant import load_plant_config, operating_point
from fuelid.plc.site import SiteConfig, load_site
from fuelid.plc.virtual import VirtualPLC, site_text
from fuelid.plc.virtual._engine import (
    GAIN_LIMITS,
    STATUS_AT_LIMIT,
    STATUS_REFUSED,
    STATUS_STALE,
    commissioning_gains,
)
from fuelid.plc.virtual._points import (
    POINTS,
    RING_FIRST_REGISTER,
    RING_HEAD_REGISTER,
    RING_RECORD_REGISTERS,
)
from fuelid.profiles.runs import Profile, load_profile, run_profile, steps_profile
from fuelid.units import LPM_PER_M3S, celsius_to_kelvin
from fuelid.workflow import plant_info
from support.waiting import await_until, wait_until

# xdist: one worker runs every module that drives a PLC at speed, one after another
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("real-time")

HAS_PYMODBUS = importlib.util.find_spec("pymodbus") is not None
needs_pymodbus = pytest.mark.skipif(
    not HAS_PYMODBUS, reason="pymodbus (the plc extra) is not installed: pip install 'fuelid[plc]'"
)
DEVICE = 1
SEQ_MODULUS = 2**32
N_CONTROL = 50  # samples per control period (1 s / 0.02 s)


# -- engine alone (no sockets) -----------------------------------------------------------------


def _ring_rows(records: dict[int, np.ndarray]) -> np.ndarray:
    return np.array(list(records.values()))


def test_engine_is_deterministic_however_it_is_sliced() -> None:
    a, b = VirtualPLC(seed=3), VirtualPLC(seed=3)
    for plc in (a, b):
        plc.write_points({"mode_request": 1, "setpoint_request": 40.0})
    rows_a = _ring_rows(a.advance(700))
    rows_b = np.array([row for _ in range(700) for row in b.advance(1).values()])
    np.testing.assert_array_equal(rows_a, rows_b)
    assert a.read_points() == b.read_points()
    c = VirtualPLC(seed=4)
    c.write_points({"mode_request": 1, "setpoint_request": 40.0})
    assert not np.array_equal(rows_a, _ring_rows(c.advance(700)))  # the seed matters


def test_engine_starts_in_man_at_the_bottom_of_the_range() -> None:
    plc = VirtualPLC(seed=0)
    points = plc.read_points()
    assert set(points) == {name for name, p in POINTS.items() if p.access == "read"}
    assert points["mode"] == 0.0
    assert points["command"] == 1.0
    assert points["status"] == STATUS_AT_LIMIT | STATUS_STALE  # at 1 V, no advisor yet
    q_1V = operating_point(load_plant_config(), 1.0, celsius_to_kelvin(20.0)).q * LPM_PER_M3S
    assert points["flow"] == pytest.approx(q_1V, abs=0.5)
    assert points["ring_head"] == points["seq"] == 0.0
    assert points["ring_size"] == 2048.0


def test_engine_quantises_the_flow_as_an_analog_input() -> None:
    plc = VirtualPLC(seed=1)
    for _ in range(20):
        plc.advance(7)
        points = plc.read_points()
        assert points["flow"] == points["flow_counts"] * 120.0 / 27648.0
    assert points["fuel_temperature_counts"] == round((20.0 + 40.0) / 120.0 * 27648.0)
    smooth = VirtualPLC(seed=1, quantisation=False, noise_sd_Lpm=0.0)
    smooth.advance(10)
    q = smooth.read_points()["flow"]
    assert q != round(q * 27648.0 / 120.0) * 120.0 / 27648.0


def test_ring_records_match_the_samples_and_wrap_the_sequence() -> None:
    plc = VirtualPLC(seed=2, seq0=SEQ_MODULUS - 30, ring_size=64)
    plc.write_points({"manual_command": 2.0})
    records = plc.advance(100)
    seqs = [int(r[0]) for r in records.values()]
    # 100 samples into a 64-slot ring: the newest 64, consecutive across the wrap
    expected = [(SEQ_MODULUS - 30 + k) % SEQ_MODULUS for k in range(37, 101)]
    assert seqs == expected
    for slot, record in records.items():
        assert slot == int(record[0]) % 64
    assert plc.seq == 70
    assert plc.read_points()["ring_head"] == 70.0
    newest = plc.ring[70 % 64]
    points = plc.read_points()
    fields = ("command", "flow", "setpoint", "excitation")
    assert list(newest) == [70.0, *(points[name] for name in fields)]


def test_man_command_takes_effect_at_the_next_scan_and_is_clamped() -> None:
    plc = VirtualPLC(seed=0)
    plc.advance(10)
    plc.write_points({"manual_command": 7.5})  # beyond the 5 V top
    rows = _ring_rows(plc.advance(45))
    assert set(rows[:39, 1]) == {1.0}  # samples 11…49: the scan at 50 has not come yet
    assert set(rows[39:, 1]) == {5.0}
    assert int(plc.read_points()["status"]) & STATUS_AT_LIMIT


def test_man_to_auto_is_bumpless_and_pi_follows_the_ideal_form() -> None:
    plc = VirtualPLC(seed=5)
    plc.write_points({"manual_command": 2.5, "setpoint_request": 45.0})
    plc.advance(20 * N_CONTROL)
    u_man = plc.read_points()["command"]
    plc.write_points({"mode_request": 1})
    rows = _ring_rows(plc.advance(20 * N_CONTROL))
    scans = rows[N_CONTROL - 1 :: N_CONTROL]  # samples at the scans (seq multiple of 50)
    assert int(scans[0, 0]) % N_CONTROL == 0
    assert scans[0, 1] == pytest.approx(u_man, abs=1e-12)  # the first AUTO output: no bump
    kc, ti = plc.gains
    e = scans[:, 3] - scans[:, 2]
    du = np.diff(scans[:, 1])
    # velocity form of the positional ideal PI: Δu_k = Kc(e_k − e_{k−1}) + Kc·h/Ti·e_{k−1}
    np.testing.assert_allclose(du, kc * np.diff(e) + kc * 1.0 / ti * e[:-1], atol=1e-9)
    assert plc.read_points()["mode"] == 1.0


def _fresh(plc: VirtualPLC, beat: int = 1) -> None:
    plc.write_points({"heartbeat": beat})


def test_staged_gains_need_apply_a_fresh_heartbeat_and_valid_values() -> None:
    plc = VirtualPLC(seed=0)
    kc0, ti0 = plc.kc0, plc.ti0
    plc.write_points({"staged_kc": 2 * kc0, "staged_ti": 3.0, "apply": 1})  # no heartbeat yet
    plc.advance(N_CONTROL)
    points = plc.read_points()
    assert (points["kc"], points["echo"]) == (kc0, 0.0)
    assert int(points["status"]) & STATUS_STALE
    assert int(points["status"]) & STATUS_REFUSED

    _fresh(plc)
    plc.write_points({"staged_kc": 2 * kc0, "staged_ti": 3.0})  # staged, apply unchanged
    plc.advance(3 * N_CONTROL)
    assert plc.gains == (kc0, ti0)
    plc.write_points({"apply": 2})
    plc.advance(N_CONTROL)
    points = plc.read_points()
    assert (points["kc"], points["ti"], points["echo"]) == (2 * kc0, 3.0, 2.0)
    assert int(points["status"]) & (STATUS_STALE | STATUS_REFUSED) == 0

    for bad in (math.nan, math.inf, -1.0, 0.0):  # refused: flagged, nothing applied
        plc.write_points(
            {"staged_kc": bad, "apply": plc.read_points()["echo"] + 10 + len(str(bad))}
        )
        plc.advance(N_CONTROL)
        points = plc.read_points()
        assert (points["kc"], points["echo"]) == (2 * kc0, 2.0)
        assert int(points["status"]) & STATUS_REFUSED

    plc.write_points({"staged_kc": 1e3, "staged_ti": 1e-6, "apply": 99})  # clamped to limits
    plc.advance(N_CONTROL)
    points = plc.read_points()
    assert points["kc"] == GAIN_LIMITS[1] * kc0
    assert points["ti"] == GAIN_LIMITS[0] * ti0
    assert points["echo"] == 99.0
    assert not int(points["status"]) & STATUS_REFUSED


def test_stale_heartbeat_ignores_sets_and_optionally_restores_commissioning() -> None:
    for restore in (False, True):
        plc = VirtualPLC(seed=0, heartbeat_timeout_s=5.0, restore_on_stale=restore)
        _fresh(plc)
        plc.write_points({"staged_kc": 0.5 * plc.kc0, "staged_ti": 2.0, "apply": 1})
        plc.advance(N_CONTROL)
        assert plc.read_points()["echo"] == 1.0
        plc.advance(6 * N_CONTROL)  # 6 s without a heartbeat change: stale
        points = plc.read_points()
        assert int(points["status"]) & STATUS_STALE
        plc.write_points({"staged_kc": 3 * plc.kc0, "staged_ti": 1.0, "apply": 2})
        plc.advance(N_CONTROL)
        points = plc.read_points()
        if restore:
            assert (points["kc"], points["ti"], points["echo"]) == (plc.kc0, plc.ti0, 0.0)
        else:
            assert (points["kc"], points["ti"], points["echo"]) == (0.5 * plc.kc0, 2.0, 1.0)
        assert int(points["status"]) & STATUS_REFUSED
        _fresh(plc, 2)  # alive again: bit 1 clears
        assert not int(plc.read_points()["status"]) & STATUS_STALE


def test_setpoint_profile_plays_in_auto_and_command_profile_in_man() -> None:
    run = VirtualPLC(seed=0, setpoint_profile="run")
    run.write_points({"mode_request": 0, "setpoint_request": 10.0})  # overridden by the run
    rows = _ring_rows(run.advance(100 * N_CONTROL))  # the newest 2048 records: 59…100 s
    profile = run_profile()
    scans = rows[rows[:, 0] % N_CONTROL == 0]
    assert run.read_points()["mode"] == 1.0
    np.testing.assert_allclose(
        scans[:, 3], [profile.at(int(s) * 0.02) for s in scans[:, 0]], atol=1e-12
    )
    at_40 = rows[(rows[:, 0] >= 80 * N_CONTROL) & (rows[:, 0] < 90 * N_CONTROL)]
    assert np.mean(at_40[:, 2]) == pytest.approx(40.0, abs=0.3)  # the PI holds the test point
    assert np.all((rows[:, 1] > 1.0) & (rows[:, 1] < 5.0))  # inside the range: no limit hit

    steps = VirtualPLC(seed=0, command_profile="steps")
    steps.write_points({"mode_request": 1, "manual_command": 4.9})  # overridden: MAN, steps
    rows = _ring_rows(steps.advance(40 * N_CONTROL))
    levels = steps_profile()
    np.testing.assert_array_equal(rows[:, 1], [levels.at(int(s) // 50 * 1.0) for s in rows[:, 0]])
    assert steps.read_points()["mode"] == 0.0
    assert levels.values.min() >= 1.5
    assert levels.values.max() <= 4.5


def test_fuel_temperature_drift_changes_the_plant() -> None:
    warm = VirtualPLC(seed=0, noise_sd_Lpm=0.0, fuel_temp_profile=([0.0, 30.0], [20.0, 50.0]))
    cold = VirtualPLC(seed=0, noise_sd_Lpm=0.0, fuel_temp_C=20.0)
    for plc in (warm, cold):
        plc.write_points({"manual_command": 3.0})
        plc.advance(40 * N_CONTROL)
    assert warm.read_points()["fuel_temperature"] == pytest.approx(50.0)
    config = load_plant_config()
    for plc, T in ((warm, 50.0), (cold, 20.0)):
        q = operating_point(config, 3.0, celsius_to_kelvin(T)).q * LPM_PER_M3S
        assert plc.read_points()["flow"] == pytest.approx(q, abs=0.01)
    assert warm.read_points()["flow"] != pytest.approx(cold.read_points()["flow"], abs=0.05)


def test_engine_refuses_bad_settings() -> None:
    with pytest.raises(ConfigError, match="whole multiple"):
        VirtualPLC(control_period_s=0.03)
    with pytest.raises(ConfigError, match="not both"):
        VirtualPLC(setpoint_profile="run", command_profile="steps")
    with pytest.raises(ConfigError, match="ring_size"):
        VirtualPLC(ring_size=1)
    with pytest.raises(ConfigError, match="built-in"):
        VirtualPLC(setpoint_profile="walk")
    with pytest.raises(ConfigError, match="kc"):
        VirtualPLC(kc=-1.0)
    with pytest.raises(DataError, match="not a write point"):
        VirtualPLC().write_points({"flow": 3.0})


def test_profiles_interpolate_step_repeat_and_load(tmp_path: Path) -> None:
    p = Profile([0.0, 10.0, 10.0, 20.0, 30.0], [1.0, 1.0, 2.0, 2.0, 4.0], repeat=True)
    times = (0.0, 9.99, 10.0, 25.0, 30.0, 35.0, 55.0)
    assert [p.at(t) for t in times] == [1.0, 1.0, 2.0, 3.0, 1.0, 1.0, 3.0]
    held = Profile([5.0, 10.0], [1.0, 3.0])
    assert (held.at(0.0), held.at(7.5), held.at(1e6)) == (1.0, 2.0, 3.0)
    assert run_profile().cycle_s == 270.0
    path = tmp_path / "sp.csv"
    path.write_text("t,setpoint\n0,20\n30,20\n30,45\n60,45\n", encoding="utf-8")
    loaded = load_profile(path, "setpoint")
    assert loaded.repeat
    assert loaded.at(45.0) == 45.0
    assert loaded.at(75.0) == 20.0
    (tmp_path / "u.csv").write_text("t_s,u_V\n0,2\n10,3\n", encoding="utf-8")
    assert load_profile(tmp_path / "u.csv", "u").at(5.0) == 2.5
    (tmp_path / "T.csv").write_text("t,fuel_temperature\n0,10\n100,30\n", encoding="utf-8")
    assert load_profile(tmp_path / "T.csv", "fuel_temperature").at(1e4) == 30.0
    (tmp_path / "bad.csv").write_text("time,flow\n0,1\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="needs columns t"):
        load_profile(tmp_path / "bad.csv", "setpoint")
    (tmp_path / "text.csv").write_text("t,u\n0,abc\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="line 2"):
        load_profile(tmp_path / "text.csv", "u")
    (tmp_path / "back.csv").write_text("t,u\n5,1\n2,1\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="never decrease"):
        load_profile(tmp_path / "back.csv", "u")
    with pytest.raises(ConfigError, match="does not exist"):
        load_profile(tmp_path / "none.csv", "u")


# -- the site file ------------------------------------------------------------------------------


@pytest.mark.parametrize("protocol", ["modbus", "opcua", "s7"])
def test_site_text_loads_for_every_protocol(protocol: str, tmp_path: Path) -> None:
    text = site_text(protocol, "127.0.0.1", 15020, kc=0.06, ti=1.4, store_url="sqlite:///x.db")
    path = tmp_path / "site.toml"
    path.write_text(text, encoding="utf-8")
    site = load_site(path)
    as_written = SiteConfig.model_validate(tomllib.loads(text))
    # the relative store file is taken from the site file's folder
    assert site.store.url == f"sqlite:///{tmp_path.resolve() / 'x.db'}"
    assert site.model_copy(update={"store": as_written.store}) == as_written
    assert site.plc.protocol == protocol
    assert site.plc.port == 15020
    assert site.missing() == []
    assert set(site.write) == {"kc", "ti", "apply", "echo", "heartbeat", "excitation"}
    assert site.ring is not None
    assert site.ring.size == 2048
    assert site.controller is not None
    assert (site.controller.kc, site.controller.ti) == (0.06, 1.4)
    flow = site.tags["flow"].address
    expected = {
        "modbus": ("ir:2", "ir:100", "ir:1000"),
        "opcua": ("ns=2;s=FuelLoop.Flow", "ns=2;s=FuelLoop.RingHead", "ns=2;s=FuelLoop.Ring"),
        "s7": ("DB1.DBD4", "DB1.DBD200", "DB1.DBD2000"),
    }[protocol]
    assert (flow, site.ring.head, site.ring.address) == expected
    if protocol == "opcua":
        assert site.plc.endpoint == "opc.tcp://127.0.0.1:15020/fuelid/plc/"


def test_print_site_and_remote_host_refusal() -> None:
    runner = CliRunner()
    result = runner.invoke(app, ["plant", "serve", "--print-site", "--word-order", "little"])
    assert result.exit_code == 0, result.stderr
    site = SiteConfig.model_validate(tomllib.loads(result.stdout))
    assert site.plc.port == 5020
    assert site.plc.word_order == "little"
    kc0, ti0 = commissioning_gains(load_plant_config(), celsius_to_kelvin(20.0), 1.0)
    assert site.controller is not None
    assert (site.controller.kc, site.controller.ti) == (kc0, ti0)
    assert site.site.plant is None  # the reference plant: no plant file to name
    plant_file = resources.files("fuelid.data") / "reference_plant.toml"
    argv = ["plant", "serve", "--print-site", "--protocol", "s7", "--config", str(plant_file)]
    result = runner.invoke(app, argv)
    assert result.exit_code == 0
    site = SiteConfig.model_validate(tomllib.loads(result.stdout))
    assert site.site.plant is not None
    assert Path(site.site.plant) == Path(str(plant_file)).resolve()
    for argv in (["--host", "0.0.0.0"], ["--host", "192.168.1.20", "--port", "5021"]):
        result = runner.invoke(app, ["plant", "serve", *argv])
        assert result.exit_code == 2
        assert "not a loopback address" in result.stderr
        assert "--allow-remote" in result.stderr
        assert result.stderr.count("\n") == 1
        assert "Traceback" not in result.stderr
    result = runner.invoke(app, ["plant", "serve", "--setpoint-profile", "nowhere.csv"])
    assert result.exit_code == 2
    assert "does not exist" in result.stderr


# -- on Modbus TCP, against a plain pymodbus client ---------------------------------------------


def _swap(register: int) -> int:
    return ((register & 0xFF) << 8) | (register >> 8)


class Plain:
    """A plain pymodbus client of the virtual PLC: the map from points.py, written out here."""

    def __init__(self, port: int, word_order: str = "big", byte_swap: bool = False) -> None:
        from pymodbus.client import AsyncModbusTcpClient

        self.client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=2, retries=1)
        self.word_order = word_order
        self.byte_swap = byte_swap
        self.last_seq: int | None = None
        self.records: list[tuple[int, float, float, float]] = []

    async def __aenter__(self) -> Plain:
        assert await self.client.connect()
        return self

    async def __aexit__(self, *exc: object) -> None:
        self.client.close()

    def _words(self, registers: Sequence[int]) -> list[int]:
        words = [_swap(r) for r in registers] if self.byte_swap else list(registers)
        return words[::-1] if self.word_order == "little" else words

    def u32(self, registers: Sequence[int]) -> int:
        hi, lo = self._words(registers)
        return (hi << 16) | lo

    def f32(self, registers: Sequence[int]) -> float:
        value: float = struct.unpack(">f", struct.pack(">HH", *self._words(registers)))[0]
        return value

    def f32_registers(self, value: float) -> list[int]:
        hi, lo = struct.unpack(">HH", struct.pack(">f", value))
        words = [lo, hi] if self.word_order == "little" else [hi, lo]
        return [_swap(w) for w in words] if self.byte_swap else words

    def u32_registers(self, value: int) -> list[int]:
        words = [value >> 16, value & 0xFFFF]
        words = words[::-1] if self.word_order == "little" else words
        return [_swap(w) for w in words] if self.byte_swap else words

    async def points(self) -> dict[str, Any]:
        rr = await self.client.read_input_registers(0, count=20, device_id=DEVICE)
        assert not rr.isError(), rr
        r = rr.registers
        one = (lambda x: _swap(x)) if self.byte_swap else (lambda x: x)
        counts = one(r[18])
        return {
            "seq": self.u32(r[0:2]),
            "flow": self.f32(r[2:4]),
            "command": self.f32(r[4:6]),
            "setpoint": self.f32(r[6:8]),
            "fuel_temperature": self.f32(r[8:10]),
            "mode": one(r[10]),
            "status": one(r[11]),
            "kc": self.f32(r[12:14]),
            "ti": self.f32(r[14:16]),
            "echo": self.u32(r[16:18]),
            "flow_counts": counts - 65536 if counts >= 32768 else counts,
        }

    async def write(self, address: int, registers: list[int]) -> None:
        rr = await self.client.write_registers(address, registers, device_id=DEVICE)
        assert not rr.isError(), rr

    async def write_f32(self, address: int, value: float) -> None:
        await self.write(address, self.f32_registers(value))

    async def head(self) -> int:
        rr = await self.client.read_input_registers(RING_HEAD_REGISTER, count=3, device_id=DEVICE)
        assert not rr.isError(), rr
        return self.u32(rr.registers[0:2])

    async def poll_ring(self, size: int = 2048) -> list[tuple[int, float, float, float]]:
        """New ring records since the last poll, oldest first (the first poll: just the head)."""
        head = await self.head()
        if self.last_seq is None:
            self.last_seq = head
            return []
        count = (head - self.last_seq) % SEQ_MODULUS
        assert count < size, f"ring overrun: {count} new records, {size} slots"
        new: list[tuple[int, float, float, float]] = []
        seq = (self.last_seq + 1) % SEQ_MODULUS
        while len(new) < count:
            slot = seq % size
            n = min(12, count - len(new), size - slot)  # ≤ 120 registers, not past the end
            width = RING_RECORD_REGISTERS  # seq, command, flow, setpoint (kept), excitation
            rr = await self.client.read_input_registers(
                RING_FIRST_REGISTER + width * slot, count=width * n, device_id=DEVICE
            )
            assert not rr.isError(), rr
            for i in range(n):
                r = rr.registers[width * i : width * i + width]
                record = (self.u32(r[0:2]), self.f32(r[2:4]), self.f32(r[4:6]), self.f32(r[6:8]))
                assert record[0] == seq, f"slot {slot}: seq {record[0]}, expected {seq}"
                new.append(record)
                seq = (seq + 1) % SEQ_MODULUS
                slot = seq % size
        self.last_seq = head
        self.records += new
        return new

    async def run_for(self, plant_s: float, period_s: float = 0.02, timeout: float = 20.0) -> None:
        """Poll the ring until ``plant_s`` of plant time has passed (or fail at ``timeout``)."""
        if self.last_seq is None:
            await self.poll_ring()
        assert self.last_seq is not None
        target = round(plant_s / period_s)
        got = 0

        async def enough() -> bool:
            nonlocal got
            got += len(await self.poll_ring())
            return got >= target

        await await_until(
            enough, timeout, f"{plant_s:g} s of plant time (the virtual PLC keeping time)",
            every=0.05,
        )  # fmt: skip

    def window(self, last_s: float) -> np.ndarray:
        """The records of the last ``last_s`` seconds of plant time, as an array."""
        rows: np.ndarray = np.array(self.records[-round(last_s / 0.02) :], dtype=float)
        return rows


def _virtual(**kwargs: Any) -> Any:
    from fuelid.plc.virtual import VirtualPlcThread

    return VirtualPlcThread(**kwargs)


@needs_pymodbus
def test_man_step_gives_the_gain_plant_info_predicts() -> None:
    u1, u2 = 2.5, 3.5
    info = plant_info(load_plant_config(), celsius_to_kelvin(20.0), 0.5 * (u1 + u2))
    K = info.to_json()["model"]["K"]  # what `fuelid plant info --u 3` prints

    async def run(port: int) -> tuple[float, float]:
        async with Plain(port) as plc:
            means = []
            for u in (u1, u2):
                await plc.write_f32(POINTS["manual_command"].register, u)
                await plc.run_for(25.0)  # > 4 settling times (5.3 s)
                plc.records.clear()
                await plc.run_for(20.0)
                rows = plc.window(20.0)
                assert np.all(rows[:, 1] == u)
                assert np.all(np.diff(rows[:, 0]) == 1)
                means.append(float(np.mean(rows[:, 2])))
            return means[0], means[1]

    with _virtual(speed=50.0, seed=11) as virtual:
        y1, y2 = asyncio.run(run(virtual.port))
    assert (y2 - y1) / (u2 - u1) == pytest.approx(K, rel=0.02)
    config, T = load_plant_config(), celsius_to_kelvin(20.0)
    for u, y in ((u1, y1), (u2, y2)):  # and the levels are the nonlinear plant's steady state
        assert y == pytest.approx(operating_point(config, u, T).q * LPM_PER_M3S, abs=0.05)


@needs_pymodbus
def test_pi_in_auto_reaches_the_setpoint() -> None:
    async def run(port: int) -> tuple[np.ndarray, dict[str, Any]]:
        async with Plain(port) as plc:
            await plc.write_f32(POINTS["setpoint_request"].register, 45.0)
            await plc.write(POINTS["mode_request"].register, [1])
            await plc.run_for(30.0)
            return plc.window(10.0), await plc.points()

    with _virtual(speed=40.0, seed=12) as virtual:
        rows, points = asyncio.run(run(virtual.port))
    assert points["mode"] == 1
    assert points["setpoint"] == 45.0
    assert abs(float(np.mean(rows[:, 2])) - 45.0) < 0.1  # integral action: no offset
    assert np.max(np.abs(rows[:, 2] - 45.0)) < 0.6  # only noise left (sd 0.1 L/min)
    assert points["status"] & STATUS_AT_LIMIT == 0


@needs_pymodbus
def test_staged_gains_apply_on_the_apply_word_echo_whole_and_do_not_bump() -> None:
    reg = {name: p.register for name, p in POINTS.items()}

    async def run(port: int, kc0: float, ti0: float) -> dict[str, Any]:
        out: dict[str, Any] = {}
        async with Plain(port) as plc:
            await plc.write(reg["heartbeat"], [1])
            await plc.write_f32(reg["setpoint_request"], 40.0)
            await plc.write(reg["mode_request"], [1])
            await plc.run_for(20.0)
            # staged values without a new apply number: nothing happens
            plc.records.clear()
            await plc.write(reg["staged_kc"], plc.f32_registers(3 * kc0) + plc.f32_registers(2.0))
            await plc.run_for(3.0)
            out["unapplied"] = await plc.points()
            # a setpoint step and a new set in the same scan: the bump test's worst case
            block = [
                *plc.f32_registers(50.0),  # hr:2 setpoint_request
                *[0, 0, 0, 0, 0, 0],  # hr:4 manual_command (unused in AUTO), hr:6–9 unused
                *plc.f32_registers(2 * kc0),  # hr:10 staged_kc
                *plc.f32_registers(0.8 * ti0),  # hr:12 staged_ti
                *plc.u32_registers(7),  # hr:14 apply
            ]
            await plc.write(reg["setpoint_request"], block)
            await plc.run_for(12.0)
            out["rows"] = np.array(plc.records, dtype=float)
            out["applied"] = await plc.points()
            # a refused set (NaN), then one beyond the PLC's limits (clamped)
            nan = plc.f32_registers(math.nan) + plc.f32_registers(2.0) + plc.u32_registers(8)
            await plc.write(reg["staged_kc"], nan)
            await plc.run_for(2.0)
            out["refused"] = await plc.points()
            big = plc.f32_registers(100.0) + plc.f32_registers(2.0) + plc.u32_registers(9)
            await plc.write(reg["staged_kc"], big)
            await plc.run_for(2.0)
            out["clamped"] = await plc.points()
        return out

    with _virtual(speed=20.0, seed=13, heartbeat_timeout_s=3600.0) as virtual:
        kc0, ti0 = virtual.plc.kc0, virtual.plc.ti0
        out = asyncio.run(run(virtual.port, kc0, ti0))
    f32 = np.float32
    assert out["unapplied"]["kc"] == f32(kc0)
    assert out["unapplied"]["echo"] == 0
    applied = out["applied"]
    assert (applied["kc"], applied["ti"], applied["echo"]) == (f32(2 * kc0), f32(0.8 * ti0), 7)
    assert applied["status"] & STATUS_REFUSED == 0
    refused = out["refused"]
    assert refused["status"] & STATUS_REFUSED
    assert refused["echo"] == 7
    assert refused["kc"] == applied["kc"]
    clamped = out["clamped"]
    assert clamped["kc"] == f32(GAIN_LIMITS[1] * kc0)
    assert clamped["echo"] == 9
    assert clamped["status"] & STATUS_REFUSED == 0

    # the PI's velocity form scan by scan: old gains up to and including the scan of the step
    # (bumpless: that scan's output is what the old gains give), the new gains after it
    rows = out["rows"]
    scans = rows[rows[:, 0] % N_CONTROL == 0]
    assert np.all((scans[:, 1] > 1.0) & (scans[:, 1] < 5.0))  # unsaturated: the form holds
    e = scans[:, 3] - scans[:, 2]
    du = np.diff(scans[:, 1])
    step = int(np.argmax(scans[:, 3] == 50.0))
    assert step >= 1
    assert scans[step - 1, 3] == 40.0

    def residual(kc: float, ti: float) -> np.ndarray:
        res: np.ndarray = np.abs(du - (kc * np.diff(e) + kc * 1.0 / ti * e[:-1]))
        return res

    old, new = residual(kc0, ti0), residual(2 * kc0, 0.8 * ti0)
    assert np.all(old[:step] < 1e-4), old[:step]  # Δu of scans 1…step
    assert np.all(new[step:] < 1e-4), new[step:]
    assert abs(kc0 * e[step]) > 0.3  # a bumpy change would have jumped by this much more


@needs_pymodbus
def test_output_limits_and_anti_windup() -> None:
    async def run(port: int) -> dict[str, Any]:
        out: dict[str, Any] = {}
        async with Plain(port) as plc:
            await plc.write_f32(POINTS["setpoint_request"].register, 90.0)  # above reach
            await plc.write(POINTS["mode_request"].register, [1])
            await plc.run_for(40.0)
            out["high"] = await plc.points()
            plc.records.clear()
            await plc.write_f32(POINTS["setpoint_request"].register, 40.0)
            await plc.run_for(20.0)
            out["back"] = np.array(plc.records, dtype=float)
            await plc.write_f32(POINTS["setpoint_request"].register, 0.0)  # below reach
            await plc.run_for(20.0)
            out["low"] = await plc.points()
            out["all"] = np.array(plc.records, dtype=float)
        return out

    with _virtual(speed=50.0, seed=14) as virtual:
        out = asyncio.run(run(virtual.port))
    assert out["high"]["command"] == 5.0
    assert out["high"]["status"] & STATUS_AT_LIMIT
    assert out["low"]["command"] == 1.0
    assert out["low"]["status"] & STATUS_AT_LIMIT
    assert np.all((out["all"][:, 1] >= 1.0) & (out["all"][:, 1] <= 5.0))
    back = out["back"]
    changed = int(np.argmax(back[:, 3] == 40.0))
    # no windup: the command leaves the limit at the first scan after the setpoint change
    assert back[changed, 1] < 5.0
    # and the flow settles near the new setpoint as from any step (within 1.5 L/min after
    # 12 s; a wound-up integral would hold 5 V for tens of seconds)
    after = back[changed + 600 :, 2]
    assert after.size > 200
    assert np.all(np.abs(after - 40.0) < 1.5)


@needs_pymodbus
def test_ring_has_no_gaps_and_wraps_the_sequence() -> None:
    start = SEQ_MODULUS - 300

    async def run(port: int) -> list[tuple[int, float, float, float]]:
        async with Plain(port) as plc:
            await plc.run_for(40.0)  # 2000 samples, the wrap after 300
            return plc.records

    with _virtual(speed=50.0, seed=15, seq0=start) as virtual:
        records = asyncio.run(run(virtual.port))
    seqs = np.array([r[0] for r in records], dtype=np.int64)
    assert np.all(np.diff(seqs) % SEQ_MODULUS == 1)  # consecutive, nothing lost or doubled
    assert seqs.max() > SEQ_MODULUS - 10
    assert seqs.min() < 1000


@needs_pymodbus
def test_stale_heartbeat_over_modbus_ignores_the_staged_set() -> None:
    reg = {name: p.register for name, p in POINTS.items()}

    async def run(port: int, kc0: float) -> tuple[dict[str, Any], dict[str, Any]]:
        async with Plain(port) as plc:
            await plc.write(reg["heartbeat"], [1])
            await plc.write(
                reg["staged_kc"],
                plc.f32_registers(2 * kc0) + plc.f32_registers(2.0) + plc.u32_registers(1),
            )
            await plc.run_for(2.0)
            fresh = await plc.points()
            await plc.run_for(6.0)  # no heartbeat: stale after 4 s
            await plc.write(
                reg["staged_kc"],
                plc.f32_registers(3 * kc0) + plc.f32_registers(3.0) + plc.u32_registers(2),
            )
            await plc.run_for(2.0)
            return fresh, await plc.points()

    with _virtual(speed=20.0, seed=16, heartbeat_timeout_s=4.0) as virtual:
        kc0 = virtual.plc.kc0
        fresh, stale = asyncio.run(run(virtual.port, kc0))
    assert fresh["echo"] == 1
    assert fresh["kc"] == np.float32(2 * kc0)
    assert fresh["status"] & STATUS_STALE == 0
    assert stale["status"] & STATUS_STALE
    assert stale["status"] & STATUS_REFUSED
    assert (stale["echo"], stale["kc"], stale["ti"]) == (1, fresh["kc"], 2.0)


@needs_pymodbus
def test_little_word_order_and_byte_swap_against_hand_computed_registers() -> None:
    async def run(port: int) -> tuple[list[int], dict[str, float], dict[str, float]]:
        async with Plain(port, word_order="little", byte_swap=True) as plc:
            await plc.run_for(1.0)
            rr = await plc.client.read_input_registers(4, count=2, device_id=DEVICE)
            raw = list(rr.registers)
            before = await plc.points()
            await plc.write_f32(POINTS["manual_command"].register, 3.25)
            await plc.run_for(2.0)
            await plc.run_for(0.1)
            return raw, before, await plc.points()

    with _virtual(speed=20.0, seed=17, word_order="little", byte_swap=True) as virtual:
        raw, before, after = asyncio.run(run(virtual.port))
    # 1.0 V = 0x3F800000: words [0x3F80, 0x0000]; little → [0x0000, 0x3F80]; swapped bytes
    assert raw == [0x0000, 0x803F]
    assert before["command"] == 1.0
    assert after["command"] == 3.25
    assert after["seq"] > before["seq"] > 0
    assert after["flow_counts"] * 120.0 / 27648.0 == pytest.approx(after["flow"], rel=1e-6)
    assert before["fuel_temperature"] == 20.0


@needs_pymodbus
def test_illegal_addresses_answer_an_exception_and_the_server_goes_on() -> None:
    async def run(port: int) -> list[Any]:
        async with Plain(port) as plc:
            answers: list[Any] = [
                await plc.client.read_input_registers(500, count=2, device_id=DEVICE),
                await plc.client.read_input_registers(101, count=4, device_id=DEVICE),
                await plc.client.read_input_registers(1000 + 10 * 2048, count=1, device_id=DEVICE),
                await plc.client.read_holding_registers(24, count=1, device_id=DEVICE),
                await plc.client.write_registers(30, [1, 2], device_id=DEVICE),
            ]
            good = await plc.points()
            answers.append(good)
        return answers

    with _virtual(speed=20.0, seed=18) as virtual:
        answers = asyncio.run(run(virtual.port))
    for answer in answers[:-1]:
        assert answer.isError()
        assert answer.exception_code == 2
    assert answers[-1]["command"] == 1.0


@needs_pymodbus
def test_link_drop_keeps_the_ring_and_a_restart_starts_over() -> None:
    async def read(
        port: int, last: int | None
    ) -> tuple[int, list[tuple[int, float, float, float]]]:
        async with Plain(port) as plc:
            plc.last_seq = last
            if last is None:
                await plc.poll_ring()
            await plc.run_for(2.0)
            assert plc.last_seq is not None
            return plc.last_seq, plc.records

    with _virtual(speed=20.0, seed=19) as virtual:
        last, first = asyncio.run(read(virtual.port, None))
        virtual.stop_link()
        # 6 s of plant time with no server: the ring keeps filling (it holds them all)
        assert virtual.plc.ring_size > 300
        wait_until(lambda: virtual.plc.seq >= last + 300, 10.0, "6 s of plant time unread")
        virtual.start_link()
        _head, backfill = asyncio.run(read(virtual.port, last))
        seqs = [r[0] for r in first + backfill]
        assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # back-filled: no gap
        assert len(backfill) > 300
        virtual.restart_plc()
        assert virtual.plc.seq < 100
        _, after = asyncio.run(read(virtual.port, None))
        assert after[0][0] < 200


@needs_pymodbus
def test_plant_serve_serves_modbus_for_its_duration() -> None:
    # port 0: the server binds a port the system chooses and says which
    runner = CliRunner()
    started = time.monotonic()
    result = runner.invoke(
        app, ["plant", "serve", "--port", "0", "--duration", "0.5", "--speed", "10"]
    )
    assert result.exit_code == 0, result.stderr
    bound = re.search(r"modbus on 127\.0\.0\.1:(\d+), 10x real time", result.stderr)
    assert bound is not None, result.stderr
    assert int(bound[1]) > 0
    assert "stopped after 5.0 s of plant time (seq 250)" in result.stderr
    assert time.monotonic() - started < 10.0


@needs_pymodbus
def test_plant_serve_refuses_a_port_in_use_in_one_line() -> None:
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        result = CliRunner().invoke(app, ["plant", "serve", "--port", str(port), "--duration", "1"])
    assert result.exit_code == 2
    assert f"cannot serve on 127.0.0.1:{port}" in result.stderr
    assert result.stderr.count("\n") == 1
