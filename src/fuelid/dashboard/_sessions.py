"""Logged-in browsers and the limit on failed logins, in the dashboard's memory.

:class:`Sessions` keeps the sessions (a restart logs everybody out): one ends after
:data:`SESSION_IDLE_S` without a request, and at the latest :data:`SESSION_MAX_S` after the
login. :class:`LoginLimiter` allows at most :data:`LOGIN_MAX_FAILURES` failed logins in
:data:`LOGIN_WINDOW_S` per client address and name together, and :data:`LOGIN_MAX_SHARED` per
address and per name alone. Both take an injectable monotonic clock (tests).
"""

from __future__ import annotations

import secrets
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from fuelid.dashboard._users import User

__all__ = [
    "LOGIN_MAX_FAILURES",
    "LOGIN_MAX_SHARED",
    "LOGIN_WINDOW_S",
    "SESSION_IDLE_S",
    "SESSION_MAX_S",
    "LoginLimiter",
    "Session",
    "Sessions",
]

SESSION_IDLE_S = 12 * 3600.0
"""A session ends after this long without a request [s]: 12 h."""
SESSION_MAX_S = 7 * 24 * 3600.0
"""A session ends this long after its login, however busy [s]: 7 days."""
LOGIN_MAX_FAILURES = 5
"""Failed logins allowed per client address and name together within :data:`LOGIN_WINDOW_S`."""
LOGIN_MAX_SHARED = 4 * LOGIN_MAX_FAILURES
"""Failed logins allowed per client address (whatever the names), and per name (from any
address), within :data:`LOGIN_WINDOW_S`: 20. Four people sharing a console (or a reverse proxy
without ``X-Forwarded-For``) can each mistype their token up to the limit of their own name and
the others can still log in; a guesser gets 20 tries per 5 minutes per address, 5,760 a day,
against a token of 256 random bits (``secrets.token_urlsafe(32)``)."""
LOGIN_WINDOW_S = 300.0
"""The window over which failed logins are counted [s]: 5 minutes."""


# ------------------------------------------------------------------------------------------------
# sessions


@dataclass
class Session:
    """A logged-in browser. ``created`` and ``last_seen`` are on the monotonic clock [s]."""

    sid: str
    user: str
    role: str
    csrf: str
    created: float
    last_seen: float
    token_sha256: str = ""
    """The digest of the token the user logged in with: a rotated token ends the session."""

    def as_user(self) -> User:
        """The session's user."""
        return User(self.user, self.role)


class Sessions:
    """Sessions in memory, by session id; lost when the dashboard restarts.

    Parameters
    ----------
    clock
        A monotonic clock [s]; :func:`time.monotonic` unless a test gives another.
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._lock = threading.Lock()
        self._sessions: dict[str, Session] = {}

    def create(self, user: User, token_sha256: str = "") -> Session:
        """Start a session for ``user`` with a new random id and CSRF token."""
        now = self._clock()
        session = Session(
            sid=secrets.token_urlsafe(32),
            user=user.name,
            role=user.role,
            csrf=secrets.token_urlsafe(32),
            created=now,
            last_seen=now,
            token_sha256=token_sha256,
        )
        with self._lock:
            self._prune(now)
            self._sessions[session.sid] = session
        return session

    def get(self, sid: str | None) -> Session | None:
        """The live session of ``sid`` (its ``last_seen`` set to now), or None."""
        if not sid:
            return None
        now = self._clock()
        with self._lock:
            session = self._sessions.get(sid)
            if session is None:
                return None
            if self._expired(session, now):
                del self._sessions[sid]
                return None
            session.last_seen = now
            return session

    def drop(self, sid: str) -> None:
        """End a session (log out); an unknown id is ignored."""
        with self._lock:
            self._sessions.pop(sid, None)

    def __len__(self) -> int:
        with self._lock:
            return len(self._sessions)

    @staticmethod
    def _expired(session: Session, now: float) -> bool:
        return now - session.last_seen > SESSION_IDLE_S or now - session.created > SESSION_MAX_S

    def _prune(self, now: float) -> None:
        for sid in [s for s, session in self._sessions.items() if self._expired(session, now)]:
            del self._sessions[sid]


# ------------------------------------------------------------------------------------------------
# failed logins


class LoginLimiter:
    """Failed logins counted over a sliding window, per (address, name), per address, per name.

    An attempt from an address for a name is refused until the oldest counted failure leaves
    the window when any of these has its limit within :data:`LOGIN_WINDOW_S`:

    - that address for that name: ``max_failures`` (one person's typos stop only their name at
      their console);
    - that address, whatever the names: ``max_shared`` (a guesser trying names is stopped);
    - that name, from any address: ``max_shared`` (a guess spread over addresses is stopped).

    A success clears its own (address, name) count only: a guesser cannot reset an address's
    count with an account of their own.

    Parameters
    ----------
    clock
        A monotonic clock [s]; :func:`time.monotonic` unless a test gives another.
    max_failures, window_s
        The limit per (address, name) [failures] and the window [s].
    max_shared
        The limit per address and per name [failures].
    """

    def __init__(
        self,
        clock: Callable[[], float] = time.monotonic,
        max_failures: int = LOGIN_MAX_FAILURES,
        window_s: float = LOGIN_WINDOW_S,
        max_shared: int = LOGIN_MAX_SHARED,
    ) -> None:
        self._clock = clock
        self.max_failures = max_failures
        self.max_shared = max_shared
        self.window_s = window_s
        self._lock = threading.Lock()
        self._failures: dict[tuple[str, ...], deque[float]] = {}

    def _limits(self, address: str, name: str) -> list[tuple[tuple[str, ...], int]]:
        """The counts an attempt is judged by, each with its limit."""
        return [
            (("pair", address, name), self.max_failures),
            (("address", address), self.max_shared),
            (("name", name), self.max_shared),
        ]

    def retry_after(self, address: str, name: str) -> float | None:
        """Seconds until an attempt from ``address`` for ``name`` is allowed, or None if now."""
        now = self._clock()
        wait = 0.0
        with self._lock:
            for key, limit in self._limits(address, name):
                times = self._recent(key, now)
                if len(times) >= limit:
                    wait = max(wait, times[-limit] + self.window_s - now)
        return wait if wait > 0.0 else None

    def failure(self, address: str, name: str) -> None:
        """Count a failed login from ``address`` for ``name``."""
        now = self._clock()
        with self._lock:
            for key, _ in self._limits(address, name):
                self._recent(key, now).append(now)
            for key in [k for k, times in self._failures.items() if not self._live(times, now)]:
                del self._failures[key]

    def success(self, address: str, name: str) -> None:
        """A login from ``address`` as ``name`` succeeded: that pair's count starts again."""
        with self._lock:
            self._failures.pop(("pair", address, name), None)

    def _live(self, times: deque[float], now: float) -> bool:
        while times and now - times[0] >= self.window_s:
            times.popleft()
        return bool(times)

    def _recent(self, key: tuple[str, ...], now: float) -> deque[float]:
        times = self._failures.setdefault(key, deque())
        self._live(times, now)
        return times
