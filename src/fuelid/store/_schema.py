"""The store's tables, in one place, and the migrations that bring an older store up to date.

A fuelid store is one SQLite file. ``PRAGMA application_id`` (:data:`APPLICATION_ID`, "FUID")
marks it as a fuelid store; ``PRAGMA user_version`` is its schema version, also written as
``schema_version`` in the ``meta`` table. Every table is STRICT. Times are UTC seconds since the
Unix epoch [s] on two clocks (since version 3): ``time`` is **plant time** (the samples' time
base: the PLC's, which an accelerated virtual PLC runs 20–50 times faster than the wall clock),
``wall_time`` the wall clock when the row was written. Units in one line: time: plant time;
wall_time: wall clock. u in V, flows in L/min, temperatures in °C (as the PLC gives them), the gains
``kc`` and ``ti`` in the controller's units (as its registers hold them).

**Versions.** Version N is reached by applying the migrations 1..N of :data:`MIGRATIONS` in order,
each in one transaction of its own (the tables, the data and the new version number commit together,
so a crash leaves the store at the version before or after a migration, never between). Opening a
store applies the migrations it lacks (:func:`upgrade`); a store whose version is newer than
:data:`SCHEMA_VERSION` is refused with a :class:`~fuelid.store.StoreError` that names both
versions, so that an older fuelid never writes into a schema it does not know.

1. fuelid 0.1: ``meta``, ``samples``, ``events``, ``models``, ``proposals`` (the online
   service created ``windows``, ``writes`` and ``online_state`` on its first use, without
   changing the version).
2. The online service's tables are part of every store: ``windows``, ``writes`` and
   ``online_state`` (``IF NOT EXISTS``: a store of version 1 may have them already). No row
   changes.
3. One clock: plant and wall time on every row; requests; the level-of-detail table. A
   ``wall_time`` column on ``samples``, ``events``, ``models``, ``windows``, ``proposals`` and
   ``writes`` (and ``finished_wall`` on ``writes``); the tables ``requests`` and
   ``samples_lod``; ``store_uuid`` and ``loop_id`` in ``meta``. Its data step maps the old
   online rows' times (wall clock before version 3) onto plant time through the windows:
   the anchors (wall, plant) = (old ``windows.time``, ``windows.t_to``), linear interpolation
   inside their range and real time outside it (:func:`plant_of_wall`; plant = wall without
   windows); ``proposals.time``, ``writes.time``, ``writes.finished``, ``models.time``,
   ``windows.time`` (at least its ``t_to``) and the ``time`` of every entry of a proposal's
   history (the old value kept as its ``wall_time``) are mapped, the old value kept in
   ``wall_time``/``finished_wall``. Samples and events keep their ``time`` (plant time
   already), their ``wall_time`` stays NULL. ``samples_lod`` is built from the samples.
4. Many loops (issue 26): ``events`` gets a stable ``id INTEGER PRIMARY KEY`` (the table is
   rebuilt, rows in their order: a VACUUM may renumber a plain rowid, and the central store
   keys every row by the store's UUID and its id); the change log ``outbox`` and the triggers
   that fill it; ``archived_days``. The outbox stays empty until a service with a ``[central]``
   table switches it on (``meta`` ``outbox`` = ``on``, :data:`OUTBOX_TABLES`).
5. Excitation on demand (issue 40): ``samples`` gets ``excitation`` (the test signal the PLC
   applied to its PI's output, read back [V]) and ``run`` (the wind-tunnel run flag, 0 or 1),
   both NULL on the rows before it and whenever the site does not record them. No row changes;
   ``samples_lod`` does not carry them.

**Tables**::

    meta(key TEXT PRIMARY KEY, value TEXT NOT NULL)
        schema_version, site_name, tag_map_hash (SHA-256 hex of the tag map), created (s UTC,
        wall clock), period_s (the sampling period, when given), store_uuid (uuid4 hex, the
        store's identity), loop_id (the site file's ``[site] loop_id``; by default the site
        name lowercased, runs of other than [a-z0-9] as "-", "loop" when empty)

    Every table's ``time`` is plant time [s UTC since the epoch, the samples' time base];
    ``wall_time`` the wall clock when the row was written [s UTC] (NULL on rows from before
    version 3 where it is not known: every sample and event written before it).

    samples(time REAL NOT NULL,          -- plant time [s UTC]
            seq INTEGER,                 -- unwrapped sequence number, NULL without a counter
            u REAL,                      -- VFD command [V]
            y REAL,                      -- flow [L/min]
            setpoint REAL,               -- [L/min]
            fuel_temperature REAL,       -- [°C]
            mode INTEGER,                -- 0 MAN, 1 AUTO
            quality INTEGER NOT NULL,    -- 0 ok, 1 stale, 2 link_down, 3 bad_value
            wall_time REAL,              -- wall clock at commit [s UTC]
            excitation REAL,             -- the test signal applied, read back [V]
            run INTEGER)                 -- 1 during a wind-tunnel run, else 0
        UNIQUE (seq) WHERE seq IS NOT NULL; UNIQUE (time) WHERE seq IS NULL; INDEX (time)
        (INSERT … ON CONFLICT DO NOTHING: a restart that re-sends samples adds no duplicates);
        NaN is stored as NULL (SQLite has no NaN) and read back as NaN; ``excitation`` and
        ``run`` are NULL where the site does not record them (no ``[tags.excitation]``,
        ``[tags.run]``) and on every row before version 5
    events(id INTEGER PRIMARY KEY, time REAL NOT NULL, kind TEXT NOT NULL,
           detail TEXT NOT NULL, wall_time REAL)                           INDEX (time)
        kinds: link_down, link_up, gap, gain_change, restart, site_mismatch, prune, …
    models(id INTEGER PRIMARY KEY, time REAL NOT NULL, t_from REAL, t_to REAL,
           T_fuel REAL, model TEXT NOT NULL, wall_time REAL)
        one per accepted identification window of the online service: the window's span and
        analysis time [plant s UTC], its mean fuel temperature [°C], the model as JSON
    proposals(id INTEGER PRIMARY KEY, time REAL NOT NULL, model_id INTEGER, kc REAL, ti REAL,
              status TEXT NOT NULL, detail TEXT NOT NULL, wall_time REAL)
        proposed PI gains (kc, ti: the new ones), filed at plant ``time``, their status
        (pending, approved, writing, applied, failed, rejected, superseded, reverted) and as
        JSON {"old", "new", "detail", "history": [{"time", "wall_time", "status", "who",
        "why"}, …]} (an entry's ``time`` plant time, ``wall_time`` the wall clock)
    windows(id INTEGER PRIMARY KEY, time REAL NOT NULL,     -- analysis [plant s UTC]: the
                                                            -- newest committed sample's
                                                            -- time, >= t_to
            t_from REAL NOT NULL, t_to REAL NOT NULL,       -- the window's data [plant s]
            accepted INTEGER NOT NULL,                      -- 0 or 1
            reason TEXT NOT NULL, T_fuel REAL,              -- [°C]
            u_mean REAL,                                    -- [V]
            model_id INTEGER,                               -- models(id) when accepted
            detail TEXT NOT NULL,                           -- JSON: gates, fit, health
            wall_time REAL)                                 -- [wall s UTC]
        INDEX (t_to); every identification window, accepted or not
    writes(id INTEGER PRIMARY KEY, time REAL NOT NULL, proposal_id INTEGER,
           kind TEXT NOT NULL,                              -- proposal, revert, restore
           kc REAL NOT NULL, ti REAL NOT NULL,              -- the gains written
           apply_seq INTEGER NOT NULL UNIQUE,               -- never reused
           status TEXT NOT NULL,                            -- intent, verified, failed,
                                                            -- not_applied
           who TEXT NOT NULL, why TEXT NOT NULL, detail TEXT NOT NULL,     -- JSON
           finished REAL,                                   -- [plant s], NULL while an intent
           wall_time REAL, finished_wall REAL)              -- the same on the wall clock
        a write of gains to the PLC: the intent is committed before the PLC is written, the
        outcome after, so an ``intent`` left by a crash is reconciled on restart; ``time`` the
        plant time of the intent, ``finished`` of the outcome
    online_state(key TEXT PRIMARY KEY, value TEXT NOT NULL,  -- JSON
                 time REAL NOT NULL)                         -- last set [wall s UTC]
        what the online service needs after a restart (last-known-good gains, …), the
        ``service`` record (pid, host, version, started, beat, beat_every_s, stopped: wall
        clock; settings), refreshed every 2 s of wall time while the service runs, and
        ``plc_gains``, the PLC's kc and ti as the recorder last read them (written by the
        store's writer on a change: :mod:`fuelid.plc._gain_reading`)
    requests(id INTEGER PRIMARY KEY, time REAL NOT NULL,    -- plant time when filed
             wall_time REAL NOT NULL,                       -- wall clock when filed
             kind TEXT NOT NULL,                            -- approve, reject, revert,
                                                            -- excite_start, excite_stop (v5)
             proposal_id INTEGER,                           -- proposals(id); NULL for revert
             who TEXT NOT NULL, why TEXT NOT NULL,
             origin TEXT NOT NULL,                          -- cli, dashboard (later central)
             status TEXT NOT NULL,                          -- waiting, done, refused, expired
             outcome TEXT NOT NULL,                         -- what was done, or why not
             done_wall REAL)                                -- wall clock when consumed
        INDEX (status); a person's decision, filed by the CLI or the dashboard and applied by
        the running service at its next beat (or at once by the CLI when no service runs)
    samples_lod(level INTEGER NOT NULL,                     -- bucket width [s]: 1 or 10
                bucket REAL NOT NULL,                       -- floor(time/level)*level [plant s]
                n INTEGER NOT NULL,                         -- samples in the bucket
                u_min REAL, u_max REAL, y_min REAL, y_max REAL,
                sp_min REAL, sp_max REAL, tf_min REAL, tf_max REAL,  -- u, y, setpoint,
                                                            -- fuel_temperature (NULLs ignored)
                bad INTEGER NOT NULL)                       -- samples with quality != 0
        PRIMARY KEY (level, bucket), WITHOUT ROWID; the samples' min/max per bucket for plots
        over long spans, kept by every append (levels :data:`LOD_LEVELS`). A re-flag
        recounts ``bad`` in the buckets it touches, never lowering it (exact while the raw
        samples are there, approximate after thinning; readers use ``bad`` > 0 as a quality
        mark); thinning keeps the rows (they summarise what was there), deleting samples
        deletes them

    outbox(id INTEGER PRIMARY KEY,                          -- the order rows are sent in
           tbl TEXT NOT NULL, row_id INTEGER NOT NULL,      -- which row changed
           wall_time REAL NOT NULL)                         -- when [wall s UTC]
        the change log of the rows a central store receives: every insert and update of
        ``events``, ``windows``, ``models``, ``proposals``, ``writes`` and ``requests`` adds a
        row, by a trigger, in the transaction that changed the row, while ``meta`` ``outbox``
        is ``on``; the sender reads the rows' current values, sends them and deletes the
        entries it sent
    archived_days(loop_id TEXT NOT NULL, date TEXT NOT NULL,   -- a loop-day (UTC)
                  samples INTEGER NOT NULL,                    -- rows in its Parquet file
                  t_first REAL, t_last REAL,                   -- [plant s UTC]
                  path TEXT NOT NULL,                          -- the file, absolute
                  wall_time REAL NOT NULL)                     -- archived at [wall s UTC]
        PRIMARY KEY (loop_id, date); the days ``fuelid archive`` wrote and read back: with an
        archive configured, retention deletes only the samples of these days

JSON is written with ``allow_nan=False``: NaN and ±inf are stored as ``null``.

**Adding a migration.** Append a :class:`Migration` to :data:`MIGRATIONS` (its ``version`` is the
next number; :data:`SCHEMA_VERSION` follows), describe it under **Versions** and change **Tables**
above, and give the test of upgrades (``tests/integration/store/test_store_schema.py``) a case
that builds a store at the version before with :func:`build_at` (or loads a dump written by the
released fuelid, as ``tests/data/store_v0_1.sql``), opens it with the current code and checks
every old row. Never edit a released migration: a store in the field has already applied it.

A migration may carry a ``data`` step (a function of the connection, run in the migration's
transaction after its statements) for rows that need computing, such as filling a new column.
"""

