"""The recorder's guards (issue 14): what a new user's trial found.

Implausible values and the word order, the tags against the ring, events on the samples' time
base, the lost-sample bookkeeping, the status line's width.
"""

from __future__ import annotations

import re
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fuelid.errors import ConfigError
from fuelid.plc import RecorderStats
from fuelid.plc._quality import RangeChecks
from fuelid.plc.site import Tag
from fuelid.store import Event, Quality, Sample, SQLiteStore
from support.recorder import REPLAY, RING_REPLAY, kinds, load, record, rows, write_log

# xdist: one worker runs every module that drives a PLC at speed, one after another
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("real-time")


def virtual_plc(**kw: Any) -> Any:
    runner = pytest.importorskip("fuelid.plc.virtual._runner", reason="no virtual PLC")
    pytest.importorskip("pymodbus", reason="the [plc] extra (pymodbus) is not installed")
    return runner.VirtualPlcThread("modbus", seed=3, command_profile="steps", **kw)


def without_ring(text: str) -> str:
    return re.sub(r"\[ring\]\n(?:[^\[\n].*\n)*", "", text)


# --- 1. plausibility ----------------------------------------------------------------------


def test_tiny_huge_and_out_of_range_commands_are_bad_values() -> None:
    events: list[tuple[str, str, float | None]] = []
    tags = {
        "command": Tag(address="hr:0", unit="V"),
        "flow": Tag(address="hr:2", unit="L/min"),
        "setpoint": Tag(address="hr:4", unit="L/min", valid=[-1.0, 200.0]),
    }
    checks = RangeChecks(tags, lambda kind, detail, t: events.append((kind, detail, t)))
    assert checks.check("command", 3.0)
    assert checks.check("flow", 0.0)
    assert not checks.check("command", 2.3e-41, 12.5)  # 3.0 V read with the wrong word order
    assert not checks.check("flow", 2.7e23)
    assert not checks.check("command", 11.0)  # no drive signal is above 10.5 V
    assert not checks.check("command", -0.5)
    assert events[0] == ("bad_value", events[0][1], 12.5)  # at the sample's time
    wide = RangeChecks(
        {"command": Tag(address="hr:0", unit="V", valid=[-10.0, 12.0])}, lambda *a: None
    )
    assert wide.check("command", 11.0)
    assert wide.check("command", -5.0)


def test_implausible_floats_in_a_recording_are_flagged_not_numbers_in_the_model(
    tmp_path: Path,
) -> None:
    n = 200
    k = np.arange(n)
    u = 2.0 + 0.5 * np.sin(0.05 * k)
    u[50], u[60], u[70] = 2.3e-41, 1e12, 11.0
    log = tmp_path / "odd.csv"
    write_log(log, n, seq=k.astype(float))
    text = log.read_text().splitlines()
    rows_ = [line.split(",") for line in text]
    for i in (50, 60, 70):
        rows_[i + 1][0] = repr(float(u[i]))
    log.write_text("\n".join(",".join(r) for r in rows_) + "\n")
    site = load(REPLAY.format(path=log, speed=10.0, period=0.02) + RING_REPLAY)
    record(site, tmp_path / "odd.db", duration_s=10.0)
    data, _, _ = rows(tmp_path / "odd.db")
    bad = set(data.seq[data.quality == Quality.BAD_VALUE].tolist())
    assert bad == {50, 60, 70}


@pytest.mark.parametrize("ring", [True, False])
def test_the_wrong_word_order_is_refused_with_the_hint_before_anything_is_stored(
    tmp_path: Path, ring: bool
) -> None:
    with virtual_plc(speed=1.0, word_order="little") as srv:
        text = srv.site_text().replace('word_order = "little"', 'word_order = "big"')
        site = load(text if ring else without_ring(text))
        started = time.monotonic()
        with pytest.raises(ConfigError) as refused:
            record(site, tmp_path / "w.db", duration_s=5.0)
    assert time.monotonic() - started < 3.0
    message = str(refused.value)
    assert "\n" not in message
    assert 'try word_order = "little" or byte_swap = true' in message
    assert re.search(r"(tags\.\w+|ring\.head) ir:\d+", message), message
    data, events, info = rows(tmp_path / "w.db")
    assert len(data) == 0
    assert info.missing_samples == 0
    assert kinds(events, "gap") == []


# --- 2. the tags against the ring ------------------------------------------------------------

WRONG_FLOW = """[tags.flow]
address = "ir:18"
type = "int16"
raw = [0, 27648]
eng = [0.0, 100.0]
unit = "L/min"
"""


def test_a_flow_tag_scaled_wrongly_disagrees_with_the_ring_and_says_so(tmp_path: Path) -> None:
    messages: list[str] = []
    with virtual_plc(speed=10.0) as srv:
        text = re.sub(r"\[tags\.flow\]\n(?:[^\[\n].*\n)*", WRONG_FLOW, srv.site_text())
        site = load(text)
        record(site, tmp_path / "m.db", duration_s=2.6, on_message=messages.append)
    data, events, _ = rows(tmp_path / "m.db")
    (event,) = kinds(events, "ring_mismatch")
    assert event.detail.startswith("tags.flow ir:18 reads ")
    assert "the ring" in event.detail
    assert "raw/eng scaling" in event.detail
    tag_value, ring_value = map(float, re.findall(r"([\d.]+) L/min", event.detail))
    assert tag_value == pytest.approx(ring_value * 100.0 / 120.0, rel=0.03)
    assert event.detail in messages
    assert data.time[0] <= event.time <= data.time[-1]  # on the samples' time base
    assert "tags.command" not in "".join(messages)  # the command agrees


