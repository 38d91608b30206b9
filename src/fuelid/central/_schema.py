"""The central store's tables in PostgreSQL, their versioned migrations, partitions and retention.

Every loop's service sends its rows here (:mod:`fuelid.central._sender`). A row is known by the
identity it has at its site: the store's UUID (``meta`` ``store_uuid`` of the SQLite file) and
the row's id in that store, ``(store_uuid, id)``; ``loop_id`` (``[site] loop_id``) is carried on
every row for the dashboard's queries. Columns keep the site's names and values (REAL as
``double precision``, INTEGER as ``bigint``), JSON text as ``jsonb``; ``synced`` is when the
row last changed here (the central clock). Times are UTC seconds since the epoch: ``time``
plant time, ``wall_time`` the site's wall clock (:mod:`fuelid.store._schema`).

**Tables** (version 1)::

    central_schema(version, summary, applied)      one row per migration applied
    stores(store_uuid PK, loop_id, site_name, tag_map_hash, first_seen, last_seen)
        a store UUID arriving with another loop id or tag-map hash is refused
    loops(loop_id PK, site_name, tag_map_hash, first_seen)
        a second store under a known loop id must have the loop's tag-map hash
    windows(store_uuid, id, loop_id, time, t_from, t_to, accepted, reason, t_fuel, u_mean,
            model_id, detail jsonb, wall_time, synced)          PARTITION BY RANGE (time)
    kpis(store_uuid, id, loop_id, time, t_from, t_to, accepted, mode, time_in_auto,
         time_at_limits, oscillating, iae_per_unit_step_s, harris_index, ok_share,
         fit_percent, plant_k, t_fuel, synced)                  PARTITION BY RANGE (time)
        one per window (same id): the loop-health numbers of its detail the fleet page uses
    models(store_uuid, id, loop_id, time, t_from, t_to, t_fuel, model jsonb, wall_time, synced)
    proposals(store_uuid, id, loop_id, time, model_id, kc, ti, status, detail jsonb,
              history_len, wall_time, synced)
        upserted on every change; ``detail`` carries the history, ``history_len`` its entries
    writes(store_uuid, id, loop_id, time, proposal_id, kind, kc, ti, apply_seq, status, who,
           why, detail jsonb, finished, wall_time, finished_wall, synced)
    events(store_uuid, id, loop_id, time, kind, detail text, wall_time, synced)
    site_requests(store_uuid, id, loop_id, time, wall_time, kind, proposal_id, who, why,
                  origin, status, outcome, done_wall, synced)   the sites' own request rows
    liveness(store_uuid PK, loop_id, service jsonb, backlog_rows, backlog_oldest_wall,
             last_send_wall, updated)                           upserted at every send
    requests(id PK, loop_id, kind, proposal_id, seen_status, seen_history_len, who, why,
             origin, status, outcome, created, expires, fetched, local_id, done, store_uuid)
        actions taken centrally, carried out by the site (:mod:`fuelid.central._requests`);
        ``store_uuid`` the loop's store they are for (a replaced store never takes them)

Keys: ``(store_uuid, id)`` on every site table; on the partitioned ``windows`` and ``kpis``
``(store_uuid, id, time)`` (PostgreSQL's unique keys on a partitioned table include the
partition key; a window's ``time`` never changes). Indexes for the fleet page: the newest
window and KPIs of a loop (``loop_id, time DESC``), the open proposals of a loop (partial:
pending or approved), liveness by loop, waiting requests by loop.

**Partitions.** ``windows`` and ``kpis`` are partitioned by month of plant time
(``<table>_pYYYYMM``, bounds the month's first second in UTC), created on demand by the sender
through ``central_ensure_partitions(parent, t_lo, t_hi)``; ``central_drop_partitions(months, now)``
drops the months that ended more than ``months`` months before ``now``, never later than the
server's clock (the retention, the owner's job: ``fuelid central retention``; the other tables
are small: a few rows per window). Both are ``SECURITY DEFINER`` functions of the migrating
role, so a site's role needs no right to create or drop tables; their ``EXECUTE`` is revoked
from ``PUBLIC`` (granted explicitly: a site's role gets ``central_ensure_partitions`` only).

**Version 2** adds to ``liveness`` what a central reader (the dashboard's fleet page) needs to
show a loop as its own store would: ``site_wall`` (the site's wall clock when it wrote the row:
the loop's state is judged as of that instant), ``send_every_s`` (the site's send interval),
``newest_sample_time`` and ``newest_sample_wall`` (the newest sample's plant and wall time),
``first_sample_time``, ``period_s`` (the store's sampling period), ``schema_version`` (the
store's) and ``site_state`` (jsonb: the site's ``online_state`` values ``current_gains``,
``last_known_good``, ``write_held``, ``revert_requested``, ``tuned_for``); and indexes for a
central reader: the windows by their model (``store_uuid, model_id``), a store's newest windows
and models by their window's end (``store_uuid, t_to DESC, id DESC``).

**Version 3** adds the results of ``fuelid reidentify --central``: ``reidentify_runs`` and
``reidentified`` (:mod:`fuelid.central._reidentified`).

**Version 4** widens ``requests.kind`` to the test signal's ``excite_start`` and ``excite_stop``
(issue 40): the column's CHECK, named ``requests_kind_check`` by PostgreSQL in version 1, is
dropped and added again with the five kinds (the rows are kept; a site of an older fuelid
refuses version 4, so no site files a kind it does not know).

**Versions.** :data:`MIGRATIONS` in order, each in one transaction with its row in
``central_schema`` (under an advisory lock: two migrators never apply one twice). A database
whose version is newer than :data:`SCHEMA_VERSION` is refused with both versions (an older
fuelid never writes into a schema it does not know); an older one asks for ``fuelid central
migrate``. Never edit a released migration: append one.
"""

