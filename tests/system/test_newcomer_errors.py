"""Issue 24 item 4.4: what a new user tripped over in the plant file, the logs and the errors.

Every refusal is one line on stderr that ends with a newline, with exit code 2.
"""

from __future__ import annotations

import re
import socket
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.plant import load_plant_config

runner = CliRunner()

SITE = """\
[site]
name = "tunnel 2 fuel loop"
[plc]
protocol = "modbus"
host = "127.0.0.1"
port = {port}
[sampling]
period_s = 0.02
control_period_s = 1.0
[tags.command]
address = "hr:100"
type = "float32"
unit = "V"
[tags.flow]
address = "ir:20"
type = "float32"
unit = "L/min"
"""


def _log(path: Path, header: str = "t_s,u_V,q_Lpm") -> Path:
    t = 0.02 * np.arange(600)
    u = np.where(t >= 2.0, 3.5, 3.0)
    y = 40.0 + 8.0 * (1.0 - np.exp(-np.clip(t - 2.2, 0.0, None) / 1.3)) + 0.05 * np.sin(7 * t)
    rows = [f"{a:.2f},{b:g},{c:.5f}" for a, b, c in zip(t, u, y, strict=True)]
    path.write_text("\n".join([header, *rows]) + "\n", encoding="utf-8")
    return path


def _refused(*args: str) -> str:
    """Run the CLI in a subprocess; the stderr of its refusal, checked to be one line."""
    done = subprocess.run(
        [sys.executable, "-m", "fuelid", *args], capture_output=True, timeout=120, check=False
    )
    assert done.returncode == 2, done.stderr.decode()
    assert done.stderr.endswith(b"\n"), done.stderr
    lines = done.stderr.decode().splitlines()
    assert lines[-1].startswith("error: "), lines
    assert "Traceback" not in done.stderr.decode()
    return lines[-1]


def test_plant_init_writes_every_parameter_with_its_unit_and_meaning(tmp_path: Path):
    out = tmp_path / "my_plant.toml"
    result = runner.invoke(app, ["plant", "init", str(out)])
    assert result.exit_code == 0, result.stderr
    text = out.read_text(encoding="utf-8")
    lines = text.splitlines()
    keys = [i for i, line in enumerate(lines) if re.match(r"^[A-Za-z_0-9]+\s*=", line)]
    assert len(keys) >= 30
    for i in keys:
        # the comment above a key: `key = value` lines stay plain to edit (and for calibrate)
        comment = lines[i - 1]
        assert comment.startswith("# "), f"no comment: {lines[i]}"
        assert len(comment) > 12, comment
        key = lines[i].split("=", 1)[0].strip()
        if key not in {"name", "description", "allow_extrapolation", "count"}:
            assert re.search(r"\[[^\]]+\]$", comment), f"no unit in brackets: {comment}"
    assert tomllib.loads(text)
    assert load_plant_config(out).model_dump() == load_plant_config().model_dump()


def test_a_folder_or_a_site_file_where_a_log_or_plant_file_is_expected(tmp_path: Path):
    log = _log(tmp_path / "log.csv")
    site = tmp_path / "site.toml"
    site.write_text(SITE.format(port=5020), encoding="utf-8")
    line = _refused("identify", str(tmp_path))
    assert "is a folder" in line
    line = _refused("identify", str(site))
    assert "site.toml is a site file (it has a [plc] table)" in line
    line = _refused("identify", str(log), "--config", str(site))
    assert "site.toml is a site file (it has a [plc] table); --config takes a plant file" in line
    line = _refused("identify", str(log), "--config", str(tmp_path))
    assert "is a folder" in line


def test_all_missing_columns_are_named_at_once(tmp_path: Path):
    log = _log(tmp_path / "odd.csv", header="t,u,y_raw")
    line = _refused("identify", str(log))
    assert "missing columns: 't_s' (time), 'u_V' (input), 'q_Lpm' (output)" in line
    assert "columns present: t, u, y_raw" in line


