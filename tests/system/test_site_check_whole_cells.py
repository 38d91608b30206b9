"""``fuelid site check`` shows every cell whole: the ring's type, a long role, a unit.

A new user's table read "2048 ×" for the ring's type (its "[seq, command, flow, setpoint]" was
taken for a rich markup tag and dropped) and cut "fuel_temperature" and "V per L/min" short on
an 80-column terminal.
"""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from fuelid.cli import app

runner = CliRunner()

SITE = """\
[site]
name = "loop"
[plc]
protocol = "modbus"
host = "127.0.0.1"
port = 5020
[sampling]
period_s = 0.02
control_period_s = 1.0
[tags.command]
address = "hr:100"
type = "float32"
unit = "V"
[tags.flow]
address = "ir:20"
type = "int16"
raw = [0, 27648]
eng = [0.0, 120.0]
unit = "L/min"
[tags.fuel_temperature]
address = "ir:22"
type = "float32"
unit = "degC"
[tags.kc]
address = "ir:24"
type = "float32"
unit = "V per L/min"
[ring]
head = "ir:100"
address = "ir:1000"
size = 2048
[controller]
form = "ideal"
gain_units = "engineering"
"""


def test_site_check_cells_are_whole_on_a_narrow_terminal(tmp_path: Path) -> None:
    path = tmp_path / "site.toml"
    path.write_text(SITE, encoding="utf-8")
    result = runner.invoke(app, ["site", "check", "--config", str(path)], env={"COLUMNS": "80"})
    assert result.exit_code == 0, result.output
    assert "2048 × [seq, command, flow, setpoint]" in result.stdout
    assert "fuel_temperature" in result.stdout
    assert "V per L/min" in result.stdout
    assert "V per…" not in result.stdout
