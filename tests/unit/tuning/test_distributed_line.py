"""The distributed-line test plant (issue 37): its frequency response, simulation and true Ms.

The plant (tests/support/distributed_line.py) lies outside fuelid's model family; these tests
check it against physics and, where it reduces to the family, against fuelid's own Ms. Each
acceptance band is stated, with where it comes from, in the comment above its assertion.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.optimize

from fuelid.io.logs import load_log
from fuelid.model import ProcessModel
from fuelid.tuning import PISettings, robustness, simc
from fuelid.tuning._rules import amigo
from support.distributed_line import (
    LPM,
    DistributedLoop,
    closed_loop_stable,
    frequency_response,
    line_response,
    sensitivity_peak,
    simulate,
    simulate_log,
    static_gain,
    steady_state,
    step_from_frequency_response,
    write_log_csv,
)

LOOP = DistributedLoop()


# (a) ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("u", [1.1, 2.0, 3.0, 4.5])
def test_zero_frequency_equals_the_static_gain_of_the_steady_state(u: float) -> None:
    delta = 1e-3
    fd = (steady_state(LOOP, u + delta)["q_Lpm"] - steady_state(LOOP, u - delta)["q_Lpm"]) / (
        2 * delta
    )
    g = frequency_response(LOOP, u, [0.0, 1e-7])
    # Band 1e-6 relative: the central difference errs by q'''·δ²/6; q(u) bends on a scale of
    # volts (K changes by 25 % over 4 V), so that is ~1e-7·K, and rounding adds
    # 1e-16·q/δ ≈ 1e-12. At ω = 1e-7 rad/s the response differs from G(0) by ω times the
    # sum of the loop's time constants and delays (< 2 s): 2e-7.
    assert abs(g[0].real / fd - 1.0) < 1e-6
    assert g[0].imag == 0.0
    assert abs(g[1] / fd - 1.0) < 1e-6
    # the closed form k_n·D/(1 + C_leak·(R'l + R_N)) is the same number to rounding
    assert static_gain(LOOP, u) == pytest.approx(fd, rel=1e-6)


# (b) ---------------------------------------------------------------------------------------


def _lumped(loop: DistributedLoop, u: float, w: np.ndarray) -> np.ndarray:
    """The lumped loop: the line as one compliance, inertance and friction.

    Pump with leakage, the line's compliance C at the pump, its inertance L and friction R in
    series, the nozzle R_N, the drive and meter lags and the dead time.
    """
    st = steady_state(loop, u)
    s = 1j * w
    L = loop.inertance * loop.length
    C = loop.compliance * loop.length
    line = 1.0 / (1.0 + (loop.C_leak + C * s) * (L * s + st["R_line"] + st["R_nozzle"]))
    return np.asarray(
        loop.k_n
        * loop.displacement
        * LPM
        * line
        * np.exp(-s * loop.tau)
        / ((loop.T_d * s + 1.0) * (loop.T_m * s + 1.0))
    )


def test_a_short_line_is_the_lumped_loop() -> None:
    w = np.geomspace(0.01, 50.0, 200)
    errors = {}
    for length in (1.0, 2.0):
        short = dataclasses.replace(LOOP, length=length)
        for u in (1.1, 3.0, 4.5):
            rel = np.abs(frequency_response(short, u, w) / _lumped(short, u, w) - 1.0)
            st = steady_state(short, u)
            series = (short.inertance * 1j * w + st["R_line"] / length) * length
            gl2 = np.abs(series * short.compliance * 1j * w * length)  # |γl|²
            # Band |γl|² at each ω: expanding cosh and sinh, the two-port's denominator
            # differs from the lumped one by −(L s + R)·C s·(1 − C_leak·R_N)/2 + O(|γl|⁴),
            # relative |γl|²·|1 − C_leak·R_N|/(2·|den|) ≤ |γl|²/2 since |den| ≥ 1 up to
            # 50 rad/s (ω²LC ≤ 0.01 there); twice that leaves room for the O(|γl|⁴) rest.
            # |γl|² ≤ 0.009 at 50 rad/s for 2 m.
            assert np.all(rel <= gl2), (length, u, float((rel / gl2).max()))
            errors[length, u] = rel[-1]
    # the error is a second-order effect of the length: halving it divides the error by 4
    # (R, L and C all scale with l, so the leading term ∝ l²); band ±5 % for the O(|γl|⁴)
    # terms (|γl|² < 1 % here) and the friction's share of the series impedance
    for u in (1.1, 3.0, 4.5):
        assert errors[2.0, u] / errors[1.0, u] == pytest.approx(4.0, rel=0.05)


# (c) ---------------------------------------------------------------------------------------


def _small_step(loop: DistributedLoop, u0: float, du: float) -> tuple[np.ndarray, np.ndarray]:
    h, before, n = 0.02, 25, 400  # step at 0.5 s, then 7.5 s (15 drive lags) to settle
    profile = np.full(n, u0)
    profile[before:] = u0 + du
    t, _, q = simulate_log(loop, profile, h)
    return t - before * h, (q - q[0]) / du


@pytest.mark.parametrize("u0", [1.1, 3.0])
def test_simulated_step_is_the_inverse_of_the_frequency_response(u0: float) -> None:
    du = 0.002
    t, step = _small_step(LOOP, u0, du)
    K = static_gain(LOOP, u0)
    # final value: band 5e-4 relative. The step is not infinitesimal: the second-order term
    # K'·du/2 with K'/K ≈ −0.08 /V is 8e-5; after 15 drive lags the transient is e^(−15).
    assert step[-1] / K == pytest.approx(1.0, abs=5e-4)
    # whole course: band 0.5 % of K. Budget: nonlinearity 1e-4; the MOC's semi-implicit
    # friction is trapezoidal in its small-signal part, O((R'Δx/Z_0)²) ≈ 1e-5; the meter
    # lag's first-order hold O(Δt²/T_m²) ≈ 1e-3 at worst (Δt = 4.9 ms); the dead time's
    # linear interpolation Δt²/8·|y''| ≈ 1e-4·K; the inverse FFT ~1e-5·K. Under 2e-3 in all.
    reference = step_from_frequency_response(LOOP, u0, t)
    assert np.max(np.abs(step - reference)) / K < 5e-3
    # and the comparison sees the wave speed: with a 5 % faster wave the echoes come 9 ms
    # earlier each round trip and the line's mode moves 5 % up; the step rises at up to
    # ~K/0.4 s during the echoes, so the curves part by ≳ 1 % of K, twice the band
    faster = dataclasses.replace(LOOP, wave_speed=1.05 * LOOP.wave_speed)
    wrong = step_from_frequency_response(faster, u0, t)
    assert np.max(np.abs(step - wrong)) / K > 5e-3


def test_echoes_arrive_every_round_trip_with_the_reflections_of_both_ends() -> None:
    # pump flow steps at once (no drive lag), the nozzle flow is read without the meter
    loop = dataclasses.replace(LOOP, T_d=0.0, T_m=0.0)
    u0, du, t_step, n_seg = 1.1, 0.002, 0.05, 40
    t, q_nozzle, _ = simulate(loop, lambda t: u0 + du * (t >= t_step), 2.0, n_seg)
    dt = t[1] - t[0]
    one_way = loop.length / loop.wave_speed
    jumps = np.diff(q_nozzle)
    window = t[1:] < t_step + 6.0 * one_way  # the first three arrivals (the 4th is at 7 l/a)
    big = np.flatnonzero(window & (np.abs(jumps) > 0.02 * np.abs(jumps).max()))
    arrivals = t[big + 1] - t_step
    # Band one MOC step: the pump's flow changes at the first grid instant after the
    # command, and the MOC (Courant number 1) carries the front exactly one reach a step.
    # Nothing else moves by 2 % of the front between arrivals: the friction spreads a change
    # of R'l/Z_0 ≈ 10 % over a round trip of 80 steps.
    expected = one_way * np.array([1.0, 3.0, 5.0])
    assert arrivals.size == 3
    assert np.all(np.abs(arrivals - expected) <= dt + 1e-12)
    # first front: transmitted into the line Z_0/(1 + C_leak·Z_0) of the displaced flow
    # (the pump sees Z_0 at first), attenuated by e^(−R'l/(2Z_0)) (the lossy line's
    # high-frequency limit), transmitted into the nozzles 2/(Z_0 + R_N); band 1 % for the
    # friction's spread (its front is exact, its tail falls into the next steps)
    st = steady_state(loop, u0)
    z0, rn, g, rl = loop.z0, st["R_nozzle"], loop.C_leak, st["R_line"]
    displaced = loop.k_n * loop.displacement * du * LPM
    front = 2.0 * z0 / ((1.0 + g * z0) * (z0 + rn)) * math.exp(-rl / (2.0 * z0))
    assert jumps[big[0]] / displaced == pytest.approx(front, rel=0.01)
    # each echo: reflected at the nozzles (R_N − Z_0)/(R_N + Z_0) = −0.59 (inverted), at the
    # pump (1/C_leak − Z_0)/(1/C_leak + Z_0) = +0.44, attenuated over the round trip; band 2 %
    gamma = (rn - z0) / (rn + z0) * (1.0 / g - z0) / (1.0 / g + z0) * math.exp(-rl / z0)
    assert jumps[big[1]] / jumps[big[0]] == pytest.approx(gamma, rel=0.02)
    assert jumps[big[2]] / jumps[big[1]] == pytest.approx(gamma, rel=0.02)


def test_a_simulated_log_is_read_by_fuelid(tmp_path: Path) -> None:
    profile = np.concatenate([np.full(100, 2.0), np.full(200, 2.5)])
    t, u, q = simulate_log(LOOP, profile, 0.02, seed=4, noise_std=0.05)
    data = load_log(write_log_csv(tmp_path / "log.csv", t, u, q))
    assert data.sample_time == pytest.approx(0.02)
    np.testing.assert_allclose(data.u, u)
    np.testing.assert_allclose(data.y, q, rtol=1e-9)
    # the noise is what was asked for: the settled stretch before the step has sd 0.05 L/min
    # (band ±25 %: 100 samples give a relative sd of 1/√200 = 7 %, 3.5 of them)
    assert np.std(q[:100]) == pytest.approx(0.05, rel=0.25)


# (d) ---------------------------------------------------------------------------------------


def test_ms_agrees_with_fuelid_where_the_plant_is_first_order_plus_delay() -> None:
    # a 5 cm line and no drive lag: K·e^(−τs)/(T_m·s + 1) and the line's parasitic lag
    # C'l·R_N ≈ 3e-5 s
    reduced = dataclasses.replace(LOOP, length=0.05, T_d=0.0)
    u = 3.0
    model = ProcessModel(K=static_gain(reduced, u), T=reduced.T_m, delay=reduced.tau)
    cases = [simc(model), amigo(model), simc(model, control_period=0.1)]
    cases.append(PISettings(rule="x", Kc=cases[0].Kc, Ti=cases[0].Ti, control_period=0.1))
    for pi in cases:
        ours = sensitivity_peak(reduced, u, pi.Kc, pi.Ti, pi.control_period)
        theirs = robustness(model, pi)
        # Band 0.5 % (the issue asks 1 %): the parasitic lag changes L by ω·3e-5 ≤ 1e-3
        # relative up to 31 rad/s, which moves Ms by at most Ms·|L·S|·1e-3 ≈ 2e-3; the alias
        # sum (h = 0.1 s) errs by ≤ 5e-5, the refined grids by ~1e-6.
        assert ours == pytest.approx(theirs.Ms, rel=5e-3), pi
        assert closed_loop_stable(reduced, u, pi.Kc, pi.Ti, pi.control_period) == theirs.stable


# (e) ---------------------------------------------------------------------------------------


def test_the_loop_is_most_aggressive_at_the_low_end() -> None:
    gains = {u: frequency_response(LOOP, u, [0.0])[0].real for u in (1.1, 2.0, 3.0, 4.0, 4.5)}
    # designed: C_leak·R = 0.134 at 1.1 V and 0.335 at 3 V, so K(1.1)/K(3) = 1.335/1.134
    # = 1.177; band ±0.5 % around it (the design arithmetic is to three figures)
    assert gains[1.1] / gains[3.0] == pytest.approx(1.177, rel=5e-3)
    values = list(gains.values())
    assert all(a > b for a, b in itertools.pairwise(values))
    # the line's own factor q_2/(D·n) relative to its static value: the first mode lifts it
    # by ~60 % at 1.1 V (nozzles far below Z_0), ~15 % at 3 V, not at all at 4.5 V (R_N ≈ Z_0).
    # Bands from the lumped estimate (ζ ≈ 0.35, 0.54, 0.66, resonant peaks 1.5, 1.1, 1.0)
    # widened for the distributed line's higher modes and the leakage: ≥ 1.4, ≤ 1.25, ≤ 1.05
    w = np.geomspace(0.5, 100.0, 2000)
    peak = {
        u: float(np.max(np.abs(line_response(LOOP, u, 1j * w) / line_response(LOOP, u, 0.0))))
        for u in (1.1, 3.0, 4.5)
    }
    assert peak[1.1] >= 1.4
    assert peak[3.0] <= 1.25
    assert peak[4.5] <= 1.05


def test_a_mid_range_first_order_model_underestimates_ms_at_the_low_end() -> None:
    # what a user's identification at mid-range gives: K exact, T and θ fitted to the exact
    # step response at 3 V with the meter's lag as a known prior
    t = np.arange(0.0, 10.0, 0.02)
    K = static_gain(LOOP, 3.0)
    truth = step_from_frequency_response(LOOP, 3.0, t)

    def residual(p: np.ndarray) -> np.ndarray:
        m = ProcessModel(K=K, T=abs(p[0]), T_f=LOOP.T_m, delay=abs(p[1]))
        return np.asarray(m.step_response(t) - truth)

    p = scipy.optimize.least_squares(residual, [0.5, 0.25]).x
    model = ProcessModel(K=K, T=abs(float(p[0])), T_f=LOOP.T_m, delay=abs(float(p[1])))
    pi = simc(model, control_period=0.1)
    printed = robustness(model, pi).Ms
    at_mid = sensitivity_peak(LOOP, 3.0, pi.Kc, pi.Ti, 0.1)
    at_low = sensitivity_peak(LOOP, 1.1, pi.Kc, pi.Ti, 0.1)
    # at the identification point the model is close: band 2 % (what the first-order model
    # misses of the line: its mode lifts |G| by ≤ 14 % above the crossover, where |L| < 0.5)
    assert at_mid == pytest.approx(printed, rel=0.02)
    # at 1.1 V the gain is 17.7 % higher: a pure gain change of that size on this loop
    # raises Ms by ~6 % (Ms grows about like 1/(1 − k·|L S|) near the peak); the band asks
    # ≥ 4 %, leaving the line's smaller phase lag at low flow room to take some back
    assert at_low > 1.04 * printed
