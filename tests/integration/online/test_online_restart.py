"""A restarted service tells where its own data starts, in plant time (issue 39).

The dashboard keeps the chips about the running loop unknown until a restarted service has
judged a window of its own; it compares plant times, the window's analysis time against the
service record's ``started_plant``: the first sample the running service recorded, newer than
any the store held when it started. Two runs of the service against the virtual PLC on loopback,
a few seconds each.
"""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("pymodbus")

from fuelid.online import OnlineService, ServiceSite
from fuelid.plc.virtual import VirtualPlcThread
from fuelid.store import SERVICE_KEY
from support.online import online_site

# xdist: one worker runs every module that drives a PLC at speed, one after another
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("real-time")

SPEED = 20.0
"""Plant time per wall time."""
RUN_S = 4.5
"""Wall time of each run [s]: the first sample is committed within about a second, and the
record is written at the next beat (every 2 s)."""
ONLINE_NO_WINDOWS = 'identify_every_s = 3600\nwindow_s = 3600\nwrite_back = "approve"\n'


def _run(site: ServiceSite, after: float | None) -> dict[str, Any]:
    """One run of the service: what it left in its record and the store.

    The record, the store's newest sample, its first sample newer than ``after`` [plant s].
    """
    service = OnlineService(site, heartbeat_s=0.05)
    try:
        asyncio.run(service.run(RUN_S))
        return {
            "record": service.history.state(SERVICE_KEY),
            "newest": service.history.plant_now(),
            "first_after": service.history.first_sample_after(after),
        }
    finally:
        service.close()


def test_each_run_records_the_plant_time_of_its_own_first_sample(tmp_path: Path) -> None:
    store = tmp_path / "s.db"
    with VirtualPlcThread(speed=SPEED, setpoint_profile="run") as virtual:
        site = online_site(virtual, store, ONLINE_NO_WINDOWS)
        first = _run(site, None)
        second = _run(site, first["newest"])
    # the first run, on an empty store: the store's first sample
    assert first["record"]["started_plant"] == first["first_after"]
    # the restart: the first sample after the previous run's newest, never one of its own
    assert second["record"]["started_plant"] == second["first_after"]
    assert second["record"]["started_plant"] > first["newest"]
    assert second["record"]["started"] > first["record"]["started"]  # wall clock, its own
