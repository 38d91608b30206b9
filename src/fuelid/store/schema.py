"""The store's tables, in one place, and the migrations that bring an older store up to date.

A fuelid store is one SQLite file. ``PRAGMA application_id`` (:data:`APPLICATION_ID`, "FUID")
marks it as a fuelid store; ``PRAGMA user_version`` is its schema version, also written as
``schema_version`` in the ``meta`` table. Every table is STRICT. Times are UTC seconds since the
Unix epoch [s]; u in V, flows in L/min, temperatures in °C (as the PLC gives them), the gains
``kc`` and ``ti`` in the controller's units (as its registers hold them).

**Versions.** Version N is reached by applying the migrations 1..N of :data:`MIGRATIONS` in order,
each in one transaction of its own (the tables, the data and the new version number commit together,
so a crash leaves the store at the version before or after a migration, never between). Opening a
store applies the migrations it lacks (:func:`upgrade`); a store whose version is newer than
:data:`SCHEMA_VERSION` is refused with a :class:`~fuelid.store.base.StoreError` that names both
versions, so that an older fuelid never writes into a schema it does not know.

1. fuelid 0.1: ``meta``, ``samples``, ``events``, ``models``, ``proposals`` (the online
   service created ``windows``, ``writes`` and ``online_state`` on its first use, without
   changing the version).
2. The online service's tables are part of every store: ``windows``, ``writes`` and
   ``online_state`` (``IF NOT EXISTS``: a store of version 1 may have them already). No row
   changes.

**Tables**::

    meta(key TEXT PRIMARY KEY, value TEXT NOT NULL)
        schema_version, site_name, tag_map_hash (SHA-256 hex of the tag map), created (s UTC),
        period_s (the sampling period, when given)
    samples(time REAL NOT NULL,          -- UTC seconds since the epoch [s]
            seq INTEGER,                 -- unwrapped sequence number, NULL without a counter
            u REAL,                      -- VFD command [V]
            y REAL,                      -- flow [L/min]
            setpoint REAL,               -- [L/min]
            fuel_temperature REAL,       -- [°C]
            mode INTEGER,                -- 0 MAN, 1 AUTO
            quality INTEGER NOT NULL)    -- 0 ok, 1 stale, 2 link_down, 3 bad_value
        UNIQUE (seq) WHERE seq IS NOT NULL; UNIQUE (time) WHERE seq IS NULL; INDEX (time)
        (INSERT … ON CONFLICT DO NOTHING: a restart that re-sends samples adds no duplicates);
        NaN is stored as NULL (SQLite has no NaN) and read back as NaN
    events(time REAL NOT NULL, kind TEXT NOT NULL, detail TEXT NOT NULL)   INDEX (time)
        kinds: link_down, link_up, gap, gain_change, restart, site_mismatch, prune, …
    models(id INTEGER PRIMARY KEY, time REAL NOT NULL, t_from REAL, t_to REAL,
           T_fuel REAL, model TEXT NOT NULL)
        one per accepted identification window of the online service: the window's span and
        analysis time [s UTC], its mean fuel temperature [°C], the model as JSON
    proposals(id INTEGER PRIMARY KEY, time REAL NOT NULL, model_id INTEGER, kc REAL, ti REAL,
              status TEXT NOT NULL, detail TEXT NOT NULL)
        proposed PI gains (kc, ti: the new ones), their status (pending, approved, writing,
        applied, failed, rejected, superseded, reverted) and as JSON
        {"old", "new", "detail", "history": [{"time", "status", "who", "why"}, …]}
    windows(id INTEGER PRIMARY KEY, time REAL NOT NULL,     -- analysis time [s UTC]
            t_from REAL NOT NULL, t_to REAL NOT NULL,       -- the window's data [s UTC]
            accepted INTEGER NOT NULL,                      -- 0 or 1
            reason TEXT NOT NULL, T_fuel REAL,              -- [°C]
            u_mean REAL,                                    -- [V]
            model_id INTEGER,                               -- models(id) when accepted
            detail TEXT NOT NULL)                           -- JSON: gates, fit, health
        INDEX (t_to); every identification window, accepted or not
    writes(id INTEGER PRIMARY KEY, time REAL NOT NULL, proposal_id INTEGER,
           kind TEXT NOT NULL,                              -- proposal, revert, restore
           kc REAL NOT NULL, ti REAL NOT NULL,              -- the gains written
           apply_seq INTEGER NOT NULL UNIQUE,               -- never reused
           status TEXT NOT NULL,                            -- intent, verified, failed,
                                                            -- not_applied
           who TEXT NOT NULL, why TEXT NOT NULL, detail TEXT NOT NULL,     -- JSON
           finished REAL)                                   -- [s UTC], NULL while an intent
        a write of gains to the PLC: the intent is committed before the PLC is written, the
        outcome after, so an ``intent`` left by a crash is reconciled on restart
    online_state(key TEXT PRIMARY KEY, value TEXT NOT NULL,  -- JSON
                 time REAL NOT NULL)                         -- last set [s UTC]
        what the online service needs after a restart (last-known-good gains, …)

JSON is written with ``allow_nan=False``: NaN and ±inf are stored as ``null``.

**Adding a migration.** Append a :class:`Migration` to :data:`MIGRATIONS` (its ``version`` is the
next number; :data:`SCHEMA_VERSION` follows), describe it under **Versions** and change **Tables**
above, and give the test of upgrades (``tests/integration/test_store_schema.py``) a case that builds
a store at the version before with :func:`build_at` (or loads a dump written by the released fuelid,
as ``tests/data/store_v0_1.sql``), opens it with the current code and checks every old row. Never
edit a released migration: a store in the field has already applied it. Migrations planned for the
next issues:

- a wall-clock column beside plant time on every row (``ALTER TABLE samples ADD COLUMN
  wall_time REAL``, and the same on ``events``, ``windows``, …; NULL on the rows written
  before it, where plant time was wall time unless the site ran a virtual PLC faster than
  real time);
- the service's liveness record (a ``liveness`` table, one row per service: pid, host, start
  and last beat [s UTC]);
- an outbox for sending rows to a central database (``outbox(id INTEGER PRIMARY KEY, tbl TEXT,
  row_id INTEGER, queued REAL, sent REAL)``, filled by the same transactions that write the
  rows).

A migration may carry a ``data`` step (a function of the connection, run in the migration's
transaction after its statements) for rows that need computing, such as filling a new column.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from fuelid.store.records import StoreError

__all__ = [
    "APPLICATION_ID",
    "MIGRATIONS",
    "SCHEMA_VERSION",
    "Migration",
    "build_at",
    "check_not_newer",
    "create",
    "stored_version",
    "upgrade",
]

APPLICATION_ID = 0x46554944
"""``PRAGMA application_id`` of a fuelid store ("FUID")."""


@dataclass(frozen=True)
class Migration:
    """One step of the schema: the statements that take a store from ``version − 1``.

    Attributes
    ----------
    version : int
        The version the store has after this migration.
    summary : str
        What it changes, one line.
    statements : tuple of str
        SQL statements run in order, in one transaction.
    data : callable, optional
        Run after the statements, in the same transaction, with the connection (rows that need
        computing).
    """

    version: int
    summary: str
    statements: tuple[str, ...]
    data: Callable[[sqlite3.Connection], None] | None = None


_V1_SAMPLES_AND_EVENTS = (
    "CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT NOT NULL) STRICT",
    """CREATE TABLE samples(
    time REAL NOT NULL,
    seq INTEGER,
    u REAL,
    y REAL,
    setpoint REAL,
    fuel_temperature REAL,
    mode INTEGER,
    quality INTEGER NOT NULL CHECK (quality BETWEEN 0 AND 3)
) STRICT""",
    "CREATE UNIQUE INDEX samples_seq ON samples(seq) WHERE seq IS NOT NULL",
    "CREATE UNIQUE INDEX samples_time_noseq ON samples(time) WHERE seq IS NULL",
    "CREATE INDEX samples_time ON samples(time)",
    "CREATE TABLE events(time REAL NOT NULL, kind TEXT NOT NULL, detail TEXT NOT NULL) STRICT",
    "CREATE INDEX events_time ON events(time)",
    """CREATE TABLE models(
    id INTEGER PRIMARY KEY, time REAL NOT NULL, t_from REAL, t_to REAL, T_fuel REAL,
    model TEXT NOT NULL
) STRICT""",
    """CREATE TABLE proposals(
    id INTEGER PRIMARY KEY, time REAL NOT NULL, model_id INTEGER REFERENCES models(id),
    kc REAL, ti REAL, status TEXT NOT NULL, detail TEXT NOT NULL
) STRICT""",
)

# the text fuelid 0.1 used when the online service created these tables: kept word for word,
# so that an upgraded store and a new one have the same schema text
_V2_ONLINE_TABLES = (
    """CREATE TABLE IF NOT EXISTS windows(
    id INTEGER PRIMARY KEY, time REAL NOT NULL, t_from REAL NOT NULL, t_to REAL NOT NULL,
    accepted INTEGER NOT NULL CHECK (accepted IN (0, 1)), reason TEXT NOT NULL,
    T_fuel REAL, u_mean REAL, model_id INTEGER REFERENCES models(id), detail TEXT NOT NULL
) STRICT""",
    "CREATE INDEX IF NOT EXISTS windows_t_to ON windows(t_to)",
    "CREATE INDEX IF NOT EXISTS windows_model ON windows(model_id) WHERE model_id IS NOT NULL",
    """CREATE TABLE IF NOT EXISTS writes(
    id INTEGER PRIMARY KEY, time REAL NOT NULL, proposal_id INTEGER REFERENCES proposals(id),
    kind TEXT NOT NULL, kc REAL NOT NULL, ti REAL NOT NULL, apply_seq INTEGER NOT NULL UNIQUE,
    status TEXT NOT NULL, who TEXT NOT NULL, why TEXT NOT NULL, detail TEXT NOT NULL,
    finished REAL
) STRICT""",
    """CREATE TABLE IF NOT EXISTS online_state(
    key TEXT PRIMARY KEY, value TEXT NOT NULL, time REAL NOT NULL
) STRICT""",
)

MIGRATIONS: tuple[Migration, ...] = (
    Migration(1, "samples, events, models and proposals (fuelid 0.1)", _V1_SAMPLES_AND_EVENTS),
    Migration(2, "the online service's windows, writes and state everywhere", _V2_ONLINE_TABLES),
)
"""Every migration, in order; ``MIGRATIONS[k]`` takes a store to version ``k + 1``."""

SCHEMA_VERSION = MIGRATIONS[-1].version
"""The schema version this fuelid writes (and the newest it opens)."""


def stored_version(con: sqlite3.Connection) -> int:
    """The schema version of an open store, read without writing anything.

    The larger of ``PRAGMA user_version`` and the ``meta`` table's ``schema_version`` (fuelid
    writes both, in the same transaction; a store that has only one of them is judged by it).

    Parameters
    ----------
    con : sqlite3.Connection
        A connection to a file that has a ``meta`` table.
    """
    user_version = int(con.execute("PRAGMA user_version").fetchone()[0])
    row = con.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
    try:
        meta_version = int(row[0]) if row is not None else 0
    except ValueError:
        meta_version = 0
    return max(user_version, meta_version)


def check_not_newer(version: int, path: str) -> None:
    """Refuse a store written by a newer fuelid (the reason names both versions).

    Raises
    ------
    StoreError
        ``version`` is larger than :data:`SCHEMA_VERSION`.

    Examples
    --------
    >>> check_not_newer(SCHEMA_VERSION, "loop.db")
    >>> check_not_newer(SCHEMA_VERSION + 1, "loop.db")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    fuelid.store.records.StoreError: loop.db: store schema version ... is newer than this ...
    """
    if version > SCHEMA_VERSION:
        raise StoreError(
            f"{path}: store schema version {version} is newer than this fuelid's "
            f"({SCHEMA_VERSION}): upgrade fuelid"
        )


def _apply(
    con: sqlite3.Connection, migration: Migration, meta: Mapping[str, str] | None = None
) -> None:
    """Run one migration in a transaction of its own (skipped when another opener ran it)."""
    con.execute("BEGIN IMMEDIATE")
    try:
        # re-read inside the transaction: two processes opening the same old store at once
        # must not both apply the same migration
        current = int(con.execute("PRAGMA user_version").fetchone()[0])
        if current < migration.version:
            for statement in migration.statements:
                con.execute(statement)
            if migration.data is not None:
                migration.data(con)
            con.executemany("INSERT INTO meta VALUES (?, ?)", (meta or {}).items())
            con.execute(
                "INSERT INTO meta VALUES ('schema_version', ?) "
                "ON CONFLICT(key) DO UPDATE SET value = excluded.value",
                (str(migration.version),),
            )
            con.execute(f"PRAGMA application_id={APPLICATION_ID}")
            con.execute(f"PRAGMA user_version={migration.version}")
        con.execute("COMMIT")
    except BaseException:
        con.execute("ROLLBACK")
        raise


def upgrade(con: sqlite3.Connection, path: str, to_version: int = SCHEMA_VERSION) -> int:
    """Apply the migrations a store lacks, each in one transaction; the version reached.

    Parameters
    ----------
    con : sqlite3.Connection
        A connection in autocommit mode (``isolation_level=None``) to a fuelid store.
    path : str
        The store's name, for messages.
    to_version : int
        Stop at this version (tests build older stores with it).

    Raises
    ------
    StoreError
        The store is newer than this fuelid, or a migration failed (it was rolled back: the
        store keeps the version before it).
    """
    version = stored_version(con)
    check_not_newer(version, path)
    for migration in MIGRATIONS[version:to_version]:
        try:
            _apply(con, migration)
        except sqlite3.Error as error:
            raise StoreError(
                f"{path}: cannot upgrade the store from schema {migration.version - 1} to "
                f"{migration.version} ({error})"
            ) from None
    return max(version, min(to_version, SCHEMA_VERSION))


def create(
    con: sqlite3.Connection,
    meta: Mapping[str, str],
    to_version: int = SCHEMA_VERSION,
    path: str = "",
) -> None:
    """Create the tables of an empty file: migration 1 with the ``meta`` rows, then the rest.

    Parameters
    ----------
    con : sqlite3.Connection
        A connection in autocommit mode to an empty SQLite file.
    meta : mapping of str to str
        The store's identity (``site_name``, ``tag_map_hash``, ``created``, ``period_s``),
        written in the transaction of migration 1 (``schema_version`` is written by each
        migration).
    to_version : int
        The version to create (tests build older stores with it).
    path : str
        The store's name, for messages.
    """
    _apply(con, MIGRATIONS[0], {k: v for k, v in meta.items() if k != "schema_version"})
    if to_version > 1:
        upgrade(con, path, to_version)


def build_at(path: str, version: int, meta: Mapping[str, str]) -> None:
    """Write a new store at an older ``version`` (for tests of the next migration).

    Parameters
    ----------
    path : str
        The file to create (absent or empty).
    version : int
        1 to :data:`SCHEMA_VERSION`.
    meta : mapping of str to str
        The identity: ``site_name`` and ``tag_map_hash`` at least.

    Examples
    --------
    >>> import tempfile, pathlib, sqlite3
    >>> db = str(pathlib.Path(tempfile.mkdtemp()) / "old.db")
    >>> build_at(db, 1, {"site_name": "tunnel 2", "tag_map_hash": "ab12"})
    >>> sqlite3.connect(db).execute("PRAGMA user_version").fetchone()[0]
    1
    """
    if not 1 <= version <= SCHEMA_VERSION:
        raise StoreError(f"schema version {version} is not between 1 and {SCHEMA_VERSION}")
    con = sqlite3.connect(path, isolation_level=None)
    try:
        create(con, meta, to_version=version, path=path)
    finally:
        con.close()
