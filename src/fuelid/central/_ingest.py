"""The central side of a send: register the store, COPY into staging, upsert, liveness.

One batch is one PostgreSQL transaction (:func:`ingest_batch`): the store's identity is checked
(:func:`register_store`), each table's rows are copied (``COPY … FROM STDIN``) into a temporary
staging table of this session (``ON COMMIT DELETE ROWS``) and moved with ``INSERT … SELECT …
ON CONFLICT (store_uuid, id) DO UPDATE … WHERE the values differ``; the windows also fill
their KPI rows (:data:`~fuelid.central._schema.KPI_COLUMNS`). The upsert is idempotent: a row
sent twice with the same values changes nothing (not even a new row version), a row sent again
after a change takes its new values; so a batch resent after a crash between the central
commit and the site's deletion of its outbox entries leaves the central store as it was.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from fuelid.central._connect import CentralError
from fuelid.central._outbox import Batch, Identity
from fuelid.central._schema import KPI_COLUMNS, PARTITIONED, SITE_TABLES, SiteTable, month_start

if TYPE_CHECKING:
    import psycopg

__all__ = [
    "SITE_STATE_KEYS",
    "SiteView",
    "ingest_batch",
    "months_of",
    "register_store",
    "upsert_liveness",
]

SITE_STATE_KEYS = (
    "current_gains",
    "last_known_good",
    "write_held",
    "revert_requested",
    "tuned_for",
    "last_known_good_tuned_for",
    "plc_gains",  # the PLC's kc and ti as the recorder last read them: the gains in force
    # the exciter's record (fuelid.online.excitation._status.STATE_KEY): a central loop page
    # shows the test signal and offers its stop as the site's page does (issue 40)
    "excitation",
)
"""The site's ``online_state`` values the liveness row carries (``site_state``)."""


@dataclass(frozen=True)
class SiteView:
    """What the site tells the centre about itself at a send (the schema-2 liveness columns).

    Attributes
    ----------
    site_wall : float or None
        The site's wall clock when it wrote the row [s UTC].
    send_every_s : float or None
        The site's send interval [s] (None: syncs by hand, ``fuelid central sync``).
    newest_sample_time, newest_sample_wall : float or None
        The newest sample's plant time and the wall time it was written [s UTC].
    first_sample_time : float or None
        The oldest sample's plant time [s UTC].
    period_s : float or None
        The store's sampling period [s].
    schema_version : int or None
        The store's schema version.
    state : dict or None
        The site's ``online_state`` values of :data:`SITE_STATE_KEYS` (those set).
    """

    site_wall: float | None = None
    send_every_s: float | None = None
    newest_sample_time: float | None = None
    newest_sample_wall: float | None = None
    first_sample_time: float | None = None
    period_s: float | None = None
    schema_version: int | None = None
    state: dict[str, Any] | None = None


def register_store(pg: psycopg.Connection, ident: Identity) -> None:
    """Record the store (and its loop) on first sight; refuse a changed identity.

    Raises
    ------
    CentralError
        The store UUID is known under another loop id or tag-map hash, or the loop id is known
        with another tag-map hash (a second site configured with the same ``loop_id``?).
    """
    pg.execute(
        "INSERT INTO loops(loop_id, site_name, tag_map_hash) VALUES (%s, %s, %s) "
        "ON CONFLICT (loop_id) DO NOTHING",
        (ident.loop_id, ident.site_name, ident.tag_map_hash),
    )
    row = pg.execute(
        "SELECT tag_map_hash FROM loops WHERE loop_id = %s", (ident.loop_id,)
    ).fetchone()
    if row is not None and row[0] != ident.tag_map_hash:
        raise CentralError(
            f"loop {ident.loop_id!r} is known to the central store with tag map "
            f"{str(row[0])[:12]}, this store (UUID {ident.store_uuid}) has "
            f"{ident.tag_map_hash[:12]}: is [site] loop_id used by two sites?"
        )
    row = pg.execute(
        "INSERT INTO stores(store_uuid, loop_id, site_name, tag_map_hash) "
        "VALUES (%s, %s, %s, %s) ON CONFLICT (store_uuid) DO UPDATE SET last_seen = now() "
        "RETURNING loop_id, tag_map_hash",
        (ident.store_uuid, ident.loop_id, ident.site_name, ident.tag_map_hash),
    ).fetchone()
    assert row is not None
    if (row[0], row[1]) != (ident.loop_id, ident.tag_map_hash):
        raise CentralError(
            f"store {ident.store_uuid} is known to the central store as loop {row[0]!r} "
            f"(tag map {str(row[1])[:12]}), not {ident.loop_id!r} (tag map "
            f"{ident.tag_map_hash[:12]}): refused"
        )


