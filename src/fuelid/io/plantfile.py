"""Updating a plant TOML file in place: new parameter values and a ``[calibration]`` table.

``fuelid calibrate`` writes its estimates back into the user's plant file. The file is the
user's: its comments, key order, blank lines and quoting must survive, so it is edited with
tomlkit (a style-preserving TOML parser) rather than re-serialised from the validated config.
This module takes plain data (dotted names and floats, a mapping for the calibration record) and
knows nothing of the plant model; validating the result is the caller's business
(:func:`fuelid.plant._config.plant_config_from_dict` on ``tomllib.loads(text)``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from datetime import date, datetime, time
from pathlib import Path
from typing import Any

import tomlkit
import tomlkit.exceptions
from tomlkit.container import OutOfOrderTableProxy
from tomlkit.items import AoT, Array, InlineTable, Item, Table

from fuelid.errors import ConfigError
from fuelid.io.files import atomic_write_bytes

CALIBRATION_TABLE = "calibration"
"""Name of the table that records a calibration."""


def update_plant_toml(
    text: str,
    values: Mapping[str, float],
    calibration: Mapping[str, Any] | None = None,
) -> str:
    r"""Set parameters of a plant TOML document and add or replace its ``[calibration]`` table.

    Each value replaces the one under its dotted name (``pump.leakage_Lpm_per_MPa``) where it
    stands, keeping its comments; a key the file leaves to its default is appended to its table
    (the table is created at the end if the file has none). The ``[calibration]`` table, if
    given, replaces any existing one and goes at the end of the document: scalars and lists as
    keys, a list of lists (the covariance, the intervals) as a multi-line array with one row per
    line, and a list of mappings (the logs) as an array of tables ``[[calibration.logs]]``.

    Parameters
    ----------
    text : str
        The plant file's text.
    values : mapping of str to float
        New values by dotted name ``table.key``, in the key's unit.
    calibration : mapping, optional
        The ``[calibration]`` table (plain data: str, int, float, bool, date-times, sequences
        and mappings; numpy arrays and scalars are converted). None leaves the table as it is.

    Returns
    -------
    str
        The updated document; every line not touched is as it was.

    Raises
    ------
    ConfigError
        If ``text`` is not valid TOML, a name is not ``table.key``, its table is not a table,
        or a value is not a finite number.

    Examples
    --------
    >>> text = "[pump]\n# measured 2024\nleakage_Lpm_per_MPa = 7.0  # at 20 °C\n"
    >>> print(update_plant_toml(text, {"pump.leakage_Lpm_per_MPa": 5.5}), end="")
    [pump]
    # measured 2024
    leakage_Lpm_per_MPa = 5.5  # at 20 °C
    """
    try:
        document = tomlkit.parse(text)
    except tomlkit.exceptions.ParseError as exc:
        raise ConfigError(f"the plant file is not valid TOML: {exc}") from None
    for name, value in values.items():
        _set_value(document, name, value)
    if calibration is not None:
        if CALIBRATION_TABLE in document:
            del document[CALIBRATION_TABLE]
        document.add(CALIBRATION_TABLE, _calibration_table(calibration))
    return tomlkit.dumps(document)


def write_text_atomically(path: str | Path, text: str) -> Path:
    """Write UTF-8 text to a temporary file beside ``path``, then rename it over ``path``.

    A crash or a full disk leaves the old file (or none), never a half-written one.

    Returns
    -------
    Path
        ``path``.
    """
    return atomic_write_bytes(path, text.encode("utf-8"))


def update_plant_file(
    path: str | Path,
    values: Mapping[str, float],
    calibration: Mapping[str, Any] | None = None,
    output: str | Path | None = None,
) -> Path:
    """Read a plant file, :func:`update_plant_toml` it and write it atomically.

    Parameters
    ----------
    path : str or Path
        The plant file to read.
    values, calibration
        As in :func:`update_plant_toml`.
    output : str or Path, optional
        Where to write (default: over ``path``).

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ConfigError
        If the file cannot be read or updated.
    """
    source = Path(path)
    try:
        text = source.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read plant config {str(source)!r}: {exc}") from None
    try:
        updated = update_plant_toml(text, values, calibration)
    except ConfigError as exc:
        raise ConfigError(f"{source}: {exc}") from None
    return write_text_atomically(source if output is None else output, updated)


def _set_value(document: tomlkit.TOMLDocument, name: str, value: float) -> None:
    """Set ``table.key`` to a float, keeping the old value's comment and place."""
    parts = name.split(".")
    if len(parts) != 2 or not all(parts):
        raise ConfigError(f"parameter name {name!r} is not of the form table.key")
    section, key = parts
    number = _finite(name, value)
    if section not in document:
        document.add(section, tomlkit.table())
    table = document[section]
    if not isinstance(table, Table | InlineTable | OutOfOrderTableProxy):
        raise ConfigError(f"{section!r} in the plant file is not a table")
    old = table.get(key)
    if isinstance(old, Item):
        new = tomlkit.item(number)
        new.trivia.comment_ws = old.trivia.comment_ws
        new.trivia.comment = old.trivia.comment
        table[key] = new
    else:
        table[key] = number


def _finite(name: str, value: Any) -> float:
    """``value`` as a finite float, or a :class:`ConfigError` naming ``name``."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{name}: not a number (got {value!r})") from None
    if not math.isfinite(number):
        raise ConfigError(f"{name}: must be a finite number (got {number!r})")
    return number


def _calibration_table(calibration: Mapping[str, Any]) -> Table:
    """The ``[calibration]`` table: lists of lists one row per line, lists of tables as AoT."""
    table = tomlkit.table()
    for key, raw in calibration.items():
        value = _plain(raw, f"{CALIBRATION_TABLE}.{key}")
        if value is None:
            continue  # TOML has no null: an absent key is the default
        table.add(str(key), _toml_item(value, f"{CALIBRATION_TABLE}.{key}"))
    return table


def _toml_item(value: Any, where: str) -> Item:
    """A tomlkit item for a plain value, laid out for reading."""
    if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
        tables = AoT([])
        for entry in value:
            sub = tomlkit.table()
            for k, v in entry.items():
                if v is not None:
                    sub.add(str(k), tomlkit.item(v))
            tables.append(sub)
        return tables
    if isinstance(value, list) and value and all(isinstance(v, list) for v in value):
        rows: Array = tomlkit.array()
        for row in value:
            rows.append(tomlkit.item(row))
        rows.multiline(True)
        return rows
    if isinstance(value, dict):
        sub = tomlkit.table()
        for k, v in value.items():
            if v is not None:
                sub.add(str(k), _toml_item(v, f"{where}.{k}"))
        return sub
    item: Item = tomlkit.item(value)
    return item


def _plain(value: Any, where: str) -> Any:
    """Plain TOML-able data: numpy arrays and scalars converted, non-finite floats refused."""
    if hasattr(value, "tolist") and not isinstance(value, str | bytes):
        value = value.tolist()  # numpy arrays and scalars, without importing numpy
    if value is None or isinstance(value, bool | int | str | datetime | date | time):
        return value
    if isinstance(value, float):
        return _finite(where, value)
    if isinstance(value, Mapping):
        return {str(k): _plain(v, f"{where}.{k}") for k, v in value.items()}
    if isinstance(value, Sequence) and not isinstance(value, str | bytes):
        return [_plain(v, where) for v in value]
    if isinstance(value, Path):
        return str(value)
    raise ConfigError(f"{where}: cannot write {type(value).__name__} {value!r} to TOML")
