"""Nonlinear simulation of the reference plant as the PLC sees it.

Checks: the linearisation predicts small steps (second-order terms ∝ Δu), the steady start and
the final value are the nonlinear operating points, the meter's delay and the controller's
sample-and-hold shift the response by exactly their amounts, the noise and the quantisation have
the configured statistics, and a warming fuel makes the flow drift down (more leakage).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import fuelid.plant.simulate
from fuelid.errors import FuelidError
from fuelid.plant import PlantConfig, linearise, operating_point, plant_coefficients, steady_state
from fuelid.plant.simulate import FuelTemperature, SimulationResult, integrate_held, simulate
from fuelid.profiles import InputProfile, step_profile

LPM = 60_000.0  # L/min per m³/s
T20 = 293.15
DELAY = 0.2  # flowmeter delay of the reference plant [s]


def _clean(cfg: PlantConfig, profile: InputProfile, **kwargs: object) -> SimulationResult:
    """Noise-free, unquantised run with a continuous controller, 0.01 s samples."""
    options: dict[str, object] = {
        "sample_time": 0.01,
        "control_period": 0.0,
        "noise_std": 0.0,
        "resolution": 0.0,
    }
    options.update(kwargs)
    return simulate(cfg, profile, **options)  # type: ignore[arg-type]


def _constant(u: float, duration: float) -> InputProfile:
    return InputProfile(np.array([0.0]), np.array([u]), duration)


# --------------------------------------------------------------------------------------------
# linearisation against small steps


@pytest.mark.parametrize(("u0", "T"), [(1.25, T20), (3.0, T20), (3.0, 253.15), (4.0, 323.15)])
def test_small_step_matches_linearisation(cfg: PlantConfig, u0: float, T: float) -> None:
    du, t_step = 0.01, 1.0
    r = _clean(cfg, step_profile(u0, u0 + du, t_step, t_step + 15.0), T_fuel=T)
    y = (r.q_meter - r.q_meter[0]) * LPM / du  # normalised response [(L/min)/V]
    lin = linearise(cfg, u0, T)
    K = lin.static_gain
    y_lin = lin.step_response(r.time - t_step)
    # The deviation is second order: Δq/Δu − K ≈ ½·K'·Δu with |K'| ≲ 1 (L/min)/V² on this
    # plant (K falls by ~2 (L/min)/V from 1 to 5 V), i.e. ≲ 0.005 (L/min)/V ≈ 4e-4·K for
    # Δu = 0.01 V; the integrator tolerance (atol 1e-11 m³/s) adds < 1e-5·K. Allow 1e-3·K.
    assert np.max(np.abs(y - y_lin)) < 1e-3 * K
    # nothing reaches the reading before the meter's delay (to rounding)
    assert np.all(np.abs(y[r.time < t_step + DELAY]) <= 1e-8 * K)


def test_meter_without_lag_matches_its_linearisation(cfg: PlantConfig) -> None:
    # T_f = 0: the reading is the line flow itself (delayed); the linear model has four states
    no_lag = cfg.model_copy(
        update={"flowmeter": cfg.flowmeter.model_copy(update={"time_constant_s": 0.0})}
    )
    u0, du, t_step = 3.0, 0.01, 1.0
    r = _clean(no_lag, step_profile(u0, u0 + du, t_step, t_step + 15.0))
    q0 = operating_point(no_lag, u0, T20).q
    assert np.all(np.abs(r.q_meter[r.time < t_step + DELAY] - q0) <= 1e-12 * q0)
    lin = linearise(no_lag, u0, T20)
    K = lin.static_gain
    y = (r.q_meter - r.q_meter[0]) * LPM / du
    # second-order terms ≲ 4e-4·K for a 0.01 V step (see the test above)
    assert np.max(np.abs(y - lin.step_response(r.time - t_step))) < 1e-3 * K
    # without the meter lag the reading leads the lagged one of the reference plant
    lagged = _clean(cfg, step_profile(u0, u0 + du, t_step, t_step + 15.0))
    half = (r.time > t_step + DELAY) & (r.time < t_step + 3.0)
    assert np.all(r.q_meter[half] > lagged.q_meter[half])


def test_large_step_departs_from_linearisation_in_proportion(cfg: PlantConfig) -> None:
    # the secant gain error grows ∝ Δu (second-order term): a 1 V step is ~100× worse than a
    # 0.01 V step, and below K because the static curve bends down (K' < 0)
    u0, t_step, T = 3.0, 1.0, T20
    K = linearise(cfg, u0, T).static_gain

    def final_gain_error(du: float) -> float:
        r = _clean(cfg, step_profile(u0, u0 + du, t_step, t_step + 25.0), T_fuel=T)
        return (r.q_meter[-1] - r.q_meter[0]) * LPM / du - K

    small, large = final_gain_error(0.01), final_gain_error(1.0)
    assert small < 0.0
    assert large < 0.0
    assert 50.0 < large / small < 150.0
    assert abs(large) > 0.005 * K  # clearly nonlinear at 1 V


# --------------------------------------------------------------------------------------------
# steady states, delay, sample-and-hold


@pytest.fixture(scope="module")
def article_step(cfg: PlantConfig) -> SimulationResult:
    """The article's experiment: 1 V until steady, then 1.5 V (step at 5 s, 35 s after it)."""
    return _clean(cfg, step_profile(1.0, 1.5, 5.0, 40.0))


