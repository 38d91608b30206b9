"""``--method pem`` and ``--method auto`` from the command line (issue 13, parts 2 and 3)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.signal
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.model import ProcessModel, simulate_model

runner = CliRunner()
H = 0.02
TRUTH = ProcessModel(K=13.5, T=1.26, T_f=0.3, delay=0.2)
PRIORS = ["--flowmeter-T", "0.3", "--flowmeter-delay", "0.2", "--order", "1"]


def _log(folder: Path, pole: float, seed: int = 3) -> Path:
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(1.5, 4.5, 12), 1000)  # 12 steps of 20 s
    sd = 0.25
    noise = scipy.signal.lfilter(
        [1.0], [1.0, -pole], rng.normal(0.0, sd * np.sqrt(1.0 - pole**2), u.size)
    )
    y = 40.0 + simulate_model(TRUTH, u, H) + noise
    path = folder / f"log_{pole:g}.csv"
    t = H * np.arange(u.size)
    np.savetxt(path, np.column_stack([t, u, y]), delimiter=",", header="t_s,u_V,q_Lpm", comments="")
    return path


def _identify(path: Path, *args: str) -> dict:
    result = runner.invoke(app, ["identify", str(path), *PRIORS, *args, "--json"])
    assert result.exit_code == 0, result.stderr
    return json.loads(result.stdout)


def test_pem_reports_its_noise_model_and_covariance_convention(tmp_path: Path):
    data = _identify(_log(tmp_path, 0.95), "--method", "pem")
    assert data["method"] == "pem"
    assert data["covariance"] == "noise-model"
    noise = data["noise_model"]
    assert (noise["nc"], noise["nd"]) == (0, 1)
    assert noise["poles"][0] == pytest.approx(0.95, abs=0.02)
    # free run for fit_percent, the one-step predictor's fit named separately (and higher)
    assert data["one_step_fit_percent"] > data["fit_percent"]
    # the residual tests are on the prediction errors: white with the right noise model
    assert data["diagnostics"]["residual_whiteness"]["passed"] is True
    for name in ("K", "T"):
        low, high = data["ci95"][name]
        assert low <= getattr(TRUTH, name) <= high


def test_auto_chooses_pem_on_coloured_noise_and_oe_on_white(tmp_path: Path):
    coloured = _identify(_log(tmp_path, 0.95), "--method", "auto")
    assert coloured["method"] == "pem"
    assert coloured["method_choice"].startswith("auto: pem")
    white = _identify(_log(tmp_path, 0.0), "--method", "auto")
    assert white["method"] == "oe"
    assert white["covariance"] == "white"
    assert white["method_choice"].startswith("auto: oe")


def test_the_covariance_choice_is_refused_where_it_does_not_apply(tmp_path: Path):
    path = _log(tmp_path, 0.0)
    for method in ("pem", "step-ls"):
        result = runner.invoke(
            app, ["identify", str(path), "--method", method, "--covariance", "hac"]
        )
        assert result.exit_code == 2
        assert "the covariance choice is oe's" in result.stderr


def test_pems_report_tests_its_prediction_errors(tmp_path: Path):
    from fuelid.io.logs import load_log
    from fuelid.plant import load_plant_config
    from fuelid.workflow import AnalysisSettings, PlantSource, analyse_log

    data = load_log(_log(tmp_path, 0.95))
    analysis = analyse_log(
        data,
        PlantSource(load_plant_config()),
        AnalysisSettings(tune_from="pem", band_width=35, control_period=1.0),  # never assumed
    )
    chosen = analysis.model_result
    assert chosen.method == "pem"
    assert chosen.prediction_errors is not None
    # the figure's test is the table's: white prediction errors, not the coloured free run
    assert analysis.whiteness.passed
    assert analysis.whiteness.p_value == pytest.approx(
        chosen.diagnostics["residual_whiteness"]["p_value"]
    )
