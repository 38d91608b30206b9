"""An archive written from a simulated loop's store, for the re-identification tests.

A stand-in for ``fuelid archive`` (store → archive, built in parallel): the samples table is
read with :mod:`sqlite3`, split by UTC day of plant time and written with the archive's own
:func:`fuelid.archive.layout.write_table` in :data:`~fuelid.archive.layout.SAMPLE_SCHEMA`, one
file per store and day; the loop's ``<store_uuid>.json`` carries the keys
:func:`~fuelid.archive.layout.read_loop_info` documents, its ``settings`` those a service
record holds (every ``[online]`` setting, ``sampling``, ``plant_hash``, ``controller``), and
the plant file (when given) is copied beside it as ``plant-<sha256>.toml``. Replace with the
real archiver once it lands.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import sqlite3
from pathlib import Path
from typing import Any

import pyarrow as pa

from fuelid.archive.layout import SAMPLE_SCHEMA, day_of, partition_dir, write_table
from fuelid.plc.site import Online

_COLUMNS = [field.name for field in SAMPLE_SCHEMA]


def service_settings(
    online: Online | None = None,
    *,
    period_s: float,
    control_period_s: float = 1.0,
    plant_hash: str | None = None,
    controller: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The ``settings`` of a service record (:func:`fuelid.online.liveness.service_record`)."""
    settings: dict[str, Any] = (online or Online()).model_dump(mode="json")
    settings.update(
        {
            "timezone": "UTC",
            "plant_hash": plant_hash,
            "plant_file": None,
            "controller": controller,
            "sampling": {"period_s": period_s, "control_period_s": control_period_s},
        }
    )
    return settings


def archive_store(
    store_path: Path,
    root: Path,
    *,
    online: Online | None = None,
    plant_file: Path | None = None,
    with_settings: bool = True,
) -> list[str]:
    """Write one store's samples into the archive at ``root``; returns the dates written.

    Parameters
    ----------
    store_path : Path
        A fuelid SQLite store (its WAL checkpointed or not: sqlite3 reads both).
    root : Path
        The archive folder (created when missing).
    online : Online, optional
        The ``[online]`` settings recorded as the service's (default settings when None).
    plant_file : Path, optional
        The plant file the service ran with: copied into ``loops/<loop_id>/``.
    with_settings : bool
        False writes ``settings: null`` (a store no service ran on).
    """
    con = sqlite3.connect(f"file:{store_path}?mode=ro", uri=True)
    try:
        meta = dict(con.execute("SELECT key, value FROM meta").fetchall())
        rows = con.execute(
            f"SELECT {', '.join(_COLUMNS)} FROM samples ORDER BY time, seq"
        ).fetchall()
    finally:
        con.close()
    loop_id = meta["loop_id"]
    store_uuid = meta["store_uuid"]
    period_s = float(meta["period_s"])
    by_day: dict[str, list[tuple[Any, ...]]] = {}
    for row in rows:
        by_day.setdefault(day_of(row[0]), []).append(row)
    for date, day_rows in sorted(by_day.items()):
        columns = list(zip(*day_rows, strict=True))
        table = pa.table(
            {name: pa.array(list(col), type=SAMPLE_SCHEMA.field(name).type)
             for name, col in zip(_COLUMNS, columns, strict=True)},
            schema=SAMPLE_SCHEMA,
        )  # fmt: skip
        path = partition_dir(root, "samples", loop_id, date) / f"{store_uuid}.parquet"
        write_table(table, path)
    folder = root / "loops" / loop_id
    folder.mkdir(parents=True, exist_ok=True)
    plant_name = None
    plant_hash = None
    if plant_file is not None:
        plant_hash = hashlib.sha256(plant_file.read_bytes()).hexdigest()
        plant_name = f"plant-{plant_hash}.toml"
        shutil.copyfile(plant_file, folder / plant_name)
    info = {
        "loop_id": loop_id,
        "store_uuid": store_uuid,
        "site_name": meta["site_name"],
        "tag_map_hash": meta["tag_map_hash"],
        "created": float(meta.get("created", 0.0) or 0.0),
        "period_s": period_s,
        "settings": (
            service_settings(online, period_s=period_s, plant_hash=plant_hash)
            if with_settings
            else None
        ),
        "plant": plant_name,
    }
    (folder / f"{store_uuid}.json").write_text(json.dumps(info, indent=2), encoding="utf-8")
    return sorted(by_day)
