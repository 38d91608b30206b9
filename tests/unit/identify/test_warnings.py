"""Warnings that are true where they are shown, with advice that applies (issue: cry-wolf warnings).

The data come from the model family, so what the warning should say is known.
"""

from __future__ import annotations

import numpy as np
import scipy.signal

from fuelid.identify import IdentifyOptions, identify
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel, simulate_model

H = 0.02


def _log(truth: ProcessModel, levels: list[float], dwell: float) -> IOData:
    u = np.repeat(levels, round(dwell / H))
    y = 40.0 + simulate_model(truth, u, H) + np.random.default_rng(0).normal(0, 0.01, u.size)
    return IOData(u, y, H)


def test_step_ls_on_a_raw_log_points_to_the_output_error_fit_on_those_samples() -> None:
    # the article's method decimates a 0.02 s log to 1 s: the advice must name the raw samples
    # the user already has and the method that fits them, not "fit the raw samples (e.g. 0.02 s)"
    truth = ProcessModel(K=13.5, T=1.3, T_f=0.3, delay=0.2)
    data = _log(truth, [1.0, 1.5, 1.2, 1.8, 1.3, 1.6], 30.0)
    result = identify(data, IdentifyOptions(method="step-ls", flowmeter_T=0.3, delay=0.2, N=8))
    advice = [w for w in result.warnings if "settling time" in w and "samples" in w]
    assert advice, result.warnings
    assert "fit the raw samples (every 0.02 s) with the output-error method" in advice[0]
    assert "e.g." not in advice[0]


def test_report_says_each_load_note_once(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import json

    from typer.testing import CliRunner

    from fuelid.cli import app

    log = tmp_path / "semi.csv"
    truth = ProcessModel(K=13.5, T=1.3, T_f=0.3, delay=0.2)
    data = _log(truth, [1.0, 2.0, 1.5, 3.0], 30.0)
    t = np.arange(data.n_samples) * H
    rows = zip(t, data.u, data.y, strict=True)
    log.write_text("t_s;u_V;q_Lpm\n" + "\n".join(f"{a:.2f};{b:.4f};{c:.4f}" for a, b, c in rows))
    args = ["report", str(log), "--out", str(tmp_path / "r.html"), "--control-period", "1"]
    args.append("--json")
    result = CliRunner().invoke(app, [*args, "--band-width", "35", "--flow-bands", "1"])
    assert result.exit_code == 0, result.stderr
    warnings = json.loads(result.stdout)["warnings"]
    notes = [w for w in warnings if "columns separated by ';'" in w]
    assert notes == ["log: columns separated by ';'"]


def test_coloured_noise_is_named_only_when_the_settled_output_shows_it() -> None:
    truth = ProcessModel(K=13.5, T=1.3, T_f=0.3, delay=0.2)
    u = np.repeat([1.0, 1.5, 1.2, 1.8, 1.3, 1.6], round(30.0 / H))
    rng = np.random.default_rng(2)
    # AR(1) measurement noise, pole 0.9 (correlation time 0.2 s): coloured everywhere
    white = rng.normal(0.0, 0.05, u.size)
    coloured = scipy.signal.lfilter([1.0], [1.0, -0.9], white)
    y = 40.0 + simulate_model(truth, u, H) + coloured
    options = IdentifyOptions(flowmeter_T=0.3, flowmeter_delay=0.2)
    result = identify(IOData(u, y, H), options)
    [whiteness] = [w for w in result.warnings if w.startswith("residuals are not white")]
    assert "also where the output has settled" in whiteness
    assert "coloured noise or a drift" in whiteness
    # the same plant with white noise and a model missing the meter lag: the misfit is in the
    # transients only, and the noise is not blamed
    y = 40.0 + simulate_model(truth, u, H) + white
    result = identify(IOData(u, y, H), IdentifyOptions(order=1, delay=0.2))
    [whiteness] = [w for w in result.warnings if w.startswith("residuals are not white")]
    assert "only after command changes" in whiteness
    assert "the noise is white" in whiteness


def test_the_simulators_logs_get_no_untrue_warning(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """`fuelid simulate`'s logs (the nonlinear plant, white meter noise) through `identify`.

    The noise is white by construction, so no warning may blame coloured noise or a drift; the
    misfit is the plant's (higher-order dynamics, the gain changing with the command), and what
    each residual warning names must be one of those.
    """
    import json

    from typer.testing import CliRunner

    from fuelid.cli import app

    runner = CliRunner()
    profiles = [
        ["--profile", "steps", "--duration", "300"],
        ["--profile", "random", "--levels", "1.0,2.0", "--hold", "5", "--duration", "300"],
        ["--profile", "random", "--levels", "1.0,5.0", "--hold", "10", "--duration", "300"],
    ]
    for k, profile in enumerate(profiles):
        log = tmp_path / f"sim{k}.csv"
        made = runner.invoke(app, ["simulate", str(log), *profile, "--seed", str(k), "--quiet"])
        assert made.exit_code == 0, made.stderr
        done = runner.invoke(app, ["identify", str(log), "--json"])
        assert done.exit_code == 0, done.stderr
        warnings = json.loads(done.stdout)["warnings"]
        untrue = [w for w in warnings if "coloured noise" in w or "drift" in w]
        assert untrue == [], (profile, untrue)
        for warning in warnings:
            if warning.startswith("residuals"):
                assert any(
                    cause in warning
                    for cause in ("transient", "outside the model family", "the gain changes")
                ), warning
