"""Tuning rules and loop robustness against numbers fixed by the formulas and by other tools.

Rules: the worked example of docs/explanation/tuning.md §3 (K = 1, T = 2 s, θ = 1 s, continuous),
the published formulas evaluated here by hand, the half rule, h/2 for a sampled PI, scaling
invariances, the PLC forms. Margins: an integrator-plus-dead-time loop with a closed-form answer,
python-control on loops it can represent exactly (no delay, or a delay of whole periods in discrete
time), and the modified z-transform of a first-order lag written out by hand.
"""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from fuelid.errors import FuelidError
from fuelid.model import ProcessModel
from fuelid.tuning import TUNING_RULES, PISettings, half_rule, list_rules, robustness, tune
from fuelid.tuning._frequency import margins, process_response

WORKED = ProcessModel(K=1.0, T=2.0, delay=1.0)


def _amigo_by_hand(K: float, T: float, L: float) -> tuple[float, float]:
    # Åström & Hägglund (2004), eq. for PI from the FOPDT step response model
    Kp = (0.15 + 0.35 * T / L - T**2 / (L + T) ** 2) / K
    Ti = 0.35 * L + 13.0 * L * T**2 / (T**2 + 12.0 * L * T + 7.0 * L**2)
    return Kp, Ti


def _ms_dense(model: ProcessModel, pi: PISettings) -> float:
    """Ms of a continuous PI on a FOPDT model from a dense grid, written out independently."""
    w = np.geomspace(1e-3, 1e2, 400_001)
    s = 1j * w
    L = pi.Kc * (1 + 1 / (s * pi.Ti)) * model.K * np.exp(-s * model.delay) / (model.T * s + 1)
    return float(np.max(1 / np.abs(1 + L)))


# --- rules -----------------------------------------------------------------------------------


def test_worked_example_simc():
    pi = tune(WORKED, "simc", control_period=0.0, closed_loop_time=1.0)
    assert pi.Kc == pytest.approx(1.0, rel=1e-12)
    assert pi.Ti == pytest.approx(2.0, rel=1e-12)


def test_worked_example_amigo_matches_the_published_formula():
    pi = tune(WORKED, "amigo", control_period=0.0)
    Kp, Ti = _amigo_by_hand(1.0, 2.0, 1.0)
    assert pi.Kc == pytest.approx(Kp, rel=1e-12)
    assert pi.Ti == pytest.approx(Ti, rel=1e-12)
    # docs/explanation/tuning.md's rounded values
    assert (round(pi.Kc, 2), round(pi.Ti, 2)) == (0.41, 1.84)


@pytest.mark.parametrize(("T", "delay", "tau_c"), [(2.0, 1.0, 1.0), (50.0, 1.0, 1.0)])
def test_simc_integral_time_switches_at_four_tau_c_plus_theta(T: float, delay: float, tau_c: float):
    pi = tune(
        ProcessModel(K=2.5, T=T, delay=delay), "simc", control_period=0.0, closed_loop_time=tau_c
    )
    assert pi.Kc == pytest.approx(T / (2.5 * (tau_c + delay)), rel=1e-12)
    # T = 2: Ti = T1; T = 50 (lag dominant): Ti = 4(τc + θ) = 8 s, faster disturbance rejection
    assert pi.Ti == pytest.approx(min(T, 4 * (tau_c + delay)), rel=1e-12)
    assert pi.Ti == pytest.approx(2.0 if T == 2.0 else 8.0, rel=1e-12)


def test_improved_simc_adds_a_third_of_the_delay_to_the_lag():
    pi = tune(WORKED, "isimc", control_period=0.0)  # τc = θ = 1
    T1 = 2.0 + 1.0 / 3.0
    assert pi.Kc == pytest.approx(T1 / (1.0 * (1.0 + 1.0)), rel=1e-12)
    assert pi.Ti == pytest.approx(T1, rel=1e-12)


def test_lambda_rule_is_imc_pi():
    pi = tune(WORKED, "lambda", control_period=0.0, closed_loop_time=3.0)
    assert pi.Kc == pytest.approx(2.0 / (1.0 * (3.0 + 1.0)), rel=1e-12)
    assert pi.Ti == pytest.approx(2.0, rel=1e-12)
    default = tune(WORKED, "lambda", control_period=0.0)  # λ = T1
    assert default.Kc == pytest.approx(2.0 / (2.0 + 1.0), rel=1e-12)


