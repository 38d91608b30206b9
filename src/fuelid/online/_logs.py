"""The online service's log lines, through :mod:`logging`: one record per event.

Every line the service logs is one record of the ``fuelid.online`` logger carrying a fixed
event word (``config``, ``start``, ``recorder``, ``window``, ``proposal``, ``write``,
``event``, ``status``) and its fields. Two formatters print it:

- :class:`KeyValueFormatter`: ``word key=value …`` (values with spaces quoted, floats to 6
  significant digits, times since the epoch to the millisecond), for journald or a file;
- :class:`JsonLineFormatter`: one JSON object per line with ``time`` (the record's wall clock
  [s UTC]), ``event`` (the word) and the same keys, every value the string the key=value form
  shows (unquoted) — the documented contract of ``fuelid online --json-log``.

Both read the record's fields: no line is built as text and parsed back.
"""

from __future__ import annotations

import json
import logging
import shlex
import time
from typing import Any

LOGGER_NAME = "fuelid.online"
"""The logger of the online service's structured lines."""

_EVENT = "fuelid_event"
_FIELDS = "fuelid_fields"

logging.getLogger(LOGGER_NAME).addHandler(logging.NullHandler())


class Quoted(str):
    """A value always quoted in the key=value form (JSON-escaped there): a name, a path."""

    __slots__ = ()


def field_text(value: Any) -> str:
    """A field's text: floats to 6 significant digits, times [s UTC] to the millisecond.

    Examples
    --------
    >>> field_text(13.899123), field_text(1795619989.04081), field_text(True)
    ('13.8991', '1795619989.041', 'True')
    """
    if isinstance(value, float):
        # a time since the epoch needs all its digits: 6 significant ones are ±5000 s
        return f"{value:.3f}" if abs(value) >= 1e6 else f"{value:.6g}"
    return str(value)


def log_line(word: str, **fields: Any) -> str:
    """``word key=value …``: the key=value form of one event.

    Examples
    --------
    >>> log_line("window", id=3, end=1795619989.0408, K=13.89912, reason="passed every gate")
    'window id=3 end=1795619989.041 K=13.8991 reason="passed every gate"'
    >>> log_line("config", site=Quoted("loop"), every_s="300")
    'config site="loop" every_s=300'
    """
    parts = [word]
    for key, value in fields.items():
        if isinstance(value, Quoted):
            text = json.dumps(str(value))
        else:
            text = field_text(value)
            if " " in text or not text:
                text = '"' + text.replace('"', "'") + '"'
        parts.append(f"{key}={text}")
    return " ".join(parts)


def log_event(logger: logging.Logger, word: str, **fields: Any) -> None:
    """Log one event: the key=value line as the message, the word and fields on the record."""
    if not logger.isEnabledFor(logging.INFO):
        return
    texts = {key: field_text(value) for key, value in fields.items()}
    logger.info(log_line(word, **fields), extra={_EVENT: word, _FIELDS: texts})


def event_of(record: logging.LogRecord) -> tuple[str, dict[str, str]] | None:
    """The event word and field texts of a record from :func:`log_event`; None for others."""
    word = getattr(record, _EVENT, None)
    fields = getattr(record, _FIELDS, None)
    if not isinstance(word, str) or not isinstance(fields, dict):
        return None
    return word, fields


class KeyValueFormatter(logging.Formatter):
    """``prefix`` + the key=value line, its whitespace collapsed to single spaces (one line).

    Parameters
    ----------
    prefix : str
        Put before every line (the CLI's ``"online: "``).
    """

    def __init__(self, prefix: str = "") -> None:
        super().__init__()
        self.prefix = prefix

    def format(self, record: logging.LogRecord) -> str:
        """The record's line."""
        return self.prefix + " ".join(record.getMessage().split())


class JsonLineFormatter(logging.Formatter):
    """One JSON object per record: ``time``, ``event`` and the event's fields as strings.

    A record not logged by :func:`log_event` becomes ``{"time", "event": "message",
    "message"}``.
    """

    def format(self, record: logging.LogRecord) -> str:
        """The record as one line of JSON."""
        found = event_of(record)
        if found is None:
            data: dict[str, Any] = {
                "time": record.created,
                "event": "message",
                "message": record.getMessage(),
            }
        else:
            word, fields = found
            data = {"time": record.created, "event": word, **fields}
        return json.dumps(data, ensure_ascii=False)


def log_record(line: str) -> dict[str, Any]:
    """A key=value line read back (from journald or a file) as a dict with ``time`` and ``event``.

    For reading old logs; the service's JSON lines come from :class:`JsonLineFormatter`.

    Examples
    --------
    >>> r = log_record('window id=3 accepted=True reason="passed every gate"')
    >>> r["event"], r["id"], r["reason"]
    ('window', '3', 'passed every gate')
    """
    record: dict[str, Any] = {"time": time.time()}
    try:
        parts = shlex.split(line)
    except ValueError:
        word, _, rest = line.partition(" ")
        return record | {"event": word, "message": rest}
    if not parts:
        return record | {"event": ""}
    record["event"] = parts[0]
    for part in parts[1:]:
        key, sep, value = part.partition("=")
        if sep:
            record[key] = value
        else:
            record.setdefault("message", "")
            record["message"] = f"{record['message']} {part}".strip()
    return record


__all__ = [
    "LOGGER_NAME",
    "JsonLineFormatter",
    "KeyValueFormatter",
    "Quoted",
    "event_of",
    "field_text",
    "log_event",
    "log_line",
    "log_record",
]
