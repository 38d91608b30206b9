"""The raw archive of the two fleet loops: value for value, four readers, export from it.

The fleet loops (tests/conftest.py ``fleet_loops``) are 3 h each on 2026-01-01 at 10 Hz:
``line-a`` AUTO, ``line-b`` MAN with 599 samples whose u, y and temperature are NULL. Both are
copied and archived once into one folder (``--before 2026-01-02``: the day is otherwise still
the newest, unfinished one). Expectations are the stores' own rows, read with sqlite3.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.dataset as ds
import pytest

from fuelid.archive import archive_store
from fuelid.archive._writer import ArchiveReport
from fuelid.cli import main
from fuelid.store import SQLiteStore

SAMPLE_COLUMNS = (
    "time, wall_time, seq, u, y, setpoint, fuel_temperature, mode, quality, excitation, run"
)
LOOPS = ("line-a", "line-b")


@pytest.fixture(scope="module")
def archived(
    fleet_loops: dict[str, Any], tmp_path_factory: pytest.TempPathFactory
) -> tuple[Path, dict[str, Any], dict[str, ArchiveReport]]:
    """Both loops copied and archived into one folder: (archive, copies, reports)."""
    from support.fleet import copy_loop

    folder = tmp_path_factory.mktemp("archive")
    copies = {name: copy_loop(loop, folder / "stores") for name, loop in fleet_loops.items()}
    reports = {}
    for name, loop in copies.items():
        with SQLiteStore(loop.path) as store:
            reports[name] = archive_store(store, folder / "archive", before="2026-01-02")
    return folder / "archive", copies, reports


def _store_rows(path: Path, sql: str) -> list[tuple[Any, ...]]:
    con = sqlite3.connect(path)
    try:
        return [tuple(row) for row in con.execute(sql).fetchall()]
    finally:
        con.close()


def _archive_rows(root: Path, kind: str, loop_id: str, sort: list[tuple[str, str]]) -> list[Any]:
    table = ds.dataset(root / kind / f"loop={loop_id}", format="parquet").to_table()
    return [tuple(row.values()) for row in table.sort_by(sort).to_pylist()]


@pytest.mark.parametrize("loop_id", LOOPS)
def test_every_sample_and_event_is_in_the_archive_value_for_value(
    archived: tuple[Path, dict[str, Any], dict[str, ArchiveReport]], loop_id: str
) -> None:
    root, copies, reports = archived
    path = copies[loop_id].path
    store = _store_rows(path, f"SELECT {SAMPLE_COLUMNS} FROM samples ORDER BY time, seq")
    archive = _archive_rows(root, "samples", loop_id, [("time", "ascending"), ("seq", "ascending")])
    assert len(store) == copies[loop_id].samples == reports[loop_id].rows
    assert archive == store  # NULL as None on both sides, floats bit for bit
    # the fixture's missing values are there as nulls (599 on line-b), none on line-a
    nulls = sum(row[4] is None for row in archive)
    assert nulls == (599 if loop_id == "line-b" else 0)
    assert all(row[1] is not None for row in archive)  # wall_time kept
    events = _store_rows(path, "SELECT time, kind, detail, wall_time FROM events ORDER BY time, id")
    assert events  # the restart, at least
    assert _archive_rows(root, "events", loop_id, [("time", "ascending")]) == events


def test_the_loop_file_holds_the_stores_identity(
    archived: tuple[Path, dict[str, Any], dict[str, ArchiveReport]],
) -> None:
    from fuelid.archive import read_loop_info

    root, copies, reports = archived
    for loop_id in LOOPS:
        info = read_loop_info(root, loop_id)
        assert info["loop_id"] == loop_id
        assert info["store_uuid"] == reports[loop_id].store_uuid
        assert info["site_name"] == copies[loop_id].site_name
        assert info["period_s"] == pytest.approx(0.1)
        # no service ran on the fixture's stores: no settings, no plant file, and why
        assert (info["settings"], info["plant"]) == (None, None)
        assert "no service" in info["plant_note"]


def _expected(copies: dict[str, Any]) -> tuple[int, float]:
    """Rows and the sum of y over both stores (SQL ignores NULL as the readers ignore null)."""
    n, total = 0, 0.0
    for loop in copies.values():
        rows, y = _store_rows(loop.path, "SELECT count(*), sum(y) FROM samples")[0]
        n, total = n + int(rows), total + float(y)
    return n, total


# Dask 2026.8's parquet reader calls DataFrame.reset_index(inplace=True), which pandas 3.1
# deprecates (Pandas4Warning): Dask's code, not the archive's; exactly that warning is ignored
@pytest.mark.filterwarnings(
    "ignore:The inplace keyword in DataFrame.reset_index is deprecated:pandas.errors.Pandas4Warning"
)
def test_pandas_pyarrow_duckdb_and_dask_read_the_same_rows(
    archived: tuple[Path, dict[str, Any], dict[str, ArchiveReport]],
) -> None:
    import duckdb
    import pandas as pd

    dd = pytest.importorskip("dask.dataframe")
    root, copies, _ = archived
    rows, y_sum = _expected(copies)
    samples = root / "samples"
    # sums in another order: equal to within rounding, 1e-9 relative (about 2e5 terms)
    frame = pd.read_parquet(samples)
    assert len(frame) == rows
    assert frame["y"].sum() == pytest.approx(y_sum, rel=1e-9)
    assert sorted(frame["loop"].astype(str).unique()) == list(LOOPS)

    dataset = ds.dataset(samples, format="parquet", partitioning="hive")
    table = dataset.to_table()
    assert table.num_rows == rows
    assert pa.types.is_string(table.schema.field("loop").type)  # keys from the path only
    line_b = dataset.to_table(filter=ds.field("loop") == "line-b")
    assert line_b.num_rows == copies["line-b"].samples

    pattern = str(samples / "**" / "*.parquet")
    con = duckdb.connect()
    n, y, loops = con.execute(
        f"SELECT count(*), sum(y), count(DISTINCT loop) FROM read_parquet('{pattern}', "
        "hive_partitioning = true)"
    ).fetchone()
    con.close()
    assert (n, loops) == (rows, 2)
    assert y == pytest.approx(y_sum, rel=1e-9)

    lazy = dd.read_parquet(str(samples))
    assert len(lazy) == rows
    assert float(lazy["y"].sum().compute()) == pytest.approx(y_sum, rel=1e-9)


@pytest.mark.parametrize("loop_id", LOOPS)
def test_export_from_the_archive_equals_export_from_the_store(
    archived: tuple[Path, dict[str, Any], dict[str, ArchiveReport]],
    tmp_path: Path,
    loop_id: str,
    capsys: pytest.CaptureFixture[str],
) -> None:
    root, copies, _ = archived
    loop = copies[loop_id]
    # an hour in the middle: line-b's second hour holds 300 of the missing samples
    lo, hi = str(loop.t_first + 3000.0), str(loop.t_first + 6600.0)
    from_store, from_archive = tmp_path / "store.csv", tmp_path / "archive.csv"
    span = ["--from", lo, "--to", hi]
    assert main(["export", "--store", str(loop.path), "-o", str(from_store), *span]) == 0
    assert (
        main(["export", "--store", str(root), "--loop", loop_id, "-o", str(from_archive), *span])
        == 0
    )
    text = from_store.read_text(encoding="utf-8")
    assert len(text.splitlines()) > 30_000  # ~36,000 ok samples of the hour, and a header
    assert from_archive.read_text(encoding="utf-8") == text
    capsys.readouterr()


def test_export_from_an_archive_refuses_a_missing_or_unnamed_loop(
    archived: tuple[Path, dict[str, Any], dict[str, ArchiveReport]],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    root, _, _ = archived
    out = str(tmp_path / "x.csv")
    assert main(["export", "--store", str(root), "-o", out]) == 2
    assert "name one with --loop" in capsys.readouterr().err
    assert main(["export", "--store", str(root), "--loop", "line-z", "-o", out]) == 2
    assert "no loop 'line-z'" in capsys.readouterr().err