def test_half_rule_with_a_second_lag_a_meter_and_a_sampled_controller():
    model = ProcessModel(K=13.0, T=1.2, T2=0.5, T_f=0.3, delay=0.2)
    r = half_rule(model, control_period=1.0)
    # T1 = 1.2 + 0.5/2; θ = 0.2 + 0.5/2 + 0.3 (smallest lag whole) + 1/2 (h/2)
    assert pytest.approx(1.45, rel=1e-12) == r.T1
    assert r.theta == pytest.approx(1.25, rel=1e-12)
    # the flowmeter lag larger than the process lag: the roles swap
    swapped = half_rule(ProcessModel(K=1.0, T=0.3, T_f=1.0), control_period=0.0)
    assert (swapped.T1, swapped.theta) == pytest.approx((1.15, 0.15), rel=1e-12)


@pytest.mark.parametrize("rule", list(TUNING_RULES))
def test_a_sampled_controller_counts_as_half_a_period_of_delay(rule: str):
    model = ProcessModel(K=3.0, T=2.0, T_f=0.3, delay=0.4)
    sampled = tune(model, rule, control_period=1.0)
    later = tune(ProcessModel(K=3.0, T=2.0, T_f=0.3, delay=0.9), rule, control_period=0.0)
    if rule in ("simc", "isimc"):  # τc defaults to θ, which includes h/2 in both
        assert sampled.tuning_parameter == pytest.approx(later.tuning_parameter)
    assert sampled.Kc == pytest.approx(later.Kc, rel=1e-12)
    assert sampled.Ti == pytest.approx(later.Ti, rel=1e-12)


@pytest.mark.parametrize("rule", list(TUNING_RULES))
def test_gain_and_time_scaling(rule: str):
    base = ProcessModel(K=2.0, T=3.0, T2=0.4, T_f=0.2, delay=0.5)
    pi = tune(base, rule, control_period=0.5)
    doubled_gain = tune(ProcessModel(K=4.0, T=3.0, T2=0.4, T_f=0.2, delay=0.5), rule, 0.5)
    assert doubled_gain.Kc == pytest.approx(pi.Kc / 2, rel=1e-12)
    assert doubled_gain.Ti == pytest.approx(pi.Ti, rel=1e-12)
    # a plant 3× slower with a PLC 3× slower: the same loop in scaled time
    slow = tune(ProcessModel(K=2.0, T=9.0, T2=1.2, T_f=0.6, delay=1.5), rule, 1.5)
    assert slow.Kc == pytest.approx(pi.Kc, rel=1e-12)
    assert slow.Ti == pytest.approx(3 * pi.Ti, rel=1e-12)


def test_plc_forms():
    pi = PISettings(rule="simc", Kc=0.0613, Ti=1.41, control_period=1.0)
    form = pi.plc_form(u_span=4.0, y_span=100.0)
    assert form["percent_of_span"]["Kc"] == pytest.approx(0.0613 * 100 / 4, rel=1e-12)
    assert form["percent_of_span"]["Ti"] == 1.41
    assert form["parallel"] == pytest.approx({"Kp": 0.0613, "Ki": 0.0613 / 1.41})
    d = form["discrete"]
    assert d["q0"] == pytest.approx(0.0613)
    assert d["q1"] == pytest.approx(-0.0613 * (1 - 1.0 / 1.41))
    assert "positional" in d["algorithm"]
    assert "velocity" in d["algorithm"]
    assert "ideal" in form["form"]
    # the velocity form's increments sum to the positional output (same controller, both forms)
    e = np.random.default_rng(0).normal(size=50)
    positional = pi.Kc * e + np.r_[0.0, np.cumsum(pi.Kc * 1.0 / pi.Ti * e)[:-1]]
    increments = d["q0"] * e + d["q1"] * np.r_[0.0, e[:-1]]
    assert np.cumsum(increments) == pytest.approx(positional, abs=1e-12)
    continuous = PISettings(rule="simc", Kc=1.0, Ti=2.0, control_period=0.0)
    assert continuous.plc_form()["discrete"] is None


def test_rules_are_listed_with_their_sources():
    rules = {r.name: r for r in list_rules()}
    assert list(rules) == ["simc", "isimc", "lambda", "amigo"]
    assert "Skogestad" in rules["simc"].source
    assert "Åström" in rules["amigo"].source
    assert rules["amigo"].parameter is None