from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from fuelid.central._connect import CentralError
from fuelid.central._reidentified import TABLES as REIDENTIFIED

if TYPE_CHECKING:
    import psycopg

__all__ = [
    "MIGRATIONS",
    "PARTITIONED",
    "SCHEMA_VERSION",
    "SITE_TABLES",
    "Migration",
    "SiteTable",
    "check_schema",
    "drop_old_partitions",
    "ensure_partitions",
    "migrate",
    "month_start",
    "schema_version",
]


@dataclass(frozen=True)
class SiteTable:
    """A site table as the central store receives it.

    Attributes
    ----------
    site : str
        The SQLite table (:data:`fuelid.store._schema.OUTBOX_TABLES`).
    central : str
        The PostgreSQL table.
    columns : tuple of (str, str)
        ``(site column, PostgreSQL type)`` in order, ``id`` first; ``jsonb`` columns arrive as
        JSON text. The central column is the site's name lowercased.
    """

    site: str
    central: str
    columns: tuple[tuple[str, str], ...]

    @property
    def names(self) -> tuple[str, ...]:
        """The central column names, in order."""
        return tuple(c.lower() for c, _ in self.columns)


_F, _I, _T, _J = "double precision", "bigint", "text", "jsonb"

SITE_TABLES: dict[str, SiteTable] = {
    t.site: t
    for t in (
        SiteTable(
            "events",
            "events",
            (("id", _I), ("time", _F), ("kind", _T), ("detail", _T), ("wall_time", _F)),
        ),
        SiteTable(
            "windows",
            "windows",
            (
                ("id", _I),
                ("time", _F),
                ("t_from", _F),
                ("t_to", _F),
                ("accepted", _I),
                ("reason", _T),
                ("T_fuel", _F),
                ("u_mean", _F),
                ("model_id", _I),
                ("detail", _J),
                ("wall_time", _F),
            ),
        ),
        SiteTable(
            "models",
            "models",
            (
                ("id", _I),
                ("time", _F),
                ("t_from", _F),
                ("t_to", _F),
                ("T_fuel", _F),
                ("model", _J),
                ("wall_time", _F),
            ),
        ),
        SiteTable(
            "proposals",
            "proposals",
            (
                ("id", _I),
                ("time", _F),
                ("model_id", _I),
                ("kc", _F),
                ("ti", _F),
                ("status", _T),
                ("detail", _J),
                ("wall_time", _F),
            ),
        ),
        SiteTable(
            "writes",
            "writes",
            (
                ("id", _I),
                ("time", _F),
                ("proposal_id", _I),
                ("kind", _T),
                ("kc", _F),
                ("ti", _F),
                ("apply_seq", _I),
                ("status", _T),
                ("who", _T),
                ("why", _T),
                ("detail", _J),
                ("finished", _F),
                ("wall_time", _F),
                ("finished_wall", _F),
            ),
        ),
        SiteTable(
            "requests",
            "site_requests",
            (
                ("id", _I),
                ("time", _F),
                ("wall_time", _F),
                ("kind", _T),
                ("proposal_id", _I),
                ("who", _T),
                ("why", _T),
                ("origin", _T),
                ("status", _T),
                ("outcome", _T),
                ("done_wall", _F),
            ),
        ),
    )
}
"""Every site table the central store receives, by its SQLite name."""

