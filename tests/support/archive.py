"""Stores for the archive's tests: whole UTC days of samples written in a second or so.

:func:`days_store` writes ``days`` UTC days of a loop at one sample per ``period_s`` into a new
store through :meth:`SQLiteStore.append_samples` (as the recorder writes), with a sine on the
command and the flow, every 13th sample's flow missing (NULL, quality ``bad_value``) and one
``restart`` event a day. Row counts per day are then known exactly: ``86400 / period_s``.
"""

from __future__ import annotations

import math
import sqlite3
from pathlib import Path

from fuelid.store import Event, Quality, Sample, SQLiteStore

T0 = 1_767_225_600.0
"""2026-01-01 00:00:00 UTC [s]."""
DATES = ("2026-01-01", "2026-01-02", "2026-01-03", "2026-01-04", "2026-01-05")
"""The UTC dates of the days :func:`days_store` writes, in order."""


def days_store(path: Path, days: int = 4, period_s: float = 10.0, loop_id: str = "line-x") -> Path:
    """A store at ``path`` with ``days`` whole UTC days from :data:`T0` (module docstring)."""
    per_day = round(86400.0 / period_s)
    with SQLiteStore(
        path, site_name=f"site {loop_id}", tag_map_hash="ab12", period_s=period_s, loop_id=loop_id
    ) as store:
        for day in range(days):
            samples = []
            for i in range(per_day):
                k = day * per_day + i
                bad = k % 13 == 0
                samples.append(
                    Sample(
                        T0 + k * period_s,
                        k,
                        2.5 + 0.5 * math.sin(0.01 * k),
                        math.nan if bad else 40.0 + 5.0 * math.sin(0.01 * k),
                        40.0,
                        20.0 + 0.001 * k,
                        1,
                        Quality.BAD_VALUE if bad else Quality.OK,
                    )
                )
            store.append(samples, [Event(T0 + day * 86400.0 + 5.0, "restart", f"day {day}")])
    return path


def rows_per_day(path: Path) -> dict[str, int]:
    """The store's samples per UTC date, counted in SQL."""
    con = sqlite3.connect(path)
    try:
        rows = con.execute(
            "SELECT date(CAST(floor(time) AS INTEGER), 'unixepoch') AS d, count(*) FROM samples "
            "GROUP BY d ORDER BY d"
        ).fetchall()
    finally:
        con.close()
    return {str(d): int(n) for d, n in rows}


def archived_rows(path: Path) -> dict[str, int]:
    """The store's ``archived_days``: date → samples recorded."""
    con = sqlite3.connect(path)
    try:
        rows = con.execute("SELECT date, samples FROM archived_days ORDER BY date").fetchall()
    finally:
        con.close()
    return {str(d): int(n) for d, n in rows}