def test_starts_at_operating_point(cfg: PlantConfig, article_step: SimulationResult) -> None:
    q0 = operating_point(cfg, 1.0, T20).q
    before = article_step.q_meter[article_step.time < 5.0 + DELAY]
    assert before.size == 520
    assert np.all(np.abs(before - q0) <= 1e-12 * q0)


def test_ends_at_new_operating_point(cfg: PlantConfig, article_step: SimulationResult) -> None:
    # 35 s after the step the slowest mode (1/T_vfd = 0.83 s⁻¹) has decayed by e^(−29) ≈ 3e-13
    q1 = operating_point(cfg, 1.5, T20).q
    assert article_step.q_meter[-1] == pytest.approx(q1, rel=1e-6)
    # and the flow rose by about K·Δu: 0.5 V at ~14 (L/min)/V ≈ 7 L/min
    rise = (article_step.q_meter[-1] - article_step.q_meter[0]) * LPM
    assert 6.0 < rise < 7.5


def test_logged_command_follows_profile(article_step: SimulationResult) -> None:
    t, u = article_step.time, article_step.u
    assert np.all(u[t < 5.0] == 1.0)
    assert np.all(u[t >= 5.0] == 1.5)
    assert t[-1] == pytest.approx(40.0, abs=1e-12)
    assert t.size == 4001


def test_noise_free_reading_is_the_meter_state(article_step: SimulationResult) -> None:
    # only the m³/s → L/min → m³/s round trip of measure_flow separates them
    np.testing.assert_allclose(article_step.q_measured, article_step.q_meter, rtol=1e-15)


def test_meter_delay_shifts_response(cfg: PlantConfig, article_step: SimulationResult) -> None:
    # a 0.5 s meter delay instead of 0.2 s shifts the whole reading by 0.3 s = 30 samples
    slow = cfg.model_copy(update={"flowmeter": cfg.flowmeter.model_copy(update={"delay_s": 0.5})})
    r = _clean(slow, step_profile(1.0, 1.5, 5.0, 40.0))
    q0 = article_step.q_meter[0]
    assert np.all(np.abs(r.q_meter[r.time < 5.5] - q0) <= 1e-12 * q0)  # none before t_step + τ
    # response is visibly under way 1 s after the delay
    assert r.q_meter[r.time >= 6.5][0] > q0 * 1.05
    shift = 30
    span = article_step.q_meter[-1] - q0
    np.testing.assert_allclose(
        r.q_meter[shift:], article_step.q_meter[:-shift], rtol=0.0, atol=1e-6 * span
    )


