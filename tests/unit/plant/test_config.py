"""Plant configuration files: the reference plant loads, broken or impossible ones are refused.

Each bad file is the packaged reference TOML with one edit, so the refusal can only come from
that edit. Every refusal must be a :class:`~fuelid.errors.ConfigError` with a one-line message
that names the offending key.
"""

from __future__ import annotations

import json
import math
from importlib import resources
from pathlib import Path

import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.errors import ConfigError, FuelidError, OutOfRangeError
from fuelid.fuel import fuel_properties
from fuelid.plant import (
    linearise,
    load_plant_config,
    operating_point,
    plant_coefficients,
    plant_config_from_dict,
)

REFERENCE_TEXT = resources.files("fuelid.data").joinpath("reference_plant.toml").read_text("utf-8")


def _write(tmp_path: Path, old: str, new: str) -> Path:
    """The reference file with the one occurrence of ``old`` replaced by ``new``."""
    assert REFERENCE_TEXT.count(old) == 1, f"edit target {old!r} must occur exactly once"
    path = tmp_path / "plant.toml"
    path.write_text(REFERENCE_TEXT.replace(old, new), encoding="utf-8")
    return path


def _refusal(path: Path) -> str:
    with pytest.raises(ConfigError) as info:
        load_plant_config(path)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_reference_plant_values() -> None:
    cfg = load_plant_config()
    assert cfg.fuel.name == "RP-3"
    assert (cfg.vfd.u_min_V, cfg.vfd.u_max_V) == (1.0, 5.0)
    assert cfg.vfd.K_f == pytest.approx(10.0, rel=1e-14)  # (50 − 10) Hz/(5 − 1) V
    assert cfg.pipeline.length_m == 80.0
    assert cfg.pipeline.d == pytest.approx(0.032, rel=1e-14)
    assert cfg.pump.D_p == pytest.approx(50e-6, rel=1e-14)
    # 8 nozzles of 2.25 mm: 8·π·2.25²/4 mm² = 31.81 mm²
    area = cfg.nozzle.A0
    assert area == pytest.approx(8 * math.pi * 2.25e-3**2 / 4.0, rel=1e-14)


def test_unchanged_copy_loads_identically(tmp_path: Path) -> None:
    path = tmp_path / "copy.toml"
    path.write_text(REFERENCE_TEXT, encoding="utf-8")
    assert load_plant_config(path) == load_plant_config()


def test_valid_edit_is_taken(tmp_path: Path) -> None:
    cfg = load_plant_config(_write(tmp_path, "length_m = 80.0", "length_m = 120.0"))
    assert cfg.pipeline.length_m == 120.0


def test_negative_length_refused(tmp_path: Path) -> None:
    message = _refusal(_write(tmp_path, "length_m = 80.0", "length_m = -80.0"))
    assert "pipeline.length_m" in message
    assert "greater than 0" in message


def test_unknown_key_refused(tmp_path: Path) -> None:
    message = _refusal(_write(tmp_path, "length_m = 80.0", "lenght_m = 80.0"))
    assert "pipeline.lenght_m" in message
    assert "unknown" in message
    # the misspelling also leaves the real key missing
    assert "pipeline.length_m" in message
    assert "missing" in message


def test_unknown_top_level_table_refused(tmp_path: Path) -> None:
    message = _refusal(_write(tmp_path, "[flowmeter]", "[flowmetre]"))
    assert "flowmetre" in message
    assert "unknown" in message


def test_missing_key_refused(tmp_path: Path) -> None:
    message = _refusal(_write(tmp_path, "inner_diameter_mm = 32.0\n", ""))
    assert "pipeline.inner_diameter_mm" in message
    assert "missing" in message


def test_broken_toml_refused(tmp_path: Path) -> None:
    message = _refusal(_write(tmp_path, "length_m = 80.0", "length_m = = 80.0"))
    assert "TOML" in message


def test_f_max_below_f_min_refused(tmp_path: Path) -> None:
    message = _refusal(_write(tmp_path, "f_max_Hz = 50.0", "f_max_Hz = 5.0"))
    assert "vfd" in message
    assert "f_max_Hz" in message


def test_rated_speed_at_synchronous_speed_refused(tmp_path: Path) -> None:
    # 2 pole pairs at 50 Hz: n_sync = 60·50/2 = 1500 rpm; a motor cannot deliver torque there
    for speed in ("1500.0", "1600.0"):
        message = _refusal(
            _write(tmp_path, "rated_speed_rpm = 1450.0", f"rated_speed_rpm = {speed}")
        )
        assert "motor" in message
        assert "rated_speed_rpm" in message
        assert "1500" in message


def test_unknown_fuel_refused(tmp_path: Path) -> None:
    message = _refusal(_write(tmp_path, 'name = "RP-3"', 'name = "diesel"'))
    assert "fuel.name" in message
    assert "diesel" in message
    for known in ("RP-3", "Jet A", "JP-8"):
        assert known in message


def test_unknown_friction_method_refused(tmp_path: Path) -> None:
    message = _refusal(
        _write(
            tmp_path,
            "bulk_modulus_MPa = 1200.0",
            'bulk_modulus_MPa = 1200.0\nfriction_method = "Moody_1944"',
        )
    )
    assert "pipeline.friction_method" in message
    assert "Moody_1944" in message
    assert "Churchill_1977" in message  # the known methods are listed


