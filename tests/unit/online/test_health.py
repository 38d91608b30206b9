"""Loop-health metrics (fuelid.online.health) against numbers that theory fixes."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import scipy.signal

from fuelid.online.health import (
    hagglund_oscillation,
    half_period_iae,
    harris_index,
    loop_health,
    noise_level,
    quantisation_step,
    sensor_health,
    setpoint_responses,
    step_response_measures,
    time_at_limits,
    time_in_auto,
)
from fuelid.plc.virtual import VirtualPLC

H = 0.02  # 50 Hz, the PLC's sample period [s]


# --- shares ---------------------------------------------------------------------------------------


def test_time_in_auto_counts_good_samples_only():
    mode = np.r_[np.ones(300), np.zeros(100)]
    ok = np.ones(400, bool)
    assert time_in_auto(mode, ok) == 0.75
    ok[:200] = False  # the bad samples do not count: 100 AUTO of 200 good
    assert time_in_auto(mode, ok) == 0.5
    assert math.isnan(time_in_auto(mode, np.zeros(400, bool)))


def test_time_at_limits_counts_both_limits_within_tolerance():
    u = np.r_[np.full(10, 1.0), np.full(5, 5.0), np.full(5, 4.997), np.full(80, 3.0)]
    assert time_at_limits(u) == 0.2
    assert time_at_limits(u, tol=0.001) == 0.15
    assert time_at_limits(u, u_min=0.0, u_max=10.0) == 0.0


# --- Hägglund -------------------------------------------------------------------------------------


def test_half_period_iae_of_a_sinusoid_is_2A_over_omega():
    # ∫ over half a period of A·|sin ωt| = 2A/ω = A·P/π, whatever the phase and the sampling
    t = np.arange(0.0, 100.0, H)
    amplitude, period = 3.0, 7.3
    ends, iae = half_period_iae(t, amplitude * np.sin(2 * np.pi * t / period + 1.1))
    assert iae == pytest.approx(np.full(iae.size, amplitude * period / np.pi), rel=1e-4)
    assert np.diff(ends) == pytest.approx(np.full(ends.size - 1, period / 2), abs=1e-6)


def test_sustained_oscillation_is_flagged_with_the_forgetting_count_of_theory():
    t = np.arange(0.0, 600.0, H)
    ti, period, amplitude = 2.0, 8.0, 5.0  # amplitude ≫ a = 1.2 L/min
    osc = hagglund_oscillation(
        t, amplitude * np.sin(2 * np.pi * t / period + 0.3), ti_s=ti, y_span=120.0
    )
    assert osc.iae_limit == pytest.approx(2 * 1.2 / (2 * np.pi / ti))
    assert osc.supervision_time == 100.0
    # zero crossings at t = 4k − 0.38 s, k = 1…150: 149 complete half periods, all detected
    assert osc.half_periods == osc.detections == 149
    # one detection every P/2: x_k = (1 − q^k)/(1 − q), q = exp(−(P/2)/T_sup)
    q = math.exp(-(period / 2) / osc.supervision_time)
    assert osc.peak_count == pytest.approx((1 - q**149) / (1 - q), rel=1e-6)
    assert osc.oscillating


def test_detection_threshold_is_the_half_period_iae_of_amplitude_a():
    # at the period Ti a half period of amplitude A integrates to A·Ti/π against IAE_lim =
    # a·Ti/π: A = 0.9·a is never a load disturbance, A = 1.1·a always
    t = np.arange(0.0, 300.0, H)
    ti, a = 3.0, 1.2
    for factor, expected in ((0.9, 0), (1.1, 199)):  # 200 crossings in 300 s
        e = factor * a * np.sin(2 * np.pi * t / ti + 0.3)
        assert hagglund_oscillation(t, e, ti_s=ti, y_span=120.0).detections == expected


def test_small_white_noise_and_a_single_load_disturbance_are_not_oscillation():
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 600.0, H)
    noise = 0.3 * rng.normal(size=t.size)  # σ = a/4: a half period holds a sample or two
    assert hagglund_oscillation(t, noise, ti_s=2.0, y_span=120.0).detections == 0
    bump = np.where(t > 100, 8.0 * (t - 100) * np.exp(-(t - 100) / 2.0), 0.0)
    osc = hagglund_oscillation(t, bump + noise, ti_s=2.0, y_span=120.0)
    assert osc.detections == 1
    assert not osc.oscillating


def test_a_slow_oscillation_counts_below_the_limit():
    # steady count 1/(1 − exp(−P/(2·T_sup))): P = 20·Ti gives 5.5 < n_lim = 10
    t = np.arange(0.0, 1000.0, H)
    osc = hagglund_oscillation(t, 5.0 * np.sin(2 * np.pi * t / 20.0 + 0.3), ti_s=1.0, y_span=120)
    assert osc.peak_count == pytest.approx(1 / (1 - math.exp(-0.2)), rel=1e-3)
    assert not osc.oscillating


def test_half_periods_touching_missing_samples_are_left_out():
    t = np.arange(0.0, 600.0, H)
    e = 5.0 * np.sin(2 * np.pi * t / 8.0 + 0.3)
    e[(t > 100.5) & (t < 101.0)] = np.nan  # inside the half period 99.62…103.62 s
    assert hagglund_oscillation(t, e, ti_s=2.0, y_span=120.0).half_periods == 148


# --- setpoint steps -------------------------------------------------------------------------------


def test_first_order_step_response_matches_its_analytic_measures():
    tau, step, t0 = 2.0, 10.0, 10.0
    t = np.arange(0.0, 60.0, H)
    sp = np.where(t < t0 - H / 2, 40.0, 40.0 + step)
    y = np.where(t < t0 - H / 2, 40.0, 40.0 + step * (1 - np.exp(-(t - t0) / tau)))
    (r,) = setpoint_responses(t, y, sp, np.ones(t.size))
    assert r.time == pytest.approx(t0)
    assert r.step == step
    # IAE = Δ·τ·(1 − e^(−T/τ)) over the T = 50 s assessed; trapezoid error h²/(12τ²) ≈ 1e-5
    assert r.iae == pytest.approx(step * tau * (1 - math.exp(-(60 - H - t0) / tau)), rel=1e-4)
    assert r.settling_time == pytest.approx(tau * math.log(20), abs=1e-3)  # 5 % band
    assert r.rise_time == pytest.approx(tau * math.log(9), abs=1e-3)  # 10 → 90 %
    assert r.overshoot_percent == 0.0
    assert r.band == pytest.approx(0.5)


@pytest.mark.parametrize("step", [10.0, -10.0])
def test_second_order_overshoot_is_exp_of_minus_pi_zeta(step):
    zeta, wn = 0.3, 2.0
    t = np.arange(0.0, 30.0, 0.005)
    _, unit = scipy.signal.step(([wn**2], [1.0, 2 * zeta * wn, wn**2]), T=t)
    r = step_response_measures(t, 40.0 + step * unit, 40.0, 40.0 + step)
    assert r.overshoot_percent == pytest.approx(
        100 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)), abs=0.01
    )
    # the envelope e^(−ζωt)/√(1−ζ²) bounds the error: settled by the time it is inside 5 %,
    # and not more than half a damped period earlier
    t_env = math.log(1 / (0.05 * math.sqrt(1 - zeta**2))) / (zeta * wn)
    half_period = math.pi / (wn * math.sqrt(1 - zeta**2))
    assert r.settling_time is not None
    assert t_env - half_period <= r.settling_time <= t_env


def test_steps_in_man_and_unsettled_responses():
    t = np.arange(0.0, 40.0, H)
    sp = np.select([t < 10, t < 20], [30.0, 40.0], 50.0)
    y = sp.copy()
    k = t >= 20
    y[k] = 40.0 + 10.0 * (1 - np.exp(-(t[k] - 20) / 20.0))  # τ = 20 s: not settled in 20 s
    mode = np.where(t < 15, 0.0, 1.0)  # the first step is made in MAN
    (r,) = setpoint_responses(t, y, sp, mode)
    assert r.time == pytest.approx(20.0)
    assert r.settling_time is None
    assert r.rise_time is None  # 90 % needs 20·ln 10 = 46 s
    # a step whose response meets the next one: it is assessed only until the next step
    rs = setpoint_responses(t, sp, sp)
    assert [(x.time, x.duration, x.iae) for x in rs] == [
        pytest.approx((10.0, 10.0 - H, 0.0)),
        pytest.approx((20.0, 20.0 - H, 0.0)),
    ]


def test_small_setpoint_changes_are_not_steps():
    t = np.arange(0.0, 20.0, H)
    sp = np.where(t < 10, 40.0, 40.3)  # below 0.5 L/min
    assert setpoint_responses(t, sp, sp) == []
    assert len(setpoint_responses(t, sp, sp, threshold=0.2)) == 1


# --- Harris ---------------------------------------------------------------------------------------

N = 100_000


def _ar1(phi: float, seed: int) -> np.ndarray:
    a = np.random.default_rng(seed).normal(size=N + 1000)
    return scipy.signal.lfilter([1.0], [1.0, -phi], a)[1000:]  # past the start-up transient


def test_white_error_is_minimum_variance():
    # η̂ = Π(1 − κ̂ₖ²) over the orders kept: 1 − η̂ ~ χ²_p/N, below 1e-3 for any p ≤ 30
    e = np.random.default_rng(11).normal(scale=0.4, size=N)
    for b in (1, 3):
        h = harris_index(e, b)
        assert h.index is not None
        assert h.index > 1 - 1e-3
        assert h.delay_samples == b


@pytest.mark.parametrize(
    ("b", "expected", "slope"), [(1, 1 - 0.8**2, 2 * 0.8), (2, 1 - 0.8**4, 4 * 0.8**3)]
)
def test_ar1_error_gives_the_analytic_index(b, expected, slope):
    # e = φe₋₁ + a: var e = σ²/(1 − φ²), σ²_mv = σ²·Σ_{i<b} φ^{2i}, so η = 1 − φ^{2b};
    # sd(φ̂) = √((1 − φ²)/N), sd(η̂) = |dη/dφ|·sd(φ̂) = 0.003 (b=1), 0.004 (b=2): 4 sd allowed
    phi = 0.8
    h = harris_index(_ar1(phi, 5), b)
    sd = slope * math.sqrt((1 - phi**2) / N)
    assert h.order == 1
    assert h.index == pytest.approx(expected, abs=4 * sd)
    fixed = harris_index(_ar1(phi, 5), b, order=1)  # the fixed-order Yule–Walker path
    assert fixed.index == pytest.approx(h.index, abs=1e-6)


def test_ma1_error_is_minimum_variance_for_b_2():
    # the output of a minimum-variance loop with b = 2 is e = a + θa₋₁: η(b=2) = 1 and
    # η(b=1) = 1/(1 + θ²) = 0.8; the AR(≤30) approximation of the MA leaves θ^30 ≈ 1e-9
    a = np.random.default_rng(7).normal(size=N + 1)
    e = a[1:] + 0.5 * a[:-1]
    assert harris_index(e, 2).index == pytest.approx(1.0, abs=0.01)
    assert harris_index(e, 1).index == pytest.approx(0.8, abs=0.01)


def test_harris_index_refuses_short_or_non_regulatory_stretches():
    e = np.random.default_rng(2).normal(size=599)
    short = harris_index(e, 1)
    assert short.index is None
    assert "too short" in short.reason
    assert harris_index(e, 1, order=2).index is not None  # 599 ≥ 20·2
    assert "MAN" in harris_index(e, 1, order=2, mode=np.r_[0, np.ones(598)]).reason
    sp = np.r_[np.full(300, 40.0), np.full(299, 41.0)]
    assert "setpoint" in harris_index(e, 1, order=2, setpoint=sp).reason
    assert harris_index(np.zeros(1000), 1, order=2).reason == "the error does not vary"


# --- sensor ---------------------------------------------------------------------------------------


def test_noise_level_recovers_sigma_under_a_trend_and_steps():
    # the successive-difference MAD's sd is ≈ 0.5 % of σ at N = 100 000: 2 % is 4 sd
    rng = np.random.default_rng(4)
    t = np.arange(N) * H
    y = 40 + 5 * np.sin(2 * np.pi * t / 300) + 10 * (t > 1000) + rng.normal(scale=0.3, size=N)
    assert noise_level(y) == pytest.approx(0.3, rel=0.02)


def test_stuck_stretch_is_found_with_its_length():
    rng = np.random.default_rng(6)
    t = np.arange(0.0, 60.0, H)
    y = 40.0 + rng.normal(scale=0.1, size=t.size)
    fresh = sensor_health(t, y)
    assert fresh.longest_run == 0.0
    assert not fresh.stuck
    y[1000:1250] = y[1000]  # 250 samples: 249 intervals of 20 ms
    s = sensor_health(t, y)
    assert s.longest_run == pytest.approx(249 * H)
    assert s.longest_run_start == pytest.approx(1000 * H)
    assert s.stuck
    y2 = 40.0 + rng.normal(scale=0.1, size=t.size)
    y2[1000:1076] = y2[1000]  # 1.5 s: below the recorder's 2 s
    assert not sensor_health(t, y2).stuck
    y3 = np.abs(rng.normal(scale=0.1, size=t.size)) + 5.0
    y3[1000:1500] = 0.0  # a stopped pump reads exactly zero: at the low end, not stuck
    low = sensor_health(t, y3, low_end=1.2)
    assert low.longest_run == pytest.approx(499 * H)
    assert not low.stuck


def test_quantisation_step_is_the_count_of_the_flow_input():
    q = 120.0 / 27648
    x = 40.0 + np.random.default_rng(8).normal(scale=0.03, size=20_000)
    assert quantisation_step(np.round(x / q) * q) == pytest.approx(q, rel=1e-6)
    assert quantisation_step(x) is None


# --- one window -----------------------------------------------------------------------------------


def _window(seed: int = 9) -> dict[str, np.ndarray]:
    """600 s at 50 Hz: MAN for 60 s, then AUTO, a 10 L/min setpoint step at 200 s.

    The step is answered by a first-order response (τ = 2 s); an AR(1) disturbance (φ = 0.8)
    rides on everything.
    """
    t = np.arange(0.0, 600.0, H)
    mode = (t >= 60).astype(float)
    sp = np.where(t < 200 - H / 2, 40.0, 50.0)
    response = np.where(t < 200 - H / 2, 40.0, 50.0 - 10.0 * np.exp(-(t - 200) / 2.0))
    disturbance = 0.05 * _ar1(0.8, seed)[: t.size]
    u = np.where(t < 100, 5.0, 3.0)
    return {"t": t, "u": u, "y": response + disturbance, "sp": sp, "mode": mode}


def test_loop_health_gathers_the_window_and_is_json_ready():
    w = _window()
    ok = np.ones(w["t"].size, bool)
    ok[5000:5010] = False  # a short bad stretch in the regulatory part before the step
    health = loop_health(
        w["t"], w["u"], w["y"], w["sp"], w["mode"], ok, ti_s=1.0, delay_s=0.02, y_span=120.0
    )
    assert health.time_in_auto == pytest.approx((30_000 - 3000) / 30_000, abs=1e-3)
    assert health.time_at_limits == pytest.approx(5000 / 30_000, abs=1e-3)
    assert not health.oscillation.oscillating
    (step,) = health.setpoint_changes
    assert step.time == pytest.approx(200.0)
    assert step.overshoot_percent < 5.0
    # 5 % band = 0.5 L/min around τ·ln 20 = 6.0 s, blurred by the disturbance (σ = 0.05/0.6 =
    # 0.083 L/min): the response leaves the band for good where 10·e^(−t/τ) = 0.5 ± 4σ
    sigma = 0.05 / math.sqrt(1 - 0.8**2)
    assert step.settling_time is not None
    assert 2.0 * math.log(10 / (0.5 + 4 * sigma)) < step.settling_time
    assert step.settling_time < 2.0 * math.log(10 / (0.5 - 4 * sigma))
    # the longest regulatory stretch: from the step's settling to the end (≈ 394 s), and on
    # it the AR(1) disturbance's η = 1 − φ² = 0.36 (b = 1; sd 0.005 at N ≈ 19 700)
    h = health.harris
    assert h.samples == pytest.approx((400 - step.settling_time) / H, abs=2)
    assert h.index == pytest.approx(0.36, abs=0.03)
    d = health.to_json()
    text = json.dumps(d, allow_nan=False)
    assert '"iae_Lpm_s"' in text
    assert d["sensor"]["stuck"] is False
    assert d["harris"]["delay_samples"] == 1


def test_loop_health_sees_a_stuck_reading_the_recorder_flagged_bad():
    w = _window()
    y = w["y"].copy()
    y[20_000:20_300] = y[20_000]  # 6 s frozen; the recorder flags it bad
    ok = np.ones(y.size, bool)
    ok[20_000:20_300] = False
    health = loop_health(
        w["t"], w["u"], y, w["sp"], w["mode"], ok, ti_s=1.0, delay_s=0.1, y_span=120.0
    )
    assert health.sensor.stuck
    assert health.sensor.longest_run == pytest.approx(299 * H)
    assert health.to_json()["sensor"]["longest_run_s"] == pytest.approx(5.98)
    assert health.harris.delay_samples == 5


def test_a_staircase_ramp_is_one_move_with_the_first_order_iae():
    # a first-order lag y' = (r − y)/τ answers any rising setpoint with ∫(r − y) dt = τ·Δ; the
    # trapezoid rule spreads each later stair over one sample: + (Δ − δ)·h/2 = 0.2 (0.5 %)
    tau, delta, stairs = 2.0, 22.0, 30
    t = np.arange(0.0, 80.0, H)
    times = 10.0 + np.arange(stairs)  # one stair per second, as the virtual PLC's run profile
    k = np.searchsorted(t, times - H / 2)
    sp = 18.0 + delta / stairs * np.searchsorted(k, np.arange(t.size), side="right")
    y = 18.0 + sum(
        delta / stairs * np.where(t >= t[j] - H / 2, 1 - np.exp(-(t - t[j]) / tau), 0.0) for j in k
    )
    (r,) = setpoint_responses(t, y, sp)
    assert (r.time, r.start, r.target) == pytest.approx((10.0, 18.0, 40.0))
    assert r.overshoot_percent == 0.0
    assert r.iae == pytest.approx(tau * delta + (delta - delta / stairs) * H / 2, rel=1e-3)


def test_virtual_plc_run_end_to_end():
    # the run profile (fuelid.profiles.runs.run_profile): 18 L/min, a 30 s ramp from
    # 30 s to 40 L/min, then steps to 50, 35, 55, 45 every 30 s; flow noise σ = 0.1 L/min,
    # quantised to 120/27648 L/min
    plc = VirtualPLC(setpoint_profile="run", seed=1, ring_size=6400)
    records: list[np.ndarray] = []
    for _ in range(3):
        records += list(plc.advance(3500).values())
    r = np.array(records)
    r = r[np.argsort(r[:, 0])]
    t, u, y, sp = r[:, 0] * plc.period_s, r[:, 1], r[:, 2], r[:, 3]
    on = np.ones(t.size)
    ok = on.astype(bool)
    health = loop_health(t, u, y, sp, on, ok, ti_s=plc.gains[1], delay_s=0.1, y_span=120.0)
    moves = [(m.time, m.start, m.target) for m in health.setpoint_changes]
    expected = [(31.0, 18, 40), (90.0, 40, 50), (120.0, 50, 35), (150.0, 35, 55), (180.0, 55, 45)]
    assert moves == [pytest.approx(m) for m in expected]
    assert all(m.settling_time is not None for m in health.setpoint_changes)
    assert health.sensor.noise == pytest.approx(0.1, rel=0.03)  # N = 10 500: sd ≈ 1 %
    assert health.sensor.quantum == pytest.approx(120 / 27648, rel=1e-9)
    assert not health.sensor.stuck
    assert not health.oscillation.oscillating
    assert (health.time_in_auto, health.time_at_limits) == (1.0, 0.0)
    assert health.harris.index is not None
    assert 0.0 < health.harris.index <= 1.0
