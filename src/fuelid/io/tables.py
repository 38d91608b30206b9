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
from dataclasses import dataclass
from io import BytesIO, StringIO
from pathlib import Path

import numpy as np
import pandas as pd

from fuelid.errors import DataError
from fuelid.io.timeseries import FloatArray

__all__ = [
    "NO_HEADER_SEARCH",
    "HeaderSearch",
    "Scale",
    "apply_scale",
    "check_scale",
    "describe_scale",
    "find_column",
    "find_header",
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
HEAD_BYTES = 65536
"""The start of a text file looked at for its encoding, preamble, header and separator."""
PREAMBLE_LINES = 200
"""Lines above the header an export's preamble may have (tag descriptions, settings)."""


@dataclass(frozen=True)
class HeaderSearch:
    """Where a table's header is: below ``skip_rows`` lines, or the first row naming ``names``.

    ``skip_rows`` (``--skip-rows``) counts the lines above the header (blank lines at the top
    of the file not counted);
    None looks for the first line among the first :data:`PREAMBLE_LINES` whose cells include
    every one of ``names`` (the columns asked for; case and spaces ignored).
    """

    names: tuple[str, ...] = ()
    skip_rows: int | None = None


NO_HEADER_SEARCH = HeaderSearch()
"""The header is the first line (for tables that are not logs)."""


def find_header(lines: Sequence[str], header: HeaderSearch, source: str) -> int:
    """The index of the header line in ``lines`` (the file's first lines, blank ones stripped).

    Raises
    ------
    DataError
        ``skip_rows`` beyond the lines there are, or lines above the first one that looks like a
        header (more cells, like the rows below it) that do not name the columns asked for.

    Examples
    --------
    >>> lines = ["Export of FIC-101", "From;2026-03-28", "t_s;u_V;q_Lpm", "0;1;20"]
    >>> find_header(lines, HeaderSearch(("t_s", "u_V", "q_Lpm")), "log.csv")
    2
    """
    if header.skip_rows is not None:
        if header.skip_rows >= len(lines) - 1:
            raise DataError(
                f"{source}: --skip-rows {header.skip_rows} skips every line read ("
                f"{len(lines)} at the top of the file)"
            )
        if _width(lines[header.skip_rows]) == 0:
            likely = _likely_header(lines)
            hint = f"; line {likely + 1} looks like it: --skip-rows {likely}" if likely else ""
            raise DataError(
                f"{source}: line {header.skip_rows + 1}, below --skip-rows "
                f"{header.skip_rows}, is no header ({_shown(lines[header.skip_rows])}: one "
                f"column){hint}"
            )
        named = _naming_lines(lines, header.names)
        if named and header.skip_rows not in named:
            raise DataError(
                f"{source}: line {header.skip_rows + 1}, below --skip-rows {header.skip_rows}, "
                f"does not name the columns asked for; line {named[-1] + 1} does: --skip-rows "
                f"{named[-1]}"
            )
        return header.skip_rows
    named = _naming_lines(lines, header.names)
    if named:  # a preamble line may name them too: the header is the one above the data
        above_data = [  # the data, or a row of units and the data, below it
            i for i in named if any(_is_data_row(line) for line in lines[i + 1 : i + 3])
        ]
        return (above_data or named)[0]
    likely = _likely_header(lines)
    if likely == 0:
        return 0
    cells = set().union(*(_cells(line) for line in lines[:PREAMBLE_LINES]))
    missing = [name for name in header.names if name.strip().casefold() not in cells]
    asked = ", ".join(missing or sorted(header.names)) or "the columns"
    raise DataError(
        f"{source}: line {likely + 1} ({_shown(lines[likely])}) looks like the header, below "
        f"{likely} line(s) of preamble, but no line names {asked}: give --skip-rows {likely} "
        "and the columns' names (--time-col, --input-col, --output-col)"
    )


def _shown(line: str) -> str:
    """A line as quoted in a message, cut to 60 characters."""
    return repr(line if len(line) <= 60 else line[:57] + "...")


def _naming_lines(lines: Sequence[str], names: Sequence[str]) -> list[int]:
    """The lines among the first :data:`PREAMBLE_LINES` whose cells include every name."""
    wanted = {name.strip().casefold() for name in names if name}
    if not wanted:
        return []
    return [i for i, line in enumerate(lines[:PREAMBLE_LINES]) if wanted <= _cells(line)]


def _cells(line: str) -> set[str]:
    """The cells of a line under any separator, unquoted, stripped and case-folded."""
    cells: set[str] = set()
    for separator in _SEPARATORS:
        cells.update(cell.strip().strip('"').strip().casefold() for cell in line.split(separator))
    return cells


def _likely_header(lines: Sequence[str]) -> int:
    """The line just above the first data row (0: none is found, or the first line is it).

    A data row has as many cells as the rows at the end of ``lines``, each holding a digit
    (numbers, stamps); the header above it has as many cells too.
    """
    rows = lines[-min(len(lines) - 1, 20) :] if len(lines) > 1 else lines
    counts = [_width(row) for row in rows]
    width = max(set(counts), key=counts.count)
    for index, line in enumerate(lines[1 : PREAMBLE_LINES + 1], start=1):
        if _width(line) == width and _is_data_row(line) and _width(lines[index - 1]) == width:
            return index - 1 if not _is_data_row(lines[index - 1]) else 0
    return 0


def _width(line: str) -> int:
    """The number of separators in a line (of the separator most frequent in it)."""
    return max(line.count(separator) for separator in _SEPARATORS)


def _is_data_row(line: str) -> bool:
    """Whether every cell of a line holds a digit (a number or a stamp), under its separator."""
    separator = max(_SEPARATORS, key=line.count)
    return all(any(ch.isdigit() for ch in cell) for cell in line.split(separator))


def _preamble_note(lines: Sequence[str], at: int) -> str:
    """``"skipped 3 line(s) above the header (an export's preamble: 'Export of FIC-101', ...)"``."""
    first = lines[0] if len(lines[0]) <= 40 else lines[0][:37] + "..."
    more = ", ..." if at > 1 else ""
    return f"skipped {at} line(s) above the header (an export's preamble: {first!r}{more})"


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


def read_frame(
    file: Path, source: str, header: HeaderSearch = NO_HEADER_SEARCH
) -> tuple[pd.DataFrame, list[str]]:
    """Read the file as a DataFrame (text cells as strings), with notes on how it was read.

    ``header`` finds the header row below an export's preamble (:class:`HeaderSearch`).
    """
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
    if not raw or raw.isspace():
        raise DataError(f"{source} is empty")
    if raw.startswith(b"PAR1"):
        return _read_parquet(file, source), []
    if suffix in PARQUET_SUFFIXES:
        kind = "text" if b"\x00" not in raw[:4096] else "binary data"
        raise DataError(
            f"{source} is not a Parquet file (it does not start with Parquet's 'PAR1' mark; it "
            f"holds {kind}): if it is a CSV export, name it .csv"
        )
    return _read_text(raw, source, header)


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


def _read_text(raw: bytes, source: str, header: HeaderSearch) -> tuple[pd.DataFrame, list[str]]:
    """Decode, find the header, sniff the separator and parse a CSV-like text table.

    Columns that are plain numbers come back as floats, parsed by pandas' C reader; anything
    else (decimal commas, date-time stamps, unit rows, bad cells) stays as strings for
    :func:`to_float` and the log reader to interpret or refuse. Plain ASCII text (a day-long
    log) is parsed from its bytes: no decoded copy, no copy of the text.
    """
    ascii_text = raw.isascii() and b"\x00" not in raw  # UTF-16 of ASCII is ASCII bytes too
    text, encoding = _decode(raw[:HEAD_BYTES] if ascii_text else raw, source)
    head = _strip_blank_lines(text[:HEAD_BYTES]).splitlines()
    if len(text) > HEAD_BYTES and len(head) > 1:
        head = head[:-1]  # the last line read may be cut short
    if not head:
        raise DataError(f"{source} is empty")
    at = find_header(head, header, source)
    separator = _sniff_separator(head[at:], source)
    notes = [] if at == 0 else [_preamble_note(head, at)]
    if encoding != "utf-8-sig":
        notes.append(f"read as {encoding.upper()} text")
    if separator != ",":
        notes.append(f"columns separated by {_SEPARATOR_NAMES[separator]}")
    # a space before a quoted cell hides the quote from the reader unless it skips the space
    spaced = any(f'{separator} "' in line for line in head[at:])
    if ascii_text:
        start = _line_start(raw, head[at].encode("ascii"))
        body: StringIO | BytesIO = BytesIO(raw if start <= 0 else raw[start:])
    else:
        stripped = _strip_blank_lines(text)
        body = StringIO(stripped[_line_start(stripped, head[at]) :])
    frame = _parse(body, separator, spaced, source)
    if not isinstance(frame.index, pd.RangeIndex):  # pandas took the first field as an index
        raise DataError(_extra_field_refusal(frame, separator, source))
    frame.columns = [str(name).strip().lstrip("\ufeff").strip() for name in frame.columns]
    if frame.empty:
        raise DataError(f"{source} has a header but no data rows")
    return frame, notes


def _line_start(text: bytes | str, line: bytes | str) -> int:
    r"""Where the first line that is ``line`` and nothing else starts in ``text`` (0: none).

    A preamble line may hold the header's text (``Tags:,t,u``): only a whole line is the header.

    Examples
    --------
    >>> _line_start("Tags:,t,u\n\nt,u\n0,1\n", "t,u")
    11
    """
    if isinstance(text, bytes) and isinstance(line, bytes):
        found_bytes = re.search(b"(?m)^" + re.escape(line) + b"\r?$", text)
        return found_bytes.start() if found_bytes else 0
    assert isinstance(text, str)
    assert isinstance(line, str)
    found = re.search("(?m)^" + re.escape(line) + "\r?$", text)
    return found.start() if found else 0


def _extra_field_refusal(frame: pd.DataFrame, separator: str, source: str) -> str:
    """Why the data rows have a field more than the header: an empty last one, or a cell split."""
    sep = _SEPARATOR_NAMES[separator]
    counts = f"({len(frame.columns) + 1} against {len(frame.columns)})"
    last = frame.iloc[:, -1]
    if bool((last.isna() | (last.astype(str).str.strip() == "")).all()):
        return (
            f"{source}: the data rows have one field more than the header {counts}, an empty "
            f"last one: each row ends with a {sep} the header does not; remove it, or name the "
            "column in the header"
        )
    return (
        f"{source}: the data rows have one field more than the header {counts}: a {sep} inside "
        "a cell (a decimal comma, milliseconds after a comma)? quote such cells, or export with "
        "another separator"
    )


def _parse(body: StringIO | BytesIO, separator: str, spaced: bool, source: str) -> pd.DataFrame:
    """The table by pandas' C reader (its default chunked reading: half the memory)."""
    try:
        return pd.read_csv(
            body,
            sep=separator,
            keep_default_na=False,
            skip_blank_lines=False,
            skipinitialspace=spaced,
            engine="c",
        )
    except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as exc:
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise DataError(f"cannot read {source} as a table: {reason}") from None


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
    elif _utf16_without_mark(raw[:HEAD_BYTES]):
        candidates = (_utf16_without_mark(raw[:HEAD_BYTES]),)
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


def _utf16_without_mark(head: bytes) -> str:
    r"""``"utf-16-le"`` or ``"utf-16-be"`` for UTF-16 text without a byte-order mark, else ``""``.

    ASCII text in UTF-16 has a zero byte in every character: the odd bytes (little-endian) or
    the even ones (big-endian).

    Examples
    --------
    >>> _utf16_without_mark("t_s,u_V\n0,1\n".encode("utf-16-le"))
    'utf-16-le'
    >>> _utf16_without_mark(b"t_s,u_V,q_Lpm")
    ''
    """
    pairs = len(head) // 2
    if pairs < 4:
        return ""
    if head[1 : 2 * pairs : 2].count(0) >= 0.9 * pairs:
        return "utf-16-le"
    if head[0 : 2 * pairs : 2].count(0) >= 0.9 * pairs:
        return "utf-16-be"
    return ""


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
