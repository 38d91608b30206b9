"""``fuelid record``, ``export`` and ``store info`` (issue 14, item 5) end to end.

Against the virtual PLC over Modbus TCP (accelerated), against the test's own Modbus server, and
on bad input: every failure one line on stderr, exit code 2, no traceback.
"""

from __future__ import annotations

import json
import random
import signal
import sqlite3
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fuelid.cli import main
from fuelid.store import SQLiteStore

pytest.importorskip("pymodbus", reason="the [plc] extra (pymodbus) is not installed")


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code: int, err: str, *needles: str) -> None:
    assert code == 2
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith("error: ")
    for needle in needles:
        assert needle in last, last


# --- the virtual PLC ------------------------------------------------------------------------


@pytest.fixture
def virtual() -> Iterator[Any]:
    runner = pytest.importorskip("fuelid.plc.virtual.runner", reason="no virtual PLC")
    from fuelid.plc.virtual.profiles import steps_profile

    # MAN steps of ±0.2 V around 3.0 V: the linearisation of `plant info --u 3` holds there
    profile = steps_profile(levels=(3.0, 3.2, 2.8, 3.2, 2.8, 3.0), dwell_s=10.0)
    with runner.VirtualPlcThread(
        "modbus", port=None, speed=20.0, seed=1, command_profile=profile, fuel_temp_C=20.0
    ) as server:
        yield server


def site_file(tmp_path: Path, server: Any, name: str = "site.toml") -> Path:
    path = tmp_path / name
    path.write_text(server.site_text(store_url=f"sqlite:///{tmp_path / 'site.db'}"))
    return path


