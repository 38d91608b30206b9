"""Reading CSV-like text tables and Parquet files as PLC exports come, or refusing them.

One reader for logs (:mod:`fuelid.io.logs`) and command profiles: UTF-8 with a byte-order mark or
GBK headers, ``;``, tab or ``,`` separators, decimal commas, column names matched with their unit
suffix or bracketed unit, the unit a column name carries (``q_Lpm`` → L/min) and the linear
scaling of a raw column (4–20 mA, counts). Every refusal is a one-line
:class:`~fuelid.errors.DataError` naming the file and what is wrong.
"""

from __future__ import annotations

import re
import tomllib
import unicodedata
from collections.abc import Sequence
from io import StringIO
from pathlib import Path

import numpy as np
import pandas as pd

from fuelid.errors import DataError
from fuelid.io.timeseries import FloatArray

__all__ = [
    "Scale",
    "apply_scale",
    "check_scale",
    "describe_scale",
    "find_column",
    "guess_unit",
    "match_column",
    "parse_scale",
    "read_frame",
    "read_table",
    "table_column",
    "to_float",
]

TEXT_SUFFIXES = (".csv", ".txt", ".tsv")
PARQUET_SUFFIXES = (".parquet", ".pq")
_SEPARATORS = ("\t", ";", ",")
_SEPARATOR_NAMES = {"\t": "tab", ";": "';'", ",": "','"}
_ENCODINGS = ("utf-8-sig", "gbk")


def read_table(path: str | Path) -> tuple[pd.DataFrame, list[str]]:
    """Read a CSV-like text table or a Parquet file as :func:`load_log` does.

    For tables that are not logs (a command profile): the same encodings, separators and
    refusals. Text cells stay strings; :func:`table_column` turns a column into numbers.

    Returns
    -------
    frame, notes
        The table and what reading it noticed (encoding, separator).
    """
    file = Path(path)
    return read_frame(file, repr(str(file)))


def table_column(frame: pd.DataFrame, name: str, source: str) -> FloatArray:
    """One column of :func:`read_table`'s frame as floats (decimal point or comma).

    Raises
    ------
    DataError
        If the column is missing (naming those present) or a cell is empty or not a number.
    """
    column = find_column(frame, name, "required", source)
    values = to_float(frame[column])
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        cell = str(frame[column].iloc[int(bad[0])])
        shown = repr(cell if len(cell) <= 24 else cell[:21] + "...")
        raise DataError(
            f"{source}: column {name!r} has {bad.size} empty, non-numeric or infinite cell(s), "
            f"first at data row {int(bad[0]) + 1} ({shown})"
        )
    return values


def read_frame(file: Path, source: str) -> tuple[pd.DataFrame, list[str]]:
    """Read the file as a DataFrame (text cells as strings), with notes on how it was read."""
    suffix = file.suffix.lower()
    if file.is_dir():
        raise DataError(f"{source} is a folder: give a log file (CSV or Parquet) in it")
    if suffix == ".toml":
        raise DataError(f"{source} {_toml_kind(file)}: a log is a CSV or Parquet file")
    if suffix not in TEXT_SUFFIXES + PARQUET_SUFFIXES:
        choices = ", ".join(TEXT_SUFFIXES + PARQUET_SUFFIXES)
        raise DataError(
            f"{source}: unknown log format {suffix or '(no extension)'!r}; use {choices}"
        )
    if not file.is_file():
        raise DataError(f"{source} does not exist or is not a file")
    try:
        raw = file.read_bytes()
    except OSError as exc:
        raise DataError(f"cannot read {source}: {exc.strerror or exc}") from None
    if not raw.strip():
        raise DataError(f"{source} is empty")
    if suffix in PARQUET_SUFFIXES or raw.startswith(b"PAR1"):
        return _read_parquet(file, source), []
    return _read_text(raw, source)


