"""The dashboard's users file: who may log in, with which role, and the SHA-256 of their token.

A user logs in with a name and a random token that :meth:`UsersFile.add` (or
:meth:`UsersFile.rotate`) returns once: only the token's SHA-256 is stored, so the file never
holds anything a person could log in with. The file is JSON::

    {"format": "fuelid-users", "version": 1,
     "users": {"ana": {"role": "engineer", "sha256": "…64 hex…",
                       "created": 1795766400.0, "rotated": null}}}

``created`` and ``rotated`` are wall-clock times [s since 1970-01-01 UTC]. The file is written
atomically (a temporary file in the same folder, flushed to disk, then renamed over the old one)
with mode 0600, and re-read whenever it changes on disk, so an administrator can add, remove or
rotate a user while the dashboard runs. Only the standard library is used here: the command
line manages users without the ``dashboard`` extra.
"""

from __future__ import annotations

import contextlib
import hashlib
import hmac
import json
import os
import re
import secrets
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fuelid.errors import ConfigError

USERS_FORMAT = "fuelid-users"
"""The ``format`` key of a users file."""

USERS_VERSION = 1
"""The ``version`` key of a users file this code reads and writes."""

ROLES = ("viewer", "engineer")
"""The roles: a viewer sees every page, an engineer also approves, rejects and reverts."""

NAME_PATTERN = re.compile(r"[A-Za-z0-9._-]{1,64}")
"""A user name: 1 to 64 letters, digits, dots, underscores or hyphens."""

TOKEN_BYTES = 32
"""Random bytes in a token: 256 bits, 43 URL-safe characters."""

FILE_MODE = 0o600
"""The users file's permissions: read and written by its owner only."""

_DUMMY_SHA256 = hashlib.sha256(b"fuelid: no such user").hexdigest()
_HEX64 = re.compile(r"[0-9a-f]{64}")


@dataclass(frozen=True)
class User:
    """A logged-in person: the name and the role (``"viewer"`` or ``"engineer"``)."""

    name: str
    role: str

    @property
    def is_engineer(self) -> bool:
        """True when this user may approve, reject and revert."""
        return self.role == "engineer"


@dataclass(frozen=True)
class UserRecord:
    """One entry of the users file (``created``, ``rotated``: wall-clock [s UTC])."""

    name: str
    role: str
    sha256: str
    created: float
    rotated: float | None


def token_sha256(token: str) -> str:
    """The stored form of a token: the hex SHA-256 of its UTF-8 bytes."""
    return hashlib.sha256(token.encode("utf-8", "surrogatepass")).hexdigest()


def check_name(name: str) -> str:
    """Return ``name`` if it is a valid user name, else raise :class:`ConfigError`."""
    if not NAME_PATTERN.fullmatch(name):
        raise ConfigError(
            f"user name {name!r} is not allowed: use 1 to 64 letters, digits, '.', '_' or '-'"
        )
    return name


def check_role(role: str) -> str:
    """Return ``role`` if it is a known role, else raise :class:`ConfigError`."""
    if role not in ROLES:
        raise ConfigError(f"role {role!r} is not known: use one of {', '.join(ROLES)}")
    return role


