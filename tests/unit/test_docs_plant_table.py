"""The reference plant's table in docs/explanation/physics.md matches ``fuelid plant info``.

The table is typed in the page (it explains the numbers); this test keeps it true: every
number in a row equals what ``plant info --json`` gives at that command and fuel temperature,
rounded to the digits the table prints.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fuelid.cli import app

PAGE = Path(__file__).resolve().parents[2] / "docs" / "explanation" / "physics.md"
COLUMNS = ("u", "fuel", "flow", "pressure", "leakage", "Re", "K", "T", "settling")


def _rows() -> list[list[str]]:
    text = PAGE.read_text(encoding="utf-8")
    section = text[text.index("{#reference-plant}") :]
    rows = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == len(COLUMNS) and re.fullmatch(r"[0-9.]+", cells[0]):
            rows.append(cells)
    return rows


def _number(cell: str) -> float:
    """A table cell as a float: '−20' (a minus sign), '1.0·10⁴'."""
    cell = cell.replace("−", "-")
    match = re.fullmatch(r"(-?[0-9.]+)·10([⁰¹²³⁴⁵⁶⁷⁸⁹]+)", cell)
    if match:
        power = int(match[2].translate(str.maketrans("⁰¹²³⁴⁵⁶⁷⁸⁹", "0123456789")))
        return float(match[1]) * 10.0**power
    return float(cell)


def _decimals(cell: str) -> int:
    mantissa = cell.split("·")[0]
    return len(mantissa.split(".")[1]) if "." in mantissa else 0


ROWS = _rows()


def test_the_page_has_the_table() -> None:
    assert len(ROWS) >= 5


@pytest.mark.parametrize("row", ROWS, ids=[f"u={r[0]},T={r[1]}" for r in ROWS])
def test_each_row_is_what_plant_info_says(row: list[str]) -> None:
    u, fuel = _number(row[0]), _number(row[1])
    result = CliRunner().invoke(
        app, ["plant", "info", "--u", f"{u}", "--fuel-temp", f"{fuel}", "--json"]
    )
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    op, model = data["operating_point"], data["model"]
    computed = {
        "flow": op["flow"],
        "pressure": op["pump_pressure"],
        "leakage": op["leakage"],
        "Re": op["reynolds"],
        "K": model["K"],
        "T": model["T"],
        "settling": model["settling_time"],
    }
    for name, cell in zip(COLUMNS[2:], row[2:], strict=True):
        if "·10" in cell:  # two significant digits of a power of ten
            assert _number(cell) == pytest.approx(computed[name], rel=0.05), name
        else:
            assert f"{computed[name]:.{_decimals(cell)}f}" == cell.replace("−", "-"), name
