"""Issue 24 item 4.1: historian bad-value markers load as missing samples, named in the notes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.errors import DataError
from fuelid.io.logs import load_log

H = 0.02
N = 400


def _rows() -> list[list[str]]:
    """A step response sampled every 20 ms, as text cells."""
    t = H * np.arange(N)
    u = np.where(t >= 1.0, 1.5, 1.0)
    y = 14.6 + 3.5 * (1.0 - np.exp(-np.clip(t - 1.0, 0.0, None) / 1.2))
    return [[f"{a:.2f}", f"{b:g}", f"{c:.6f}"] for a, b, c in zip(t, u, y, strict=True)]


def _write(path: Path, rows: list[list[str]]) -> Path:
    lines = ["t_s,u_V,q_Lpm"] + [",".join(row) for row in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_historian_markers_are_gaps_counted_by_text(tmp_path: Path) -> None:
    rows = _rows()
    for i in (100, 101, 102, 103, 104, 105, 106, 107):
        rows[i][2] = " bad input " if i % 2 else "Bad Input"
    for i in (250, 251, 252, 253):
        rows[i][2] = "#N/A"
    rows[300][1] = ""
    data = load_log(_write(tmp_path / "historian.csv", rows))
    notes = " | ".join(data.notes)
    assert "12 samples marked bad in column q_Lpm: 8 'Bad Input', 4 '#N/A'" in notes
    assert "1 sample marked bad in column u_V: 1 empty" in notes
    assert data.n_samples == N - 13
    assert len(data.segment_starts) == 3  # three stretches of bad samples: four segments
    assert np.all(np.isfinite(data.y))


@pytest.mark.parametrize(
    "marker", ["#N/A", "Bad Input", "Bad", "I/O Timeout", "Comm Fail", "Shutdown", "NaN", "", "nan"]
)
def test_each_default_marker_is_a_missing_sample(tmp_path: Path, marker: str) -> None:
    rows = _rows()
    rows[200][2] = f"  {marker.upper()} "
    data = load_log(_write(tmp_path / "one.csv", rows))
    assert data.n_samples == N - 1
    assert any("1 sample marked bad in column q_Lpm" in note for note in data.notes)


def test_other_text_is_refused_with_column_row_and_text(tmp_path: Path) -> None:
    rows = _rows()
    rows[200][2] = "Calibrating"
    with pytest.raises(DataError, match=r"'q_Lpm'.*data row 201.*'Calibrating'"):
        load_log(_write(tmp_path / "text.csv", rows))


def test_site_specific_markers(tmp_path: Path) -> None:
    rows = _rows()
    rows[200][2] = "Calibrating"
    rows[260][2] = "Scan Off"
    path = _write(tmp_path / "site.csv", rows)
    data = load_log(path, bad_values=("calibrating", " Scan Off"))
    assert data.n_samples == N - 2
    assert any("'Calibrating'" in note and "'Scan Off'" in note for note in data.notes)


def test_bad_values_option_on_the_commands_that_read_logs(tmp_path: Path) -> None:
    rows = _rows()
    rows[200][2] = "Calibrating"
    path = _write(tmp_path / "site.csv", rows)
    runner = CliRunner()
    refused = runner.invoke(app, ["identify", str(path), "--json"])
    assert refused.exit_code == 2
    assert "'Calibrating'" in refused.stderr
    for command in ("identify", "report", "calibrate"):
        result = runner.invoke(app, [command, "--help"])
        assert "--bad-values" in result.stdout, command
    loaded = runner.invoke(
        app, ["identify", str(path), "--json", "--bad-values", "Calibrating,Scan Off"]
    )
    assert loaded.exit_code == 0, loaded.stderr
    assert "1 sample marked bad in column q_Lpm: 1 'Calibrating'" in loaded.stderr
