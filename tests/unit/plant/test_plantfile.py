"""Writing calibrations back into plant files, and the ``[calibration]`` table's schema.

:func:`fuelid.io.plantfile.update_plant_toml` must change only the values it is given (every
comment, blank line and key order kept) and put a ``[calibration]`` table at the end that the
plant loader reads back to the same numbers, bit for bit. The schema
(:class:`fuelid.plant._config.CalibrationRecord`) refuses records whose sizes, symmetry or
finiteness are wrong, unknown parameter names and unknown keys.
"""

from __future__ import annotations

import copy
import math
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fuelid.errors import ConfigError
from fuelid.io.plantfile import update_plant_file, update_plant_toml, write_text_atomically
from fuelid.plant import (
    calibrated_temperature_range,
    get_parameter,
    load_plant_config,
    plant_config_from_dict,
)

REFERENCE_TEXT = resources.files("fuelid.data").joinpath("reference_plant.toml").read_text("utf-8")
#: the reference plant with comments of every kind a user writes
COMMENTED = (
    REFERENCE_TEXT.replace("lag_s = 1.2", "lag_s = 1.2  # from the drive's ramp setting")
    .replace("[pump]\n", "[pump]\n# bench test, 2023-04\n")
    .replace("damping_N_m_s_per_rad = 0.02\n", "")  # left to its default
)
SHA = "0123456789abcdef" * 4


def _calibration(**changes: Any) -> dict[str, Any]:
    record: dict[str, Any] = {
        "parameters": ["pump.leakage_Lpm_per_MPa", "vfd.lag_s"],
        "values": [6.25, 1.3],
        "stderr": [0.2, 0.01],
        "covariance": [[0.04, 1e-4], [1e-4, 1e-4]],
        "ci95": [[5.858, 6.642], [1.2804, 1.3196]],
        "logs": [
            {"file": "cold.csv", "sha256": SHA, "fuel_temperature_C": 10.0},
            {"file": "warm.csv", "sha256": SHA, "fuel_temperature_C": 40.0},
        ],
        "fit_percent": [96.1, 95.4],
        "created": "2026-11-25T17:00:00+00:00",
        "fuelid_version": "0.1.0",
        "method": "output error, nonlinear ODE",
    }
    record.update(changes)
    return record


def _load(text: str) -> Any:
    return plant_config_from_dict(tomllib.loads(text), "test plant")


VALUES = {"pump.leakage_Lpm_per_MPa": 6.25, "vfd.lag_s": 1.3}


def test_only_the_given_values_change() -> None:
    out = update_plant_toml(COMMENTED, VALUES, _calibration())
    before, after = COMMENTED.splitlines(), out.splitlines()
    # the original lines, in order, with exactly two of them changed
    changed = [(a, b) for a, b in zip(before, after, strict=False) if a != b]
    assert changed == [
        (
            "lag_s = 1.2  # from the drive's ramp setting",
            "lag_s = 1.3  # from the drive's ramp setting",
        ),
        ("leakage_Lpm_per_MPa = 7.0", "leakage_Lpm_per_MPa = 6.25"),
    ]
    # everything added comes after the original text
    assert after[len(before)] == "" or after[len(before)].startswith("[calibration]")
    assert out.rstrip().count("[calibration]") == 1
    assert out.index("[calibration]") > out.index("[flowmeter]")


def test_round_trip_through_the_loader(tmp_path: Path) -> None:
    calibration = _calibration()
    out = update_plant_toml(COMMENTED, VALUES, calibration)
    path = write_text_atomically(tmp_path / "plant.toml", out)
    cfg = load_plant_config(path)
    for name, value in VALUES.items():
        assert get_parameter(cfg, name) == value
    record = cfg.calibration
    assert record is not None
    assert list(record.parameters) == calibration["parameters"]
    assert list(record.values) == calibration["values"]
    assert [list(row) for row in record.covariance or ()] == calibration["covariance"]
    assert [list(pair) for pair in record.ci95 or ()] == calibration["ci95"]
    assert [log.file for log in record.logs] == ["cold.csv", "warm.csv"]
    assert list(record.fit_percent) == calibration["fit_percent"]
    assert record.method == "output error, nonlinear ODE"
    assert calibrated_temperature_range(cfg) == (10.0, 40.0)
    # the rest of the plant is the reference's
    reference = load_plant_config()
    assert cfg.pipeline == reference.pipeline
    assert cfg.nozzle == reference.nozzle


