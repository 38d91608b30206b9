"""The calibration's covariance propagated to K, T and the settling time (delta method).

The numbers the theory fixes: with one calibrated parameter θ of standard deviation σ the
standard error of a prediction g is |dg/dθ|·σ, the derivative taken here by an independent
finite difference on the linearised plant; the interval is g ± 1.959964·σ_g and scales linearly
with σ; the variances of uncorrelated parameters add and perfectly correlated ones add as
amplitudes. The static gain does not depend on the time constants at all (drive lag, meter lag),
so a covariance on those gives K no spread but T does.
"""

from __future__ import annotations

import json
import math
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.errors import ConfigError
from fuelid.io.plantfile import update_plant_toml
from fuelid.plant import (
    PlantConfig,
    linearise,
    load_plant_config,
    plant_config_from_dict,
    prediction_uncertainty,
    with_parameters,
)
from fuelid.plant._config import REFERENCE_PLANT
from fuelid.plant._uncertainty import Z95

U, T20 = 3.0, 293.15
SHA = "ab" * 32
LOGS = [
    {"file": "cold.csv", "sha256": SHA, "fuel_temperature_C": 10.0},
    {"file": "warm.csv", "sha256": SHA, "fuel_temperature_C": 40.0},
]


def _reference_text() -> str:
    return resources.files("fuelid.data").joinpath(REFERENCE_PLANT).read_text("utf-8")


def _calibrated(
    parameters: list[str], covariance: list[list[float]], logs: list[dict[str, Any]] | None = None
) -> PlantConfig:
    base = load_plant_config()
    values = [
        float(getattr(getattr(base, name.split(".")[0]), name.split(".")[1])) for name in parameters
    ]
    record = {
        "parameters": parameters,
        "values": values,
        "covariance": covariance,
        "logs": LOGS if logs is None else logs,
    }
    return plant_config_from_dict(tomllib.loads(update_plant_toml(_reference_text(), {}, record)))


def _predict(cfg: PlantConfig) -> dict[str, float]:
    reduced = linearise(cfg, U, T20).equivalent_model()
    return {"K": reduced.model.K, "T": reduced.model.T, "settling_time": reduced.settling_time}


def _moved(cfg: PlantConfig, section: str, key: str, value: float) -> PlantConfig:
    """The plant with one key changed, built without fuelid.plant._parameters."""
    part = getattr(cfg, section)
    return cfg.model_copy(update={section: part.model_copy(update={key: value})})


def _derivative(section: str, key: str, h: float) -> dict[str, float]:
    """Central difference of K, T, settling time over one key, step h (not the library's)."""
    cfg = load_plant_config()
    theta = getattr(getattr(cfg, section), key)
    up = _predict(_moved(cfg, section, key, theta + h))
    down = _predict(_moved(cfg, section, key, theta - h))
    return {name: (up[name] - down[name]) / (2 * h) for name in up}


@pytest.fixture(scope="module")
def leakage_slope() -> dict[str, float]:
    return _derivative("pump", "leakage_Lpm_per_MPa", 0.02)


@pytest.fixture(scope="module")
def lag_slope() -> dict[str, float]:
    return _derivative("vfd", "lag_s", 0.005)


def test_one_parameter_stderr_is_slope_times_sigma(leakage_slope: dict[str, float]) -> None:
    sigma = 0.5  # (L/min)/MPa
    cfg = _calibrated(["pump.leakage_Lpm_per_MPa"], [[sigma**2]])
    result = prediction_uncertainty(cfg, U, T20)
    # more internal leakage, less flow per volt: K falls
    assert leakage_slope["K"] < 0.0
    # K is exact to rounding; T (a fit) and the settling time (a crossing on a grid) are
    # resolved to ~1e-8 s, and leakage moves them by only ~3e-4 s per (L/min)/MPa: 1 %
    for name, rel in (("K", 1e-5), ("T", 1e-2), ("settling_time", 1e-2)):
        q = result.quantities[name]
        assert q.value == pytest.approx(_predict(load_plant_config())[name], rel=1e-12)
        assert q.stderr == pytest.approx(abs(leakage_slope[name]) * sigma, rel=rel)
        lo, hi = q.ci95
        assert (hi - q.value) == pytest.approx(Z95 * q.stderr, rel=1e-12)
        assert (q.value - lo) == pytest.approx(Z95 * q.stderr, rel=1e-12)