def test_record_export_identify_gives_the_plants_gain(
    virtual: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    site = site_file(tmp_path, virtual)
    db, log = tmp_path / "run.db", tmp_path / "run.csv"
    code, out, err = run(capsys, "record", "--config", str(site), "--store", str(db),
                         "--duration", "4")  # fmt: skip
    assert code == 0, err
    assert "recorded" in out
    assert "0 lost" in out
    code, out, err = run(capsys, "export", "--store", str(db), "--out", str(log))
    assert code == 0, err
    code, out, err = run(capsys, "identify", str(log), "--json")  # no options: default columns
    assert code == 0, err
    K = json.loads(out)["model"]["K"]
    code, out, err = run(capsys, "plant", "info", "--u", "3.0", "--fuel-temp", "20", "--json")
    K_plant = json.loads(out)["model"]["K"]
    assert pytest.approx(K_plant, rel=0.03) == K
    code, out, err = run(capsys, "store", "info", "--store", str(db), "--json")
    info = json.loads(out)
    assert info["site_name"] == "virtual fuel loop"
    assert info["gaps"] == 0
    assert info["rows"] > 0.9 * 4.0 * 20.0 / 0.02  # 4 s at 20x, 50 Hz of plant time


@pytest.mark.parametrize("drops", [5, pytest.param(100, marks=pytest.mark.slow)])
def test_link_drops_on_the_virtual_plc_are_back_filled_from_its_ring(
    virtual: Any, tmp_path: Path, drops: int
) -> None:
    from fuelid.plc.adapters.modbus import ModbusSource
    from fuelid.plc.recorder import record_site
    from fuelid.plc.site import load_site

    site = load_site(site_file(tmp_path, virtual))
    # up longer than the answer timeout plus a ring poll: each drop is one the recorder sees
    down_s, up_s = 0.15, 0.5

    def flap() -> None:
        time.sleep(up_s)
        for _ in range(drops):
            virtual.stop_link()
            time.sleep(down_s)
            virtual.start_link()
            time.sleep(up_s)

    thread = threading.Thread(target=flap, daemon=True)
    thread.start()
    db = tmp_path / "flap.db"
    duration = drops * (down_s + up_s + 0.1) + up_s + 1.0  # until the flapping is over
    source = ModbusSource(site, timeout_s=0.25)
    stats = record_site(site, str(db), duration_s=duration, source=source, backoff_s=(0.05, 0.1))
    thread.join(5.0)
    with SQLiteStore(db) as store:
        data, info = store.read(), store.info()
    assert stats.drops == drops
    assert info.events["link_down"] == info.events["link_up"] == drops
    seqs = data.seq.tolist()
    assert seqs == list(range(seqs[0], seqs[-1] + 1))  # none lost, none doubled
    assert info.gaps == 0
    assert stats.lost == 0
    assert np.all(data.quality == 0)


def test_an_unreachable_plc_exits_2_only_after_give_up(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from test_modbus_adapter import free_port

    site = tmp_path / "site.toml"
    port = free_port()
    site.write_text(SITE.format(port=port, device_id=1, flow="ir:2"))
    started = time.monotonic()
    code, _, err = run(capsys, "record", "--config", str(site), "--store",
                       str(tmp_path / "x.db"), "--give-up-after", "1")  # fmt: skip
    assert 1.0 <= time.monotonic() - started < 5.0
    assert_one_line_error(code, err, "gave up after", f"127.0.0.1:{port}")
    assert err.count("retrying") == 1  # retried with backoff, said once


SITE = """
[site]
name = "bad input loop"
[plc]
protocol = "modbus"
port = {port}
device_id = {device_id}
[tags.flow]
address = "{flow}"
unit = "L/min"
[tags.command]
address = "ir:4"
unit = "V"
"""


@pytest.mark.parametrize(
    ("device_id", "flow", "needles"),
    [
        (7, "ir:2", ("plc.device_id = 7",)),
        (1, "ir:40000", ("tags.flow: ir:40000 does not exist on the PLC", "exception 2")),
    ],
)
def test_a_wrong_device_id_or_register_is_one_line_and_exit_2(
    virtual: Any,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    device_id: int,
    flow: str,
    needles: tuple[str, ...],
) -> None:
    site = tmp_path / "site.toml"
    site.write_text(SITE.format(port=virtual.port, device_id=device_id, flow=flow))
    code, _, err = run(capsys, "record", "--config", str(site), "--store",
                       str(tmp_path / "x.db"), "--duration", "5")  # fmt: skip
    assert_one_line_error(code, err, *needles)


@pytest.mark.parametrize("content", [b"just text, not a database\n" * 10, None])
def test_a_file_that_is_not_a_fuelid_store_is_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: bytes | None
) -> None:
    path = tmp_path / "other.db"
    if content is None:  # an SQLite file of another application
        con = sqlite3.connect(path)
        con.execute("CREATE TABLE t(x)")
        con.commit()
        con.close()
    else:
        path.write_bytes(content)
    code, _, err = run(capsys, "store", "info", "--store", str(path))
    assert_one_line_error(code, err, "not a fuelid store")
    code, _, err = run(capsys, "export", "--store", str(path), "--out", str(tmp_path / "o.csv"))
    assert_one_line_error(code, err, "not a fuelid store")
    site = tmp_path / "site.toml"
    site.write_text(SITE.format(port=1, device_id=1, flow="ir:2"))
    code, _, err = run(capsys, "record", "--config", str(site), "--store", str(path))
    assert_one_line_error(code, err, "not a fuelid store")
    if content is None:  # nothing written into someone else's database
        con = sqlite3.connect(path)
        try:
            tables = con.execute("SELECT name FROM sqlite_schema WHERE type = 'table'").fetchall()
        finally:
            con.close()
        assert tables == [("t",)]
    else:
        assert path.read_bytes() == content
    code, _, err = run(capsys, "store", "info", "--store", str(tmp_path / "absent.db"))
    assert_one_line_error(code, err, "no such store")


def test_export_keeps_gaps_as_gaps_and_respects_the_range(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from fuelid.io.logs import load_log
    from fuelid.store import Quality, Sample, tag_map_hash

    db = tmp_path / "g.db"
    t0, h = 1_700_000_000.0, 0.02
    samples = [
        Sample(t0 + h * k, k, 2.0 + (k // 50) % 2, 40.0 + 0.1 * (k % 7), 41.0, 20.0, 0,
               Quality.BAD_VALUE if 200 <= k < 220 else Quality.OK)
        for k in range(400)
    ]  # fmt: skip
    with SQLiteStore(db, site_name="g", tag_map_hash=tag_map_hash("g"), period_s=h) as store:
        store.append_samples(samples)
    out = tmp_path / "g.csv"
    code, text, err = run(capsys, "export", "--store", str(db), "--out", str(out),
                          "--from", "2023-11-14T22:13:20Z", "--to", str(t0 + h * 350))  # fmt: skip
    assert code == 0, err
    assert "330 samples" in text
    assert "20 not ok left out" in text
    data = load_log(out)
    assert data.n_samples == 330
    assert data.segment_starts == (200,)  # the flagged stretch is a gap, not interpolated
    code, _, err = run(capsys, "export", "--store", str(db), "--out", str(out))
    assert_one_line_error(code, err, "exists")
    code, _, err = run(capsys, "export", "--store", str(db), "--out", str(out), "--force",
                       "--from", "yesterday")  # fmt: skip
    assert_one_line_error(code, err, "neither UTC seconds nor ISO 8601")


def test_store_info_prints_rows_span_gaps_and_link_events(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from fuelid.store import Event, Sample, tag_map_hash

    db = tmp_path / "i.db"
    with SQLiteStore(db, site_name="info loop", tag_map_hash=tag_map_hash("i")) as store:
        store.append([Sample(10.0 + 0.02 * k, k, 1.0, 2.0) for k in (0, 1, 2, 5, 6)],
                     [Event(10.0, "link_down"), Event(10.1, "link_up")])  # fmt: skip
    code, out, err = run(capsys, "store", "info", "--store", str(db))
    assert code == 0, err
    assert "info loop" in out
    assert "rows       5" in out
    assert "gaps       1 (2 samples missing" in out
    assert "link       1 down, 1 up" in out
    code, out, _ = run(capsys, "store", "info", "--store", str(db), "--json")
    info = json.loads(out)
    assert (info["rows"], info["gaps"], info["missing_samples"]) == (5, 1, 2)
    assert info["span_s"] == pytest.approx(0.12)
    assert info["units"]["span_s"] == "s"


# --- kill -9 ---------------------------------------------------------------------------------


def committed(db: Path) -> int:
    if not db.exists():
        return 0
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    try:
        return int(con.execute("SELECT count(*) FROM samples").fetchone()[0])
    except sqlite3.OperationalError:  # created, schema not yet committed
        return 0
    finally:
        con.close()


@pytest.mark.parametrize("kills", [3, pytest.param(20, marks=pytest.mark.slow)])
def test_kill_9_of_fuelid_record_keeps_what_was_committed_and_restarts_append(
    tmp_path: Path, kills: int
) -> None:
    runner = pytest.importorskip("fuelid.plc.virtual.runner", reason="no virtual PLC")
    rng = random.Random(14)
    db = tmp_path / "k.db"
    # real time: the 2048-record ring holds 41 s, more than a restart of `fuelid record` takes
    with runner.VirtualPlcThread("modbus", speed=1.0, seed=2, command_profile="steps") as srv:
        site = site_file(tmp_path, srv)
        for _ in range(kills):
            seen = committed(db)
            child = subprocess.Popen(
                [sys.executable, "-m", "fuelid", "record", "--config", str(site),
                 "--store", str(db)],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            )  # fmt: skip
            try:
                deadline = time.monotonic() + 60.0
                while committed(db) <= seen:  # wait for its first commit
                    assert child.poll() is None, "fuelid record died on its own"
                    assert time.monotonic() < deadline, "fuelid record never committed"
                    time.sleep(0.05)
                time.sleep(rng.uniform(0.0, 1.5))
                before_kill = committed(db)
                child.send_signal(signal.SIGKILL)
            finally:
                child.kill()
                child.wait(10.0)
            con = sqlite3.connect(db)
            try:
                assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
                assert con.execute("SELECT count(*) FROM samples").fetchone()[0] >= before_kill
            finally:
                con.close()
    with SQLiteStore(db) as store:
        data, info = store.read(), store.info()
    seqs = data.seq.tolist()
    # each restart appended after the last stored sample and back-filled the time it was down
    assert seqs == list(range(seqs[0], seqs[-1] + 1))
    assert info.gaps == 0


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_sigterm_and_sigint_stop_after_a_final_commit(tmp_path: Path, sig: int) -> None:
    runner = pytest.importorskip("fuelid.plc.virtual.runner", reason="no virtual PLC")
    db = tmp_path / "stop.db"
    with runner.VirtualPlcThread("modbus", speed=1.0, seed=3, command_profile="steps") as srv:
        site = site_file(tmp_path, srv)
        child = subprocess.Popen(
            [sys.executable, "-m", "fuelid", "record", "--config", str(site), "--store", str(db)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            deadline = time.monotonic() + 60.0
            while committed(db) == 0:
                assert child.poll() is None, child.communicate()
                assert time.monotonic() < deadline
                time.sleep(0.05)
            time.sleep(0.5)  # mid-batch: the commit interval is 1 s
            child.send_signal(sig)
            out, err = child.communicate(timeout=30.0)
        finally:
            child.kill()
    assert child.returncode == 0, err
    assert "Traceback" not in err
    stored = int(out.split("recorded ")[1].split()[0])
    assert committed(db) == stored > 0  # everything handed to the writer was committed
