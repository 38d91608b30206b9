"""The test signal's design (issue 40): the loop's sensitivity, the Cramér–Rao bound, the choice.

Numbers fixed by theory, not by a previous run:

- the plant input's answer to a signal added to the PI's output is S = 1/(1 + C·G): the PLC's
  own discrete PI (:class:`fuelid.tuning._controller.DiscretePI`) on the sampled plant gives the
  same sequence, to rounding;
- the expected standard error of K is the Cramér–Rao bound of an output-error fit of that input
  (white noise, K, T, the dead time and the offset free): the spread of K over repeated noise
  realisations must match it, within the Monte Carlo band;
- the amplitude the design picks is the smallest that meets each gate: the binding gate's
  expected value sits at its aim, the others inside theirs.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.signal

from fuelid.io.timeseries import IOData
from fuelid.lti import discretise
from fuelid.model import ProcessModel
from fuelid.online.excitation._design import (
    DESIGN_MARGIN,
    DesignGoal,
    LoopNoise,
    design_signal,
    gbn_levels,
    needed_amplitudes,
    prbs_design,
    unit_response,
)
from fuelid.tuning import DiscretePI, input_sensitivity, simc

MODEL = ProcessModel(K=13.0, T=1.3, T_f=0.3, delay=0.2)
"""About the reference plant at 3 V and 20 °C ((L/min)/V, s)."""
PI = simc(MODEL, control_period=1.0)


def test_the_sensitivity_is_the_plc_pi_answering_the_signal() -> None:
    lags = discretise(MODEL.time_constants, MODEL.delay, 1.0)
    signal = gbn_levels(120, 3.0, seed=2)
    pi = DiscretePI(PI, -1e9, 1e9, u0=0.0)
    u = np.zeros(signal.size)
    for k in range(signal.size):
        y = MODEL.K * lags.response(np.r_[u[:k], 0.0])[-1]  # the flow at the scan: u[k] unknown
        u[k] = pi.update(0.0, y) + signal[k]
    num, den = input_sensitivity(MODEL, PI)
    expected = scipy.signal.lfilter(num, den, signal)
    assert np.max(np.abs(u - expected)) < 1e-9


def test_a_constant_signal_is_rejected_by_the_integral() -> None:
    num, den = input_sensitivity(MODEL, PI)
    assert abs(np.sum(num) / np.sum(den)) < 1e-12


def test_the_expected_stderr_of_K_is_the_spread_of_output_error_fits() -> None:
    """Monte Carlo against the bound: M fits, the spread's relative error ~ 1/√(2M) (theory.md).

    Acceptance band, fixed before the run: with M = 60 the sample sd of K̂ has a relative
    standard error of 1/√120 = 9.1 %; the band is ±3 of those, 27 %, around the bound.
    """
    from fuelid.identify import OutputError

    period_s, window_s, sigma = 0.02, 120.0, 0.1
    levels = gbn_levels(60, 8.0, seed=4)
    noise = LoopNoise.white(sigma)
    unit = unit_response(MODEL, PI, levels, noise, period_s=period_s, window_s=window_s)
    amplitude = 0.05
    expected_se = unit.rel_stderr["K"] / amplitude * MODEL.K
    # the input the signal makes in closed loop, then the open-loop output-error problem on it
    num, den = input_sensitivity(MODEL, PI)
    periods = math.ceil(window_s / PI.control_period)
    s = np.zeros(periods)
    s[: levels.size] = amplitude * levels
    u = np.repeat(scipy.signal.lfilter(num, den, s), 50)[: round(window_s / period_s)]
    lags = discretise(MODEL.time_constants, MODEL.delay, period_s)
    clean = 60.0 + MODEL.K * lags.response(u)
    rng = np.random.default_rng(11)
    estimates = []
    for _ in range(60):
        y = clean + rng.normal(0.0, sigma, size=u.size)
        fit = OutputError(order=1, T_f=MODEL.T_f, initial="rest", u_before=0.0, covariance="white")
        fit.fit(IOData(u=u, y=y, sample_time=period_s))
        estimates.append(fit.K_)
    spread = float(np.std(estimates, ddof=1))
    print(f"sd of K over 60 fits {spread:.4g}, the bound {expected_se:.4g}")
    assert abs(spread / expected_se - 1.0) < 0.27


def test_the_amplitude_is_the_smallest_that_meets_each_gate() -> None:
    noise = LoopNoise.white(0.1)
    goal = DesignGoal()
    design = design_signal(
        MODEL, PI, noise, goal, amplitude_cap_V=1.0, period_s=0.02, window_s=600.0, burst_s=180.0
    )
    assert design.reaches_goal
    assert design.amplitude_V == pytest.approx(max(design.needed_V.values()))
    aims = {
        "K": DESIGN_MARGIN * goal.max_rel_stderr_K,
        "T": DESIGN_MARGIN * goal.max_rel_stderr_T,
    }
    for name, aim in aims.items():
        assert design.expected_rel_stderr[name] <= aim * (1 + 1e-9)
        if design.bound == name:
            assert design.expected_rel_stderr[name] == pytest.approx(aim)
    assert design.expected_fit_percent >= goal.min_fit_percent
    # the signal's level is ±amplitude, held per control period, over the burst only
    values = design.values()
    assert set(np.round(np.abs(values), 12)) == {round(design.amplitude_V, 12)}
    assert values.size == 180


def test_a_cap_below_the_need_is_said() -> None:
    noise = LoopNoise.white(0.1)
    design = design_signal(
        MODEL, PI, noise, DesignGoal(), amplitude_cap_V=0.01, period_s=0.02, window_s=600.0,
        burst_s=180.0,
    )  # fmt: skip
    assert design.bound == "amplitude"
    assert not design.reaches_goal
    assert design.amplitude_V == 0.01


def test_needed_amplitudes_scale_as_theory_says() -> None:
    """Standard errors ∝ 1/a, added variance ∝ a²: twice the noise, twice every amplitude."""
    noise = LoopNoise.white(0.1)
    unit = unit_response(MODEL, PI, gbn_levels(180, 8.0, 0), noise, period_s=0.02, window_s=600.0)
    louder = unit_response(
        MODEL, PI, gbn_levels(180, 8.0, 0), LoopNoise.white(0.2), period_s=0.02, window_s=600.0
    )
    one = needed_amplitudes(unit, noise, DesignGoal())
    two = needed_amplitudes(louder, LoopNoise.white(0.2), DesignGoal())
    for name in ("K", "T", "fit"):
        assert two[name] == pytest.approx(2.0 * one[name], rel=1e-9)


def test_the_design_needs_less_flow_variance_than_a_prbs_on_a_slow_loop() -> None:
    """The same standard error of K; the PRBS clocked at h puts its power where T and K trade."""
    slow = ProcessModel(K=5.0, T=8.0, T_f=0.3, delay=1.0)
    pi = simc(slow, control_period=1.0)
    noise = LoopNoise.white(0.1)
    goal = DesignGoal(max_rel_stderr_T=math.inf, min_fit_percent=-math.inf)
    kwargs = {"period_s": 0.02, "window_s": 600.0, "burst_s": 180.0}
    designed = design_signal(slow, pi, noise, goal, amplitude_cap_V=10.0, **kwargs)
    prbs = prbs_design(slow, pi, noise, goal, **kwargs)
    assert designed.expected_rel_stderr["K"] == pytest.approx(prbs.expected_rel_stderr["K"])
    assert (designed.added_flow_sd_Lpm / prbs.added_flow_sd_Lpm) ** 2 <= 0.5