PARTITIONED = ("windows", "kpis")
"""The central tables partitioned by month of plant time."""

KPI_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("mode", _T, "d->>'mode'"),
    ("time_in_auto", _F, "(d->'health'->>'time_in_auto')::float8"),
    ("time_at_limits", _F, "(d->'health'->>'time_at_limits')::float8"),
    ("oscillating", "boolean", "(d->'health'->'oscillation'->>'oscillating')::boolean"),
    ("iae_per_unit_step_s", _F, "(d->'health'->>'iae_per_unit_step_s')::float8"),
    ("harris_index", _F, "(d->'health'->'harris'->>'index')::float8"),
    ("ok_share", _F, "(d->'health'->>'ok_share')::float8"),
    ("fit_percent", _F, "(d->>'fit_percent')::float8"),
    ("plant_k", _F, "(d->>'plant_K')::float8"),
)
"""The KPI columns of a window: (name, type, expression of its detail ``d`` as jsonb): the mode
and shares [0-1], oscillating, IAE per unit setpoint step [s], the Harris index [0-1], the
share of good samples [0-1], the fit [%] and the plant gain K [L/min per V]."""


def _site_table_sql(table: SiteTable) -> list[str]:
    cols = ",\n    ".join(
        f"{name} {kind}" for name, (_, kind) in zip(table.names, table.columns, strict=True)
    )
    partitioned = table.central in PARTITIONED
    key = "store_uuid, id, time" if partitioned else "store_uuid, id"
    tail = " PARTITION BY RANGE (time)" if partitioned else ""
    return [
        f"""CREATE TABLE {table.central}(
    store_uuid text NOT NULL,
    loop_id text NOT NULL,
    {cols},
    synced timestamptz NOT NULL DEFAULT now(),
    PRIMARY KEY ({key})
){tail}"""
    ]