from __future__ import annotations

import json
import re
import sqlite3
import uuid
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from fuelid.store._records import StoreError
from fuelid.store._schema_v4 import OUTBOX_TABLES, V4_MANY_LOOPS, outbox_triggers

__all__ = [
    "APPLICATION_ID",
    "LOD_LEVELS",
    "LOD_SELECT",
    "MIGRATIONS",
    "OUTBOX_TABLES",
    "SCHEMA_VERSION",
    "Migration",
    "build_at",
    "check_not_newer",
    "create",
    "default_loop_id",
    "plant_of_wall",
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

LOD_LEVELS: tuple[int, ...] = (1, 10)
"""The ``samples_lod`` levels: bucket widths [s of plant time]."""

_V3_ONE_CLOCK = (
    "ALTER TABLE samples ADD COLUMN wall_time REAL",
    "ALTER TABLE events ADD COLUMN wall_time REAL",
    "ALTER TABLE models ADD COLUMN wall_time REAL",
    "ALTER TABLE windows ADD COLUMN wall_time REAL",
    "ALTER TABLE proposals ADD COLUMN wall_time REAL",
    "ALTER TABLE writes ADD COLUMN wall_time REAL",
    "ALTER TABLE writes ADD COLUMN finished_wall REAL",
    """CREATE TABLE requests(
    id INTEGER PRIMARY KEY, time REAL NOT NULL, wall_time REAL NOT NULL,
    kind TEXT NOT NULL CHECK (kind IN ('approve', 'reject', 'revert')),
    proposal_id INTEGER REFERENCES proposals(id), who TEXT NOT NULL, why TEXT NOT NULL,
    origin TEXT NOT NULL,
    status TEXT NOT NULL CHECK (status IN ('waiting', 'done', 'refused', 'expired')),
    outcome TEXT NOT NULL, done_wall REAL
) STRICT""",
    "CREATE INDEX requests_status ON requests(status)",
    """CREATE TABLE samples_lod(
    level INTEGER NOT NULL, bucket REAL NOT NULL, n INTEGER NOT NULL,
    u_min REAL, u_max REAL, y_min REAL, y_max REAL, sp_min REAL, sp_max REAL,
    tf_min REAL, tf_max REAL, bad INTEGER NOT NULL,
    PRIMARY KEY (level, bucket)
) STRICT, WITHOUT ROWID""",
)

LOD_SELECT = (
    "SELECT ?1, floor(time / ?1) * ?1 AS b, count(*), min(u), max(u), min(y), max(y), "
    "min(setpoint), max(setpoint), min(fuel_temperature), max(fuel_temperature), "
    "sum(quality != 0) FROM samples"
)
"""The level-of-detail rows of ``samples`` at level ``?1`` [s] (append ``WHERE`` and
``GROUP BY b``)."""


def default_loop_id(site_name: str) -> str:
    """A loop id from a site name: lowercase, runs of other than ``[a-z0-9]`` as ``-``.

    Examples
    --------
    >>> default_loop_id("Tunnel 2 / fuel")
    'tunnel-2-fuel'
    >>> default_loop_id("§§")
    'loop'
    """
    text = re.sub(r"[^a-z0-9]+", "-", site_name.lower()).strip("-")
    return text[:40].strip("-") or "loop"


def plant_of_wall(anchors: Sequence[tuple[float, float]]) -> Callable[[float], float]:
    """The map of a wall time onto plant time through ``(wall, plant)`` anchors [s UTC].

    Inside the anchors' range: linear interpolation (``numpy.interp`` over the anchors sorted by
    wall time); outside it the nearest anchor's plant time plus the wall time since it (real
    time assumed); with no anchors plant time is wall time.

    Examples
    --------
    >>> f = plant_of_wall([(100.0, 1000.0), (200.0, 3000.0)])
    >>> f(150.0), f(90.0), f(210.0)
    (2000.0, 990.0, 3010.0)
    """
    import numpy as np

    if not anchors:
        return float
    pairs = sorted((float(w), float(p)) for w, p in anchors)
    walls = np.array([w for w, _ in pairs])
    plants = np.array([p for _, p in pairs])

    def plant(wall: float) -> float:
        w = float(wall)
        if w < walls[0]:
            return float(plants[0] + (w - walls[0]))
        if w > walls[-1]:
            return float(plants[-1] + (w - walls[-1]))
        return float(np.interp(w, walls, plants))

    return plant


def _v3_data(con: sqlite3.Connection) -> None:
    """Old wall times onto plant time, the LOD table from the samples, the store's ids."""
    anchors = con.execute("SELECT time, t_to FROM windows").fetchall()
    plant = plant_of_wall(anchors)

    def mapped(value: float | None) -> float | None:
        return None if value is None else plant(value)

    for table in ("models", "proposals"):
        rows = con.execute(f"SELECT rowid, time FROM {table}").fetchall()
        con.executemany(
            f"UPDATE {table} SET time = ?, wall_time = ? WHERE rowid = ?",
            [(plant(t), t, rowid) for rowid, t in rows],
        )
    rows = con.execute("SELECT id, time, t_to FROM windows").fetchall()
    con.executemany(
        "UPDATE windows SET time = ?, wall_time = ? WHERE id = ?",
        [(max(t_to, plant(t)), t, rowid) for rowid, t, t_to in rows],
    )
    rows = con.execute("SELECT id, time, finished FROM writes").fetchall()
    con.executemany(
        "UPDATE writes SET time = ?, wall_time = ?, finished = ?, finished_wall = ? WHERE id = ?",
        [(plant(t), t, mapped(f), f, rowid) for rowid, t, f in rows],
    )
    updates = []
    for rowid, text in con.execute("SELECT id, detail FROM proposals").fetchall():
        try:
            stored = json.loads(text)
        except ValueError:
            continue
        history = stored.get("history") if isinstance(stored, dict) else None
        if not isinstance(history, list):
            continue
        for entry in history:
            if isinstance(entry, dict) and isinstance(entry.get("time"), int | float):
                entry["wall_time"] = entry["time"]
                entry["time"] = plant(entry["time"])
        updates.append((json.dumps(stored, allow_nan=False, separators=(",", ":")), rowid))
    con.executemany("UPDATE proposals SET detail = ? WHERE id = ?", updates)
    for level in LOD_LEVELS:
        con.execute(f"INSERT INTO samples_lod {LOD_SELECT} GROUP BY b", (level,))
    meta = dict(con.execute("SELECT key, value FROM meta").fetchall())
    con.executemany(
        "INSERT OR IGNORE INTO meta VALUES (?, ?)",
        [
            ("store_uuid", uuid.uuid4().hex),
            ("loop_id", default_loop_id(meta.get("site_name", ""))),
        ],
    )


_V5_EXCITATION = (
    "ALTER TABLE samples ADD COLUMN excitation REAL",
    "ALTER TABLE samples ADD COLUMN run INTEGER CHECK (run IN (0, 1))",
    # a person's start or stop of the signal is a request too: SQLite cannot widen a CHECK,
    # so the table is made anew with its rows
    """CREATE TABLE requests_v5(
    id INTEGER PRIMARY KEY, time REAL NOT NULL, wall_time REAL NOT NULL,
    kind TEXT NOT NULL
        CHECK (kind IN ('approve', 'reject', 'revert', 'excite_start', 'excite_stop')),
    proposal_id INTEGER REFERENCES proposals(id), who TEXT NOT NULL, why TEXT NOT NULL,
    origin TEXT NOT NULL,
    status TEXT NOT NULL CHECK (status IN ('waiting', 'done', 'refused', 'expired')),
    outcome TEXT NOT NULL, done_wall REAL
) STRICT""",
    "INSERT INTO requests_v5 SELECT * FROM requests",
    "DROP TABLE requests",
    "ALTER TABLE requests_v5 RENAME TO requests",
    "CREATE INDEX requests_status ON requests(status)",
    *outbox_triggers(("requests",)),  # dropped with the old table
)

MIGRATIONS: tuple[Migration, ...] = (
    Migration(1, "samples, events, models and proposals (fuelid 0.1)", _V1_SAMPLES_AND_EVENTS),
    Migration(2, "the online service's windows, writes and state everywhere", _V2_ONLINE_TABLES),
    Migration(
        3,
        "one clock: plant and wall time on every row; requests; the level-of-detail table",
        _V3_ONE_CLOCK,
        _v3_data,
    ),
    Migration(
        4,
        "many loops: a stable id on events, the outbox for a central store, archived days",
        V4_MANY_LOOPS,
    ),
    Migration(
        5,
        "excitation on demand: the applied test signal and the run flag on every sample; "
        "requests to start or stop a signal",
        _V5_EXCITATION,
    ),
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
    fuelid.store._records.StoreError: loop.db: store schema version ... is newer than this ...
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
