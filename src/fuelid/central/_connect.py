"""A connection to the central store from its URL, with libpq's own credentials.

The URL (``[central] url``, ``--url``) names the server, the database and the role:
``postgresql://site_line_a@central.example/fuelid?sslmode=verify-full``. The password is never
in it: libpq reads ``PGPASSWORD``, the password file (``~/.pgpass`` or ``PGPASSFILE``) or a
service file (``postgresql:///?service=fuelid``, ``~/.pg_service.conf`` or ``PGSERVICEFILE``),
and TLS follows ``sslmode`` (``verify-full`` with ``sslrootcert``). A half-open connection (a
router that dropped it silently) must not hold a sync cycle, or the service's stop, for the
kernel's ~15 minutes of retransmissions: unless the URL sets them, TCP keepalives
(:data:`KEEPALIVES`: a dead peer noticed within about a minute), ``tcp_user_timeout`` and a
server-side ``statement_timeout`` (:data:`STATEMENT_TIMEOUT_S`) bound every wait. A failure
becomes one line, :class:`CentralError`, naming the server without any password (a password
typed into a URL on the command line is masked before the URL is printed).
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

from fuelid.errors import FuelidError

if TYPE_CHECKING:
    import psycopg

__all__ = [
    "CONNECT_TIMEOUT_S",
    "KEEPALIVES",
    "STATEMENT_TIMEOUT_S",
    "CentralError",
    "connect",
    "connect_defaults",
    "one_line",
    "redact",
]

CONNECT_TIMEOUT_S = 10
"""libpq's ``connect_timeout`` unless the URL sets one [s]."""
KEEPALIVES: dict[str, int] = {
    "keepalives": 1,
    "keepalives_idle": 30,  # [s] idle before the first probe
    "keepalives_interval": 10,  # [s] between probes
    "keepalives_count": 3,  # unanswered probes: the connection is dead (30 + 3 × 10 = 60 s)
    "tcp_user_timeout": 60_000,  # [ms] unacknowledged data: the connection is dead
}
"""libpq's TCP settings, each unless the URL sets it."""
STATEMENT_TIMEOUT_S = 300
"""The server cancels a statement running longer [s] (a batch of 5000 windows takes about
a second), unless the URL sets ``options``."""


class CentralError(FuelidError):
    """The central store cannot be reached or used (the reason in one line)."""


def redact(url: str) -> str:
    """The URL with any password masked (``user:***@``, ``password=***``).

    Examples
    --------
    >>> redact("postgresql://site:s3cret@db.example:5432/fuelid?password=x&sslmode=require")
    'postgresql://site:***@db.example:5432/fuelid?password=***&sslmode=require'
    """
    url = re.sub(r"(://[^:/@?]*:)[^@/?]*@", r"\1***@", url)
    return re.sub(r"(?i)(password=)[^&\s]*", r"\1***", url)


def one_line(error: BaseException) -> str:
    """A psycopg error as one line (libpq's messages run over several)."""
    text = " ".join(str(error).split())
    return text or type(error).__name__


def connect_defaults(url: str) -> dict[str, str | int]:
    """The connection settings :func:`connect` adds: those the URL does not set itself.

    ``connect_timeout`` (:data:`CONNECT_TIMEOUT_S`), :data:`KEEPALIVES` and ``options`` with
    the ``statement_timeout`` (:data:`STATEMENT_TIMEOUT_S`); a URL's own ``options`` is kept
    whole (libpq takes one ``options``).

    Examples
    --------
    >>> sorted(connect_defaults("postgresql://h/db?options=-c%20x%3D1&keepalives_idle=5"))
    ['connect_timeout', 'keepalives', 'keepalives_count', 'keepalives_interval', 'tcp_user_timeout']
    >>> connect_defaults("postgresql://h/db")["options"]
    '-c statement_timeout=300s'
    """
    out: dict[str, str | int] = {}
    if "connect_timeout" not in url:
        out["connect_timeout"] = CONNECT_TIMEOUT_S
    for key, value in KEEPALIVES.items():
        if not re.search(rf"\b{key}=", url):  # keepalives= is no prefix of keepalives_idle=
            out[key] = value
    if "options=" not in url:
        out["options"] = f"-c statement_timeout={STATEMENT_TIMEOUT_S}s"
    return out


def connect(
    url: str, *, autocommit: bool = False, application_name: str = "fuelid"
) -> psycopg.Connection:
    """Connect to the central store.

    Parameters
    ----------
    url : str
        A libpq URL (``postgresql://…``) or connection string; no password needed in it.
    autocommit : bool
        Every statement its own transaction (False: psycopg's default, explicit commits).
    application_name : str
        Shown in ``pg_stat_activity`` (``fuelid sync line-a``).

    Raises
    ------
    CentralError
        psycopg is missing, the URL is malformed, the server is unreachable or refuses the role.
    """
    try:
        import psycopg
    except ImportError:
        raise CentralError("the central store needs psycopg: pip install 'fuelid[fleet]'") from None
    if not re.match(r"^postgres(ql)?://", url) and "=" not in url:
        raise CentralError(f"central url {redact(url)!r}: not a postgresql:// URL")
    extra: dict[str, str | int] = {"application_name": application_name}
    extra.update(connect_defaults(url))
    try:
        return psycopg.connect(url, autocommit=autocommit, **extra)  # type: ignore[arg-type]
    except psycopg.Error as error:
        raise CentralError(f"central store {redact(url)}: {one_line(error)}") from None
