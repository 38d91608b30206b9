"""The site file's side of excitation on demand (issue 40): roles, the ring field, ``[excitation]``.

Every rule is checked with its one-line reason, naming the key: the roles ``excitation`` (read
and write, in V) and ``run``, the ring field ``excitation``, the table's keys and bounds, and
what excitation on needs (amplitude, ``write.excitation``, ``write.heartbeat``,
``tags.excitation``, ``tags.mode``); ``missing()`` lists ``tags.run`` only with excitation on.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.errors import ConfigError
from fuelid.online import ServiceSite, load_service_site
from fuelid.plc.site import (
    READ_ROLES,
    RING_DEFAULT_FIELDS,
    RING_FIELDS,
    ROLE_UNITS,
    WRITE_ROLE_UNITS,
    WRITE_ROLES,
    Excitation,
)

runner = CliRunner()
DOCS = Path(__file__).resolve().parents[3] / "docs" / "reference" / "site-file.md"

BASE = """\
[site]
name = "tunnel 2 fuel loop"
[plc]
protocol = "modbus"
host = "127.0.0.1"
port = 5020
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
"""
MODE = '[tags.mode]\naddress = "ir:30"\ntype = "uint16"\n'
TAG_EXCITATION = '[tags.excitation]\naddress = "ir:32"\ntype = "float32"\nunit = "V"\n'
TAG_RUN = '[tags.run]\naddress = "di:0"\ntype = "bool"\n'
HEARTBEAT = '[write.heartbeat]\naddress = "hr:206"\ntype = "uint16"\n'
WRITE_EXCITATION = '[write.excitation]\naddress = "hr:208"\ntype = "float32"\nunit = "V"\n'
ON = '[excitation]\nmode = "always"\namplitude = 0.1\n'
COMPLETE = BASE + MODE + TAG_EXCITATION + HEARTBEAT + WRITE_EXCITATION
"""Everything excitation on needs, without the table itself."""


def _load(tmp_path: Path, text: str) -> ServiceSite:
    path = tmp_path / "site.toml"
    path.write_text(text, encoding="utf-8")
    return load_service_site(path)


def _refused(tmp_path: Path, text: str) -> str:
    """The one-line reason of a refused file (also what ``site check`` prints, exit 2)."""
    with pytest.raises(ConfigError) as caught:
        _load(tmp_path, text)
    message = str(caught.value)
    assert "\n" not in message
    result = runner.invoke(app, ["site", "check", "--config", str(tmp_path / "site.toml")])
    assert result.exit_code == 2
    assert len(result.stderr.strip().splitlines()) == 1
    return message


def test_the_new_roles_and_the_ring_field_are_known() -> None:
    assert READ_ROLES[-2:] == ("excitation", "run")
    assert "excitation" in WRITE_ROLES
    assert ROLE_UNITS["excitation"] == ("V",)
    assert WRITE_ROLE_UNITS["excitation"] == ("V",)
    assert RING_FIELDS[-1] == "excitation"  # after the others
    # the default record is the layout before the field: an old site's ring reads as before
    assert RING_DEFAULT_FIELDS == ("seq", "command", "flow", "setpoint")


def test_a_site_without_the_table_has_excitation_off_with_the_documented_defaults(
    tmp_path: Path,
) -> None:
    site = _load(tmp_path, BASE)
    assert site.excitation == Excitation()
    e = site.excitation
    assert (e.mode, e.target, e.amplitude, e.max_share) == ("off", "output", None, 0.3)
    assert (e.wait_after_move_s, e.margin_to_limits) == (None, None)
    # off: nothing else is needed, and neither the signal nor the run flag is "missing"
    assert not [line for line in site.missing() if line.startswith(("run", "excitation"))]


def test_the_read_and_write_excitation_and_the_run_flag_are_accepted(tmp_path: Path) -> None:
    site = _load(tmp_path, COMPLETE + TAG_RUN)
    assert site.tags["excitation"].unit == "V"
    assert site.write["excitation"].unit == "V"
    assert site.tags["run"].type == "bool"
    for run in ('type = "uint16"', 'type = "float32"', 'type = "int16"\nunit = "flag"'):
        text = BASE + f'[tags.run]\naddress = "ir:40"\n{run}\n'
        assert "run" in _load(tmp_path, text).tags  # any type, any unit


@pytest.mark.parametrize(
    ("text", "key"),
    [
        (BASE + TAG_EXCITATION.replace('unit = "V"', 'unit = "mV"'), "tags.excitation.unit"),
        (BASE + TAG_EXCITATION.replace('unit = "V"\n', ""), "tags.excitation.unit"),
        (BASE + WRITE_EXCITATION.replace('unit = "V"', 'unit = "%"'), "write.excitation.unit"),
    ],
)
def test_the_excitation_must_be_in_volts_on_both_sides(tmp_path: Path, text: str, key: str) -> None:
    message = _refused(tmp_path, text)
    assert f"{key}: " in message
    assert "the test signal is in V: scale the raw value" in message
    assert 'say unit = "V"' in message


def test_a_scaled_excitation_in_volts_is_accepted(tmp_path: Path) -> None:
    scaled = '[tags.excitation]\naddress = "ir:32"\ntype = "int16"\n'
    scaled += 'raw = [-27648, 27648]\neng = [-1.0, 1.0]\nunit = "V"\n'
    site = _load(tmp_path, BASE + scaled)
    assert site.tags["excitation"].to_engineering(13824) == pytest.approx(0.5)


@pytest.mark.parametrize(
    ("table", "key", "reason"),
    [
        ('mode = "sometimes"', "excitation.mode", "'sometimes' is not one of the known"),
        ('target = "setpoint"', "excitation.target", "'setpoint' is not one of the known"),
        ("amplitude = 0.0", "excitation.amplitude", "greater than 0"),
        ("amplitude = -0.1", "excitation.amplitude", "greater than 0"),
        ("amplitude = inf", "excitation.amplitude", "finite"),
        ("max_share = 0.0", "excitation.max_share", "greater than 0"),
        ("max_share = 1.5", "excitation.max_share", "less than or equal to 1"),
        ("wait_after_move_s = -1.0", "excitation.wait_after_move_s", "greater than or equal"),
        ("margin_to_limits = -0.2", "excitation.margin_to_limits", "greater than or equal"),
        ("amplitud = 0.1", "excitation.amplitud", "unknown key"),
    ],
)
def test_bad_keys_of_the_table_are_refused_with_the_key(
    tmp_path: Path, table: str, key: str, reason: str
) -> None:
    message = _refused(tmp_path, BASE + f"[excitation]\n{table}\n")
    assert f"{key}: " in message
    assert reason in message


def test_the_bounds_themselves_are_accepted(tmp_path: Path) -> None:
    table = "[excitation]\nmax_share = 1.0\nwait_after_move_s = 0.0\nmargin_to_limits = 0.0\n"
    e = _load(tmp_path, BASE + table).excitation
    assert (e.max_share, e.wait_after_move_s, e.margin_to_limits) == (1.0, 0.0, 0.0)
    # off with an amplitude is fine: the amplitude waits for the mode
    assert _load(tmp_path, BASE + "[excitation]\namplitude = 0.2\n").excitation.amplitude == 0.2


@pytest.mark.parametrize("mode", ["when_unidentified", "always"])
def test_excitation_on_without_an_amplitude_is_refused(tmp_path: Path, mode: str) -> None:
    message = _refused(tmp_path, COMPLETE + f'[excitation]\nmode = "{mode}"\n')
    assert re.search(rf"excitation: amplitude is required with mode = '{mode}'", message)


@pytest.mark.parametrize(
    ("left_out", "reason"),
    [
        (
            WRITE_EXCITATION,
            "write.excitation is required with excitation on ([excitation] mode = 'always') "
            "(the register the PLC adds to its PI's output)",
        ),
        (
            HEARTBEAT,
            "write.heartbeat: the PLC zeroes the signal when fuelid's heartbeat is stale: "
            "[write.heartbeat] is required with excitation on",
        ),
        (
            TAG_EXCITATION,
            "tags.excitation is required with excitation on ([excitation] mode = 'always') "
            "(the signal the PLC applied",
        ),
        (
            MODE,
            "tags.mode is required with excitation on ([excitation] mode = 'always') "
            "(no signal in MAN needs to know the mode)",
        ),
    ],
)
def test_excitation_on_needs_its_registers_and_the_mode(
    tmp_path: Path, left_out: str, reason: str
) -> None:
    assert left_out in COMPLETE
    message = _refused(tmp_path, COMPLETE.replace(left_out, "") + ON)
    assert reason in message


def test_excitation_on_with_everything_is_accepted_and_asks_for_the_run_flag(
    tmp_path: Path,
) -> None:
    site = _load(tmp_path, COMPLETE + ON)
    assert (site.excitation.mode, site.excitation.amplitude) == ("always", 0.1)
    assert (
        "run: a wind-tunnel run cannot be told: no signal is held off during a run"
        in site.missing()
    )
    with_run = _load(tmp_path, COMPLETE + TAG_RUN + ON)
    assert not [line for line in with_run.missing() if line.startswith("run")]
    # the heartbeat and the excitation register need no write_back
    assert with_run.online.write_back == "off"
    result = runner.invoke(app, ["site", "check", "--config", str(tmp_path / "site.toml")])
    assert result.exit_code == 0, result.stderr


def test_the_ring_may_carry_the_applied_excitation(tmp_path: Path) -> None:
    ring = '[ring]\nhead = "ir:1000"\naddress = "ir:1002"\nsize = 512\n'
    plain = _load(tmp_path, BASE + ring).ring
    assert plain is not None
    assert plain.fields == list(RING_DEFAULT_FIELDS)
    assert plain.record_registers == 8
    fields = 'fields = ["seq", "command", "flow", "setpoint", "excitation"]\n'
    site = _load(tmp_path, BASE + ring + fields)
    assert site.ring is not None
    assert site.ring.fields[-1] == "excitation"
    assert site.ring.record_registers == 10  # one float32 more
    twice = 'fields = ["seq", "command", "flow", "excitation", "excitation"]\n'
    message = _refused(tmp_path, BASE + ring + twice)
    assert "ring: fields: each of seq, command, flow, setpoint, excitation at most once" in message


def test_the_docs_excitation_example_is_a_valid_site_file(tmp_path: Path) -> None:
    text = DOCS.read_text(encoding="utf-8")
    section = text.split("## The `[excitation]` table", 1)[1]
    (example,) = re.findall(r"```toml\n(.*?)```", section, flags=re.DOTALL)
    tomllib.loads(example)  # valid TOML on its own
    site = _load(tmp_path, BASE + example)
    assert site.excitation.mode == "when_unidentified"
    assert {"excitation", "heartbeat"} <= set(site.write)
    assert {"excitation", "run", "mode"} <= set(site.tags)