_V1 = [
    """CREATE TABLE stores(
    store_uuid text PRIMARY KEY, loop_id text NOT NULL, site_name text NOT NULL,
    tag_map_hash text NOT NULL, first_seen timestamptz NOT NULL DEFAULT now(),
    last_seen timestamptz NOT NULL DEFAULT now())""",
    "CREATE INDEX stores_loop ON stores(loop_id)",
    """CREATE TABLE loops(
    loop_id text PRIMARY KEY, site_name text NOT NULL, tag_map_hash text NOT NULL,
    first_seen timestamptz NOT NULL DEFAULT now())""",
    *(sql for t in SITE_TABLES.values() for sql in _site_table_sql(t)),
    "ALTER TABLE proposals ADD COLUMN history_len integer NOT NULL DEFAULT 0",
    """CREATE TABLE kpis(
    store_uuid text NOT NULL, id bigint NOT NULL, loop_id text NOT NULL,
    time double precision NOT NULL, t_from double precision, t_to double precision,
    accepted bigint, t_fuel double precision, """
    + ", ".join(f"{name} {kind}" for name, kind, _ in KPI_COLUMNS)
    + """,
    synced timestamptz NOT NULL DEFAULT now(),
    PRIMARY KEY (store_uuid, id, time)) PARTITION BY RANGE (time)""",
    "CREATE INDEX windows_loop_time ON windows(loop_id, time DESC)",
    "CREATE INDEX kpis_loop_time ON kpis(loop_id, time DESC)",
    "CREATE INDEX models_loop_time ON models(loop_id, time DESC)",
    "CREATE INDEX events_loop_time ON events(loop_id, time DESC)",
    "CREATE INDEX writes_loop ON writes(loop_id, id DESC)",
    "CREATE INDEX proposals_open ON proposals(loop_id, id) WHERE status IN ('pending', 'approved')",
    """CREATE TABLE liveness(
    store_uuid text PRIMARY KEY, loop_id text NOT NULL, service jsonb,
    backlog_rows bigint NOT NULL, backlog_oldest_wall double precision,
    last_send_wall double precision, updated timestamptz NOT NULL DEFAULT now())""",
    "CREATE INDEX liveness_loop ON liveness(loop_id)",
    """CREATE TABLE requests(
    id bigserial PRIMARY KEY, loop_id text NOT NULL,
    kind text NOT NULL CHECK (kind IN ('approve', 'reject', 'revert')),
    proposal_id bigint, seen_status text, seen_history_len integer,
    who text NOT NULL, why text NOT NULL, origin text NOT NULL,
    status text NOT NULL DEFAULT 'waiting'
        CHECK (status IN ('waiting', 'done', 'refused', 'expired')),
    outcome text NOT NULL DEFAULT '', created timestamptz NOT NULL DEFAULT now(),
    expires timestamptz NOT NULL, fetched timestamptz, local_id bigint, done timestamptz,
    store_uuid text NOT NULL)""",
    "CREATE INDEX requests_waiting ON requests(loop_id, id) WHERE status = 'waiting'",
    # monthly partitions on demand, for roles that may not create tables (SECURITY DEFINER)
    """CREATE FUNCTION central_ensure_partitions(parent text, t_lo float8, t_hi float8)
RETURNS void LANGUAGE plpgsql SECURITY DEFINER SET search_path FROM CURRENT AS $$
DECLARE
    m timestamp := date_trunc('month', to_timestamp(t_lo) AT TIME ZONE 'UTC');
    last timestamp := to_timestamp(t_hi) AT TIME ZONE 'UTC';
    part text;
BEGIN
    IF parent NOT IN ('windows', 'kpis') THEN
        RAISE EXCEPTION 'not a partitioned table: %', parent;
    END IF;
    IF t_hi - t_lo > 86400.0 * 366 * 20 THEN
        RAISE EXCEPTION 'a span of more than 20 years: % to %', t_lo, t_hi;
    END IF;
    WHILE m <= last LOOP
        part := parent || '_p' || to_char(m, 'YYYYMM');
        IF to_regclass(part) IS NULL THEN
            PERFORM pg_advisory_xact_lock(hashtext('fuelid partition ' || part));
            -- read pg_class itself: an advisory lock does not refresh this session's catalog
            -- cache, so to_regclass may still miss a partition another sender just committed
            IF NOT EXISTS (SELECT 1 FROM pg_class WHERE relname = part
                           AND relnamespace = current_schema()::regnamespace) THEN
                BEGIN
                    EXECUTE format(
                        'CREATE TABLE %I PARTITION OF %I FOR VALUES FROM (%s) TO (%s)',
                        part, parent, extract(epoch FROM m),
                        extract(epoch FROM m + interval '1 month'));
                EXCEPTION WHEN duplicate_table OR unique_violation THEN
                    NULL;  -- created meanwhile by another sender: what was wanted
                END;
            END IF;
        END IF;
        m := m + interval '1 month';
    END LOOP;
END $$""",
    """CREATE FUNCTION central_drop_partitions(months integer, now_s float8)
RETURNS SETOF text LANGUAGE plpgsql SECURITY DEFINER SET search_path FROM CURRENT AS $$
DECLARE
    -- the server's clock bounds the caller's: a clock in the future never drops this month
    cutoff timestamp := date_trunc('month', to_timestamp(least(now_s, extract(epoch FROM now())))
                        AT TIME ZONE 'UTC') - make_interval(months => months);
    part record;
BEGIN
    IF months < 1 THEN
        RAISE EXCEPTION 'retention of % months: at least 1', months;
    END IF;
    FOR part IN
        SELECT c.relname, p.relname AS parent FROM pg_inherits i
        JOIN pg_class c ON c.oid = i.inhrelid JOIN pg_class p ON p.oid = i.inhparent
        WHERE p.relname IN ('windows', 'kpis') AND c.relname ~ '_p[0-9]{6}$'
        ORDER BY c.relname
    LOOP
        -- the month ends at or before the cutoff: all of it is older than the retention
        IF to_timestamp(right(part.relname, 6), 'YYYYMM')::timestamp + interval '1 month'
           <= cutoff THEN
            EXECUTE format('DROP TABLE %I', part.relname);
            RETURN NEXT part.relname;
        END IF;
    END LOOP;
END $$""",
    # PostgreSQL lets PUBLIC execute a new function: these two run as the owner, so only the
    # roles granted them (a site's sender: ensure; the owner's retention job: drop) may
    "REVOKE EXECUTE ON FUNCTION central_ensure_partitions(text, float8, float8) FROM PUBLIC",
    "REVOKE EXECUTE ON FUNCTION central_drop_partitions(integer, float8) FROM PUBLIC",
]