# --- 3. events on the samples' time base -------------------------------------------------------


def test_at_speed_link_down_and_up_bracket_the_hole_in_the_samples(tmp_path: Path) -> None:
    from fuelid.plc.adapters import ModbusSource

    period = 0.02
    with virtual_plc(speed=10.0, ring_size=256) as srv:
        site = load(srv.site_text())

        def outage() -> None:
            srv.stop_link()
            # the behaviour: the link down for 1 s (500 samples of plant time, more than the
            # ring holds; five times the recorder's ring poll)
            time.sleep(1.0)
            srv.start_link()

        threading.Timer(1.0, outage).start()
        stats = record(
            site, tmp_path / "e.db", 3.0, ModbusSource(site, timeout_s=0.25),
            backoff_s=(0.05, 0.1),
        )  # fmt: skip
    data, events, info = rows(tmp_path / "e.db")
    assert stats.drops == 1
    (down,), (up,) = kinds(events, "link_down"), kinds(events, "link_up")
    (hole,) = np.flatnonzero(np.diff(data.seq) != 1)
    before, after = data.time[hole], data.time[hole + 1]
    assert after - before > 5.0  # data time: ~ 10 s of plant time in the 1 s outage
    assert down.time == pytest.approx(before + period, abs=1e-6)
    assert up.time == after
    for event in (down, up):  # one clock in a detail: the wall time is the event's wall_time
        assert "wall clock" not in event.detail
    assert re.fullmatch(
        r"after \d+\.\d{3} s without a link \(\d+ attempts\); \d+ samples back-filled", up.detail
    ), up.detail
    (gap,) = kinds(events, "gap")
    assert gap.time == after
    assert info.missing_samples == stats.lost == int(data.seq[hole + 1] - data.seq[hole] - 1)
    assert kinds(events, "ring_mismatch") == []  # the virtual PLC's own site agrees with its ring


# --- 4. bookkeeping ----------------------------------------------------------------------


def test_store_info_does_not_count_the_restart_break_as_a_missing_sample(tmp_path: Path) -> None:
    with SQLiteStore(tmp_path / "b.db", site_name="s", tag_map_hash="h", period_s=0.02) as store:
        # 10 left out at a restart; 13-19 lost; 22-29: a restart (one left out) and 7 lost
        seqs = [*range(10), 11, 12, 20, 21, 30, 31]
        samples = [Sample(100.0 + 0.02 * i, s, 2.0, 40.0) for i, s in enumerate(seqs)]
        store.append(
            samples,
            [
                Event(samples[10].time, "restart", "PLC restart"),
                Event(samples[14].time, "restart", "PLC restart"),
                Event(samples[14].time, "gap", "7 sample(s) lost"),
            ],
        )
        info = store.info()
    assert info.gaps == 3  # the restart breaks are breaks all the same
    assert info.missing_samples == 7 + 7


# --- 5. the status line --------------------------------------------------------------------


@pytest.mark.parametrize("link", ["connecting", "up", "down"])
def test_the_status_line_fits_80_columns_in_every_state(link: str) -> None:
    stats = RecorderStats(
        link=link,
        stored=12_345_678_901,
        lost=4_294_967_296,
        flagged=9_876_543_210,
        drops=12_345,
        restarts=678,
        last_error="cannot reach modbus 127.0.0.1:5020 device 1: connection refused or no "
        "route (is the PLC on, the address and port right?)",
    )
    assert len(stats.line()) <= 80
    assert stats.line().startswith(f"link {link}")
    small = RecorderStats(link=link, stored=5, last_error=stats.last_error)
    assert len(small.line()) <= 80
    assert "stored" in small.line()
    assert "lost" in small.line()


INT_SITE = """[site]
name = "integer tags"
[plc]
protocol = "modbus"
port = {port}
word_order = "big"
[tags.flow]
address = "ir:18"
type = "int16"
raw = [0, 27648]
eng = [0.0, 120.0]
unit = "L/min"
[tags.seq]
address = "ir:0"
type = "uint32"
[tags.command]
address = "ir:19"
type = "int16"
unit = "V"
"""


@pytest.mark.parametrize(
    ("ring", "needle"),
    [
        # the head and the slots disagree; at the PLC's very first scan (head 0, which reads
        # right) the record's floats, or the head's jump, give it away
        (True, r"ring\.head ir:100 (reads \d+, but slot \d+ of|jumped)|ring record 0 at ir:1000"),
        (False, "tags.seq ir:0 jumped"),
    ],
)
def test_without_float_tags_the_ring_or_the_counter_gives_the_word_order_away(
    tmp_path: Path, ring: bool, needle: str
) -> None:
    with virtual_plc(speed=1.0, word_order="little") as srv:
        text = INT_SITE.format(port=srv.port)
        if ring:
            text += '[ring]\nhead = "ir:100"\naddress = "ir:1000"\nsize = 2048\n'
        with pytest.raises(ConfigError, match=needle) as refused:
            record(load(text), tmp_path / "i.db", duration_s=5.0)
    assert 'try word_order = "little"' in str(refused.value)
    assert len(rows(tmp_path / "i.db")[0]) == 0
