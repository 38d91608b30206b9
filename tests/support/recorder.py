"""The recorder tests' site files, logs and readers (replayed CSV logs into SQLite stores).

Shared by tests/integration/plc/test_recorder.py and test_recorder_guards.py.
"""

from __future__ import annotations

import asyncio
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from fuelid.plc import Recorder, RecorderStats, site_identity
from fuelid.plc.adapters import PlcSource, open_source
from fuelid.plc.site import SiteConfig
from fuelid.store import SampleWriter, SQLiteStore


def load(text: str) -> SiteConfig:
    return SiteConfig.model_validate(tomllib.loads(text))


def record(
    site: SiteConfig, db: Path, duration_s: float, source: PlcSource | None = None, **kw: Any
) -> RecorderStats:
    store = SQLiteStore(db, period_s=site.sampling.period_s, **site_identity(site))
    writer = SampleWriter(store, commit_interval_s=0.2)
    try:
        recorder = Recorder(source or open_source(site), writer, **kw)
        return asyncio.run(recorder.run(duration_s))
    finally:
        writer.close()
        store.close()


def rows(db: Path) -> tuple[Any, list[Any], Any]:
    with SQLiteStore(db) as store:
        return store.read(), store.read_events(), store.info()


def kinds(events: list[Any], kind: str) -> list[Any]:
    return [e for e in events if e.kind == kind]


REPLAY = """
[site]
name = "replay loop"
[plc]
protocol = "replay"
path = "{path}"
speed = {speed}
[sampling]
period_s = {period}
control_period_s = 1.0
[tags.command]
address = "u"
unit = "V"
[tags.flow]
address = "counts"
type = "int16"
raw = [0, 27648]
eng = [0.0, 120.0]
unit = "L/min"
[tags.fuel_temperature]
address = "temp"
unit = "degC"
"""


def write_log(path: Path, n: int, flow: np.ndarray | None = None, **extra: Any) -> None:
    k = np.arange(n)
    counts = flow if flow is not None else 13824.0 + 2000.0 * np.sin(0.05 * k) + (k * 7919) % 13
    columns = {"u": 2.0 + 0.5 * np.sin(0.05 * k), "counts": counts, "temp": 20.0 + 0 * k}
    columns.update(extra)
    names = list(columns)
    lines = [",".join(names)]
    for i in range(n):
        lines.append(",".join(repr(float(columns[c][i])) for c in names))
    path.write_text("\n".join(lines) + "\n")


RING_REPLAY = (
    '[ring]\nhead = "seq"\naddress = "seq"\nsize = 512\nfields = ["seq", "command", "flow"]\n'
)
