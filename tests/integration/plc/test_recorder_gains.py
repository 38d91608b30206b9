"""The recorder keeps the PLC's gains as read in the store (fuelid.plc._gain_reading).

A Modbus PLC written in the tests (support.modbus.FakePlc, loopback) runs a sample counter,
u and y every 10 ms and holds kc and ti in two float32 tags; the test changes them at the PLC
while a recorder runs and reads the store's ``online_state`` row ``plc_gains`` from another
connection, as the dashboard does: the first reading and each change are kept, with the plant
time of the reading, not one write per poll. Polled (on the counter's time base: the reading
waits for the next sample's time) and with a ring (timed at the ring's head).
"""

from __future__ import annotations

import json
import sqlite3
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from fuelid.plc import encode
from support.recorder import load, record, rows
from support.waiting import wait_until

pytest.importorskip("pymodbus", reason="the [plc] extra (pymodbus) is not installed")

RING_SIZE = 256
SITE = """
[site]
name = "gains loop"
[plc]
protocol = "modbus"
host = "127.0.0.1"
port = {port}
[sampling]
period_s = 0.01
control_period_s = 1.0
[tags.seq]
address = "ir:0"
type = "uint32"
[tags.flow]
address = "ir:2"
unit = "L/min"
[tags.command]
address = "ir:4"
unit = "V"
[tags.kc]
address = "ir:12"
unit = "V per L/min"
[tags.ti]
address = "ir:14"
unit = "s"
"""
RING = f"""
[ring]
head = "ir:100"
address = "ir:1000"
size = {RING_SIZE}
fields = ["seq", "command", "flow"]
"""


class Program:
    """Every scan: the next sample (seq, y, u), its ring record, then the ring's head."""

    def __init__(self) -> None:
        self.seq = -1

    def __call__(self, plc: Any) -> list[tuple[int, list[int]]]:
        self.seq += 1
        seq = self.seq
        u, y = 2.0 + (seq % 100) * 0.01, 20.0 + (seq % 97) * 0.1
        words = encode(seq, "uint32")
        return [
            (1000 + 6 * (seq % RING_SIZE), words + encode(u, "float32") + encode(y, "float32")),
            (100, words),
            (0, words + encode(y, "float32") + encode(u, "float32")),
        ]


def stored(db: Path) -> tuple[dict[str, Any], float] | None:
    """The ``plc_gains`` value and the wall time it was last written, read as a reader does."""
    con = sqlite3.connect(db, timeout=5.0)
    try:
        row = con.execute("SELECT value, time FROM online_state WHERE key = 'plc_gains'").fetchone()
    except sqlite3.OperationalError:  # the store is still being created
        return None
    finally:
        con.close()
    return None if row is None else (json.loads(row[0]), float(row[1]))


def committed_samples(db: Path) -> int:
    """The samples a reader sees (committed)."""
    con = sqlite3.connect(db, timeout=5.0)
    try:
        return int(con.execute("SELECT count(*) FROM samples").fetchone()[0])
    finally:
        con.close()


def wait_for(db: Path, ok: Callable[[dict[str, Any]], bool], seconds: float) -> Any:
    """The stored reading and its row time once ``ok`` holds; fails after ``seconds``."""

    def found() -> Any:
        reading = stored(db) if db.exists() else None
        return reading if reading is not None and ok(reading[0]) else None

    return wait_until(
        found, seconds, lambda: f"the store's plc_gains to follow (it holds {stored(db)})"
    )


def gains(kc: float, ti: float) -> list[int]:
    """The registers of kc and ti, written at once: a poll never sees one without the other."""
    return encode(kc, "float32") + encode(ti, "float32")


# the slow set: 4 s each of a PLC at speed (the fast set's 6-min budget); the status and the
# pages' use of the reading are unit-tested (test_dashboard_views, test_online_cli)
@pytest.mark.slow
@pytest.mark.parametrize("ring", [False, True], ids=["polled", "ring"])
def test_the_store_keeps_the_gains_as_read_and_follows_a_change(tmp_path: Path, ring: bool) -> None:
    from support.modbus import FakePlc

    plc = FakePlc(ir=1000 + 6 * RING_SIZE + 8, program=Program())
    db = tmp_path / "g.db"
    try:
        plc.set_ir(12, gains(0.05, 2.0))
        plc.wait_scans(10)  # the PLC runs (its ring filling) when the recorder starts
        site = load(SITE.format(port=plc.port) + (RING if ring else ""))
        runner = threading.Thread(target=record, args=(site, db, 4.0))
        runner.start()
        try:
            first, written = wait_for(db, lambda v: True, 3.0)
            # polls and three commits (0.2 s apart) with the same gains: no new write
            seen = committed_samples(db)
            wait_until(lambda: committed_samples(db) >= seen + 60, 10.0, "0.6 s more samples")
            again = stored(db)
            plc.set_ir(12, gains(0.08, 3.0))
            changed, _ = wait_for(db, lambda v: v["kc"] == pytest.approx(0.08), 1.5)
        finally:
            runner.join(10.0)
    finally:
        plc.close()
    assert (first["kc"], first["ti"]) == pytest.approx((0.05, 2.0))
    assert again == (first, written)
    assert (changed["kc"], changed["ti"]) == pytest.approx((0.08, 3.0))
    assert changed["units"] == "block"
    assert changed["tag_units"] == {"kc": "V per L/min", "ti": "s"}
    # plant time: the samples' time base, at a sample of the run; wall time of the reading
    data = rows(db)[0]
    assert data.time[0] <= first["time"] < changed["time"] <= data.time[-1]
    assert first["wall_time"] < changed["wall_time"] <= time.time()
