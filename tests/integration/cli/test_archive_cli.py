"""``fuelid archive``: the table, ``--json`` (every key in docs/reference/json.md), exit 2.

The store (:func:`support.archive.days_store`) holds four whole UTC days at one sample per
10 s (8,640 a day); ``--before 2026-01-03`` archives exactly the first two.
"""

from __future__ import annotations

import json
import re
import shutil
import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from fuelid.cli import main
from support.archive import DATES, days_store

REFERENCE = Path(__file__).resolve().parents[3] / "docs" / "reference"
PER_DAY = 8640


@pytest.fixture(scope="module")
def template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return days_store(tmp_path_factory.mktemp("days") / "loop.db")


@pytest.fixture
def store_path(template: Path, tmp_path: Path) -> Path:
    target = tmp_path / "loop.db"
    shutil.copyfile(template, target)
    return target


def test_the_table_names_each_day_and_the_totals(
    store_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["archive", "--store", str(store_path), "--to", str(tmp_path / "a")]
    assert main([*argv, "--before", DATES[2]]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[:3] == ["date", "rows", "MB"]
    assert [line.split()[:2] for line in out[1:3]] == [[DATES[0], str(PER_DAY)], [DATES[1], "8640"]]
    assert out[3].startswith(f"2 day(s) of loop line-x before {DATES[2]}: {2 * PER_DAY} rows")
    assert "no service ran" in out[4]


def test_no_finished_day_says_so_and_how_to_take_the_current_one(
    store_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["archive", "--store", str(store_path), "--to", str(tmp_path / "a")]
    assert main([*argv, "--before", DATES[0]]) == 0  # the first day: nothing before it
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"no finished day of loop line-x before {DATES[0]}: nothing archived")
    assert "--before YYYY-MM-DD" in out[0]
    assert "nan" not in " ".join(out)


def _keys(data: Any) -> Iterator[str]:
    if isinstance(data, dict):
        for key, value in data.items():
            yield key
            if key not in ("options", "units"):
                yield from _keys(value)
    elif isinstance(data, list):
        for item in data:
            yield from _keys(item)


def _documented() -> set[str]:
    text = re.sub(
        r"^\s*(```|~~~).*?^\s*\1",
        "",
        (REFERENCE / "json.md").read_text(encoding="utf-8"),
        flags=re.DOTALL | re.MULTILINE,
    )
    names: set[str] = set()
    for span in re.findall(r"`([^`]+)`", text):
        names.update(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", span))
    return names


def test_json_reports_the_days_and_every_key_is_documented(
    store_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["archive", "--store", str(store_path), "--to", str(tmp_path / "a"), "--json"]
    assert main([*argv, "--before", DATES[2]]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [d["date"] for d in data["days"]] == list(DATES[:2])
    assert data["rows"] == 2 * PER_DAY
    assert data["loop_id"] == "line-x"
    assert data["bytes_written"] == data["parquet_bytes"] > 0
    assert data["compression"] == pytest.approx(data["store_bytes"] / data["parquet_bytes"])
    missing = sorted(set(_keys(data)) - _documented())
    assert not missing, f"fuelid archive --json keys not in json.md: {missing}"
    # a second run writes nothing and says so
    assert main([*argv, "--before", DATES[2]]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["bytes_written"] == 0
    assert [d["written"] for d in again["days"]] == [False, False]


def _exit_2(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    return err


def test_bad_input_is_one_line_and_exit_2(
    store_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    to = ["--to", str(tmp_path / "a")]
    assert "no such store" in _exit_2(
        ["archive", "--store", str(tmp_path / "none.db"), *to], capsys
    )
    other = tmp_path / "other.db"
    sqlite3.connect(other).execute("CREATE TABLE t(x)").connection.close()
    assert "not a fuelid store" in _exit_2(["archive", "--store", str(other), *to], capsys)
    text = tmp_path / "notes.txt"
    text.write_text("hello\n" * 100)
    assert "not a fuelid store" in _exit_2(["archive", "--store", str(text), *to], capsys)
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert "cannot write to the archive folder" in _exit_2(
        ["archive", "--store", str(store_path), "--to", str(blocker / "a")], capsys
    )
    for date in ("2026-13-01", "yesterday", "2026-1-5"):
        message = _exit_2(["archive", "--store", str(store_path), *to, "--before", date], capsys)
        assert "is not a date" in message
    con = sqlite3.connect(store_path)
    con.execute("DELETE FROM meta WHERE key = 'loop_id'")
    con.commit()
    con.close()
    assert "no loop id" in _exit_2(["archive", "--store", str(store_path), *to], capsys)
    assert not (tmp_path / "a" / "samples").exists()  # nothing was written by any of them