@pytest.mark.parametrize(
    ("model", "rule", "h", "closed_loop_time", "message"),
    [
        (WORKED, "ziegler", 1.0, None, "unknown tuning rule"),
        (WORKED, "simc", -1.0, None, "control period"),
        (ProcessModel(K=-1.0, T=2.0, delay=1.0), "simc", 1.0, None, "positive"),
        (WORKED, "simc", 1.0, 0.0, "tau_c"),
        (WORKED, "lambda", 1.0, -2.0, "lambda"),
        (WORKED, "amigo", 1.0, 1.0, "no tuning parameter"),
        (ProcessModel(K=1.0, T=2.0), "simc", 0.0, None, "dead time"),
    ],
)
def test_bad_tuning_requests_are_refused(
    model: ProcessModel, rule: str, h: float, closed_loop_time: float | None, message: str
):
    with pytest.raises(FuelidError, match=message):
        tune(model, rule, h, closed_loop_time)


# --- margins ---------------------------------------------------------------------------------


@pytest.mark.parametrize(("k", "theta"), [(0.5, 1.0), (0.2, 3.0), (1.0, 0.3)])
def test_margins_of_an_integrator_with_dead_time(k: float, theta: float):
    # L(s) = k·e^(−θs)/s: |L| = 1 at ω = k, phase −90° − kθ; phase −180° at ω = π/(2θ)
    def loop(w: np.ndarray) -> np.ndarray:
        return np.asarray(k * np.exp(-1j * w * theta) / (1j * w), dtype=complex)

    r = margins(loop, np.geomspace(1e-3 * k, 20 / theta, 3000))
    assert r.crossover_frequency == pytest.approx(k, rel=1e-9)
    assert r.phase_margin_deg == pytest.approx(90.0 - math.degrees(k * theta), abs=1e-7)
    assert r.phase_crossover_frequency == pytest.approx(math.pi / (2 * theta), rel=1e-9)
    assert r.gain_margin == pytest.approx(math.pi / (2 * k * theta), rel=1e-9)
    assert r.stable


def test_worked_example_ms_matches_an_independent_dense_grid():
    for rule, expected in (("simc", 1.59), ("amigo", 1.21)):
        pi = tune(WORKED, rule, control_period=0.0)
        ms = robustness(WORKED, pi).Ms
        assert ms == pytest.approx(_ms_dense(WORKED, pi), rel=1e-6)
        assert round(ms, 2) == expected


def test_continuous_margins_match_python_control_without_delay():
    model = ProcessModel(K=2.0, T=3.0, T2=1.0, T_f=0.5)
    pi = PISettings(rule="x", Kc=2.0, Ti=2.0, control_period=0.0)
    plant = control.tf([2.0], [1.0]) * control.tf([1], [3.0, 1]) * control.tf([1], [1.0, 1])
    plant = plant * control.tf([1], [0.5, 1])
    loop = plant * control.tf([2.0 * 2.0, 2.0], [2.0, 0.0])
    gm, pm, sm, _, wgc, _ = control.stability_margins(loop)
    r = robustness(model, pi)
    assert r.gain_margin == pytest.approx(gm, rel=1e-5)
    assert r.phase_margin_deg == pytest.approx(pm, rel=1e-5)
    assert r.crossover_frequency == pytest.approx(wgc, rel=1e-5)
    assert r.Ms == pytest.approx(1 / sm, rel=1e-4)


@pytest.mark.parametrize("delay_periods", [0, 1, 3])
def test_sampled_margins_match_python_control_with_whole_period_delays(delay_periods: int):
    h = 0.5
    model = ProcessModel(K=1.5, T=2.0, T_f=0.4, delay=delay_periods * h)
    pi = PISettings(rule="x", Kc=0.5, Ti=1.8, control_period=h)
    plant = control.c2d(
        control.tf([1.5], [1]) * control.tf([1], [2.0, 1]) * control.tf([1], [0.4, 1]), h, "zoh"
    )
    plant = plant * control.tf([1], [1] + [0] * delay_periods, h)
    # forward-Euler PI: Kc·(1 + (h/Ti)/(z − 1))
    pi_z = control.tf([pi.Kc, pi.Kc * (h / pi.Ti - 1.0)], [1.0, -1.0], h)
    gm, pm, sm, _, wgc, _ = control.stability_margins(plant * pi_z)
    r = robustness(model, pi)
    assert r.gain_margin == pytest.approx(gm, rel=1e-5)
    assert r.phase_margin_deg == pytest.approx(pm, rel=1e-5)
    assert r.crossover_frequency == pytest.approx(wgc, rel=1e-5)
    assert r.Ms == pytest.approx(1 / sm, rel=1e-3)


