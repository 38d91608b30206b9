"""Fixtures of the integration tests: a temporary PostgreSQL cluster for the central store.

``pg_cluster`` (session): one throw-away cluster per test session (per xdist worker) on a free
loopback port (:class:`support.postgres.PgCluster`), stopped and removed at the end; skipped
with the reason without PostgreSQL or psycopg, failed instead under CI. ``central_url`` gives
each test a database of its own (``CREATE DATABASE … TEMPLATE template0``) with the central
schema migrated.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import pytest

_databases = itertools.count()


@pytest.fixture(scope="session")
def pg_cluster() -> Iterator[object]:
    """A running PostgreSQL cluster (``support.postgres.PgCluster``)."""
    import importlib.util
    import os

    if importlib.util.find_spec("psycopg") is None:
        reason = "psycopg is not installed (the fleet extra: pip install 'fuelid[fleet]')"
        if os.environ.get("CI"):
            pytest.fail(f"{reason}; CI must run the central-store tests")
        pytest.skip(reason)
    from support.postgres import PgCluster, find_pg_bin

    cluster = PgCluster(find_pg_bin())
    try:
        cluster.start()
        yield cluster
    finally:
        cluster.close()


@pytest.fixture
def central_url(pg_cluster: object) -> str:
    """A fresh database of ``pg_cluster`` with the central schema; its URL."""
    from fuelid.central import connect, migrate
    from support.postgres import PgCluster

    assert isinstance(pg_cluster, PgCluster)
    url = pg_cluster.create_database(f"central_{next(_databases)}")
    with connect(url) as con:
        migrate(con)
    return url
