"""The load note counts bad cells per text: an empty cell and each user marker by itself.

A historian export with five known markers, an empty cell and a ``--bad-values "No Data"`` cell
was described as "... 2 other", while the docs promise the cells "counted per column and text".
"""

from __future__ import annotations

from collections import Counter

import pandas as pd

from fuelid.io._bad_values import describe_bad_marks, find_bad_marks


def test_every_text_is_counted_by_itself() -> None:
    cells = ["1.0", "#N/A", "Bad Input", "I/O Timeout", "Comm Fail", "", "No Data", "#N/A"]
    mask, counts = find_bad_marks(pd.Series(cells), extra=["No Data"])
    assert int(mask.sum()) == 7
    note = describe_bad_marks("FT201.PV", counts)
    assert "other" not in note
    assert "1 empty" in note
    assert "1 'No Data'" in note
    assert "2 '#N/A'" in note
    for text in ("Bad Input", "I/O Timeout", "Comm Fail"):
        assert f"1 {text!r}" in note


def test_note_totals_the_listed_counts() -> None:
    counts = Counter({"#N/A": 3, "Bad": 2, "Shutdown": 1, "NaN": 1, "": 2, "Scan Off": 1})
    note = describe_bad_marks("q", counts)
    assert note.startswith("10 samples marked bad in column q: ")
    listed = note.split(": ", 1)[1]
    assert sum(int(part.split()[0]) for part in listed.split(", ")) == 10
