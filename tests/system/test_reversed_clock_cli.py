"""Issue 37 through the CLI: a backwards clock is refused, a flow that leads its command is named.

The log is written by ``fuelid simulate`` (the built-in reference plant, a 0.5 V step at 10 s,
60 s at 0.02 s). Acceptance, stated before running: the clock reversed → exit 2 and exactly one
line on stderr, ``error: ...`` naming data row 1 and its time (60 s), nothing on stdout; five
swapped rows → exit 0 with today's "timestamps out of order ... sorted by time" warning; the
input and output columns swapped → exit 0, ``diagnostics.lead.leads`` true in the JSON and the
"moves before its command" warning, in the JSON and on stderr; the log as written → no
such warning and ``leads`` false.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from fuelid.cli import app

runner = CliRunner()


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("reversed_clock") / "log.csv"
    result = runner.invoke(app, ["simulate", str(path), "--quiet"])
    assert result.exit_code == 0, result.stderr
    return path


def test_a_clock_that_counts_down_is_refused_in_one_line(log: Path, tmp_path: Path) -> None:
    frame = pd.read_csv(log)
    frame["t_s"] = frame["t_s"].max() - frame["t_s"]  # rows kept in time order
    path = tmp_path / "reversed.csv"
    frame.to_csv(path, index=False)
    for extra in ([], ["--json"]):
        done = subprocess.run(
            [sys.executable, "-m", "fuelid", "identify", str(path), *extra],
            capture_output=True,
            timeout=120,
            check=False,
        )
        stderr = done.stderr.decode()
        assert done.returncode == 2, stderr
        assert done.stdout == b""
        assert stderr.endswith("\n")
        lines = stderr.splitlines()
        assert len(lines) == 1, lines
        assert lines[0].startswith(f"error: {path}: the time column 't_s' runs backwards")
        assert "t = 60 s at data row 1 " in lines[0]
        assert "a reversed clock column, or rows in reverse order" in lines[0]
        assert "Traceback" not in stderr


def test_a_few_swapped_rows_still_load_with_the_warning(log: Path, tmp_path: Path) -> None:
    frame = pd.read_csv(log)
    order = list(range(len(frame)))
    for i in (100, 400, 501, 1700, 2900):
        order[i], order[i + 1] = order[i + 1], order[i]
    path = tmp_path / "swapped_rows.csv"
    frame.iloc[order].to_csv(path, index=False)
    result = runner.invoke(app, ["identify", str(path), "--json"])
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    note = "timestamps out of order (first at data row 102): sorted by time"
    assert note in data["warnings"]
    assert note in " ".join(result.stderr.split())
    assert data["diagnostics"]["lead"]["leads"] is False


def test_swapped_columns_are_said_to_lead_their_command(log: Path, tmp_path: Path) -> None:
    frame = pd.read_csv(log)
    swapped = frame.rename(columns={"u_V": "q_Lpm", "q_Lpm": "u_V"})
    path = tmp_path / "swapped_columns.csv"
    swapped.to_csv(path, index=False)
    result = runner.invoke(app, ["identify", str(path), "--json"])
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    lead = data["diagnostics"]["lead"]
    assert lead["leads"] is True
    assert -2.0 <= lead["peak_lag_s"] <= -0.3
    # the signal check (a "command" of 14…22 V) may come first: it is true as well
    (said,) = [w for w in data["warnings"] if w.startswith("the flow moves before its command")]
    assert "reversed clock" in said
    assert "swapped input and output columns" in said
    assert "the flow moves before its command" in " ".join(result.stderr.split())


def test_the_log_as_written_is_not_said_to_lead(log: Path) -> None:
    result = runner.invoke(app, ["identify", str(log), "--json"])
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert data["diagnostics"]["lead"]["leads"] is False
    assert data["diagnostics"]["lead"]["peak_lag_s"] > 0.3
    assert not any("moves before" in w for w in data["warnings"])