class UsersFile:
    """The users file at ``path``: read, checked, cached, and re-read when it changes on disk.

    Parameters
    ----------
    path
        The JSON file. :meth:`add` creates it when it is missing; every other method refuses a
        missing file with :class:`~fuelid.errors.ConfigError`.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self._lock = threading.RLock()
        self._records: dict[str, UserRecord] = {}
        self._stamp: tuple[int, int, int] | None = None

    # reading ---------------------------------------------------------------------------------

    def load(self) -> dict[str, UserRecord]:
        """Read and check the file now; return its users by name.

        Raises
        ------
        ConfigError
            The file is missing or unreadable, not JSON, not a fuelid users file, of another
            version, or has a bad name, role, digest or time.
        """
        with self._lock:
            stamp = self._stat()
            try:
                text = self.path.read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError) as exc:
                raise ConfigError(f"users file {self.path}: cannot read it ({exc})") from None
            self._records = _parse(text, self.path)
            self._stamp = stamp
            return dict(self._records)

    def _stat(self) -> tuple[int, int, int]:
        try:
            st = self.path.stat()
        except FileNotFoundError:
            raise ConfigError(
                f"users file {self.path} does not exist: create it with "
                "`fuelid dashboard user add NAME --role viewer|engineer`"
            ) from None
        except OSError as exc:
            raise ConfigError(f"users file {self.path}: cannot read it ({exc})") from None
        # a replace makes a new inode: a change within the clock's resolution is still seen
        return (st.st_mtime_ns, st.st_size, st.st_ino)

    def _current(self) -> dict[str, UserRecord]:
        """The users, re-read when the file changed since the last read."""
        with self._lock:
            if self._stamp is None or self._stat() != self._stamp:
                self.load()
            return self._records

    def names(self) -> list[str]:
        """The user names, sorted."""
        return sorted(self._current())

    def records(self) -> list[UserRecord]:
        """Every user's entry, sorted by name."""
        users = self._current()
        return [users[name] for name in sorted(users)]

    def lookup(self, name: str) -> UserRecord | None:
        """The entry of ``name``, or None when there is no such user."""
        return self._current().get(name)

    def verify(self, name: str, token: str) -> User | None:
        """The user whose name and token these are, or None.

        The token's SHA-256 is compared with :func:`hmac.compare_digest`; an unknown name is
        compared against a dummy digest all the same, so the time taken does not tell which
        names exist.
        """
        record = self._current().get(name)
        stored = record.sha256 if record is not None else _DUMMY_SHA256
        match = hmac.compare_digest(token_sha256(token), stored)
        if record is None or not match:
            return None
        return User(record.name, record.role)

    # writing ---------------------------------------------------------------------------------

    def add(self, name: str, role: str) -> str:
        """Add a user; return their new token (shown once: only its SHA-256 is stored)."""
        check_name(name)
        check_role(role)
        with self._lock:
            users = dict(self._current()) if self.path.exists() else {}
            if name in users:
                raise ConfigError(
                    f"user {name!r} already exists in {self.path}: rotate their token or remove "
                    "them first"
                )
            token = secrets.token_urlsafe(TOKEN_BYTES)
            users[name] = UserRecord(name, role, token_sha256(token), time.time(), None)
            self._write(users)
            return token

    def remove(self, name: str) -> None:
        """Remove a user: their token no longer logs in."""
        with self._lock:
            users = dict(self._current())
            if name not in users:
                raise ConfigError(f"no user {name!r} in {self.path}")
            del users[name]
            self._write(users)

    def rotate(self, name: str) -> str:
        """Give a user a new token and return it; the old one no longer logs in."""
        with self._lock:
            users = dict(self._current())
            old = users.get(name)
            if old is None:
                raise ConfigError(f"no user {name!r} in {self.path}")
            token = secrets.token_urlsafe(TOKEN_BYTES)
            users[name] = UserRecord(name, old.role, token_sha256(token), old.created, time.time())
            self._write(users)
            return token

    def _write(self, users: dict[str, UserRecord]) -> None:
        """Replace the file atomically: the old one stays whole if anything fails."""
        document = {
            "format": USERS_FORMAT,
            "version": USERS_VERSION,
            "users": {
                name: {
                    "role": record.role,
                    "sha256": record.sha256,
                    "created": record.created,
                    "rotated": record.rotated,
                }
                for name, record in sorted(users.items())
            },
        }
        text = json.dumps(document, indent=2) + "\n"
        folder = self.path.parent
        if not folder.is_dir():
            raise ConfigError(f"users file {self.path}: folder {folder} does not exist")
        tmp_name: str | None = None
        try:
            fd, tmp_name = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".tmp", dir=folder)
            with os.fdopen(fd, "w", encoding="utf-8") as handle:
                os.chmod(tmp_name, FILE_MODE)
                handle.write(text)
                handle.flush()
                os.fsync(handle.fileno())
            os.replace(tmp_name, self.path)
            tmp_name = None
        except OSError as exc:
            raise ConfigError(f"users file {self.path}: cannot write it ({exc})") from None
        finally:
            if tmp_name is not None:
                with contextlib.suppress(OSError):
                    os.unlink(tmp_name)
        with contextlib.suppress(OSError):  # the rename is done; this only hastens it to disk
            _fsync_folder(folder)
        self._records = dict(users)
        self._stamp = self._stat()


def _fsync_folder(folder: Path) -> None:
    """Flush the folder's entry of the renamed file to disk (POSIX; elsewhere a no-op)."""
    if os.name != "posix":
        return
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _parse(text: str, path: Path) -> dict[str, UserRecord]:
    """Check a users file's text and return its users; any fault is a one-line ConfigError."""

    def bad(reason: str) -> ConfigError:
        return ConfigError(f"users file {path}: {reason}")

    try:
        document: Any = json.loads(text)
    except ValueError as exc:
        raise bad(f"not JSON ({exc})") from None
    if not isinstance(document, dict) or document.get("format") != USERS_FORMAT:
        raise bad(f'not a fuelid users file (no "format": "{USERS_FORMAT}")')
    if document.get("version") != USERS_VERSION:
        raise bad(
            f"version {document.get('version')!r} is not known: this fuelid reads version "
            f"{USERS_VERSION}"
        )
    entries = document.get("users")
    if not isinstance(entries, dict):
        raise bad('"users" must be an object of name: entry')
    users: dict[str, UserRecord] = {}
    for name, entry in entries.items():
        if not NAME_PATTERN.fullmatch(name):
            raise bad(f"user name {name!r} is not allowed")
        if not isinstance(entry, dict):
            raise bad(f"user {name!r}: the entry must be an object")
        role = entry.get("role")
        if role not in ROLES:
            raise bad(f"user {name!r}: role {role!r} is not known (use one of {', '.join(ROLES)})")
        digest = entry.get("sha256")
        if not isinstance(digest, str) or not _HEX64.fullmatch(digest):
            raise bad(f"user {name!r}: sha256 must be 64 lower-case hex digits")
        created = _time(entry.get("created"))
        rotated = entry.get("rotated")
        if created is None or not (rotated is None or _time(rotated) is not None):
            raise bad(f"user {name!r}: created and rotated must be times in s (rotated or null)")
        users[name] = UserRecord(name, role, digest, created, _time(rotated))
    return users


def _time(value: object) -> float | None:
    """A wall-clock time [s] from JSON, or None when it is not a finite number ≥ 0."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    t = float(value)
    return t if 0.0 <= t < float("inf") else None
