"""A reader's connection to the central store: one, shared, locked, reconnecting.

:class:`CentralDB` is one connection to the central PostgreSQL database shared by every central
loop a reader shows (the dashboard's; :func:`fuelid.central.connect`: libpq's own credentials,
never a password in the URL), behind one lock; a failure drops it and the next read
reconnects, at most every ``retry_s`` (:data:`RETRY_S` by default: a dead server must not cost
every page a connect timeout). :meth:`CentralDB.reading` runs several reads in one read-only
snapshot (``REPEATABLE READ``), so that a loop's status is one moment of the central store.
"""

from __future__ import annotations

import contextlib
import threading
import time as _time
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Any, TypeVar

from fuelid.central._connect import CentralError, connect, one_line, redact
from fuelid.central._schema import check_schema

if TYPE_CHECKING:
    import psycopg

__all__ = ["RETRY_S", "CentralDB"]

RETRY_S = 5.0
"""The default ``retry_s`` of :class:`CentralDB` [s]."""

T = TypeVar("T")


class CentralDB:
    """One connection to the central store (see the module docstring).

    Parameters
    ----------
    url : str
        The central store's libpq URL (``postgresql://dashboard@central.example/fuelid``).
    retry_s : float
        After a failure, reads fail at once with its reason for this long before reconnecting
        [s].
    """

    def __init__(self, url: str, retry_s: float = RETRY_S) -> None:
        self.url = url
        self.retry_s = float(retry_s)
        self.shown_url = redact(url)
        self._con: psycopg.Connection | None = None
        self._lock = threading.RLock()
        self.error: str | None = None
        self._failed_at = 0.0
        self._depth = 0

    def _connection(self) -> psycopg.Connection:
        if self._con is not None and not self._con.closed:
            return self._con
        if self.error is not None and _time.monotonic() - self._failed_at < self.retry_s:
            raise CentralError(self.error)
        try:
            con = connect(self.url, autocommit=True, application_name="fuelid dashboard")
            try:
                check_schema(con)
            except BaseException:
                con.close()
                raise
        except CentralError as error:
            self._failed(str(error))
            raise
        self._con = con
        self.error = None
        return con

    def _failed(self, reason: str) -> None:
        self.error = reason
        self._failed_at = _time.monotonic()
        if self._con is not None:
            with contextlib.suppress(Exception):  # a connection the server cut may not close
                self._con.close()
            self._con = None

    def _error(self, error: Exception) -> CentralError:
        import psycopg

        if isinstance(error, CentralError):
            return error
        reason = f"central store {self.shown_url}: {one_line(error)}"
        if isinstance(error, psycopg.OperationalError | psycopg.InterfaceError):
            self._failed(reason)  # the connection is gone: reconnect at the next read
        return CentralError(reason)

    def check(self) -> None:
        """Connect now (at start: an unreachable store is a one-line error there).

        Raises
        ------
        CentralError
            Unreachable, refused, or a schema other than this fuelid's.
        """
        with self._lock:
            self.error = None
            self._connection()

    @contextlib.contextmanager
    def reading(self) -> Iterator[None]:
        """Every read inside is one read-only snapshot of the central store."""
        import psycopg

        with self._lock:
            if self._depth:  # already in a snapshot: the outer one holds
                yield
                return
            try:
                con = self._connection()
                with con.transaction():
                    con.execute("SET TRANSACTION ISOLATION LEVEL REPEATABLE READ, READ ONLY")
                    self._depth = 1
                    try:
                        yield
                    finally:
                        self._depth = 0
            except psycopg.Error as error:
                raise self._error(error) from None

    def query(self, sql: str, args: Sequence[Any] | dict[str, Any] = ()) -> list[Any]:
        """The rows of one query (inside :meth:`reading`: in its snapshot)."""
        import psycopg

        with self._lock:
            try:
                return self._connection().execute(sql.encode(), args).fetchall()
            except psycopg.Error as error:
                raise self._error(error) from None

    def call(self, function: Callable[[psycopg.Connection], T]) -> T:
        """``function(connection)`` under the lock (a write: central requests)."""
        import psycopg

        with self._lock:
            try:
                return function(self._connection())
            except psycopg.Error as error:
                raise self._error(error) from None

    def close(self) -> None:
        """Close the connection."""
        with self._lock:
            if self._con is not None:
                with contextlib.suppress(Exception):
                    self._con.close()
                self._con = None
