"""The report's model curves after a gap: each segment restarts from its own measured state.

The log comes from a known linear plant (the model family itself, so the identified models are
unbiased to within their standard errors) with white measurement noise of std σ. Before the gap
the flow is steady at one level, after it at another (both off the record's initial level, the
command change falls inside the gap and has settled when the log resumes). Right after the
restart every curve drawn in the report's comparison figure must lie within the noise of the
measured flow: |y − ŷ| ≤ 4σ per sample (for the 20 samples of the first 2 s the chance that
noise alone leaves that band is 20 · 6.3e-5 ≈ 1e-3; the models' own level error, a few
thousandths of the 14 L/min step, is far below σ). Before the fix the step-ls curve was
interpolated across the gap from the level before it (a dip of about ΔL · 0.5 s / 12 s ≈ 0.6
L/min = 30σ at the first sample) and its restart held the fit's level with a least-squares free
response that overshoots a constant error.
"""

from __future__ import annotations

import numpy as np
import pytest

from fuelid.htmlreport import report_figures
from fuelid.identify import IdentifyOptions, identify
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel, simulate_model
from fuelid.plant import load_plant_config
from fuelid.workflow import AnalysisSettings, PlantSource, analyse_log

H = 0.1
"""Sample time [s]."""
SIGMA = 0.02
"""Flowmeter noise std [L/min]."""
TRUTH = ProcessModel(K=14.0, T=1.5, delay=0.3)
LEVELS = (1.0, 1.5, 2.5, 1.5, 1.0, 2.0, 1.25, 1.75, 1.0, 2.25)
"""Command levels [V], 30 s each: the gap removes 58 … 69.5 s, around the step to 2.5 V at 60 s."""
GAP = (580, 695)
"""The samples removed [index]: the log resumes 9.5 s (> 6 T) after the step inside the gap."""


def _log() -> IOData:
    u = np.repeat(LEVELS, 300)
    rng = np.random.default_rng(11)
    y = 14.0 + simulate_model(TRUTH, u, H) + rng.normal(0.0, SIGMA, u.size)
    keep = np.ones(u.size, dtype=bool)
    keep[GAP[0] : GAP[1]] = False
    return IOData(u[keep], y[keep], H, segment_starts=(GAP[0],), segment_t0=(GAP[1] * H,))


@pytest.fixture(scope="module")
def comparison_lines() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The comparison figure's lines, by label (measured, then one per method)."""
    analysis = analyse_log(
        _log(), PlantSource(load_plant_config(), None), AnalysisSettings(control_period=1.0)
    )
    figure = report_figures(analysis)["comparison"][0]
    lines = figure.axes[0].get_lines()
    return {
        str(line.get_label()).split(" ")[0]: (
            np.asarray(line.get_xdata(), dtype=float),
            np.asarray(line.get_ydata(), dtype=float),
        )
        for line in lines
    }


@pytest.mark.parametrize("method", ["oe", "step-ls"])
def test_model_curve_restarts_at_the_measured_flow(
    comparison_lines: dict[str, tuple[np.ndarray, np.ndarray]], method: str
) -> None:
    t, measured = comparison_lines["measured"]
    t_curve, curve = comparison_lines[method]
    np.testing.assert_array_equal(t_curve, t)
    restart = GAP[1] * H
    after = (t >= restart - 1e-9) & (t < restart + 2.0)
    assert after.sum() == 20
    # steady and off the initial level (14 L/min): a restart from a wrong state would show
    assert np.all(np.abs(measured[after] - 14.0 - TRUTH.K * 1.5) < 5 * SIGMA)
    worst = float(np.max(np.abs(curve[after] - measured[after])))
    assert worst <= 4 * SIGMA, f"{method}: {worst:.3f} L/min off the measured flow"


def test_no_line_is_drawn_across_the_gap(
    comparison_lines: dict[str, tuple[np.ndarray, np.ndarray]],
) -> None:
    t, measured = comparison_lines["measured"]
    inside = (t > GAP[0] * H - H / 2) & (t < GAP[1] * H - H / 2)
    assert inside.sum() == 1
    assert np.isnan(measured[inside]).all()
    for _, (_, curve) in comparison_lines.items():
        assert np.isnan(curve[inside]).all()


def test_step_ls_restarts_from_the_measured_state_where_its_level_is_off() -> None:
    """step-ls restarts from the measured flow where its own level is off the measured one.

    The plant's gain grows with the command (y = 14 + (10 + 4u)·u through the lag), so the
    fitted step-ls model's level is off the measured one at most commands, by far more than σ.
    After the gap the fitted simulation must still start at the measured flow (within 4σ of the
    decimated samples, whose noise is at most σ), not at the model's level with a free response
    whose least squares overshoots the constant error.
    """
    u = np.repeat(LEVELS, 300)
    rng = np.random.default_rng(12)
    static = (10.0 + 4.0 * u) * u
    y = 14.0 + simulate_model(ProcessModel(K=1.0, T=1.5, delay=0.3), static, H)
    y += rng.normal(0.0, SIGMA, u.size)
    keep = np.ones(u.size, dtype=bool)
    keep[GAP[0] : GAP[1]] = False
    data = IOData(u[keep], y[keep], H, segment_starts=(GAP[0],), segment_t0=(GAP[1] * H,))
    result = identify(data, IdentifyOptions(method="step-ls", control_period=1.0, delay=0.3, N=10))
    after = (result.time >= GAP[1] * H) & (result.time < GAP[1] * H + 3.0)
    off = np.abs(result.y_hat[after] - result.y[after])
    steady_error = abs(float(np.mean(result.y_hat[-50:] - result.y[-50:])))
    assert steady_error > 5 * SIGMA  # the model's level is off at this command
    assert float(off.max()) <= 4 * SIGMA