def _stage_name(table: SiteTable) -> str:
    return f"stage_{table.central}"


def _create_stage(pg: psycopg.Connection, table: SiteTable) -> None:
    cols = ", ".join(
        f"{name} {'text' if kind == 'jsonb' else kind}"
        for name, (_, kind) in zip(table.names, table.columns, strict=True)
    )
    pg.execute(
        f"CREATE TEMP TABLE IF NOT EXISTS {_stage_name(table)} ({cols}) ON COMMIT DELETE ROWS"
    )


def _upsert_sql(target: str, key: str, columns: Sequence[str], select: str) -> str:
    """INSERT … SELECT … ON CONFLICT DO UPDATE only where a value differs."""
    names = ", ".join(columns)
    sets = ", ".join(f"{c} = EXCLUDED.{c}" for c in columns)
    old = ", ".join(f"{target}.{c}" for c in columns)
    new = ", ".join(f"EXCLUDED.{c}" for c in columns)
    return (
        f"INSERT INTO {target} (store_uuid, loop_id, {names}) {select} "
        f"ON CONFLICT ({key}) DO UPDATE SET {sets}, synced = now() "
        f"WHERE ({old}) IS DISTINCT FROM ({new})"
    )


def _table_sql(table: SiteTable) -> str:
    exprs = [
        f"{name}::jsonb" if kind == "jsonb" else name
        for name, (_, kind) in zip(table.names, table.columns, strict=True)
    ]
    columns = list(table.names)
    if table.central == "proposals":  # the history's length: what a request's sender saw
        columns.append("history_len")
        exprs.append("coalesce(jsonb_array_length(detail::jsonb -> 'history'), 0)")
    key = "store_uuid, id, time" if table.central in PARTITIONED else "store_uuid, id"
    select = f"SELECT %(uuid)s, %(loop)s, {', '.join(exprs)} FROM {_stage_name(table)}"
    return _upsert_sql(table.central, key, columns, select)


def _kpi_sql() -> str:
    columns = ["id", "time", "t_from", "t_to", "accepted", "t_fuel"]
    columns += [name for name, _, _ in KPI_COLUMNS]
    exprs = ["id", "time", "t_from", "t_to", "accepted", "t_fuel"]
    exprs += [expr for _, _, expr in KPI_COLUMNS]
    # MATERIALIZED: each detail parsed once (a plain subquery is inlined and the cast run
    # for every KPI expression: nine parses of a 7 kB JSON per window)
    select = (
        "WITH s AS MATERIALIZED (SELECT *, detail::jsonb AS d FROM stage_windows) "
        f"SELECT %(uuid)s, %(loop)s, {', '.join(exprs)} FROM s"
    )
    return _upsert_sql("kpis", "store_uuid, id, time", columns, select)


def _storable(row: tuple[Any, ...]) -> tuple[Any, ...]:
    r"""The row with NUL characters (and JSON's ``\u0000``) replaced by U+FFFD.

    PostgreSQL refuses NUL in text and ``\u0000`` in jsonb; a PLC string carrying one must not
    block the outbox (a batch that can never commit would be resent for ever).

    Examples
    --------
    >>> _storable((1, "a\x00b", '{"s": "\\u0000"}', None))
    (1, 'a�b', '{"s": "\\ufffd"}', None)
    """
    if not any(isinstance(v, str) and ("\x00" in v or "\\u0000" in v) for v in row):
        return row
    return tuple(
        v.replace("\x00", "\ufffd").replace("\\u0000", "\\ufffd") if isinstance(v, str) else v
        for v in row
    )