def test_control_period_holds_step_to_next_update(cfg: PlantConfig) -> None:
    # a step requested at 10.3 s reaches the drive at the next 1 s controller update, 11.0 s
    r = _clean(cfg, step_profile(2.0, 2.5, 10.3, 15.0), control_period=1.0)
    assert np.all(r.u[r.time < 11.0] == 2.0)
    assert np.all(r.u[r.time >= 11.0] == 2.5)
    q0 = operating_point(cfg, 2.0, T20).q
    assert np.all(np.abs(r.q_meter[r.time < 11.0 + DELAY] - q0) <= 1e-12 * q0)
    # identical to a continuous controller given the step at 11.0 s
    ref = _clean(cfg, step_profile(2.0, 2.5, 11.0, 15.0), control_period=0.0)
    np.testing.assert_allclose(r.q_meter, ref.q_meter, rtol=1e-12, atol=0.0)


# --------------------------------------------------------------------------------------------
# noise, quantisation, reproducibility


def test_seed_reproducible(cfg: PlantConfig) -> None:
    profile = step_profile(3.0, 3.5, 2.0, 10.0)
    # the config's noise (0.1 L/min) and resolution (0.01 L/min), 0.02 s samples
    a = simulate(cfg, profile, seed=11)
    b = simulate(cfg, profile, seed=11)
    c = simulate(cfg, profile, seed=12)
    np.testing.assert_array_equal(a.q_measured, b.q_measured)
    np.testing.assert_array_equal(a.q_meter, c.q_meter)  # the noise does not touch the plant
    # σ = 10 resolution steps: two independent draws coincide in < 5 % of the samples
    assert np.mean(a.q_measured != c.q_measured) > 0.9


def test_noise_level_matches_noise_std(cfg: PlantConfig) -> None:
    sigma_lpm = 0.5
    r = _clean(cfg, _constant(3.0, 100.0), noise_std=sigma_lpm / LPM, seed=5)
    e = (r.q_measured - r.q_meter) * LPM
    n = e.size  # 10001
    assert n == 10_001
    # sample sd has relative sd 1/√(2(n−1)) = 0.71 %, the mean sd σ/√n; allow 5 of each
    assert e.std(ddof=1) == pytest.approx(sigma_lpm, rel=5.0 / math.sqrt(2.0 * (n - 1)))
    assert abs(e.mean()) < 5.0 * sigma_lpm / math.sqrt(n)
    # white: lag-1 autocorrelation within 5/√n of zero
    rho1 = float(np.corrcoef(e[:-1], e[1:])[0, 1])
    assert abs(rho1) < 5.0 / math.sqrt(n)


def test_config_noise_used_by_default(cfg: PlantConfig) -> None:
    # reference flowmeter: σ = 0.1 L/min, resolution 0.01 L/min (var adds r²/12, negligible)
    r = simulate(cfg, _constant(2.0, 200.0), sample_time=0.02, seed=3)
    e = (r.q_measured - r.q_meter) * LPM
    n = e.size
    expected = math.sqrt(0.1**2 + 0.01**2 / 12.0)
    assert e.std(ddof=1) == pytest.approx(expected, rel=5.0 / math.sqrt(2.0 * (n - 1)))


@pytest.mark.parametrize("noise_lpm", [0.0, 0.2])
def test_quantisation_grid(cfg: PlantConfig, noise_lpm: float) -> None:
    res_lpm = 0.05
    r = _clean(
        cfg,
        step_profile(1.5, 4.0, 1.0, 8.0),
        noise_std=noise_lpm / LPM,
        resolution=res_lpm / LPM,
        seed=1,
    )
    k = r.q_measured * LPM / res_lpm
    assert np.max(np.abs(k - np.round(k))) < 1e-6
    if noise_lpm == 0.0:
        # rounding to nearest: error at most half a step
        assert np.max(np.abs(r.q_measured - r.q_meter)) * LPM <= res_lpm / 2.0 + 1e-9


# --------------------------------------------------------------------------------------------
# fuel temperature


