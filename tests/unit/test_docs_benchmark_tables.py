"""benchmarks/_docs_table.py: every benchmark page says what produced it, and the index lists all.

Pages are written into a temporary folder here: ``make test`` never writes into docs/.
"""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def tables() -> ModuleType:
    path = ROOT / "benchmarks" / "_docs_table.py"
    spec = importlib.util.spec_from_file_location("fuelid_bench_docs_table", path)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_a_page_states_machine_date_versions_and_command(
    tables: ModuleType, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    table = tables.Table(("case", "best s"), ("s", ".3f"), (10, 8))
    table.add("a | b", 1.23456)
    page = tables.write_page("simulate", "Intro.", [table], seconds=2.0, docs=tmp_path)
    text = page.read_text(encoding="utf-8")
    assert text.startswith("# Simulation speed\n")
    assert re.search(r"Measured on \d{4}-\d\d-\d\d: .+, \d+ cores", text)
    assert "numpy " in text
    assert "Command: `python " in text
    assert "| a \\| b | 1.235 |" in text  # a pipe in a cell does not break the table
    assert "a | b" in capsys.readouterr().out  # the row is printed as before
    assert "[Simulation speed](simulate.md)" in (tmp_path / "index.md").read_text(encoding="utf-8")


def test_placeholders_and_the_index_cover_every_benchmark(
    tables: ModuleType, tmp_path: Path
) -> None:
    for name in tables.BENCHMARKS:
        tables.placeholder(name, tmp_path)
    index = tables.write_index(tmp_path).read_text(encoding="utf-8")
    for name in tables.BENCHMARKS:
        assert f"({name}.md)" in index
        assert tables.NOT_RUN in (tmp_path / f"{name}.md").read_text(encoding="utf-8")
    assert "measured" not in index


def test_every_benchmark_page_of_the_docs_is_in_the_registry(tables: ModuleType) -> None:
    pages = {p.stem for p in (ROOT / "docs" / "benchmarks").glob("*.md")} - {"index"}
    assert pages == set(tables.BENCHMARKS)
