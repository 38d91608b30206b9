"""Store schema version 4 (many loops): the outbox, its triggers and ``archived_days``.

The statements of migration 4 of :mod:`fuelid.store._schema` (which documents the tables): the
``events`` table rebuilt with a stable id, the change log ``outbox`` filled by a trigger on
every insert and update of :data:`OUTBOX_TABLES` while ``meta`` ``outbox`` is ``on``, and the
archived days. Kept apart from the migration list so that module stays readable.
"""

from __future__ import annotations

__all__ = ["OUTBOX_TABLES", "V4_MANY_LOOPS", "outbox_triggers"]

OUTBOX_TABLES = ("events", "windows", "models", "proposals", "writes", "requests")
"""The tables whose inserts and updates go to the outbox (a central store receives them)."""

_WALL_NOW = "((julianday('now') - 2440587.5) * 86400.0)"  # SQLite 3.40 has no unixepoch('subsec')


def outbox_triggers(tables: tuple[str, ...] = OUTBOX_TABLES) -> tuple[str, ...]:
    """The outbox's triggers on ``tables``.

    A table made anew by a later migration needs its own again: dropping a table drops them.
    """
    statements = []
    for table in tables:
        for op in ("INSERT", "UPDATE"):
            statements.append(
                f"CREATE TRIGGER outbox_{table}_{op.lower()} AFTER {op} ON {table} "
                "WHEN (SELECT value FROM meta WHERE key = 'outbox') = 'on' BEGIN "
                f"INSERT INTO outbox(tbl, row_id, wall_time) VALUES ('{table}', NEW.rowid, "
                f"{_WALL_NOW}); END"
            )
    return tuple(statements)


V4_MANY_LOOPS = (
    """CREATE TABLE events_v4(
        id INTEGER PRIMARY KEY, time REAL NOT NULL, kind TEXT NOT NULL, detail TEXT NOT NULL,
        wall_time REAL) STRICT""",
    "INSERT INTO events_v4(time, kind, detail, wall_time) "
    "SELECT time, kind, detail, wall_time FROM events ORDER BY rowid",
    "DROP TABLE events",
    "ALTER TABLE events_v4 RENAME TO events",
    "CREATE INDEX events_time ON events(time)",
    """CREATE TABLE outbox(
        id INTEGER PRIMARY KEY, tbl TEXT NOT NULL, row_id INTEGER NOT NULL,
        wall_time REAL NOT NULL) STRICT""",
    """CREATE TABLE archived_days(
        loop_id TEXT NOT NULL, date TEXT NOT NULL, samples INTEGER NOT NULL, t_first REAL,
        t_last REAL, path TEXT NOT NULL, wall_time REAL NOT NULL,
        PRIMARY KEY (loop_id, date)) STRICT""",
    *outbox_triggers(),
)
"""The statements of migration 4, in order."""
