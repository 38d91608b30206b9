"""The text historians write in place of a sample they could not read, and how it is counted.

A historian export (OSIsoft PI, Wonderware, WinCC, iFIX, a SCADA's CSV dump) does not leave a
bad sample empty: it writes its quality as text, ``#N/A``, ``Bad Input``, ``I/O Timeout``,
``Comm Fail``, ``Shutdown``, ``NaN``. Those cells are missing samples, not broken files:
:func:`fuelid.io.logs.load_log` takes them out as gaps and names them here, by column and text.
Any other text in a numeric column is still refused (it may be a unit row gone wrong, a shifted
column, a value the historian printed oddly): only the markers known, or given with
``--bad-values``, are read as "no sample".
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence

import numpy as np
import pandas as pd

__all__ = [
    "DEFAULT_BAD_VALUES",
    "BadMarks",
    "describe_bad_marks",
    "find_bad_marks",
    "marker_key",
    "parse_bad_values",
]

DEFAULT_BAD_VALUES: tuple[str, ...] = (
    "#N/A",
    "Bad Input",
    "Bad",
    "I/O Timeout",
    "Comm Fail",
    "Shutdown",
    "NaN",
    "",
)
"""Cell texts read as a missing sample (case and surrounding spaces ignored; ``""``: empty)."""

BadMarks = tuple[np.ndarray[tuple[int], np.dtype[np.bool_]], Counter[str]]
"""Where a column holds a marker, and how many of each (by the text as first written)."""


def marker_key(text: str) -> str:
    """The form a cell and a marker are compared in: stripped, case folded.

    Examples
    --------
    >>> marker_key("  Bad Input "), marker_key("#n/a")
    ('bad input', '#n/a')
    """
    return text.strip().casefold()


def parse_bad_values(text: str | None) -> tuple[str, ...]:
    """The site's extra markers from ``--bad-values "Text1,Text2"`` (empty items dropped).

    Examples
    --------
    >>> parse_bad_values("Calibrating, Scan Off,,")
    ('Calibrating', 'Scan Off')
    >>> parse_bad_values(None)
    ()
    """
    if not text:
        return ()
    return tuple(item.strip() for item in text.split(",") if item.strip())


def find_bad_marks(series: pd.Series, extra: Iterable[str] = ()) -> BadMarks:
    """The cells of ``series`` that hold a bad-value marker, and the count of each text.

    Parameters
    ----------
    series : pandas.Series
        One column as read (text cells as strings; a float column's NaN counts as ``NaN``).
    extra : iterable of str
        Site-specific markers besides :data:`DEFAULT_BAD_VALUES`.

    Returns
    -------
    mask, counts
        True where the cell is a marker; the number of cells per marker, keyed by the text as it
        first appears in the column (stripped; ``""`` for empty cells).

    Examples
    --------
    >>> mask, counts = find_bad_marks(pd.Series(["1.5", " bad input", "#N/A", "Bad Input", ""]))
    >>> mask.tolist(), dict(counts)
    ([False, True, True, True, True], {'bad input': 2, '#N/A': 1, '': 1})
    """
    markers = {marker_key(text) for text in (*DEFAULT_BAD_VALUES, *extra)}
    if pd.api.types.is_numeric_dtype(series.dtype) and not pd.api.types.is_bool_dtype(series.dtype):
        # a numeric column (Parquet, or pandas' fast path) can only hold NaN as "no sample"
        values = np.asarray(series.to_numpy(dtype=float, na_value=np.nan), dtype=np.float64)
        mask = np.isnan(values) if "nan" in markers else np.zeros(values.size, dtype=bool)
        return mask, Counter({"NaN": int(mask.sum())}) if mask.any() else Counter()
    text = series.astype(str).str.strip()
    keys = text.str.casefold()
    mask = np.asarray(keys.isin(markers).to_numpy(), dtype=bool)
    if series.isna().any():  # a None or NaN object cell (Parquet) is a missing sample as well
        mask |= np.asarray(series.isna().to_numpy(), dtype=bool)
        text = text.where(~series.isna(), "NaN")
        keys = text.str.casefold()
    first: dict[str, str] = {}
    counts: Counter[str] = Counter()
    for key, shown in zip(keys[mask], text[mask], strict=True):
        counts[first.setdefault(key, shown)] += 1
    return mask, counts


def describe_bad_marks(column: str, counts: Counter[str], rows: Sequence[int] = ()) -> str:
    """``"12 samples marked bad in column flow: 8 'Bad Input', 4 '#N/A'"``.

    Examples
    --------
    >>> describe_bad_marks("flow", Counter({"Bad Input": 8, "#N/A": 4}))
    "12 samples marked bad in column flow: 8 'Bad Input', 4 '#N/A'"
    >>> describe_bad_marks("q", Counter({"#N/A": 2, "Bad": 1, "Comm Fail": 1, "": 1, "No Data": 1}))
    "6 samples marked bad in column q: 2 '#N/A', 1 'Bad', 1 'Comm Fail', 1 empty, 1 'No Data'"
    >>> describe_bad_marks("u", Counter({"": 1}), rows=[301])
    '1 sample marked bad in column u: 1 empty (data row 301)'
    """
    total = sum(counts.values())
    ranked = counts.most_common()
    # every text counted by itself (the markers are few: the known ones and the user's), an
    # empty cell as "empty": lumping them as "other" hid which marker the user's data held
    listed = ", ".join(
        f"{count} empty" if text == "" else f"{count} {text!r}" for text, count in ranked
    )
    where = ""
    if rows:
        shown = ", ".join(str(row) for row in rows[:3]) + (", ..." if len(rows) > 3 else "")
        where = f" (data row{'s' if len(rows) > 1 else ''} {shown})"
    noun = "sample" if total == 1 else "samples"
    return f"{total} {noun} marked bad in column {column}: {listed}{where}"