@dataclass(frozen=True)
class Migration:
    """One step of the central schema: the statements taking it from ``version − 1``."""

    version: int
    summary: str
    statements: tuple[str, ...]


_V2 = [
    "ALTER TABLE liveness ADD COLUMN site_wall double precision",
    "ALTER TABLE liveness ADD COLUMN send_every_s double precision",
    "ALTER TABLE liveness ADD COLUMN newest_sample_time double precision",
    "ALTER TABLE liveness ADD COLUMN newest_sample_wall double precision",
    "ALTER TABLE liveness ADD COLUMN first_sample_time double precision",
    "ALTER TABLE liveness ADD COLUMN period_s double precision",
    "ALTER TABLE liveness ADD COLUMN schema_version integer",
    "ALTER TABLE liveness ADD COLUMN site_state jsonb",
    # a model's window, as a central reader asks for it (the site's models.window_id join)
    "CREATE INDEX windows_model ON windows(store_uuid, model_id) WHERE model_id IS NOT NULL",
    # a store's newest windows and models in the site's own order (by the window's end)
    # (with accepted: the counts of a store's windows read the index alone)
    "CREATE INDEX windows_store_end ON windows(store_uuid, t_to DESC, id DESC) INCLUDE (accepted)",
    "CREATE INDEX models_store_end ON models(store_uuid, t_to DESC, id DESC)",
]

_V4 = [
    # version 1's inline CHECK, which PostgreSQL named <table>_<column>_check: dropped by that
    # name (a database whose constraint is named otherwise fails here, loudly, rather than
    # keep the old CHECK that would refuse the new kinds beside the new one)
    "ALTER TABLE requests DROP CONSTRAINT requests_kind_check",
    "ALTER TABLE requests ADD CONSTRAINT requests_kind_check CHECK (kind IN "
    "('approve', 'reject', 'revert', 'excite_start', 'excite_stop'))",
]

MIGRATIONS: tuple[Migration, ...] = (
    Migration(
        1,
        "stores, loops, the site tables (windows and KPIs by month), liveness, requests",
        tuple(_V1),
    ),
    Migration(
        2,
        "liveness: the site's clock, send interval, newest sample, sampling period and state",
        tuple(_V2),
    ),
    Migration(3, "the results of fuelid reidentify: reidentify_runs, reidentified", REIDENTIFIED),
    Migration(4, "requests: the test signal's kinds excite_start and excite_stop", tuple(_V4)),
)
"""Every migration in order; ``MIGRATIONS[k]`` takes the database to version ``k + 1``."""

SCHEMA_VERSION = MIGRATIONS[-1].version
"""The central schema version this fuelid writes (and the newest it accepts)."""

_LOCK = "SELECT pg_advisory_xact_lock(hashtext('fuelid central schema'))"


def schema_version(con: psycopg.Connection) -> int:
    """The database's central schema version; 0 when it has none (an empty database)."""
    with con.transaction():
        exists = con.execute("SELECT to_regclass('central_schema') IS NOT NULL").fetchone()
        if not exists or not exists[0]:
            return 0
        row = con.execute("SELECT coalesce(max(version), 0) FROM central_schema").fetchone()
    return int(row[0]) if row else 0


def _newer(version: int) -> CentralError:
    return CentralError(
        f"central store schema version {version} is newer than this fuelid's "
        f"({SCHEMA_VERSION}): upgrade fuelid"
    )


