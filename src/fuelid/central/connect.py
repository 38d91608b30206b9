"""A connection to the central store from its URL, with libpq's own credentials.

The URL (``[central] url``, ``--url``) names the server, the database and the role:
``postgresql://site_line_a@central.example/fuelid?sslmode=verify-full``. The password is never
in it: libpq reads ``PGPASSWORD``, the password file (``~/.pgpass`` or ``PGPASSFILE``) or a
service file (``postgresql:///?service=fuelid``, ``~/.pg_service.conf`` or ``PGSERVICEFILE``),
and TLS follows ``sslmode`` (``verify-full`` with ``sslrootcert``). A failure becomes one line,
:class:`CentralError`, naming the server without any password (a password typed into a URL on
the command line is masked before the URL is printed).
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

from fuelid.errors import FuelidError

if TYPE_CHECKING:
    import psycopg

__all__ = ["CONNECT_TIMEOUT_S", "CentralError", "connect", "one_line", "redact"]

CONNECT_TIMEOUT_S = 10
"""libpq's ``connect_timeout`` unless the URL sets one [s]."""


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
    if "connect_timeout" not in url:
        extra["connect_timeout"] = CONNECT_TIMEOUT_S
    try:
        return psycopg.connect(url, autocommit=autocommit, **extra)  # type: ignore[arg-type]
    except psycopg.Error as error:
        raise CentralError(f"central store {redact(url)}: {one_line(error)}") from None