def test_interval_scales_linearly_with_sigma() -> None:
    widths = []
    for sigma in (0.1, 0.2, 0.4):
        cfg = _calibrated(["pump.leakage_Lpm_per_MPa"], [[sigma**2]])
        lo, hi = prediction_uncertainty(cfg, U, T20).quantities["K"].ci95
        widths.append(hi - lo)
    assert widths[1] == pytest.approx(2 * widths[0], rel=1e-9)
    assert widths[2] == pytest.approx(4 * widths[0], rel=1e-9)


def test_gain_does_not_depend_on_time_constants(lag_slope: dict[str, float]) -> None:
    # K = −C·A⁻¹·B is the static gain: the drive's and the meter's lags do not enter it
    sigma_lag, sigma_meter = 0.1, 0.05
    cfg = _calibrated(
        ["vfd.lag_s", "flowmeter.time_constant_s"], [[sigma_lag**2, 0.0], [0.0, sigma_meter**2]]
    )
    result = prediction_uncertainty(cfg, U, T20)
    K = result.quantities["K"]
    assert K.stderr <= 1e-9 * K.value
    # the lag does move T (the lumped process lag contains the drive's), by |dT/dlag|·σ …
    meter_T = _derivative("flowmeter", "time_constant_s", 0.005)["T"]
    expected_T = math.hypot(lag_slope["T"] * sigma_lag, meter_T * sigma_meter)
    assert lag_slope["T"] > 0.5  # T grows almost one for one with the drive lag
    assert result.quantities["T"].stderr == pytest.approx(expected_T, rel=2e-3)


def test_correlation_enters_as_theory_says(
    leakage_slope: dict[str, float], lag_slope: dict[str, float]
) -> None:
    s1, s2 = 0.5, 0.1
    g1, g2 = leakage_slope["T"], lag_slope["T"]
    for rho in (0.0, 1.0, -1.0, 0.3):
        cov = [[s1**2, rho * s1 * s2], [rho * s1 * s2, s2**2]]
        cfg = _calibrated(["pump.leakage_Lpm_per_MPa", "vfd.lag_s"], cov)
        stderr = prediction_uncertainty(cfg, U, T20).quantities["T"].stderr
        expected = math.sqrt(g1**2 * s1**2 + g2**2 * s2**2 + 2 * rho * g1 * g2 * s1 * s2)
        assert stderr == pytest.approx(expected, rel=2e-3)


def test_parameter_at_its_bound_uses_a_one_sided_difference() -> None:
    # damping 0 may not go negative: the derivative is taken forward; the torque balance
    # T_e = B·ω + T_p loses B·ω of pump torque, so the speed, the flow and K fall with B
    cfg = with_parameters(
        _calibrated(["motor.damping_N_m_s_per_rad"], [[1e-4]]),
        {"motor.damping_N_m_s_per_rad": 0.0},
    )
    result = prediction_uncertainty(cfg, U, T20)
    gradient = result.quantities["K"].gradient["motor.damping_N_m_s_per_rad"]
    assert gradient < 0.0
    # the record holds 0.02, the plant 0.0: said so
    assert any("differ from the [calibration] record" in note for note in result.warnings)


def test_extrapolation_is_flagged() -> None:
    cfg = _calibrated(["pump.leakage_Lpm_per_MPa"], [[0.01]])
    inside = prediction_uncertainty(cfg, U, T20)
    assert not inside.extrapolated
    assert inside.warnings == ()
    assert inside.to_json()["calibration"] == {
        "parameters": ["pump.leakage_Lpm_per_MPa"],
        "fuel_temperature_range_C": [10.0, 40.0],
        "extrapolated": False,
        "warnings": [],
    }
    edge = prediction_uncertainty(cfg, U, 283.15)  # exactly 10 °C: inside
    assert not edge.extrapolated
    cold = prediction_uncertainty(cfg, U, 278.15)
    assert cold.extrapolated
    assert cold.warnings == (
        "5 °C is outside the calibration logs' 10…40 °C: K, T come from the physics, not from "
        "data at this temperature",
    )
    no_logs = prediction_uncertainty(_calibrated(["vfd.lag_s"], [[0.01]], logs=[]), U, 278.15)
    assert not no_logs.extrapolated  # nothing to compare with


