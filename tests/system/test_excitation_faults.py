"""The test signal ends without fuelid (issue 40): kill -9 and a clean stop of ``fuelid online``.

``fuelid online --config SITE`` runs as a process of its own against the virtual PLC (Modbus on
127.0.0.1, 5× real time so that the service's 1 s heartbeat stays inside the PLC's 10 s timeout);
``fuelid online excite --start`` asks it for a signal (it begins where the next window
begins, and at most once per window length, a restart included). Then:

- **kill -9**: nothing of fuelid writes 0; the PLC's heartbeat rule must zero the signal. Band,
  fixed before the run: within the timeout (10 s of plant time) after the last beat, which came
  at most one beat (1 s of wall, 5 s of plant) before the kill, plus two control periods (the
  scan that sees it stale, the hold): 17 s of plant time after the kill;
- **SIGTERM**: the service writes 0 before it exits; the PLC applies it at its next scan: the
  applied signal is 0 within two control periods (2 s of plant) of the process's exit.
"""

from __future__ import annotations

import signal
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pymodbus")

from fuelid.plc.virtual import VirtualPlcThread
from support.waiting import wait_until

SPEED = 5.0
TIMEOUT_S = 10.0
"""The PLC's heartbeat timeout [s of plant time]."""
SETPOINT = 40.0
SITE_TABLES = """
[online]
identify_every_s = 60
window_s = 120
write_back = "off"

[excitation]
mode = "off"
amplitude = 0.3
"""


def _site(virtual: VirtualPlcThread, tmp_path: Path, db: Path) -> Path:
    """The virtual PLC's site file with the reference plant: the first signal's model."""
    from importlib import resources

    plant = str(resources.files("fuelid.data").joinpath("reference_plant.toml"))
    site = tmp_path / "site.toml"
    text = virtual.site_text(store_url=f"sqlite:///{db}", plant=plant) + SITE_TABLES
    site.write_text(text, encoding="utf-8")
    return site


def _fuelid(*args: str) -> list[str]:
    return [sys.executable, "-m", "fuelid", *args]


def _beating(db: Path) -> bool:
    if not db.exists():
        return False
    try:
        with sqlite3.connect(db) as con:
            row = con.execute("SELECT value FROM online_state WHERE key = 'service'").fetchone()
    except sqlite3.Error:
        return False
    return row is not None and '"beat"' in row[0]


def _start_with_a_signal(
    site: Path, db: Path, virtual: VirtualPlcThread, log: Path
) -> subprocess.Popen[str]:
    with log.open("w", encoding="utf-8") as stderr:  # a file: a full pipe would stall it
        service = subprocess.Popen(
            _fuelid("online", "--config", str(site), "--store", str(db), "--duration", "300"),
            stdout=subprocess.DEVNULL, stderr=stderr, text=True,
        )  # fmt: skip
    wait_until(lambda: _beating(db) and service.poll() is None, 60.0, "beat of the service")
    # the service's heartbeats: the PLC takes the advisor as alive
    wait_until(lambda: not virtual.plc.heartbeat_stale(), 60.0, "the PLC to see the heartbeat")
    asked = subprocess.run(
        _fuelid("online", "excite", "--start", "--store", str(db), "--why", "test"),
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert asked.returncode == 0, asked.stderr
    wait_until(lambda: virtual.plc.read_points()["excitation"] != 0.0, 60.0, "signal applied")
    return service


@pytest.mark.slow  # two service runs of ~30 s each against a PLC at 5x
def test_kill_9_and_a_clean_stop_leave_no_signal_on_the_plc(tmp_path: Path) -> None:
    db = tmp_path / "loop.db"
    services: list[subprocess.Popen[str]] = []
    with VirtualPlcThread(
        speed=SPEED, setpoint_profile=([0.0, 1.0], [SETPOINT, SETPOINT]),
        heartbeat_timeout_s=TIMEOUT_S,
    ) as virtual:  # fmt: skip
        try:
            site = _site(virtual, tmp_path, db)
            services.append(_start_with_a_signal(site, db, virtual, tmp_path / "killed.log"))
            first_burst = virtual.plc.time_s
            killed_at = virtual.plc.time_s
            services[-1].send_signal(signal.SIGKILL)
            services[-1].wait(10.0)
            wait_until(lambda: virtual.plc.read_points()["excitation"] == 0.0, 30.0, "zero (kill)")
            after_kill = virtual.plc.time_s - killed_at
            # one burst per window_s (120 s of plant time), across a restart too
            wait_until(lambda: virtual.plc.time_s > first_burst + 125.0, 60.0, "the next window")
            services.append(_start_with_a_signal(site, db, virtual, tmp_path / "stopped.log"))
            services[-1].send_signal(signal.SIGTERM)
            services[-1].wait(60.0)
            exited_at = virtual.plc.time_s
            wait_until(lambda: virtual.plc.read_points()["excitation"] == 0.0, 10.0, "zero (stop)")
            after_stop = virtual.plc.time_s - exited_at
        finally:
            for service in services:
                if service.poll() is None:
                    service.kill()
                    service.wait()
    err = (tmp_path / "stopped.log").read_text(encoding="utf-8")
    print(f"signal zero {after_kill:.1f} s (plant) after kill -9, {after_stop:.1f} s after SIGTERM")
    assert after_kill <= TIMEOUT_S + 5.0 + 2.0
    assert services[-1].returncode == 0, err
    assert "excitation_stop" in err
    assert "the service stops" in err
    assert after_stop <= 2.0
