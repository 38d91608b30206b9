"""Re-identification results in the central store: a loop-day at a time, whole or not at all.

``fuelid reidentify … --central URL`` sends, after its loop-days are done, every loop-day of its
selection that has a result (computed now or by an earlier run) and each loop's tracking and
summary. A result set is known by its **run id**: the SHA-256 of what the loop's results were
made with (the ``[online]`` settings, the sampling, the plant file's hash: the fingerprint
``RESULT/settings/<loop_id>.json`` holds), so the same archive analysed with the same settings
lands on the same rows (re-identification is deterministic), and other settings on other rows,
side by side with the live service's windows.

Tables (central migration 3)::

    reidentify_runs(run_id, loop_id, fingerprint jsonb, summary jsonb, tracking jsonb, updated)
        PRIMARY KEY (run_id, loop_id)
    reidentified(run_id, loop_id, date, t_from, t_to, accepted, reason, mode, method,
                 k, t, t2, t_f, delay, se_k, se_t, se_t2, se_t_f, se_delay, model_order,
                 fit_percent, t_fuel, u_mean, plant_k, ok_share, time_in_auto,
                 time_at_limits, oscillating, harris_index, iae_per_unit_step_s,
                 gates jsonb, health jsonb)
        PRIMARY KEY (run_id, loop_id, t_to); INDEX (loop_id, t_to)

Times are plant time [s UTC]; K in (L/min)/V, T, T2, T_f and the delay in s, temperatures in
°C, shares in [0, 1]. A loop-day is replaced in one transaction (its rows deleted, then copied
in), so a retried or killed send leaves the day as it was or whole, never twice.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from fuelid.central._connect import CentralError

if TYPE_CHECKING:
    import psycopg

__all__ = [
    "COLUMNS",
    "TABLES",
    "register_run",
    "send_loop_day",
]

COLUMNS: tuple[tuple[str, str, str], ...] = (
    # (result column, central column, PostgreSQL type)
    ("t_from", "t_from", "double precision"),
    ("t_to", "t_to", "double precision"),
    ("accepted", "accepted", "boolean"),
    ("reason", "reason", "text"),
    ("mode", "mode", "text"),
    ("method", "method", "text"),
    ("K", "k", "double precision"),
    ("T", "t", "double precision"),
    ("T2", "t2", "double precision"),
    ("T_f", "t_f", "double precision"),
    ("delay", "delay", "double precision"),
    ("se_K", "se_k", "double precision"),
    ("se_T", "se_t", "double precision"),
    ("se_T2", "se_t2", "double precision"),
    ("se_T_f", "se_t_f", "double precision"),
    ("se_delay", "se_delay", "double precision"),
    ("order", "model_order", "bigint"),
    ("fit_percent", "fit_percent", "double precision"),
    ("T_fuel", "t_fuel", "double precision"),
    ("u_mean", "u_mean", "double precision"),
    ("plant_K", "plant_k", "double precision"),
    ("ok_share", "ok_share", "double precision"),
    ("time_in_auto", "time_in_auto", "double precision"),
    ("time_at_limits", "time_at_limits", "double precision"),
    ("oscillating", "oscillating", "boolean"),
    ("harris_index", "harris_index", "double precision"),
    ("iae_per_unit_step_s", "iae_per_unit_step_s", "double precision"),
    ("gates", "gates", "jsonb"),
    ("health", "health", "jsonb"),
)
"""The result columns sent, their central names and types (the rest stay in the Parquet)."""

_COLUMN_SQL = ",\n        ".join(f"{name} {kind}" for _, name, kind in COLUMNS)

TABLES: tuple[str, ...] = (
    """CREATE TABLE reidentify_runs(
        run_id text NOT NULL, loop_id text NOT NULL, fingerprint jsonb NOT NULL,
        summary jsonb, tracking jsonb, updated timestamptz NOT NULL DEFAULT now(),
        PRIMARY KEY (run_id, loop_id))""",
    f"""CREATE TABLE reidentified(
        run_id text NOT NULL, loop_id text NOT NULL, date date NOT NULL,
        {_COLUMN_SQL},
        PRIMARY KEY (run_id, loop_id, t_to))""",
    "CREATE INDEX reidentified_loop ON reidentified(loop_id, t_to)",
    "CREATE INDEX reidentified_day ON reidentified(run_id, loop_id, date)",
)
"""The statements of central migration 3."""


def register_run(
    con: psycopg.Connection,
    run_id: str,
    loop_id: str,
    fingerprint: Mapping[str, Any],
    summary: Mapping[str, Any] | None = None,
    tracking: Mapping[str, Any] | None = None,
) -> None:
    """Record (or update) a loop's result set: what it was made with, its summary (committed)."""
    from psycopg.types.json import Jsonb

    with con.transaction():
        con.execute(
            "INSERT INTO reidentify_runs(run_id, loop_id, fingerprint, summary, tracking) "
            "VALUES (%s, %s, %s, %s, %s) ON CONFLICT (run_id, loop_id) DO UPDATE SET "
            "fingerprint = EXCLUDED.fingerprint, summary = EXCLUDED.summary, "
            "tracking = EXCLUDED.tracking, updated = now()",
            (
                run_id,
                loop_id,
                Jsonb(dict(fingerprint)),
                None if summary is None else Jsonb(dict(summary)),
                None if tracking is None else Jsonb(dict(tracking)),
            ),
        )


def _value(kind: str, value: Any) -> Any:
    if value is None:
        return None
    if kind == "jsonb":  # the result files hold JSON text; keep it as it is
        json.loads(value)  # a broken JSON text must fail here, not half-way through a COPY
        return value
    if kind == "double precision" and value != value:  # NaN: missing, as in the Parquet
        return None
    return value


def send_loop_day(
    con: psycopg.Connection,
    run_id: str,
    loop_id: str,
    date: str,
    rows: Sequence[Mapping[str, Any]],
) -> int:
    """Replace one loop-day's rows of a result set, in one transaction; the rows sent.

    ``rows`` are result rows keyed by the result columns of :data:`COLUMNS` (the Parquet's).
    """
    names = ", ".join(["run_id", "loop_id", "date", *(name for _, name, _ in COLUMNS)])
    try:
        with con.transaction():
            con.execute(
                "DELETE FROM reidentified WHERE run_id = %s AND loop_id = %s AND date = %s",
                (run_id, loop_id, date),
            )
            with con.cursor().copy(f"COPY reidentified ({names}) FROM STDIN") as copy:
                for row in rows:
                    copy.write_row(
                        (
                            run_id,
                            loop_id,
                            date,
                            *(_value(kind, row.get(key)) for key, _, kind in COLUMNS),
                        )
                    )
    except Exception as error:
        import psycopg

        if isinstance(error, psycopg.Error):
            raise CentralError(
                f"central store: re-identification results of {loop_id} {date} not sent "
                f"({' '.join(str(error).split())})"
            ) from None
        raise
    return len(rows)