def test_no_covariance_no_uncertainty() -> None:
    with pytest.raises(ConfigError, match="no \\[calibration\\] table"):
        prediction_uncertainty(load_plant_config(), U, T20)

    text = update_plant_toml(_reference_text(), {}, {"parameters": ["vfd.lag_s"], "values": [1.2]})
    with pytest.raises(ConfigError, match="no covariance"):
        prediction_uncertainty(plant_config_from_dict(tomllib.loads(text)), U, T20)


# --------------------------------------------------------------------------------------------
# fuelid plant info

runner = CliRunner()


def _plant_file(tmp_path: Path, record: dict[str, Any]) -> Path:
    path = tmp_path / "plant.toml"
    path.write_text(update_plant_toml(_reference_text(), {}, record), encoding="utf-8")
    return path


def test_plant_info_json_carries_the_uncertainty(
    tmp_path: Path, leakage_slope: dict[str, float]
) -> None:
    sigma = 0.5
    record = {
        "parameters": ["pump.leakage_Lpm_per_MPa"],
        "values": [7.0],
        "covariance": [[sigma**2]],
        "logs": LOGS,
    }
    path = _plant_file(tmp_path, record)
    args = ["plant", "info", "--json", "--config", str(path), "--u", str(U)]
    result = runner.invoke(app, [*args, "--fuel-temp", "20"])
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    K = data["uncertainty"]["K"]
    assert K["stderr"] == pytest.approx(abs(leakage_slope["K"]) * sigma, rel=1e-5)
    assert K["ci95"][0] == pytest.approx(data["model"]["K"] - Z95 * K["stderr"], rel=1e-12)
    assert set(data["uncertainty"]) == {"K", "T", "settling_time"}
    assert data["calibration"] == {
        "parameters": ["pump.leakage_Lpm_per_MPa"],
        "fuel_temperature_range_C": [10.0, 40.0],
        "extrapolated": False,
        "warnings": [],
    }
    assert "note:" not in result.stderr

    cold = runner.invoke(app, [*args, "--fuel-temp", "5"])
    assert cold.exit_code == 0, cold.stderr
    assert json.loads(cold.stdout)["calibration"]["extrapolated"] is True
    assert "note: 5 °C is outside the calibration logs' 10…40 °C" in cold.stderr

    table = runner.invoke(app, ["plant", "info", "--config", str(path), "--u", str(U)])
    assert table.exit_code == 0, table.stderr
    assert "± (1σ)" in table.stdout
    assert "95 % interval" in table.stdout


def test_plant_info_without_calibration_is_unchanged() -> None:
    result = runner.invoke(app, ["plant", "info", "--json"])
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert "uncertainty" not in data
    assert "calibration" not in data
    table = runner.invoke(app, ["plant", "info"])
    assert "±" not in table.stdout


def test_plant_info_with_a_record_but_no_covariance(tmp_path: Path) -> None:
    record = {"parameters": ["vfd.lag_s"], "values": [1.2], "logs": LOGS}
    path = _plant_file(tmp_path, record)
    result = runner.invoke(app, ["plant", "info", "--json", "--config", str(path)])
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert data["uncertainty"] is None
    assert data["calibration"]["parameters"] == ["vfd.lag_s"]
    assert "no covariance" in result.stderr


def test_a_calibrated_meter_lag_gives_t_f_its_own_standard_error() -> None:
    """The equivalent model's T_f is flowmeter.time_constant_s itself: σ(T_f) = σ(θ)."""
    sigma = 0.02  # s
    cfg = _calibrated(["flowmeter.time_constant_s", "vfd.lag_s"], [[sigma**2, 0.0], [0.0, 1e-4]])
    result = prediction_uncertainty(cfg, U, T20)
    t_f = result.quantities["T_f"]
    assert t_f.value == cfg.flowmeter.time_constant_s
    assert t_f.stderr == pytest.approx(sigma, rel=1e-12)
    assert t_f.gradient == {"flowmeter.time_constant_s": 1.0, "vfd.lag_s": 0.0}
    assert (
        "T_f" not in prediction_uncertainty(_calibrated(["vfd.lag_s"], [[1e-4]]), U, T20).quantities
    )