def test_floats_survive_bit_for_bit() -> None:
    awkward = 0.1 + 0.2  # 0.30000000000000004
    tiny = 1.234567890123e-17
    out = update_plant_toml(
        REFERENCE_TEXT,
        {"pump.leakage_Lpm_per_MPa": awkward},
        _calibration(covariance=[[tiny, 0.0], [0.0, awkward]]),
    )
    cfg = _load(out)
    assert cfg.pump.leakage_Lpm_per_MPa == awkward
    assert cfg.calibration.covariance == ((tiny, 0.0), (0.0, awkward))


def test_default_key_is_added_to_its_table() -> None:
    out = update_plant_toml(COMMENTED, {"motor.damping_N_m_s_per_rad": 0.035})
    assert _load(COMMENTED).motor.damping_N_m_s_per_rad == 0.0  # the default before
    assert _load(out).motor.damping_N_m_s_per_rad == 0.035
    motor = out[out.index("[motor]") : out.index("[pump]")]
    assert "damping_N_m_s_per_rad = 0.035" in motor


def test_calibration_is_replaced_not_repeated() -> None:
    once = update_plant_toml(COMMENTED, VALUES, _calibration())
    twice = update_plant_toml(once, VALUES, _calibration())
    assert twice == once
    other = update_plant_toml(
        once, {}, _calibration(method="step least squares", logs=[], fit_percent=[])
    )
    assert other.count("[calibration]") == 1
    assert "[[calibration.logs]]" not in other
    assert _load(other).calibration.method == "step least squares"
    # None leaves an existing table alone
    assert update_plant_toml(once, {"vfd.lag_s": 1.3}, None) == once


def test_calibration_in_the_middle_moves_to_the_end() -> None:
    middle = REFERENCE_TEXT.replace(
        "[vfd]",
        '[calibration]\nparameters = ["vfd.lag_s"]\nvalues = [1.2]\n\n[vfd]',
    )
    assert _load(middle).calibration.parameters == ("vfd.lag_s",)
    out = update_plant_toml(middle, {}, _calibration())
    assert out.count("[calibration]") == 1
    assert out.index("[calibration]") > out.index("[flowmeter]")
    assert _load(out).calibration.parameters == ("pump.leakage_Lpm_per_MPa", "vfd.lag_s")


def test_numpy_data_is_written_as_plain_toml() -> None:
    calibration = _calibration(
        values=np.array([6.25, 1.3]),
        covariance=np.array([[0.04, 1e-4], [1e-4, 1e-4]]),
        fit_percent=[np.float64(96.1), np.float64(95.4)],
    )
    out = update_plant_toml(REFERENCE_TEXT, {"vfd.lag_s": np.float64(1.3)}, calibration)
    cfg = _load(out)
    assert cfg.vfd.lag_s == 1.3
    assert cfg.calibration.values == (6.25, 1.3)


def test_update_plant_file_writes_atomically(tmp_path: Path) -> None:
    path = tmp_path / "plant.toml"
    path.write_text(COMMENTED, encoding="utf-8")
    update_plant_file(path, VALUES, _calibration())
    assert load_plant_config(path).vfd.lag_s == 1.3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plant.toml"]  # no temporaries left
    copy_path = update_plant_file(path, {"vfd.lag_s": 1.4}, None, output=tmp_path / "new.toml")
    assert load_plant_config(copy_path).vfd.lag_s == 1.4
    assert load_plant_config(path).vfd.lag_s == 1.3
    with pytest.raises(ConfigError, match="cannot read"):
        update_plant_file(tmp_path / "missing.toml", VALUES)


