"""The site file (issue 14, item 1) and the register codec, against hand-computed words."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.errors import ConfigError, DataError
from fuelid.online import load_service_site
from fuelid.plc import decode, encode
from fuelid.plc.site import load_site

runner = CliRunner()

# the issue's example, as written: this shape must work (keys may be added, none renamed)
EXAMPLE = """\
[site]
name = "tunnel 2 fuel loop"
[plc]
protocol = "modbus"          # modbus | opcua | s7 | replay
host = "127.0.0.1"
port = 5020
device_id = 1
word_order = "little"        # 32-bit values: big = ABCD, little = CDAB
byte_swap = false
[sampling]
period_s = 0.02
control_period_s = 1.0
[tags.command]               # u, the VFD command
address = "hr:100"
type = "float32"
unit = "V"
[tags.flow]                  # y, the flowmeter
address = "ir:20"
type = "int16"
raw = [0, 27648]             # optional linear scaling raw → engineering
eng = [0.0, 120.0]
unit = "L/min"
[tags.fuel_temperature]
address = "ir:21"
type = "int16"
raw = [0, 27648]
eng = [-40.0, 80.0]
unit = "degC"
[tags.mode]                  # 0 = MAN, 1 = AUTO
address = "ir:30"
type = "uint16"
"""


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "site.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_the_issues_example_loads_as_written(tmp_path: Path):
    site = load_service_site(_write(tmp_path, EXAMPLE))
    assert site.site.name == "tunnel 2 fuel loop"
    assert (site.plc.protocol, site.plc.port, site.plc.word_order) == ("modbus", 5020, "little")
    assert (site.sampling.period_s, site.sampling.control_period_s) == (0.02, 1.0)
    assert set(site.tags) == {"command", "flow", "fuel_temperature", "mode"}
    # Siemens counts: 27648 is full scale, 13824 half of it
    assert site.tags["flow"].to_engineering(13824) == pytest.approx(60.0)
    assert site.tags["fuel_temperature"].to_engineering(0) == pytest.approx(-40.0)
    assert site.tags["flow"].to_raw(120.0) == pytest.approx(27648.0)
    assert site.store.url == "sqlite:///fuelid.db"
    assert any(line.startswith("setpoint:") for line in site.missing())


@pytest.mark.parametrize(
    ("change", "key", "reason"),
    [
        (('address = "ir:20"', 'address = "30021"'), "tags.flow.address", "not 30001/40001"),
        (('address = "hr:100"', 'address = "coil:3"'), "tags.command.type", "bool"),
        (('unit = "V"', 'unit = "mA"'), "tags.command.unit", "scale the raw value"),
        (("eng = [0.0, 120.0]\n", ""), "tags.flow", "raw and eng together"),
        (('protocol = "modbus"', 'protocol = "profibus"'), "plc.protocol", "modbus"),
        (("control_period_s = 1.0", "control_period_s = 0.01"), "sampling", "shorter"),
        (("[tags.mode]", "[tags.moed]"), "tags.moed", "unknown role"),
        (("device_id = 1", 'device_id = 1\nwordorder = "big"'), "plc.wordorder", "unknown key"),
    ],
)
def test_bad_site_files_are_refused_with_the_key_and_the_reason(
    tmp_path: Path, change: tuple[str, str], key: str, reason: str
):
    old, new = change
    assert old in EXAMPLE
    path = _write(tmp_path, EXAMPLE.replace(old, new, 1))
    with pytest.raises(ConfigError) as caught:
        load_service_site(path)
    message = str(caught.value)
    assert key in message
    assert reason in message
    # the command line: one line on stderr, exit code 2
    result = runner.invoke(app, ["site", "check", "--config", str(path)])
    assert result.exit_code == 2
    assert key in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_flow_and_command_are_the_only_required_tags(tmp_path: Path):
    text = EXAMPLE.split("[tags.fuel_temperature]")[0]
    site = load_service_site(_write(tmp_path, text))
    assert set(site.tags) == {"command", "flow"}
    without_flow = text.split("[tags.flow]")[0]
    with pytest.raises(ConfigError, match=r"tags\.flow is required"):
        load_service_site(_write(tmp_path, without_flow))


OPCUA = 'protocol = "opcua"\nendpoint = "opc.tcp://127.0.0.1:4840/fuel"'
S7 = 'protocol = "s7"'
VALID = {OPCUA: ("ns=2;s=FuelLoop.U", "ns=2;s=FuelLoop.Flow"), S7: ("DB1.DBD0", "DB1.DBD4")}


@pytest.mark.parametrize(
    ("protocol", "address", "type_", "ok"),
    [
        (OPCUA, "ns=2;s=FuelLoop.Kc", "float32", True),
        (OPCUA, "FuelLoop.Kc", "float32", False),
        (S7, "DB1.DBD8", "float32", True),
        (S7, "DB1.DBW8", "float32", False),
        (S7, "DB1.DBX8.3", "bool", True),
        (S7, "DB1.DBX8", "bool", False),
        (S7, "DB1.DBB8", "uint16", False),
    ],
)
def test_addresses_follow_each_protocols_syntax(
    tmp_path: Path, protocol: str, address: str, type_: str, ok: bool
):
    command, flow = VALID[protocol]
    text = (
        f'[site]\nname = "x"\n[plc]\n{protocol}\n'
        f'[tags.command]\naddress = "{command}"\ntype = "float32"\nunit = "V"\n'
        f'[tags.flow]\naddress = "{flow}"\ntype = "float32"\nunit = "L/min"\n'
        f'[tags.kc]\naddress = "{address}"\ntype = "{type_}"\n'
    )
    path = _write(tmp_path, text)
    if ok:
        assert load_service_site(path).tags["kc"].address == address
    else:
        with pytest.raises(ConfigError, match=r"tags\.kc\.(address|type)"):
            load_service_site(path)


@pytest.mark.parametrize(
    ("value", "type_", "word_order", "byte_swap", "registers"),
    [
        # 3.5 = 0x40600000: ABCD, CDAB, BADC, DCBA
        (3.5, "float32", "big", False, [0x4060, 0x0000]),
        (3.5, "float32", "little", False, [0x0000, 0x4060]),
        (3.5, "float32", "big", True, [0x6040, 0x0000]),
        (3.5, "float32", "little", True, [0x0000, 0x6040]),
        # -2 as int16 is 0xFFFE; 70000 as uint32 is 0x00011170
        (-2, "int16", "big", False, [0xFFFE]),
        (70000, "uint32", "big", False, [0x0001, 0x1170]),
        (70000, "uint32", "little", False, [0x1170, 0x0001]),
        (-70000, "int32", "big", False, [0xFFFE, 0xEE90]),
        (27648, "int16", "big", True, [0x006C]),
        (1, "bool", "big", False, [1]),
    ],
)
def test_register_words_match_hand_computed_values(value, type_, word_order, byte_swap, registers):
    assert encode(value, type_, word_order, byte_swap) == registers
    assert decode(registers, type_, word_order, byte_swap) == pytest.approx(value)


def test_float32_words_agree_with_struct_and_out_of_range_integers_are_refused():
    words = encode(-12.625, "float32")
    assert struct.unpack(">f", bytes.fromhex(f"{words[0]:04x}{words[1]:04x}"))[0] == -12.625
    with pytest.raises(DataError, match="does not fit a int16"):
        encode(40000, "int16")
    with pytest.raises(DataError, match="takes 2 register"):
        decode([1], "float32")


def test_site_check_prints_the_tag_map(tmp_path: Path):
    result = runner.invoke(app, ["site", "check", "--config", str(_write(tmp_path, EXAMPLE))])
    assert result.exit_code == 0, result.stderr
    assert "tunnel 2 fuel loop" in result.stdout
    assert "ir:20" in result.stdout
    assert "0…27648 → 0…120 L/min" in result.stdout
    assert "missing" in result.stdout


def test_the_docs_example_is_a_valid_site_file():
    # docs/examples/site.toml is the file the site-file how-to and the README's tour show
    example = Path(__file__).resolve().parents[3] / "docs" / "examples" / "site.toml"
    site = load_service_site(example)
    assert site.controller is not None
    assert site.controller.gain_units == "percent"
    assert set(site.write) == {"kc", "ti", "apply"}


RING = """
[ring]
head = "ir:100"
address = "ir:1000"
size = 2048
"""


def test_a_ring_buffer_is_described_by_head_address_and_size(tmp_path: Path):
    site = load_service_site(_write(tmp_path, EXAMPLE + RING))
    assert site.ring is not None
    assert site.ring.fields == ["seq", "command", "flow", "setpoint"]
    # seq uint32 + three float32 = 8 registers: 2048 records end at register 1000 + 16383
    assert site.ring.record_registers == 8


@pytest.mark.parametrize(
    ("ring", "reason"),
    [
        ('head = "ir:100"\naddress = "ir:60000"\nsize = 2048', "run past register 65535"),
        ('head = "ir:100"\naddress = "coil:3"\nsize = 16', "ring.address"),
        ('head = "ir:100"\naddress = "ir:1000"\nsize = 16\nfields = ["flow", "seq"]', "start"),
        ('head = "ir:100"\naddress = "ir:1000"\nsize = 16\nfields = ["seq", "flow"]', "command"),
        ('head = "40001"\naddress = "ir:1000"\nsize = 16', "ring.head"),
        ('head = "ir:100"\naddress = "ir:1000"\nsize = 1', "size"),
    ],
)
def test_a_ring_that_cannot_be_read_is_refused(tmp_path: Path, ring: str, reason: str):
    with pytest.raises(ConfigError, match=reason):
        load_service_site(_write(tmp_path, EXAMPLE + "[ring]\n" + ring + "\n"))


def test_site_check_shows_the_ring_and_what_it_exposes(tmp_path: Path):
    assert [
        line for line in load_service_site(_write(tmp_path, EXAMPLE)).missing() if "seq" in line
    ]
    site = load_service_site(_write(tmp_path, EXAMPLE + RING))
    # the ring carries the setpoint and the sequence number, so neither is missing
    assert not [line for line in site.missing() if line.startswith(("setpoint", "seq"))]
    result = runner.invoke(app, ["site", "check", "--config", str(tmp_path / "site.toml")])
    assert result.exit_code == 0
    assert "ir:1000" in result.output
    assert "2048" in result.output


@pytest.mark.parametrize(
    ("extra", "reason"),
    [
        # a float32 at ir:20 takes ir:20 and ir:21: a second value at ir:21 is a typo
        ('[tags.setpoint]\naddress = "ir:19"\ntype = "float32"\nunit = "L/min"\n', "overlaps"),
        ('[tags.kc]\naddress = "ir:30"\ntype = "uint16"\n', r"tags\.(kc|mode): ir:30 overlaps"),
    ],
)
def test_two_roles_sharing_a_register_are_refused(tmp_path: Path, extra: str, reason: str):
    with pytest.raises(ConfigError, match=reason):
        load_service_site(_write(tmp_path, EXAMPLE + extra))


def test_adjacent_registers_and_s7_bits_in_one_byte_are_accepted(tmp_path: Path):
    load_service_site(
        _write(tmp_path, EXAMPLE + '[tags.kc]\naddress = "ir:31"\ntype = "float32"\n')
    )
    s7 = (
        '[site]\nname = "s7"\n[plc]\nprotocol = "s7"\n'
        '[tags.flow]\naddress = "DB1.DBD0"\nunit = "L/min"\n'
        '[tags.command]\naddress = "DB1.DBD4"\nunit = "V"\n'
        '[tags.mode]\naddress = "DB1.DBX8.0"\ntype = "bool"\n'
        '[tags.setpoint]\naddress = "DB1.DBD6"\nunit = "L/min"\n'
    )
    with pytest.raises(ConfigError, match=r"tags\.setpoint: DB1\.DBD6 overlaps tags\.command"):
        load_service_site(_write(tmp_path, s7))
    load_service_site(_write(tmp_path, s7.replace("DB1.DBD6", "DB1.DBD10")))


def test_the_online_table_has_documented_defaults(tmp_path: Path):
    online = load_service_site(_write(tmp_path, EXAMPLE)).online
    assert (online.identify_every_s, online.window_s, online.write_back) == (300.0, 600.0, "off")
    assert (online.ms_target, online.gain_bounds, online.agree_windows) == (1.7, [0.5, 2.0], 2)
    assert (online.hysteresis, online.rule) == (0.1, "simc")


@pytest.mark.parametrize(
    ("online", "reason"),
    [
        ("identify_every_s = 10", "online.identify_every_s"),
        ("gain_bounds = [1.2, 2.0]", "gain_bounds"),
        ('write_back = "sometimes"', "online.write_back"),
        ('write_back = "auto"', "write.kc is missing"),
        ('rule = "zn"', "online.rule"),
        ("identify_every_s = 600\nwindow_s = 300", "never be analysed"),
    ],
)
def test_bad_online_settings_are_refused(tmp_path: Path, online: str, reason: str):
    with pytest.raises(ConfigError, match=reason):
        load_service_site(_write(tmp_path, EXAMPLE + "[online]\n" + online + "\n"))


def test_write_back_needs_the_write_side_and_the_controller_table(tmp_path: Path):
    write = "".join(
        f'[write.{role}]\naddress = "hr:{200 + 2 * i}"\ntype = "float32"\n'
        for i, role in enumerate(("kc", "ti", "apply", "echo"))
    )
    online = '[online]\nwrite_back = "approve"\n'
    with pytest.raises(ConfigError, match=r"\[controller\]"):
        load_service_site(_write(tmp_path, EXAMPLE + write + online))
    controller = "[controller]\nkc = 0.05\nti = 1.4\n"
    site = load_service_site(_write(tmp_path, EXAMPLE + write + controller + online))
    assert site.online.write_back == "approve"


def test_the_plc_side_passes_the_online_table_over(tmp_path: Path):
    """[online] is the service's: the PLC side (fuelid.plc.site) neither reads nor checks it."""
    path = _write(tmp_path, EXAMPLE + '[online]\nwrite_back = "sometimes"\n')
    assert not hasattr(load_site(path), "online")
    with pytest.raises(ConfigError, match=r"online\.write_back"):
        load_service_site(path)