def check_schema(con: psycopg.Connection) -> int:
    """The version, when it is this fuelid's; else a one-line reason.

    Raises
    ------
    CentralError
        No fuelid schema, an older one (run ``fuelid central migrate``) or a newer one.
    """
    version = schema_version(con)
    if version > SCHEMA_VERSION:
        raise _newer(version)
    if version < SCHEMA_VERSION:
        found = "no fuelid schema" if version == 0 else f"schema version {version}"
        raise CentralError(
            f"the central store has {found}, this fuelid needs {SCHEMA_VERSION}: "
            "run `fuelid central migrate --url URL` (as the database's owner)"
        )
    return version


def migrate(con: psycopg.Connection, upto: int | None = None) -> tuple[int, int]:
    """Create or upgrade the schema; ``(version before, version after)``.

    Each migration runs in a transaction of its own, under an advisory lock, with its row in
    ``central_schema``: a failure leaves the version before it. ``upto`` stops at that version
    (the newest, :data:`SCHEMA_VERSION`, by default): a test builds an older database with it
    to check the migrations after it.

    Raises
    ------
    CentralError
        The database's schema is newer than this fuelid's, or ``upto`` is not a version.
    """
    target = SCHEMA_VERSION if upto is None else int(upto)
    if not 1 <= target <= SCHEMA_VERSION:
        raise CentralError(f"no central schema version {upto}: 1 to {SCHEMA_VERSION}")
    before = schema_version(con)
    if before > SCHEMA_VERSION:
        raise _newer(before)
    with con.transaction():
        con.execute(_LOCK)  # first: two migrators of an empty database create it once
        con.execute(
            "CREATE TABLE IF NOT EXISTS central_schema(version integer PRIMARY KEY, "
            "summary text NOT NULL, applied timestamptz NOT NULL DEFAULT now())"
        )
    for migration in MIGRATIONS:
        with con.transaction():
            con.execute(_LOCK)
            row = con.execute("SELECT coalesce(max(version), 0) FROM central_schema").fetchone()
            current = int(row[0]) if row else 0
            if current > SCHEMA_VERSION:
                raise _newer(current)
            if current >= migration.version or migration.version > target:
                continue
            for statement in migration.statements:
                con.execute(statement.encode())  # bytes: no client-side placeholders
            con.execute(
                "INSERT INTO central_schema(version, summary) VALUES (%s, %s)",
                (migration.version, migration.summary),
            )
    return before, schema_version(con)


def month_start(t: float) -> float:
    """The first second of ``t``'s month in UTC [s since the epoch].

    Examples
    --------
    >>> month_start(1_767_225_600.0 + 40 * 86400.0)  # 2026-02-10 → 2026-02-01
    1769904000.0
    """
    # floor first: fromtimestamp rounds to microseconds, so the last instant of a month
    # would land in the next one, where PostgreSQL's range partitions do not put it
    day = _dt.datetime.fromtimestamp(math.floor(t), _dt.UTC)
    return _dt.datetime(day.year, day.month, 1, tzinfo=_dt.UTC).timestamp()


def ensure_partitions(con: psycopg.Connection, parent: str, t_lo: float, t_hi: float) -> None:
    """The monthly partitions of ``parent`` covering plant times ``t_lo``..``t_hi`` [s UTC]."""
    con.execute("SELECT central_ensure_partitions(%s, %s, %s)", (parent, t_lo, t_hi))


def drop_old_partitions(
    con: psycopg.Connection, months: int, now: float | None = None
) -> list[str]:
    """Drop the monthly partitions older than ``months`` months; the names dropped.

    A partition goes when its whole month ended before the first of the month ``months``
    months before ``now`` (the server's clock by default, and never later than it) [s UTC]:
    with ``months=12`` on 2027-03-15, February 2026 and older go, March 2026 stays. The
    owner's job (``fuelid central retention``): ``PUBLIC`` may not execute the function.
    """
    when = math.inf if now is None else float(now)  # least(inf, now()) is the server's now
    with con.transaction():
        rows = con.execute("SELECT central_drop_partitions(%s, %s)", (int(months), when)).fetchall()
    return [str(r[0]) for r in rows]
