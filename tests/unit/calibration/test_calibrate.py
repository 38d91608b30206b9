"""``fuelid calibrate`` (issue 16): physical parameters recovered from simulated logs.

The logs come from a plant whose leakage (+40 %), VFD lag (−30 %) and nozzle discharge
coefficient (−10 %) differ from the reference file, at two fuel temperatures, with the reference
meter's noise; the refusals name what the data cannot determine.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fuelid.cli import main
from fuelid.errors import FuelidError
from fuelid.plant import get_parameter, load_plant_config, with_parameters

LEAK, LAG, CD = "pump.leakage_Lpm_per_MPa", "vfd.lag_s", "nozzle.discharge_coefficient"
REFERENCE = load_plant_config()
TRUTH = {
    LEAK: 1.4 * get_parameter(REFERENCE, LEAK),
    LAG: 0.7 * get_parameter(REFERENCE, LAG),
    CD: 0.9 * get_parameter(REFERENCE, CD),
}
DISPLACEMENT = "pump.displacement_cm3_per_rev"
LEVELS = "1.5,3.0,2.0,4.5,2.5,4.0"


def plant_file(path: Path, values: dict[str, float]) -> Path:
    from fuelid.io.plantfile import update_plant_toml

    text = (Path(__file__).parents[3] / "src/fuelid/data/reference_plant.toml").read_text()
    path.write_text(update_plant_toml(text, values))
    return path


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("calibrate")
    worn = plant_file(folder / "worn.toml", TRUTH)
    # the discharge coefficient held at the truth: what flow-only calibration may assume
    plant_file(folder / "start_cd_known.toml", {CD: TRUTH[CD]})
    out = {"folder": folder, "worn": worn}
    for temp in (10, 45):
        path = folder / f"log{temp}.csv"
        code = main(["simulate", str(path), "-c", str(worn), "-p", "steps", "--levels", LEVELS,
                     "--dwell", "15", "--duration", "90", "--fuel-temp", str(temp),
                     "--pressure", "--seed", str(temp), "-q"])  # fmt: skip
        assert code == 0
        out[f"log{temp}"] = path
    return out


def calibrate_json(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, dict, str]:
    code = main(["calibrate", *argv, "--json"])
    out, err = capsys.readouterr()
    return code, (json.loads(out) if code == 0 else {}), err


def assert_recovered(result: dict, names: list[str]) -> None:
    for name in names:
        estimate, error = result["parameters"][name], result["stderr"][name]
        assert abs(estimate - TRUTH[name]) < 3.0 * error, (name, estimate, TRUTH[name], error)
        assert abs(estimate / TRUTH[name] - 1.0) < 0.02, name
        low, high = result["ci95"][name]
        assert low < estimate < high


def test_flow_alone_recovers_leakage_and_vfd_lag_across_two_temperatures(
    logs: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    folder = logs["folder"]
    code, result, err = calibrate_json(
        capsys, str(logs["log10"]), str(logs["log45"]), "-c", str(folder / "start_cd_known.toml"),
        "--free", f"{LEAK},{LAG}",
    )  # fmt: skip
    assert code == 0, err
    assert_recovered(result, [LEAK, LAG])
    assert result["identifiability"]["identifiable"]
    # the residual noise is the meter's 0.1 L/min (plus its 0.01 L/min quantisation)
    assert result["noise_std"]["flow"] == pytest.approx(0.1, rel=0.05)
    for entry in result["fit_percent"]:
        assert entry["flow"] > 98.0
        assert entry["heldout_flow"] > 98.0
    assert [log["fuel_temperature_C"] for log in result["logs"]] == pytest.approx([10, 45])
    # provenance as the other commands: the first input's hash at the top, every log's in `logs`
    assert result["input_sha256"] == result["logs"][0]["sha256"]
    assert result["options"]["free"] == [LEAK, LAG]


def test_with_pump_pressure_all_three_are_recovered_and_k_predicted_at_a_third_temperature(
    logs: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    folder = logs["folder"]
    calibrated = folder / "calibrated.toml"
    code, result, err = calibrate_json(
        capsys, str(logs["log10"]), str(logs["log45"]), "--free", f"{LEAK},{LAG},{CD}",
        "--pressure-col", "p_pump_MPa", "--out", str(calibrated), "--force",
    )  # fmt: skip
    assert code == 0, err
    assert_recovered(result, [LEAK, LAG, CD])
    assert result["noise_std"]["pressure"] == pytest.approx(0.002, rel=0.1)
    # the calibrated file loads, records the calibration, and predicts K at −15 °C (no log
    # there) within three standard errors of the true plant's
    config = load_plant_config(calibrated)
    assert config.calibration is not None
    assert list(config.calibration.parameters) == [LEAK, LAG, CD]
    assert main(["plant", "info", "-c", str(calibrated), "--fuel-temp", "-15", "--u", "3",
                 "--json"]) == 0  # fmt: skip
    predicted = json.loads(capsys.readouterr().out)
    assert main(["plant", "info", "-c", str(logs["worn"]), "--fuel-temp", "-15", "--u", "3",
                 "--json"]) == 0  # fmt: skip
    true_k = json.loads(capsys.readouterr().out)["model"]["K"]
    k, k_stderr = predicted["model"]["K"], predicted["uncertainty"]["K"]["stderr"]
    assert abs(k - true_k) < 3.0 * k_stderr
    assert predicted["calibration"]["extrapolated"] is True


def test_leakage_and_discharge_coefficient_from_flow_alone_are_refused_by_name(
    logs: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["calibrate", str(logs["log10"]), str(logs["log45"]), "--free", f"{LEAK},{CD}"])
    out, err = capsys.readouterr()
    assert code == 2
    assert out == ""
    line = err.strip().splitlines()[-1]
    assert LEAK in line
    assert CD in line
    assert "--pressure-col" in line  # the advice names the data that would separate them


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--free", "pump.leak"], "calibratable:"),
        (["--free", "nozzle.count"], "nozzle.count is a setting of the plant file"),
        (["--free", "pump.leakage_Lpm_per_Mpa"], "did you mean pump.leakage_Lpm_per_MPa?"),
        (["--free", f"{LEAK},{LEAK}"], "twice"),
        (["--free", "flowmeter.delay_s"], "dead time"),
        (["--free", LEAK, "--fuel-temp", "10"], "1 temperature(s) for 2 log(s)"),
    ],
)
def test_bad_requests_are_one_line_errors(
    logs: dict[str, Path], capsys: pytest.CaptureFixture[str], argv: list[str], needle: str
) -> None:
    code = main(["calibrate", str(logs["log10"]), str(logs["log45"]), *argv])
    err = capsys.readouterr().err
    assert code == 2
    assert "Traceback" not in err
    assert needle in err.strip().splitlines()[-1]


def test_a_log_without_fuel_temperature_needs_one(
    logs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import pandas as pd

    bare = tmp_path / "bare.csv"
    pd.read_csv(logs["log10"]).drop(columns=["T_fuel_degC"]).to_csv(bare, index=False)
    code = main(["calibrate", str(bare), "--free", LEAK])
    assert code == 2
    assert "--fuel-temp" in capsys.readouterr().err


def test_a_fit_that_does_not_converge_gives_no_numbers(logs: dict[str, Path]) -> None:
    from fuelid.calibration.calibrate import calibrate, load_calibration_log
    from fuelid.greybox import ConvergenceError

    start = with_parameters(REFERENCE, {LEAK: 30.0, LAG: 3.0})
    loaded = [load_calibration_log(logs["log10"])]
    with pytest.raises(ConvergenceError, match="did not converge"):
        calibrate(start, loaded, [LEAK, LAG], max_iterations=2)
    assert issubclass(ConvergenceError, FuelidError)


def test_profile_likelihood_interval_agrees_with_the_gaussian_one_when_well_determined(
    logs: dict[str, Path],
) -> None:
    from fuelid.calibration.calibrate import calibrate, load_calibration_log

    start = load_plant_config(logs["folder"] / "start_cd_known.toml")
    start = with_parameters(start, {LEAK: TRUTH[LEAK]})
    loaded = [load_calibration_log(logs["log10"])]
    result = calibrate(start, loaded, [LAG], holdout=0.0, profile=[LAG])
    gaussian, profile = result.ci95[LAG], result.profile_ci95[LAG]
    assert gaussian is not None
    half_width = (gaussian[1] - gaussian[0]) / 2
    # a well-determined parameter's likelihood is nearly quadratic in log θ: the two agree to a
    # small share of the half-width, and both contain the truth
    assert profile[0] == pytest.approx(gaussian[0], abs=0.1 * half_width)
    assert profile[1] == pytest.approx(gaussian[1], abs=0.1 * half_width)
    assert profile[0] < TRUTH[LAG] < profile[1]


def test_tune_on_a_calibrated_plant_says_where_the_calibration_has_no_data(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from fuelid.io.plantfile import update_plant_toml

    text = (Path(__file__).parents[3] / "src/fuelid/data/reference_plant.toml").read_text()
    table = {
        "parameters": [LAG],
        "values": [get_parameter(REFERENCE, LAG)],
        "stderr": [0.01],
        "covariance": [[1e-4]],
        "logs": [{"file": "a.csv", "sha256": "0" * 64, "fuel_temperature_C": 10.0},
                 {"file": "b.csv", "sha256": "1" * 64, "fuel_temperature_C": 30.0}],
    }  # fmt: skip
    calibrated = tmp_path / "calibrated.toml"
    calibrated.write_text(update_plant_toml(text, {}, table))
    code = main(["tune", "-c", str(calibrated), "--K", "13", "--T", "0.9", "--flowmeter-T", "0.3",
                 "--delay", "0.2", "--fuel-temp", "20", "--t-min", "0", "--t-max", "40",
                 "--control-period", "1", "--json"])  # fmt: skip
    out, err = capsys.readouterr()
    assert code == 0, err
    plant = json.loads(out)["plant"]
    assert plant["calibration"]["fuel_temperature_range_C"] == [10.0, 30.0]
    assert plant["calibration"]["extrapolated"] is False  # 20 °C lies inside 10…30 °C
    # the temperature check's ends, 0 and 40 °C, lie outside: said on stderr
    assert "0 °C is outside the calibration logs' 10…30 °C" in err
    assert "40 °C is outside" in err


def test_a_log_cut_mid_step_is_warned_about_and_so_is_its_misfit(
    logs: dict[str, Path], tmp_path: Path
) -> None:
    import pandas as pd

    from fuelid.calibration.calibrate import calibrate, load_calibration_log, starts_at_rest

    frame = pd.read_csv(logs["log10"])
    cut = frame[frame["t_s"] >= 15.3].copy()  # 0.3 s after the first step: the flow is rising
    cut["t_s"] -= cut["t_s"].iloc[0]
    path = tmp_path / "cut.csv"
    cut.to_csv(path, index=False)
    loaded = load_calibration_log(path)
    assert not starts_at_rest(loaded.record, 0.1)
    assert starts_at_rest(load_calibration_log(logs["log10"]).record, 0.1)
    start = with_parameters(REFERENCE, {CD: TRUTH[CD], LAG: TRUTH[LAG]})
    result = calibrate(start, [loaded], [LEAK], holdout=0.0)
    text = " ".join(result.warnings)
    assert "does not start at rest" in text
    assert "the meter noise" in text or "meter noise" in text


def test_fuel_temp_over_a_logged_temperature_is_noted(logs: dict[str, Path]) -> None:
    from fuelid.calibration.calibrate import load_calibration_log

    loaded = load_calibration_log(logs["log10"], fuel_temp_C=40.0)
    assert loaded.fuel_temperature_C == 40.0
    assert any("overrides the log's own fuel temperature" in note for note in loaded.notes)


def test_a_plant_file_wrong_elsewhere_is_called_a_misfit_not_missing_data(
    logs: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    """The pump's displacement 20 % short in the start file, only the leakage free.

    The start plant delivers too little even without leakage: the fit drives the leakage to
    nothing, where it loses its sensitivity. The refusal
    says the plant file does not fit (the residuals against the meter's noise), not that the
    data lack a temperature.
    """
    folder = logs["folder"]
    short = {"pump.displacement_cm3_per_rev": 0.8 * get_parameter(REFERENCE, DISPLACEMENT)}
    start = plant_file(folder / "short_pump.toml", short)
    code = main(["calibrate", str(logs["log10"]), "-c", str(start), "--free", LEAK,
                 "--pressure-col", "p_pump_MPa"])  # fmt: skip
    out, err = capsys.readouterr()
    assert (code, out) == (2, "")
    line = err.strip().splitlines()[-1]
    assert "the plant file does not fit these logs" in line
    assert "against the meter's 0.1 L/min" in line
    assert "another fuel temperature" not in line


def test_estimates_that_trade_three_ways_are_warned_about(
    logs: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    """Displacement, f_min and f_max: two combinations of the three carry nearly everything.

    Flow ∝ displacement × drive frequency, and the frequency is linear in the command between
    f_min and f_max. No pair of sensitivities is alike, so the report passes, but the estimates
    correlate near ±1, and that is said.
    """
    free = f"{DISPLACEMENT},vfd.f_min_Hz,vfd.f_max_Hz"
    code, result, err = calibrate_json(
        capsys, str(logs["log10"]), str(logs["log45"]), "-c", str(logs["worn"]), "--free", free,
        "--pressure-col", "p_pump_MPa",
    )  # fmt: skip
    assert code == 0, err
    correlated = [w for w in result["warnings"] if "are estimated with correlation" in w]
    assert correlated, result["warnings"]
    matrix = np.array(result["correlation"]["matrix"])
    assert np.max(np.abs(matrix - np.eye(3))) > 0.999


def test_one_force_covers_the_calibrated_file_and_the_figure(
    logs: dict[str, Path], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """Both outputs exist: refused (before any fit) without --force, written with it."""
    out, fig = tmp_path / "cal.toml", tmp_path / "cal.png"
    out.write_text("old")
    fig.write_bytes(b"old")
    argv = [
        "calibrate",
        str(logs["log10"]),
        str(logs["log45"]),
        "--free",
        LEAK,
        "--fuel-temp",
        "10,45",
        "--out",
        str(out),
        "--plot",
        str(fig),
        "--force-misfit",
    ]  # fmt: skip  (leakage alone does not fit: a misfit, written anyway)
    assert main(argv) == 2
    assert "--force" in capsys.readouterr().err
    out.unlink()
    assert main(argv) == 2
    assert "--force" in capsys.readouterr().err
    assert main([*argv, "--force"]) == 0
    assert out.read_text() != "old"
    assert fig.read_bytes() != b"old"


def test_a_calibration_warning_travels_with_the_calibrated_file(
    logs: dict[str, Path], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """A misfit warning is kept in [calibration] and repeated wherever the file is used.

    Leakage alone from the reference file, whose lag and C_d are wrong for these logs.
    """
    out = tmp_path / "cal.toml"
    code = main(["calibrate", str(logs["log10"]), str(logs["log45"]), "--free", LEAK,
                 "--out", str(out), "--force-misfit"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 0, err
    assert "the calibrated plant does not fit the logs" in err
    record = load_plant_config(out).calibration
    assert record is not None
    assert any("does not fit the logs" in w for w in record.warnings)
    assert main(["plant", "info", "--config", str(out), "--fuel-temp", "20", "--json"]) == 0
    captured = capsys.readouterr()
    assert "note: the calibration warned: the flow residuals" in captured.err
    assert json.loads(captured.out)["calibration"]["warnings"] == list(record.warnings)