def test_known_friction_method_accepted(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        "bulk_modulus_MPa = 1200.0",
        'bulk_modulus_MPa = 1200.0\nfriction_method = "Clamond"',
    )
    assert load_plant_config(path).pipeline.friction_method == "Clamond"


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ("inertia_kg_m2 = 0.06", "inertia_kg_m2 = 0.0", "motor.inertia_kg_m2"),
        (
            "mechanical_efficiency = 0.9",
            "mechanical_efficiency = 1.2",
            "pump.mechanical_efficiency",
        ),
        (
            "discharge_coefficient = 0.7",
            "discharge_coefficient = -0.7",
            "nozzle.discharge_coefficient",
        ),
        ("lag_s = 1.2", "lag_s = 0.0", "vfd.lag_s"),
        ("delay_s = 0.2", "delay_s = -0.2", "flowmeter.delay_s"),
        ("pole_pairs = 2", "pole_pairs = 2.5", "motor.pole_pairs"),
        ("length_m = 80.0", 'length_m = "long"', "pipeline.length_m"),
    ],
)
def test_impossible_values_refused(tmp_path: Path, old: str, new: str, key: str) -> None:
    assert key in _refusal(_write(tmp_path, old, new))


def test_several_errors_reported_on_one_line(tmp_path: Path) -> None:
    path = tmp_path / "plant.toml"
    path.write_text(
        REFERENCE_TEXT.replace("length_m = 80.0", "length_m = -1.0").replace(
            "lag_s = 1.2", "lag_s = -1.0"
        ),
        encoding="utf-8",
    )
    message = _refusal(path)
    assert "pipeline.length_m" in message
    assert "vfd.lag_s" in message


def test_missing_file_refused(tmp_path: Path) -> None:
    message = _refusal(tmp_path / "no_such_plant.toml")
    assert "no_such_plant.toml" in message
    assert "does not exist" in message


def test_directory_refused(tmp_path: Path) -> None:
    assert "directory" in _refusal(tmp_path)


def test_dict_validation_names_source() -> None:
    with pytest.raises(ConfigError, match=r"^my plant: .*missing required key") as info:
        plant_config_from_dict({"name": "x"}, source="my plant")
    assert "\n" not in str(info.value)


def test_config_error_is_a_fuelid_error() -> None:
    assert issubclass(ConfigError, FuelidError)
    assert issubclass(OutOfRangeError, FuelidError)


# --------------------------------------------------------------------------------------------
# fuel temperature outside the RP-3 (TS-1) range −20…60 °C


def test_fuel_temperature_out_of_range_refused() -> None:
    cfg = load_plant_config()
    hot = 353.15  # 80 °C
    with pytest.raises(OutOfRangeError, match="outside"):
        fuel_properties(hot, "RP-3")
    with pytest.raises(OutOfRangeError, match="outside"):
        plant_coefficients(cfg, hot)
    with pytest.raises(OutOfRangeError, match="outside"):
        operating_point(cfg, 3.0, hot)
    with pytest.raises(OutOfRangeError, match="outside"):
        linearise(cfg, 3.0, hot)
    with pytest.raises(OutOfRangeError, match="outside"):
        plant_coefficients(cfg, 243.15)  # −30 °C


def test_extrapolation_when_allowed(tmp_path: Path) -> None:
    path = _write(tmp_path, "allow_extrapolation = false", "allow_extrapolation = true")
    c = plant_coefficients(load_plant_config(path), 353.15)
    # TS-1 density extrapolated by hand: 794 − 0.72·80 = 736.4 kg/m³
    assert c.rho == pytest.approx(736.4, rel=1e-12)


def test_command_outside_signal_range_refused() -> None:
    cfg = load_plant_config()
    for u in (0.5, 5.5, float("nan")):
        with pytest.raises(OutOfRangeError, match="signal range"):
            operating_point(cfg, u, 293.15)
        with pytest.raises(OutOfRangeError, match="signal range"):
            linearise(cfg, u, 293.15)


# --------------------------------------------------------------------------------------------
# a flowmeter without lag (time_constant_s = 0) is allowed, and every command handles it


def test_meter_without_lag_through_the_cli(tmp_path: Path) -> None:
    path = _write(tmp_path, "time_constant_s = 0.3", "time_constant_s = 0.0")
    cfg = load_plant_config(path)
    assert cfg.flowmeter.time_constant_s == 0.0
    runner = CliRunner()
    table = runner.invoke(app, ["plant", "info", "--config", str(path)])
    assert table.exit_code == 0, table.output
    assert "(L/min)/V" in table.stdout
    result = runner.invoke(
        app, ["plant", "info", "--json", "--config", str(path), "--u", "3", "--fuel-temp", "20"]
    )
    assert result.exit_code == 0, result.output
    model = json.loads(result.stdout)["model"]
    assert model["T_f"] == 0.0
    assert math.isfinite(model["settling_time"])
    # the gain is the slope of the steady-state curve: (q(3.001 V) − q(2.999 V))/2 mV
    q_hi = operating_point(cfg, 3.001, 293.15).q
    q_lo = operating_point(cfg, 2.999, 293.15).q
    assert model["K"] == pytest.approx((q_hi - q_lo) / 2e-3 * 60_000.0, rel=1e-4)