def test_a_flow_column_without_a_unit_is_named(tmp_path: Path):
    log = _log(tmp_path / "F.csv", header="t_s,u_V,F")
    result = runner.invoke(app, ["identify", str(log), "--output-col", "F"])
    assert result.exit_code == 0, result.stderr
    assert "flow column 'F' has no unit: give --flow-unit" in " ".join(result.stderr.split())
    assert "output unit" not in result.stdout
    given = runner.invoke(app, ["identify", str(log), "--output-col", "F", "--flow-unit", "L/min"])
    assert given.exit_code == 0, given.stderr
    assert "has no unit" not in given.stderr
    assert "(L/min)/V" in given.stdout


def test_every_refusal_line_ends_with_a_newline(tmp_path: Path):
    log = _log(tmp_path / "log.csv")
    for args in (
        ["identify", str(tmp_path / "absent.csv")],
        ["identify", str(log), "--order", "7"],
        ["report", str(log), "--flow-span", "-1"],
        ["plant", "info", "--fuel-temp", "warm"],
        ["tune", "--K", "1"],
    ):
        _refused(*args)


def test_every_command_s_refusal_ends_with_a_newline(tmp_path: Path):
    """The same through the runner, over every command that reads a file a newcomer may mix up."""
    log = _log(tmp_path / "log.csv")
    site = tmp_path / "site.toml"
    site.write_text(SITE.format(port=5020), encoding="utf-8")
    folder = str(tmp_path)
    assert runner.invoke(app, ["plant", "init", str(tmp_path / "plant.toml")]).exit_code == 0
    cases = [
        ["report", folder],
        ["report", str(site)],
        ["calibrate", folder, "--free", "vfd.lag_s", "--fuel-temp", "20"],
        ["calibrate", str(log), "--free", "vfd.lag_s", "--config", str(site)],
        ["plant", "info", "--config", folder],
        ["plant", "info", "--config", str(site)],
        ["tune", "--K", "1", "--T", "1", "--config", str(site)],
        ["simulate", str(tmp_path / "out.csv"), "--config", folder],
        ["site", "check", "--config", folder],
        ["site", "check", "--config", str(tmp_path / "absent.toml")],
        ["site", "check", "--config", str(tmp_path / "plant.toml")],
        ["record", "--config", str(tmp_path / "plant.toml")],
        ["identify", str(log), "--bad-values", "x", "--input-col", "volts"],
    ]
    for args in cases:
        result = runner.invoke(app, args)
        if args[-1].endswith("plant.toml"):
            assert "is a plant file (it has a [vfd] table)" in result.stderr
        assert result.exit_code == 2, (args, result.stderr)
        assert result.stderr_bytes.endswith(b"\n"), args
        assert result.stderr.count("\n") == 1, (args, result.stderr)
        assert result.stderr.startswith("error: "), (args, result.stderr)


def _closed_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def test_record_that_stored_no_sample_exits_2(tmp_path: Path):
    pytest.importorskip("pymodbus", reason="the [plc] extra (pymodbus) is not installed")
    site = tmp_path / "site.toml"
    site.write_text(SITE.format(port=_closed_port()), encoding="utf-8")
    line = _refused(
        "record", "--config", str(site), "--store", str(tmp_path / "s.db"), "--duration", "1"
    )
    assert "no sample" in line


def test_site_check_shows_long_addresses_whole(tmp_path: Path):
    pytest.importorskip("asyncua", reason="the [plc] extra (asyncua) is not installed")
    node = "ns=2;s=Channel1.Device1.FuelLine.FlowMeter.Value"
    text = (
        SITE.format(port=4840)
        .replace(
            'protocol = "modbus"\nhost = "127.0.0.1"\nport = 4840',
            'protocol = "opcua"\nendpoint = "opc.tcp://127.0.0.1:4840"',
        )
        .replace('address = "ir:20"\ntype = "float32"', f'address = "{node}"\ntype = "float32"')
        .replace('address = "hr:100"\ntype = "float32"', 'address = "ns=2;s=Cmd"\ntype = "float32"')
    )
    site = tmp_path / "site.toml"
    site.write_text(text, encoding="utf-8")
    result = runner.invoke(app, ["site", "check", "--config", str(site)])
    assert result.exit_code == 0, result.stderr
    assert node in result.stdout
