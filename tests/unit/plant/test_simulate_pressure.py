"""The pump outlet pressure in simulated logs (``fuelid simulate --pressure``).

Numbers fixed by the physics: at rest the pressure is the operating point's
(:func:`fuelid.plant._system.steady_state`); between, it is the state p of the ODE at the sample
time itself (no flowmeter dead time), which an independent integration of the same ODE gives;
the logged value carries white noise of the asked standard deviation, quantised to the asked
step.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.errors import FuelidError
from fuelid.io.timeseries import PRESSURE_COLUMN
from fuelid.plant import PlantConfig, plant_coefficients, steady_state
from fuelid.plant.simulate import SimulationResult, integrate_held, simulate
from fuelid.profiles import step_profile

T20 = 293.15
MPA = 1e6  # Pa per MPa
U0, U1, T_STEP, END = 1.0, 1.5, 10.0, 60.0


@pytest.fixture(scope="module")
def run(cfg: PlantConfig) -> SimulationResult:
    return simulate(
        cfg,
        step_profile(U0, U1, T_STEP, END),
        sample_time=0.02,
        control_period=0.0,
        seed=3,
        pressure=True,
    )


def test_pressure_at_rest_is_the_operating_points(cfg: PlantConfig, run: SimulationResult) -> None:
    c = plant_coefficients(cfg, T20)
    p0 = steady_state(U0, c).p_pump
    p1 = steady_state(U1, c).p_pump
    before = run.time < T_STEP
    after = run.time > END - 10.0  # ~8 settling times after the step
    assert np.allclose(run.p_pump[before], p0, rtol=1e-9)
    assert np.allclose(run.p_pump[after], p1, rtol=1e-6)
    assert run.p_pump[-1] == pytest.approx(p1, rel=1e-6)  # the last sample too
    # the logged values: mean within 4 standard errors (plus half a step) of the truth,
    # scatter the configured 0.002 MPa
    logged = run.p_measured[after]
    n = logged.size
    assert abs(logged.mean() - p1) < 4 * 2000.0 / np.sqrt(n) + 50.0
    assert np.std(logged) == pytest.approx(2000.0, rel=0.1)
    # quantised to 0.0001 MPa
    steps = logged / 100.0
    assert np.allclose(steps, np.round(steps), atol=1e-6)


def test_pressure_is_the_state_at_the_sample_time(cfg: PlantConfig, run: SimulationResult) -> None:
    # integrate the ODE independently from the step on: p at t, not at t − τ
    c = plant_coefficients(cfg, T20)
    x0 = steady_state(U0, c).state
    t = np.array([T_STEP, T_STEP + 0.1, T_STEP + 0.2, T_STEP + 1.0, T_STEP + 3.0])
    states = integrate_held(x0, t - T_STEP, U1, c)
    index = np.searchsorted(run.time, t - 1e-9)
    np.testing.assert_allclose(run.p_pump[index], states[:, 2], rtol=1e-5)
    # within the meter's 0.2 s dead time the reading has not moved, the pressure has
    delay = cfg.flowmeter.delay_s
    early = (run.time > T_STEP) & (run.time < T_STEP + delay - 0.01)
    np.testing.assert_allclose(run.q_meter[early], run.q_meter[0], rtol=1e-9)
    assert np.all(run.p_pump[early] > run.p_pump[0])


def test_log_columns(run: SimulationResult) -> None:
    log = run.to_log()
    assert list(log.signals) == ["u_V", "q_Lpm", "T_fuel_degC", PRESSURE_COLUMN]
    assert log.units[PRESSURE_COLUMN] == "MPa"
    np.testing.assert_allclose(log[PRESSURE_COLUMN], run.p_measured / MPA)
    truth = run.to_log(include_truth=True)
    assert {"q_true_Lpm", "p_true_MPa"} <= set(truth.signals)
    np.testing.assert_allclose(truth["p_true_MPa"], run.p_pump / MPA)


def test_without_pressure_nothing_changes(cfg: PlantConfig, run: SimulationResult) -> None:
    plain = simulate(
        cfg, step_profile(U0, U1, T_STEP, END), sample_time=0.02, control_period=0.0, seed=3
    )
    assert plain.p_pump is None
    assert plain.p_measured is None
    assert list(plain.to_log(include_truth=True).signals) == [
        "u_V",
        "q_Lpm",
        "T_fuel_degC",
        "q_true_Lpm",
    ]
    # the flow is the same to far below the meter's resolution (a few more solver outputs)
    np.testing.assert_allclose(plain.q_meter, run.q_meter, rtol=1e-7)
    with pytest.raises(FuelidError, match="no pump pressure"):
        plain.measure_pressure()


def test_noise_settings_and_seed(run: SimulationResult) -> None:
    exact = run.measure_pressure(noise_std=0.0, resolution=0.0)
    np.testing.assert_array_equal(exact.p_measured, run.p_pump)
    again = run.measure_pressure(seed=3)
    np.testing.assert_array_equal(again.p_measured, run.p_measured)
    with pytest.raises(FuelidError, match="must be zero or positive"):
        run.measure_pressure(noise_std=-1.0)


runner = CliRunner()


def test_cli_pressure_column(tmp_path: Path, cfg: PlantConfig) -> None:
    out = tmp_path / "log.csv"
    args = ["simulate", str(out), "--pressure", "--truth", "--quiet", "--json"]
    result = runner.invoke(app, [*args, "--control-period", "0"])
    assert result.exit_code == 0, result.stderr
    log = pd.read_csv(out)
    assert {"p_pump_MPa", "p_true_MPa", "q_true_Lpm"} <= set(log.columns)
    c = plant_coefficients(cfg, T20)
    p1 = steady_state(1.5, c).p_pump / MPA  # default step 1 → 1.5 V at 10 s, 60 s long
    tail = log[log["t_s"] > 50.0]
    assert tail["p_true_MPa"].to_numpy() == pytest.approx(p1, rel=1e-6)
    assert abs(tail["p_pump_MPa"].mean() - p1) < 4 * 0.002 / np.sqrt(len(tail)) + 5e-5
    summary = json.loads(result.stdout)
    assert summary["units"]["p_range"] == "MPa"
    assert summary["p_range"][0] <= p1 <= summary["p_range"][1]

    quiet = tmp_path / "exact.csv"
    exact_args = ["--pressure-noise-std", "0", "--pressure-resolution", "0", "--quiet"]
    result = runner.invoke(app, ["simulate", str(quiet), "--pressure", *exact_args])
    assert result.exit_code == 0, result.stderr
    exact = pd.read_csv(quiet)
    assert exact["p_pump_MPa"].iloc[-1] == pytest.approx(p1, rel=1e-6)

    plain = tmp_path / "plain.csv"
    assert runner.invoke(app, ["simulate", str(plain), "--quiet"]).exit_code == 0
    assert "p_pump_MPa" not in pd.read_csv(plain).columns


def test_cli_refuses_negative_noise(tmp_path: Path) -> None:
    args = ["simulate", str(tmp_path / "x.csv"), "--pressure", "--pressure-resolution", "-1"]
    result = runner.invoke(app, args)
    assert result.exit_code == 2
    assert "--pressure-resolution" in result.stderr
    assert not (tmp_path / "x.csv").exists()


def test_last_sample_of_a_meter_without_delay(cfg: PlantConfig) -> None:
    # the sample at the very end of the run is the final state, not the initial one (a meter
    # without dead time reads it, as the pressure transmitter always does)
    no_delay = cfg.model_copy(
        update={"flowmeter": cfg.flowmeter.model_copy(update={"delay_s": 0.0})}
    )
    r = simulate(
        no_delay,
        step_profile(U0, U1, T_STEP, END),
        control_period=0.0,
        noise_std=0.0,
        resolution=0.0,
        pressure=True,
    )
    c = plant_coefficients(no_delay, T20)
    assert r.q_meter[-1] == pytest.approx(steady_state(U1, c).q, rel=1e-6)
    assert r.p_pump[-1] == pytest.approx(steady_state(U1, c).p_pump, rel=1e-6)


def test_cli_refuses_pressure_settings_without_pressure(tmp_path: Path) -> None:
    """A pressure setting without --pressure would be silently ignored: it is refused."""
    args = ["simulate", str(tmp_path / "x.csv"), "--pressure-noise-std", "0.01"]
    result = runner.invoke(app, args)
    assert result.exit_code == 2
    assert "add --pressure" in result.stderr
    assert not (tmp_path / "x.csv").exists()