def _toml_kind(file: Path) -> str:
    """What a TOML file given as a log is: a site file, a plant file, or some TOML file."""
    try:
        data = tomllib.loads(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return "is a TOML file, not a log"
    if "plc" in data:
        return "is a site file (it has a [plc] table), not a log"
    if "vfd" in data or "flowmeter" in data:
        return "is a plant file (it has a [vfd] table), not a log"
    return "is a TOML file, not a log"


def _read_parquet(file: Path, source: str) -> pd.DataFrame:
    """Read a Parquet file, refusing a corrupt one in one line."""
    try:
        frame = pd.read_parquet(file)
    except Exception as exc:  # pyarrow raises its own exception types
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise DataError(f"cannot read {source} as Parquet: {reason}") from None
    frame.columns = [str(name).strip() for name in frame.columns]
    if frame.empty:
        raise DataError(f"{source} holds no data rows")
    return frame


def _read_text(raw: bytes, source: str) -> tuple[pd.DataFrame, list[str]]:
    """Decode, sniff the separator and parse a CSV-like text table.

    Columns that are plain numbers come back as floats (parsed by pandas' C reader, the fast
    path for a long log); anything else (decimal commas, date-time stamps, unit rows, bad cells)
    stays as strings for :func:`to_float` and the log reader to interpret or refuse.
    """
    text, encoding = _decode(raw, source)
    text = _strip_blank_lines(text)
    if not text:
        raise DataError(f"{source} is empty")
    head = text[:65536].splitlines()
    separator = _sniff_separator(head, source)
    try:
        frame = pd.read_csv(
            StringIO(text),
            sep=separator,
            keep_default_na=False,
            skip_blank_lines=False,
            skipinitialspace=True,
            engine="c",
            low_memory=False,
        )
    except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as exc:
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise DataError(f"cannot read {source} as a table: {reason}") from None
    frame.columns = [str(name).strip().lstrip("\ufeff").strip() for name in frame.columns]
    if frame.empty:
        raise DataError(f"{source} has a header but no data rows")
    notes = []
    if encoding != "utf-8-sig":
        notes.append(f"read as {encoding.upper()} text")
    if separator != ",":
        notes.append(f"columns separated by {_SEPARATOR_NAMES[separator]}")
    return frame, notes


def _strip_blank_lines(text: str) -> str:
    r"""``text`` without its leading and trailing lines that are empty or only whitespace.

    Examples
    --------
    >>> _strip_blank_lines("  \n\nt,u\n1,2\n \n\t\n")
    't,u\n1,2'
    """
    # scan line by line from each end only: a long log is not split into lines here
    start = 0
    while True:
        newline = text.find("\n", start)
        if newline < 0 or text[start:newline].strip():
            break
        start = newline + 1
    stop = len(text)
    while stop > start:
        newline = text.rfind("\n", start, stop)
        if text[newline + 1 : stop].strip():
            break
        if newline < start:
            stop = start
            break
        stop = newline
    return text[start:stop].strip("\r\n") if text[start:stop].strip() else ""


def _decode(raw: bytes, source: str) -> tuple[str, str]:
    """Decode as UTF-16 (with its BOM), UTF-8 (BOM stripped) or GBK; refuse binary content."""
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        candidates: tuple[str, ...] = ("utf-16",)
    elif b"\x00" in raw:
        raise DataError(f"{source} is not a text table (it holds binary data)")
    else:
        candidates = _ENCODINGS
    for encoding in candidates:
        try:
            text = raw.decode(encoding)
        except UnicodeDecodeError:
            continue
        if any(unicodedata.category(ch) == "Cc" and ch not in "\t\r\n" for ch in text[:65536]):
            raise DataError(f"{source} is not a text table (it holds control characters)")
        return text, encoding
    raise DataError(f"{source} is not a text table (neither UTF-8 nor GBK text)")


def _sniff_separator(lines: Sequence[str], source: str) -> str:
    """Tab, ``;`` or ``,``: the one found in the header, preferring one as frequent in row 1."""
    header = lines[0]
    found = [sep for sep in _SEPARATORS if sep in header]
    if not found:
        shown = header if len(header) <= 40 else header[:37] + "..."
        raise DataError(
            f"{source} is not a table of signals: its header {shown!r} has a single column "
            "(no ',', ';' or tab separator)"
        )
    if len(lines) > 1:
        for sep in found:
            if lines[1].count(sep) == header.count(sep):
                return sep
    return found[0]


def match_column(frame: pd.DataFrame, name: str) -> str | None:
    """The column called ``name`` (exactly, else ignoring case and spaces if unique), or None."""
    columns = [str(column) for column in frame.columns]
    if name in columns:
        return name
    key = name.strip().casefold()
    matches = [column for column in columns if column.strip().casefold() == key]
    return matches[0] if len(matches) == 1 else None


def find_column(frame: pd.DataFrame, name: str, role: str, source: str, hint: str = "") -> str:
    """The column called ``name``, or a DataError naming the columns present."""
    found = match_column(frame, name)
    if found is None:
        present = ", ".join(str(column) for column in frame.columns)
        tail = f" ({hint})" if hint else ""
        raise DataError(f"{source} has no {role} column {name!r}; columns present: {present}{tail}")
    return found


def to_float(series: pd.Series) -> FloatArray:
    """Numbers (decimal point or comma) as floats; empty or non-numeric cells become NaN."""
    if pd.api.types.is_bool_dtype(series.dtype) or pd.api.types.is_datetime64_any_dtype(
        series.dtype
    ):
        return np.full(len(series), np.nan)
    if not pd.api.types.is_numeric_dtype(series.dtype):
        series = series.astype(str).str.strip().str.replace(",", ".", regex=False)
    numbers = pd.to_numeric(series, errors="coerce")
    return np.asarray(numbers.to_numpy(dtype=float, na_value=np.nan), dtype=np.float64)


# --- units and scaling of raw columns ------------------------------------------------------------

Scale = tuple[float, float, float, float]
"""A linear scaling ``(raw_low, raw_high, eng_low, eng_high)``, e.g. 4–20 mA → 1–5 V."""

_UNITS = {
    "V": "V",
    "mV": "mV",
    "A": "A",
    "mA": "mA",
    "Lpm": "L/min",
    "lpm": "L/min",
    "Lps": "L/s",
    "m3h": "m³/h",
    "kgh": "kg/h",
    "degC": "degC",
    "K": "K",
    "s": "s",
    "Hz": "Hz",
    "rpm": "rpm",
    "pct": "%",
    "Pa": "Pa",
    "kPa": "kPa",
    "MPa": "MPa",
    "bar": "bar",
}
_BRACKET_UNIT = re.compile(r"[\[(（]\s*([^\])）]+?)\s*[\])）]\s*$")


def parse_scale(text: str) -> Scale:
    """Parse the command-line syntax of a linear scaling, ``raw_low:raw_high:eng_low:eng_high``.

    Parameters
    ----------
    text : str
        Four numbers separated by ``:`` (decimal commas then allowed) or by ``,``.

    Returns
    -------
    tuple of 4 float
        ``(raw_low, raw_high, eng_low, eng_high)``.

    Raises
    ------
    DataError
        Not four finite numbers, or an empty raw or engineering range.

    Examples
    --------
    >>> parse_scale("4:20:1:5")
    (4.0, 20.0, 1.0, 5.0)
    >>> parse_scale("0, 27648, 0, 100")
    (0.0, 27648.0, 0.0, 100.0)
    >>> parse_scale("4:20:0:2,5")
    (4.0, 20.0, 0.0, 2.5)
    """
    if ":" in text:
        parts = [part.strip().replace(",", ".") for part in text.split(":")]
    else:
        parts = [part.strip() for part in text.split(",")]
    if len(parts) != 4:
        raise DataError(
            f"scale {text!r} must be four numbers raw_low:raw_high:eng_low:eng_high "
            f"(e.g. 4:20:1:5), got {len(parts)} part(s)"
        )
    try:
        numbers = [float(part) for part in parts]
    except ValueError:
        raise DataError(
            f"scale {text!r} must be four numbers raw_low:raw_high:eng_low:eng_high (e.g. 4:20:1:5)"
        ) from None
    return check_scale((numbers[0], numbers[1], numbers[2], numbers[3]), f"scale {text!r}")


def check_scale(scale: Sequence[float], what: str) -> Scale:
    """Validate a ``(raw_low, raw_high, eng_low, eng_high)`` scaling."""
    if len(scale) != 4:
        raise DataError(f"{what} needs 4 numbers (raw_low, raw_high, eng_low, eng_high)")
    values = tuple(float(value) for value in scale)
    if not all(np.isfinite(values)):
        raise DataError(f"{what} must hold finite numbers, got {values}")
    raw_low, raw_high, eng_low, eng_high = values
    if raw_low == raw_high:
        raise DataError(f"{what}: the raw range {raw_low:g}..{raw_high:g} is empty")
    if eng_low == eng_high:
        raise DataError(f"{what}: the engineering range {eng_low:g}..{eng_high:g} is empty")
    return raw_low, raw_high, eng_low, eng_high


def apply_scale(values: FloatArray, scale: Scale) -> FloatArray:
    """Map ``raw_low..raw_high`` linearly onto ``eng_low..eng_high``."""
    raw_low, raw_high, eng_low, eng_high = scale
    return eng_low + (values - raw_low) * ((eng_high - eng_low) / (raw_high - raw_low))


def describe_scale(scale: Scale) -> str:
    """``"4..20 -> 1..5"``."""
    raw_low, raw_high, eng_low, eng_high = scale
    return f"{raw_low:g}..{raw_high:g} -> {eng_low:g}..{eng_high:g}"


def guess_unit(name: str) -> str:
    """Unit from a column name: suffix ``u_V`` → V, ``q_Lpm`` → L/min, or brackets ``q [L/min]``.

    Examples
    --------
    >>> guess_unit("q_Lpm"), guess_unit("流量(L/min)"), guess_unit("flow")
    ('L/min', 'L/min', '')
    """
    bracket = _BRACKET_UNIT.search(name)
    if bracket:
        return bracket.group(1)
    if "_" in name:
        return _UNITS.get(name.rsplit("_", 1)[1], "")
    return ""
