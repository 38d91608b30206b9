"""``fuelid plant info --help`` gives the model the table prints, T2 included.

The help said K·e^(−τs)/((T·s+1)(T_f·s+1)) while the table had a T2 row.
"""

from __future__ import annotations

import re

from typer.testing import CliRunner

from fuelid.cli import app

runner = CliRunner()


def _text(output: str) -> str:
    return " ".join(re.sub(r"-\n\s+", "-", output).replace("│", " ").split())


def test_help_model_has_the_rows_the_table_prints() -> None:
    help_text = _text(runner.invoke(app, ["plant", "info", "--help"]).stdout)
    assert "K·e^(−τs)/((T·s+1)(T2·s+1)(T_f·s+1))" in help_text
    assert "T2 = 0" in help_text
    table = runner.invoke(app, ["plant", "info"], env={"COLUMNS": "120"})
    assert table.exit_code == 0, table.output
    assert "T2 (second process lag)" in table.stdout
