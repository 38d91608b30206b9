"""The log lines of ``fuelid online``: the documented key sets and one JSON object per line.

The keys are a documented contract (README, ``fuelid online --json-log``): ``time``, ``event``
(the word) and the event's keys, every value a string, the text the key=value form shows.
"""

from __future__ import annotations

import io
import json
import logging
from collections.abc import Iterator
from typing import Any

import pytest

from fuelid.online import JsonLineFormatter, KeyValueFormatter, Quoted, log_event
from fuelid.online._logs import field_text, log_line

DOCUMENTED: dict[str, dict[str, Any]] = {
    "config": {
        "site": Quoted("virtual fuel loop"),
        "store": Quoted("/tmp/demo/j.db"),
        "every_s": "300",
        "window_s": "600",
        "write_back": "auto",
    },
    "start": {
        "identifies": True,
        "tracks": True,
        "proposes": True,
        "writes": True,
        "write_back": "auto",
        "missing_for_proposals": [],
        "plant": "plant file reference_plant.toml",
    },
    "recorder": {"message": "connected to modbus 127.0.0.1:48095 device 1"},
    "window": {
        "id": 1,
        "end": 1795619989.040801,
        "accepted": True,
        "mode": "AUTO",
        "K": 13.89912,
        "T_fuel": -9.98841,
        "seconds": 2.21222,
        "reason": "passed every gate",
    },
    "proposal": {"id": 2, "Kc": 0.0123, "Ti": 1.5, "reason": "K moved"},
    "write": {"proposal": 2, "apply": 7, "Kc": 0.0123, "Ti": 1.5, "ok": True},
    "event": {"kind": "revert", "detail": 'IAE 4.16 s > 1.5 × 2.58 s "before" (by service)'},
    "status": {"line": "link up | 2439.5/s | 572 stored | 0 lost"},
}


@pytest.fixture
def logged() -> Iterator[tuple[logging.Logger, io.StringIO, io.StringIO]]:
    """A logger with a JSON and a key=value handler, each writing to its own buffer."""
    logger = logging.getLogger("fuelid.online.test")
    logger.setLevel(logging.INFO)
    logger.propagate = False
    as_json, as_text = io.StringIO(), io.StringIO()
    handlers = [logging.StreamHandler(as_json), logging.StreamHandler(as_text)]
    handlers[0].setFormatter(JsonLineFormatter())
    handlers[1].setFormatter(KeyValueFormatter("online: "))
    for handler in handlers:
        logger.addHandler(handler)
    yield logger, as_json, as_text
    for handler in handlers:
        logger.removeHandler(handler)


def test_every_documented_event_is_one_json_object_with_its_keys(
    logged: tuple[logging.Logger, io.StringIO, io.StringIO],
) -> None:
    logger, as_json, _ = logged
    for word, fields in DOCUMENTED.items():
        log_event(logger, word, **fields)
    lines = as_json.getvalue().splitlines()
    assert len(lines) == len(DOCUMENTED)
    for line, (word, fields) in zip(lines, DOCUMENTED.items(), strict=True):
        record = json.loads(line)
        assert list(record) == ["time", "event", *fields]
        assert record["event"] == word
        assert isinstance(record["time"], float)
        for key, value in fields.items():
            assert record[key] == field_text(value)  # a string, as the key=value form shows it


def test_json_values_are_the_unquoted_key_value_texts(
    logged: tuple[logging.Logger, io.StringIO, io.StringIO],
) -> None:
    logger, as_json, as_text = logged
    log_event(logger, "window", **DOCUMENTED["window"])
    log_event(logger, "config", **DOCUMENTED["config"])
    window, config = (json.loads(line) for line in as_json.getvalue().splitlines())
    assert window["end"] == "1795619989.041"  # a time keeps its milliseconds
    assert window["K"] == "13.8991"  # 6 significant digits
    assert window["reason"] == "passed every gate"
    assert config["site"] == "virtual fuel loop"
    assert as_text.getvalue().splitlines() == [
        "online: " + log_line("window", **DOCUMENTED["window"]),
        'online: config site="virtual fuel loop" store="/tmp/demo/j.db" every_s=300 '
        "window_s=600 write_back=auto",
    ]


def test_a_value_with_a_line_break_stays_on_one_line(
    logged: tuple[logging.Logger, io.StringIO, io.StringIO],
) -> None:
    logger, as_json, as_text = logged
    log_event(logger, "event", kind="tracking", detail="first line\nsecond line")
    (line,) = as_json.getvalue().splitlines()
    assert json.loads(line)["detail"] == "first line\nsecond line"
    assert as_text.getvalue() == 'online: event kind=tracking detail="first line second line"\n'


def test_a_plain_record_is_a_message_event(
    logged: tuple[logging.Logger, io.StringIO, io.StringIO],
) -> None:
    logger, as_json, _ = logged
    logger.info("link up | 10 stored")
    record = json.loads(as_json.getvalue())
    assert set(record) == {"time", "event", "message"}
    assert (record["event"], record["message"]) == ("message", "link up | 10 stored")