def test_fractional_delay_follows_the_modified_z_transform():
    # K/(Ts+1) behind a ZOH with θ = d·h + τ', m = 1 − τ'/h (Franklin, Powell & Workman §4.6):
    # G(z) = K·z^(−d)·[(1 − e^(−mh/T))·z⁻¹ + (e^(−mh/T) − e^(−h/T))·z⁻²] / (1 − e^(−h/T)·z⁻¹)
    K, T, h, theta = 2.0, 1.5, 1.0, 2.3
    d, m = 2, 1 - 0.3 / h
    w = np.linspace(0.05, math.pi / h, 50)
    zi = np.exp(-1j * w * h)
    a, am = math.exp(-h / T), math.exp(-m * h / T)
    expected = K * zi**d * ((1 - am) * zi + (am - a) * zi**2) / (1 - a * zi)
    got = process_response(ProcessModel(K=K, T=T, delay=theta), w, h)
    assert got == pytest.approx(expected, rel=1e-10, abs=1e-12)


def test_continuous_dead_time_is_exact_not_pade():
    w = np.geomspace(0.01, 100, 200)
    with_delay = process_response(ProcessModel(K=1.0, T=2.0, delay=0.7), w)
    without = process_response(ProcessModel(K=1.0, T=2.0), w)
    assert with_delay == pytest.approx(without * np.exp(-0.7j * w), rel=1e-13)


def test_a_gain_beyond_the_margin_is_unstable():
    pi = tune(WORKED, "simc", control_period=1.0)
    nominal = robustness(WORKED, pi)
    assert nominal.stable
    too_much = robustness(WORKED, pi.with_gain_factor(1.2 * nominal.gain_margin))
    assert not too_much.stable
    assert too_much.gain_margin < 1.0
    just_inside = robustness(WORKED, pi.with_gain_factor(0.9 * nominal.gain_margin))
    assert just_inside.stable


@pytest.mark.parametrize("h", [0.0, 1.0])
def test_heavily_detuned_loop_is_stable(h: float):
    """Kc → 0: L ≈ K·Kc/(Ti·s) crosses over at ω ≈ K·Kc/Ti, far below every plant pole.

    The loop is then an almost pure integrator at its crossover: phase margin → 90°, Ms → 1,
    gain margin ≈ (the margin of Kc = 1 at the same Ti) / Kc, and it is stable.
    """
    model = ProcessModel(K=1.0, T=2.0, delay=1.0)
    pi = PISettings(rule="simc", Kc=1e-5, Ti=2.0, control_period=h)
    r = robustness(model, pi)
    assert r.stable
    assert r.phase_margin_deg == pytest.approx(90.0, abs=0.01)
    assert r.Ms == pytest.approx(1.0, abs=1e-3)
    assert r.crossover_frequency == pytest.approx(1e-5 / 2.0, rel=1e-3)
    assert r.gain_margin > 1e4


def test_borderline_design_is_flagged():
    """A lag far below the control period: SIMC's h/2 gives an integral gain of 1/K per period.

    With the plant static between samples and the measurement one period late,
    y[k] = K·u[k−1] and u[k] = u[k−1] + e[k−1]/K give z² − z + 1 = 0: poles on the unit circle,
    gain margin 1. The result must say so, not only print the numbers.
    """
    from fuelid.tuning import evaluate_tuning

    res = evaluate_tuning(ProcessModel(K=13.5, T=1e-6), "simc", control_period=1.0)
    assert res.robustness.gain_margin == pytest.approx(1.0, abs=1e-3)
    assert any("barely stable" in w for w in res.warnings)
    assert res.to_json()["warnings"] == res.warnings
    # the worked example is a sound design: nothing to flag
    sound = evaluate_tuning(ProcessModel(K=1.0, T=2.0, delay=1.0), "simc", control_period=0.0)
    assert sound.warnings == []
