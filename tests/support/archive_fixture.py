"""An archive written from a simulated loop's store, for the re-identification tests.

The store is copied (the shared ``fleet_loops`` stores stay as they are), given the service
record a live service would have left (its ``settings``: every ``[online]`` setting,
``sampling``, ``plant_hash``, ``plant_file``, ``controller``), and archived by the real
archiver, :func:`fuelid.archive._writer.archive_store`, every day of it (``before`` the day
after the newest sample).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import shutil
import tempfile
from pathlib import Path
from typing import Any

from fuelid.archive import archive_store as archive_days
from fuelid.archive import day_of
from fuelid.online import Online
from fuelid.store import OnlineHistory, SQLiteStore


def service_settings(
    online: Online | None = None,
    *,
    period_s: float,
    control_period_s: float = 1.0,
    plant_hash: str | None = None,
    controller: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The ``settings`` of a service record (:func:`fuelid.online._liveness.service_record`)."""
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
    plant_hash = None
    if plant_file is not None:
        plant_hash = hashlib.sha256(plant_file.read_bytes()).hexdigest()
    with tempfile.TemporaryDirectory(prefix="fuelid-archive-fixture-") as folder:
        copy = Path(folder) / store_path.name
        shutil.copyfile(store_path, copy)
        for suffix in ("-wal", "-shm"):  # a store that was not checkpointed
            if Path(f"{store_path}{suffix}").exists():
                shutil.copyfile(f"{store_path}{suffix}", f"{copy}{suffix}")
        with SQLiteStore(copy) as store:
            period_s = float(store.period_s or 0.1)
            if with_settings:
                settings = service_settings(online, period_s=period_s, plant_hash=plant_hash)
                settings["plant_file"] = None if plant_file is None else str(plant_file)
                with OnlineHistory(store) as history:
                    history.set_state("service", {"settings": settings, "stopped": 0.0})
            last = store.last_time()
            assert last is not None
            after = dt.date.fromisoformat(day_of(last)) + dt.timedelta(days=1)
            report = archive_days(store, root, before=after.isoformat())
    return sorted(day.date for day in report.days)
