"""``fuelid tune --schedule`` with --simulate or --sweep: refused in one line, not dropped.

A new user ran ``tune --schedule --simulate --plot loop.png`` and got the schedule only, its
figure written where the help promised the closed-loop one.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fuelid.cli import app

runner = CliRunner()


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        (["--simulate"], "--simulate"),
        (["--sweep", "10"], "--sweep"),
        (["--simulate", "--sweep", "10"], "--simulate and --sweep"),
    ],
)
def test_schedule_refuses_simulate_and_sweep(tmp_path: Path, extra: list[str], named: str) -> None:
    plot = tmp_path / "loop.png"
    args = ["tune", "--K", "8.8", "--T", "1.0", "--delay", "0.5", "--schedule", *extra]
    result = runner.invoke(app, [*args, "--plot", str(plot)])
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert "--schedule" in lines[0]
    assert named in lines[0]
    assert not plot.exists()


def test_plot_help_says_what_it_writes_in_each_mode() -> None:
    result = runner.invoke(app, ["tune", "--help"], env={"COLUMNS": "200"})
    assert result.exit_code == 0
    # the help is wrapped, at a hyphen too ("closed-\n loop")
    text = " ".join(re.sub(r"-\n\s+", "-", result.stdout).replace("│", " ").split())
    assert "the closed-loop figure, or with --schedule the gain schedule" in text
