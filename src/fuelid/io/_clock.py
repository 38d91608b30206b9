"""Times as text: one formatter for every time a person reads (``fuelid online``'s lines).

Stored times are UTC seconds since the epoch on two clocks (plant time and the wall clock, see
:mod:`fuelid.store._schema`); a person reads them in the site's time zone (``[site] timezone``,
an IANA name, "UTC" by default). :func:`format_time` and :func:`format_age` are the only places
that turn them into text.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from functools import lru_cache
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

__all__ = ["format_age", "format_time", "zone"]


@lru_cache(maxsize=32)
def zone(name: str | None) -> ZoneInfo:
    """The time zone of an IANA name; UTC for None, an empty or an unknown name."""
    try:
        return ZoneInfo(name or "UTC")
    except (ZoneInfoNotFoundError, ValueError):
        return ZoneInfo("UTC")


def format_time(t: float | None, tz: str | None = "UTC") -> str:
    """A time [s UTC since the epoch] as ``2026-11-27 08:15:03 CET`` in the zone ``tz``.

    "never" for None, "unknown" for a non-finite time.

    Examples
    --------
    >>> format_time(1_795_767_303.4)
    '2026-11-27 08:15:03 UTC'
    >>> format_time(1_795_767_303.4, "Europe/Zurich")
    '2026-11-27 09:15:03 CET'
    >>> format_time(None)
    'never'
    """
    if t is None:
        return "never"
    if not math.isfinite(t):
        return "unknown"
    when = datetime.fromtimestamp(float(t), UTC).astimezone(zone(tz))
    return f"{when:%Y-%m-%d %H:%M:%S} {when.tzname()}"


def format_age(seconds: float | None) -> str:
    """An age [s] as a person says it: ``0.6 s``, ``42 s``, ``4 min``, ``3.2 h``, ``2.5 d``.

    Examples
    --------
    >>> [format_age(s) for s in (0.62, 42.4, 250.0, 11_520.0, 216_000.0)]
    ['0.6 s', '42 s', '4 min', '3.2 h', '2.5 d']
    >>> format_age(-3.0), format_age(None)
    ('in 3.0 s', 'unknown')
    """
    if seconds is None or not math.isfinite(seconds):
        return "unknown"
    if seconds < 0:
        return f"in {format_age(-seconds)}"
    if seconds < 10.0:
        return f"{seconds:.1f} s"
    if seconds < 120.0:
        return f"{seconds:.0f} s"
    if seconds < 7200.0:
        return f"{seconds / 60.0:.0f} min"
    if seconds < 172_800.0:
        return f"{seconds / 3600.0:.1f} h"
    return f"{seconds / 86400.0:.1f} d"