def test_gain_units_that_contradict_the_controller_table_are_refused(tmp_path: Path) -> None:
    """A kc tag in V per L/min read by a site that says its PI takes percent gains: 25x off."""
    text = EXAMPLE + (
        '[tags.kc]\naddress = "ir:90"\ntype = "float32"\nunit = "V per L/min"\n'
        '[controller]\ngain_units = "percent"\nu_span_V = 4.0\ny_span_Lpm = 100.0\n'
    )
    with pytest.raises(ConfigError, match=r'tags.kc.unit: "V per L/min", but \[controller\]'):
        load_service_site(_write(tmp_path, text))


def test_relative_paths_are_taken_from_the_site_file_s_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A service started by systemd in / must find the plant and the store beside its site file."""
    folder = tmp_path / "etc"
    folder.mkdir()
    text = EXAMPLE.replace("[site]\n", '[site]\nplant = "worn.toml"\n', 1)
    text += '[store]\nurl = "sqlite:///data/loop.db"\n'
    path = folder / "site.toml"
    path.write_text(text, encoding="utf-8")
    monkeypatch.chdir(tmp_path)  # anywhere but the site file's folder
    site = load_service_site(path)
    assert site.site.plant == str(folder.resolve() / "worn.toml")
    assert site.store.url == f"sqlite:///{folder.resolve() / 'data' / 'loop.db'}"


def test_the_site_time_zone_and_loop_id_are_checked(tmp_path: Path):
    site = load_service_site(_write(tmp_path, EXAMPLE))
    assert (site.site.timezone, site.site.loop_id) == ("UTC", None)
    named = EXAMPLE.replace(
        'name = "tunnel 2 fuel loop"\n',
        'name = "tunnel 2 fuel loop"\ntimezone = "Europe/Zurich"\nloop_id = "t2-fuel"\n',
    )
    site = load_service_site(_write(tmp_path, named))
    assert (site.site.timezone, site.site.loop_id) == ("Europe/Zurich", "t2-fuel")
    with pytest.raises(ConfigError, match=r"site\.timezone.*'Mars/Olympus'"):
        load_service_site(_write(tmp_path, named.replace("Europe/Zurich", "Mars/Olympus")))
    with pytest.raises(ConfigError, match=r"site\.loop_id"):
        load_service_site(_write(tmp_path, named.replace("t2-fuel", "T2 fuel")))