def months_of(rows: Sequence[tuple[Any, ...]]) -> set[float]:
    """The months (their first second [s UTC]) of the rows' plant ``time`` (column 1)."""
    return {month_start(float(r[1])) for r in rows}


def ingest_batch(pg: psycopg.Connection, ident: Identity, batch: Batch) -> int:
    """Send one batch in one transaction (the partitions exist already); rows sent.

    Parameters
    ----------
    pg : psycopg.Connection
        A connection (not autocommit) to a central store of the current schema.
    ident : Identity
        The sending store.
    batch : Batch
        :func:`~fuelid.central._outbox.read_batch`.
    """
    params = {"uuid": ident.store_uuid, "loop": ident.loop_id}
    sent = 0
    with pg.transaction():
        register_store(pg, ident)
        for site_name, rows in batch.rows.items():
            if not rows:
                continue
            table = SITE_TABLES[site_name]
            _create_stage(pg, table)
            with pg.cursor() as cur:
                with cur.copy(
                    f"COPY {_stage_name(table)} ({', '.join(table.names)}) FROM STDIN"
                ) as copy:
                    for row in rows:
                        copy.write_row(_storable(row))
                if table.central in PARTITIONED:
                    # a row's time never changes at a site; if it did, its old copy would stay
                    # in another partition under the same (store_uuid, id)
                    for target in ("windows", "kpis"):
                        cur.execute(
                            f"DELETE FROM {target} t USING stage_windows s WHERE "
                            "t.store_uuid = %(uuid)s AND t.id = s.id AND t.time <> s.time",
                            params,
                        )
                cur.execute(_table_sql(table).encode(), params)
                if table.central == "windows":
                    cur.execute(_kpi_sql().encode(), params)
            sent += len(rows)
    return sent


def upsert_liveness(
    pg: psycopg.Connection,
    ident: Identity,
    service: dict[str, Any] | None,
    backlog_rows: int,
    backlog_oldest_wall: float | None,
    last_send_wall: float | None,
    site: SiteView | None = None,
) -> None:
    """The store's liveness row: its service record, its backlog and its view (one transaction).

    ``site`` (schema 2) carries what a central reader needs to judge the loop as its own store
    would (:class:`SiteView`); None leaves those columns as they were.
    """
    from psycopg.types.json import Jsonb

    view = site or SiteView()
    keep = site is None  # an older caller: the version-2 columns are left as they were
    extra = (
        "site_wall",
        "send_every_s",
        "newest_sample_time",
        "newest_sample_wall",
        "first_sample_time",
        "period_s",
        "schema_version",
        "site_state",
    )
    sets = ", ".join(f"{c} = liveness.{c}" if keep else f"{c} = EXCLUDED.{c}" for c in extra)
    with pg.transaction():
        pg.execute(
            "INSERT INTO liveness(store_uuid, loop_id, service, backlog_rows, "
            f"backlog_oldest_wall, last_send_wall, {', '.join(extra)}, updated) "
            "VALUES (%s, %s, %s, %s, %s, %s, %s, %s, %s, %s, %s, %s, %s, %s, now()) "
            "ON CONFLICT (store_uuid) DO UPDATE SET loop_id = EXCLUDED.loop_id, "
            "service = EXCLUDED.service, backlog_rows = EXCLUDED.backlog_rows, "
            "backlog_oldest_wall = EXCLUDED.backlog_oldest_wall, "
            "last_send_wall = coalesce(EXCLUDED.last_send_wall, liveness.last_send_wall), "
            f"{sets}, updated = now()",
            (
                ident.store_uuid,
                ident.loop_id,
                None if service is None else Jsonb(service),
                int(backlog_rows),
                backlog_oldest_wall,
                last_send_wall,
                view.site_wall,
                view.send_every_s,
                view.newest_sample_time,
                view.newest_sample_wall,
                view.first_sample_time,
                view.period_s,
                view.schema_version,
                None if view.state is None else Jsonb(view.state),
            ),
        )
