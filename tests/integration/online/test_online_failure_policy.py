"""The online service's failure policy against the virtual PLC on loopback (real Modbus TCP).

An analysis that raises ends the schedule's task and is logged (``event kind=task_failed``),
while the recorder goes on recording; ``run`` raises the error once the recording ends.
"""

from __future__ import annotations

import asyncio
import io
import json
import logging
import tomllib
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("pymodbus")

from fuelid.online import LOGGER_NAME, JsonLineFormatter, OnlineService, ServiceSite
from fuelid.plc.virtual import VirtualPlcThread

SPEED = 50.0
"""Plant time per wall time: a 60 s window of plant time is 1.2 s of wall time."""
ONLINE = "identify_every_s = 60\nwindow_s = 60\n"
RUN_S = 5.0
"""Wall time of the run [s]: the first window falls due after about 1.2 s."""


class AnalysisBroke(RuntimeError):
    """The analysis' failure in this test."""


def _site(virtual: VirtualPlcThread, store: Path) -> ServiceSite:
    text = virtual.site_text(store_url=f"sqlite:///{store}")
    return ServiceSite.model_validate(tomllib.loads(f"{text}\n[online]\n{ONLINE}"))


def test_an_analysis_that_raises_leaves_the_recorder_recording(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    failed_at: list[float] = []

    async def broken_analysis(samples: Any, t_from: float, t_to: float, *args: Any) -> Any:
        failed_at.append(t_to)
        raise AnalysisBroke("the fit fell over")

    stream = io.StringIO()
    handler = logging.StreamHandler(stream)
    handler.setFormatter(JsonLineFormatter())
    logger = logging.getLogger(LOGGER_NAME)
    level = logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    lines: list[str] = []
    try:
        with VirtualPlcThread(speed=SPEED, setpoint_profile="run") as virtual:
            site = _site(virtual, tmp_path / "s.db")
            service = OnlineService(site, on_message=lines.append, isolate=False)
            monkeypatch.setattr(service.worker, "analyse", broken_analysis)
            try:
                with pytest.raises(AnalysisBroke):
                    asyncio.run(service.run(RUN_S))
                newest = service.store.last_time()
                windows = service.history.counts()["windows"]
            finally:
                service.close()
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)
    assert len(failed_at) == 1  # the schedule's task ended with its failure
    assert windows == 0
    assert newest is not None
    # the recorder went on: samples of well over a window of plant time after the failure
    assert newest > failed_at[0] + 60.0
    failures = [line for line in lines if line.startswith("event kind=task_failed")]
    assert len(failures) == 1
    assert "schedule: AnalysisBroke: the fit fell over" in failures[0]
    records = [json.loads(line) for line in stream.getvalue().splitlines()]
    assert len(records) == len(lines)  # one JSON object per line, one per log line
    by_event = {r["event"]: r for r in records}
    assert set(by_event["start"]) == {
        "time",
        "event",
        "identifies",
        "tracks",
        "proposes",
        "writes",
        "excites",
        "excitation",
        "write_back",
        "missing_for_proposals",
        "plant",
    }
    assert set(by_event["recorder"]) == {"time", "event", "message"}
    assert set(by_event["event"]) == {"time", "event", "kind", "detail"}