@pytest.mark.parametrize(
    ("text", "values", "calibration", "match"),
    [
        ("[pump\n", {}, None, "not valid TOML"),
        (REFERENCE_TEXT, {"leakage": 1.0}, None, "table.key"),
        (REFERENCE_TEXT, {"pump.leakage_Lpm_per_MPa": math.nan}, None, "finite"),
        (REFERENCE_TEXT, {"name.x": 1.0}, None, "not a table"),
        (REFERENCE_TEXT, {}, {"values": [math.inf]}, "calibration.values: must be a finite"),
        (REFERENCE_TEXT, {}, {"when": object()}, "cannot write"),
    ],
)
def test_update_refuses_bad_input(
    text: str, values: dict[str, float], calibration: dict[str, Any] | None, match: str
) -> None:
    with pytest.raises(ConfigError, match=match):
        update_plant_toml(text, values, calibration)


# --------------------------------------------------------------------------------------------
# the [calibration] table's schema


def _with(record: dict[str, Any]) -> dict[str, Any]:
    data = copy.deepcopy(tomllib.loads(REFERENCE_TEXT))
    data["calibration"] = record
    return data


def test_minimal_record_and_temperature_range() -> None:
    cfg = plant_config_from_dict(_with({"parameters": ["vfd.lag_s"], "values": [1.2]}))
    assert cfg.calibration.covariance is None
    assert calibrated_temperature_range(cfg) is None  # no logs
    assert calibrated_temperature_range(load_plant_config()) is None  # no [calibration]
    logs = _calibration()["logs"] + [{"file": "c", "sha256": SHA, "fuel_temperature_C": -5.0}]
    cfg = plant_config_from_dict(_with(_calibration(logs=logs, fit_percent=[1.0, 2.0, 3.0])))
    assert calibrated_temperature_range(cfg) == (-5.0, 40.0)


def test_toml_datetime_is_accepted() -> None:
    text = update_plant_toml(REFERENCE_TEXT, {}, _calibration(created=None))
    text = text.replace("[calibration]\n", "[calibration]\ncreated = 2026-11-25T17:00:00Z\n")
    assert _load(text).calibration.created == "2026-11-25T17:00:00+00:00"


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"parameters": ["pump.leak"]}, "unknown plant parameter 'pump.leak'; valid: "),
        ({"parameters": ["vfd.lag_s", "vfd.lag_s"]}, "listed twice"),
        ({"values": [6.25]}, "values has 1 entries, expected 2"),
        ({"values": [6.25, math.nan]}, "values must hold finite"),
        ({"stderr": [0.2, -0.01]}, "stderr must not be negative"),
        ({"covariance": [[0.04, 1e-4], [0.0, 1e-4]]}, "symmetric"),
        ({"covariance": [[0.04, 1e-4]]}, "covariance must be 2×2"),
        ({"covariance": [[0.04, 1e-4], [1e-4]]}, "covariance must be 2×2"),
        ({"covariance": [[0.04, math.inf], [math.inf, 1e-4]]}, "finite"),
        ({"covariance": [[-0.04, 0.0], [0.0, 1e-4]]}, "non-negative diagonal"),
        ({"covariance": [[1.0, 2.0], [2.0, 1.0]]}, "positive semi-definite"),
        ({"ci95": [[5.8, 6.6]]}, "ci95 has 1 entries, expected 2"),
        ({"ci95": [[6.6, 5.8], [1.28, 1.32]]}, "lo <= hi"),
        ({"fit_percent": [96.1]}, "fit_percent has 1 entries, expected 2"),
        ({"created": "yesterday"}, "ISO 8601"),
        ({"logs": [{"file": "a", "sha256": "abc", "fuel_temperature_C": 10.0}]}, "64 hex"),
        ({"logs": [{"file": "a", "sha256": SHA, "T": 10.0}]}, "calibration.logs.0.T: unknown key"),
        ({"comment": "by hand"}, "calibration.comment: unknown key"),
    ],
)
def test_bad_records_are_refused(changes: dict[str, Any], match: str) -> None:
    with pytest.raises(ConfigError, match=match.replace(".", r"\.").replace("(", r"\(")) as info:
        plant_config_from_dict(_with(_calibration(**changes)), "plant.toml")
    assert "\n" not in str(info.value)