def test_warming_fuel_lowers_flow(cfg: PlantConfig) -> None:
    # 3 V held; fuel warms −20 → +50 °C over 40 s, then stays: thinner fuel leaks more
    cold, warm, ramp = 253.15, 323.15, 40.0
    temperature = FuelTemperature.ramp(cold, warm, ramp)
    r = _clean(
        cfg,
        _constant(3.0, 70.0),
        T_fuel=temperature,
        sample_time=0.1,
    )
    q_cold = operating_point(cfg, 3.0, cold).q
    q_warm = operating_point(cfg, 3.0, warm).q
    assert q_warm < 0.95 * q_cold
    assert r.q_meter[0] == pytest.approx(q_cold, rel=1e-12)
    # 30 s after the ramp ends the flow is the warm operating point
    assert r.q_meter[-1] == pytest.approx(q_warm, rel=1e-6)
    # the drift is downward throughout the ramp (samples 5 s apart)
    during = r.q_meter[(r.time >= 0.0) & (r.time <= ramp)][::50]
    assert np.all(np.diff(during) < 0.0)
    # a ramp this slow is tracked quasi-statically: the flow lags the steady flow of the
    # present temperature by less than the plant's time scale (T + T_f + τ ≈ 1.8 s < 2 s)
    for t in (10.0, 20.0, 30.0):
        q_t = r.q_meter[np.argmin(np.abs(r.time - t))]
        q_now = operating_point(cfg, 3.0, float(temperature.at(t))).q
        q_before = operating_point(cfg, 3.0, float(temperature.at(t - 2.0))).q
        assert q_now < q_t < q_before
    # logged temperature follows the ramp: 20 s into 70 K over 40 s = +35 K
    assert r.T_fuel[np.argmin(np.abs(r.time - 20.0))] == pytest.approx(cold + 35.0, rel=1e-12)


# --------------------------------------------------------------------------------------------
# refusals


@pytest.mark.parametrize(("u0", "u1"), [(1.0, 5.5), (0.5, 2.0)])
def test_command_outside_signal_range_refused(cfg: PlantConfig, u0: float, u1: float) -> None:
    with pytest.raises(FuelidError, match="signal range"):
        simulate(cfg, step_profile(u0, u1, 1.0, 5.0))


def test_fuel_temperature_outside_range_refused(cfg: PlantConfig) -> None:
    with pytest.raises(FuelidError, match="outside"):
        simulate(cfg, _constant(2.0, 5.0), T_fuel=353.15)


@pytest.mark.parametrize("sample_time", [0.0, -0.02, float("nan")])
def test_bad_sample_time_refused(cfg: PlantConfig, sample_time: float) -> None:
    with pytest.raises(FuelidError, match="sample time"):
        simulate(cfg, _constant(2.0, 5.0), sample_time=sample_time)


# --------------------------------------------------------------------------------------------
# the held-command integration shared with the closed loop


def test_integrate_held_reaches_the_new_operating_point(cfg: PlantConfig) -> None:
    c = plant_coefficients(cfg, T20)
    x0 = steady_state(2.0, c).state
    times = np.array([0.0, 0.5, 1.0, 2.0, 60.0])
    states = integrate_held(x0, times, 3.0, c)
    assert states.shape == (5, 5)
    assert np.array_equal(states[0], x0)
    rest = steady_state(3.0, c).state
    # 60 s is many times the slowest lag: the end is the rest state of the new command
    assert states[-1] == pytest.approx(rest, rel=1e-6)
    # on the way the flow rises (the ramp of the drive and the lag of the line)
    assert np.all(np.diff(states[:4, 3]) > 1e-6)


@pytest.mark.parametrize(
    ("setting", "value", "message"),
    [("MAX_STEPS", 1, "Excess work done"), ("RTOL", -1.0, "Illegal input")],
)
def test_solver_failure_is_a_fuelid_error(
    cfg: PlantConfig, monkeypatch: pytest.MonkeyPatch, setting: str, value: object, message: str
) -> None:
    # a solver that gives up (too few steps allowed, an impossible tolerance) must not pass
    # silently, nor as a bare warning: it is refused with the span and the solver's reason
    monkeypatch.setattr(fuelid.plant.simulate, setting, value)
    c = plant_coefficients(cfg, T20)
    with pytest.raises(FuelidError, match=f"ODE solver failed on 0…2 s at u = 3 V: {message}"):
        integrate_held(steady_state(2.0, c).state, np.array([0.0, 1.0, 2.0]), 3.0, c)
    with pytest.raises(FuelidError, match=f"ODE solver failed .*{message}"):
        simulate(cfg, step_profile(2.0, 3.0, 1.0, 5.0))
