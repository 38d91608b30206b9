"""The PLC's PI and the closed loop: control law, anti-windup, bumpless changes, metrics, plant.

Numbers come from the control law written out by hand, from closed-form step responses, from an
independent time-stepping of the sampled loop, and from the reference plant's schedule.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import fuelid.plant.simulate
from fuelid.errors import FuelidError
from fuelid.model import ProcessModel
from fuelid.plant import PlantConfig, load_plant_config, operating_point
from fuelid.plant.simulate import simulate
from fuelid.profiles import InputProfile
from fuelid.tuning import PISettings, gain_schedule, tune
from fuelid.tuning.closedloop import (
    ClosedLoopResult,
    DiscretePI,
    closed_loop_poles,
    disturbance_metrics,
    flow_at,
    linear_closed_loop,
    place_step,
    reachable_flows,
    setpoint_step_metrics,
    simulate_closed_loop,
    standard_runs,
    standard_scenario,
    steady_command,
)
from fuelid.units import LPM_PER_M3S, celsius_to_kelvin, kelvin_to_celsius

CONFIG = load_plant_config()
COLD, ROOM, WARM = celsius_to_kelvin(-20.0), celsius_to_kelvin(20.0), celsius_to_kelvin(50.0)
PI = PISettings(rule="simc", Kc=0.1, Ti=2.0, control_period=1.0)

# --- the discrete PI -------------------------------------------------------------------------


def test_positional_forward_euler_law():
    # u[k] = u0 + Kc·e[k] + Kc·h/Ti·Σ_{j<k} e[j] while inside the limits
    e = np.random.default_rng(1).normal(0.0, 2.0, 40)
    pi = DiscretePI(PI, 1.0, 5.0, u0=3.0)
    got = [pi.update(setpoint=50.0, measurement=50.0 - ek) for ek in e]
    expected = 3.0 + 0.1 * e + 0.1 * 1.0 / 2.0 * np.r_[0.0, np.cumsum(e)[:-1]]
    assert np.all((expected > 1.0) & (expected < 5.0))  # the case really is unsaturated
    assert got == pytest.approx(expected, abs=1e-12)


def _naive_pi(errors: np.ndarray, u0: float) -> list[float]:
    """The same PI with the output clipped but no anti-windup: the integral runs away."""
    integral, out = u0, []
    for e in errors:
        out.append(min(max(0.1 * e + integral, 1.0), 5.0))
        integral += 0.1 * 1.0 / 2.0 * e
    return out


def test_anti_windup_no_runaway_and_fast_release():
    errors = np.r_[np.full(60, 100.0), np.full(30, -1.0)]  # 60 s saturated, then a small reversal
    pi = DiscretePI(PI, 1.0, 5.0, u0=3.0)
    out, integrals = [], []
    for e in errors:
        out.append(pi.update(0.0, -e))
        integrals.append(pi.integral)
    assert out[:60] == [5.0] * 60
    # while saturated the integral is held where the output just meets the limit (Tt = h):
    # I = u_max − Kc·e·(1 − h/Ti) = 5 − 10·0.5, it never grows
    assert integrals[1:60] == pytest.approx([5.0 - 10.0 * 0.5] * 59)
    # after the reversal the output leaves the limit at once ...
    assert out[60] < 5.0
    # ... whereas without anti-windup it stays stuck (the integral grew by 5 V per period)
    naive = _naive_pi(errors, 3.0)
    assert naive[60:] == [5.0] * 30


def test_bumpless_gain_change():
    a = DiscretePI(PI, 1.0, 5.0, u0=2.5)
    b = DiscretePI(PI, 1.0, 5.0, u0=2.5)
    errors = [1.5, 0.8, 0.4]
    for e in errors:
        a.update(0.0, -e)
        b.update(0.0, -e)
    a.set_gains(0.3, 0.7)  # three times the gain, a third of the integral time
    # for the same error as before the switch, the output is what it would have been
    assert a.update(0.0, -errors[-1]) == pytest.approx(b.update(0.0, -errors[-1]), abs=1e-12)


def test_bumpless_gain_change_on_the_plant():
    """A gain change mid-transient moves the command only by ΔKc·(e[k] − e[k−1])."""
    pi = tune(ProcessModel(K=13.5, T=1.26, T_f=0.3, delay=0.2), "simc", 1.0)
    flow = flow_at(CONFIG, 3.0, ROOM)
    setpoint = InputProfile(np.array([0.0, 5.0]), np.array([flow, flow + 5.0]), 30.0)
    new_Kc = 2 * pi.Kc
    kwargs = {"T_fuel": ROOM}
    changed = simulate_closed_loop(
        CONFIG, pi, setpoint, **kwargs, gain_changes={7.0: (new_Kc, pi.Ti)}
    )
    same = simulate_closed_loop(CONFIG, pi, setpoint, **kwargs)
    k6, k7 = np.searchsorted(same.time, [6.0, 7.0])
    error = same.setpoint - same.flow  # what the controller read at its instants (no noise)
    assert error[k7] > 1.0  # mid-transient: a non-bumpless change would kick by ΔKc·e[k]
    kick = changed.command[k7] - same.command[k7]
    assert kick == pytest.approx((new_Kc - pi.Kc) * (error[k7] - error[k6]), abs=1e-9)


# --- metrics on signals with known answers ---------------------------------------------------


def test_first_order_metrics():
    tau = 2.0
    t = np.linspace(0.0, 40.0, 400_001)
    m = setpoint_step_metrics(t, 10.0 + 5.0 * (1 - np.exp(-t / tau)), 10.0, 15.0)
    assert m.overshoot_percent == 0.0
    assert m.settling_time == pytest.approx(tau * math.log(50.0), abs=1e-3)
    assert m.iae == pytest.approx(5.0 * tau, rel=1e-6)


@pytest.mark.parametrize("zeta", [0.2, 0.5, 0.7])
def test_second_order_overshoot(zeta: float):
    wn = 1.5
    wd = wn * math.sqrt(1 - zeta**2)
    t = np.linspace(0.0, 60.0, 600_001)
    phi = math.acos(zeta)
    y = 1 - np.exp(-zeta * wn * t) * np.sin(wd * t + phi) / math.sqrt(1 - zeta**2)
    m = setpoint_step_metrics(t, y, 0.0, 1.0)
    assert m.overshoot_percent == pytest.approx(
        100 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)), rel=1e-6
    )


def test_disturbance_metrics():
    # a deviation e = 0.4·e^(−t) from a setpoint of 10: peak 0.4, back in 2 % (0.2) at ln 2
    t = np.linspace(0.0, 20.0, 200_001)
    m = disturbance_metrics(t, 10.0 - 0.4 * np.exp(-t), 10.0, 0.2)
    assert m.peak_deviation == pytest.approx(0.4)
    assert m.settling_time == pytest.approx(math.log(2.0), abs=1e-3)
    assert m.iae == pytest.approx(0.4, rel=1e-6)


# --- the linear closed loop ------------------------------------------------------------------


def _time_stepped(K: float, T: float, d: int, Kc: float, Ti: float, h: float, n: int):
    """Sampled loop stepped by hand: y[k+1] = a·y[k] + K(1−a)·u[k−d], forward-Euler PI."""
    a = math.exp(-h / T)
    y, u, integral = np.zeros(n), np.zeros(n), 0.0
    for k in range(n):
        e = 1.0 - y[k]
        u[k] = Kc * e + integral
        integral += Kc * h / Ti * e
        if k + 1 < n:
            y[k + 1] = a * y[k] + K * (1 - a) * (u[k - d] if k >= d else 0.0)
    return y, u


@pytest.mark.parametrize("d", [0, 1, 2])
def test_linear_closed_loop_against_a_time_stepped_loop(d: int):
    K, T, h = 2.0, 3.0, 0.5
    model = ProcessModel(K=K, T=T, delay=d * h)
    pi = PISettings(rule="x", Kc=0.6, Ti=2.5, control_period=h)
    res = linear_closed_loop(model, pi, duration=30.0, oversample=10)
    y, u = _time_stepped(K, T, d, pi.Kc, pi.Ti, h, 60)
    assert res.setpoint_response[::10] == pytest.approx(y, abs=1e-10)
    assert res.setpoint_command[::10] == pytest.approx(u, abs=1e-10)


def test_linear_load_step_recovery():
    # a unit load at the plant input: the integral must end at −1 V, and it grows by
    # Kc·h/Ti per sample of error, so the summed deviation is exactly Ti/Kc [output unit·s]
    model = ProcessModel(K=13.5, T=1.26, T_f=0.3, delay=0.2)
    pi = PISettings(rule="x", Kc=0.0613, Ti=1.41, control_period=1.0)
    res = linear_closed_loop(model, pi, oversample=10)
    deviation_at_samples = res.disturbance_response[::10]
    assert np.sum(deviation_at_samples) * 1.0 == pytest.approx(pi.Ti / pi.Kc, rel=1e-6)
    # recovery: within 2 % of the uncontrolled effect (K per volt) from settling_time on
    m = res.disturbance
    band = 0.02 * model.K
    assert math.isfinite(m.settling_time)
    assert m.settling_time > 0.0
    after = res.time >= m.settling_time - 1e-9
    assert np.all(np.abs(res.disturbance_response[after]) <= band)
    just_before = np.flatnonzero(~after)[-1]
    assert abs(res.disturbance_response[just_before]) > band


def test_closed_loop_poles_inside_and_outside_the_unit_circle():
    model = ProcessModel(K=13.5, T=1.26, T_f=0.3, delay=0.2)
    pi = tune(model, "simc", 1.0)
    assert np.max(closed_loop_poles(model, pi)) < 1.0
    assert np.max(closed_loop_poles(model, pi.with_gain_factor(10.0))) > 1.0


# --- the nonlinear plant ---------------------------------------------------------------------


@pytest.mark.parametrize(("u", "T_fuel"), [(1.5, 253.15), (3.0, 293.15), (4.5, 323.15)])
def test_steady_command_inverts_the_operating_point(u: float, T_fuel: float):
    flow = operating_point(CONFIG, u, T_fuel).q * LPM_PER_M3S
    assert steady_command(CONFIG, flow, T_fuel) == pytest.approx(u, abs=1e-6)


@pytest.fixture(scope="module")
def schedule():
    return gain_schedule(CONFIG, "simc", 1.0)


def test_scheduled_gains_on_the_plant_at_every_band(schedule):
    """Each band's gains, on the nonlinear plant in the middle of its band, meet the targets."""
    for band in schedule.bands:
        T_mid = 0.5 * (band.T_low + band.T_high)
        u_mid = 0.5 * (band.u_low + band.u_high)
        flow = flow_at(CONFIG, u_mid, T_mid)
        step = (
            0.05 * CONFIG.flowmeter.span_Lpm if u_mid < 4.0 else -0.05 * CONFIG.flowmeter.span_Lpm
        )
        (run,) = standard_runs(CONFIG, band.pi, (T_mid,), flow, step)
        s = run.summary()
        where = (
            f"band {kelvin_to_celsius(band.T_low):g}…{kelvin_to_celsius(band.T_high):g} °C, "
            f"{band.u_low:.2f}…{band.u_high:.2f} V"
        )
        assert s["overshoot_percent"] < 25.0, where
        assert s["settling_time"] < 15.0, where
        assert s["disturbance_settling_time"] < 15.0, where
        assert s["time_at_limits"] == 0.0, where


def test_reachable_flows_are_held_at_every_temperature():
    lo, hi = reachable_flows(CONFIG, (COLD, WARM), headroom=0.0)
    # the common range: the higher of the two minimum flows, the lower of the two maximum flows
    assert lo == pytest.approx(max(flow_at(CONFIG, 1.0, T) for T in (COLD, WARM)))
    assert hi == pytest.approx(min(flow_at(CONFIG, 5.0, T) for T in (COLD, WARM)))
    for T_fuel in (COLD, WARM):
        for flow in (lo, hi):
            u = steady_command(CONFIG, flow, T_fuel)
            assert 1.0 - 1e-9 <= u <= 5.0 + 1e-9
    narrowed = reachable_flows(CONFIG, (COLD, WARM), headroom=0.05)
    assert narrowed == pytest.approx((lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo)))


@pytest.mark.parametrize(
    ("flow", "step", "expected"),
    [
        (30.0, 10.0, (30.0, 10.0)),  # fits as asked
        (30.0, -10.0, (30.0, -10.0)),  # downward as asked
        (18.0, -10.0, (18.0, 10.0)),  # no room below: turns round
        (55.0, 10.0, (55.0, -10.0)),  # no room above: turns round
        (5.0, 10.0, (15.0, 10.0)),  # start below the range: from its bottom
        (70.0, 10.0, (60.0, -10.0)),  # start above the range: from its top
        (40.0, 100.0, (15.0, 45.0)),  # wider than the range: the whole range, upward
        (40.0, -100.0, (60.0, -45.0)),
    ],
)
def test_place_step_stays_in_range(flow, step, expected):
    start, signed = place_step(flow, step, 15.0, 60.0)
    assert (start, signed) == pytest.approx(expected)
    assert 15.0 <= start <= 60.0
    assert 15.0 <= start + signed <= 60.0


def test_standard_runs_near_the_top_of_the_drive():
    """A start the warm fuel cannot reach is brought inside, and the step goes down."""
    pi = tune(ProcessModel(K=13.5, T=1.26, T_f=0.3, delay=0.2), "simc", 1.0)
    lo, hi = reachable_flows(CONFIG, (COLD, WARM))
    runs = standard_runs(CONFIG, pi, (COLD, WARM), flow_at(CONFIG, 5.0, COLD), 10.0)
    for run in runs:
        assert run.setpoint[0] == pytest.approx(hi)
        assert run.setpoint[-1] == pytest.approx(hi - 10.0)
        assert lo <= run.setpoint[-1]
        s = run.summary()
        assert s["overshoot_percent"] < 25.0
        assert s["settling_time"] < 15.0
        assert s["time_at_limits"] == 0.0


def test_the_controller_acts_on_the_logged_noisy_reading():
    """With meter noise and quantisation the PI sees exactly what is logged, no other draw.

    Replaying the controller on the logged flow at the control instants must give the logged
    command there, to rounding; the logged flow is on the 0.01 L/min grid and noisy.
    """
    pi = tune(ProcessModel(K=13.5, T=1.26, T_f=0.3, delay=0.2), "simc", 1.0)
    flow = flow_at(CONFIG, 3.0, ROOM)
    setpoint = InputProfile(np.array([0.0, 5.0]), np.array([flow, flow + 5.0]), 30.0)
    kwargs = {"T_fuel": ROOM, "noise_std": 0.3, "resolution": 0.01, "seed": 4}
    run = simulate_closed_loop(CONFIG, pi, setpoint, **kwargs)
    instants = np.searchsorted(run.time, np.arange(30.0))  # every control instant is logged
    assert run.time[instants] == pytest.approx(np.arange(30.0), abs=1e-12)
    replay = DiscretePI(pi, 1.0, 5.0, u0=steady_command(CONFIG, flow, ROOM))
    for k in instants:
        u = replay.update(float(run.setpoint[k]), float(run.flow[k]))
        assert u == pytest.approx(run.command[k], abs=1e-12), f"t = {run.time[k]:g} s"
    assert np.allclose(run.flow * 100.0, np.round(run.flow * 100.0), atol=1e-9)
    clean = simulate_closed_loop(CONFIG, pi, setpoint, T_fuel=ROOM)
    at_rest = run.time < 5.0  # before the step: the 0.3 L/min noise and the loop's reaction to it
    assert 0.25 < np.std(run.flow[at_rest] - clean.flow[at_rest]) < 0.4


def test_saturation_and_recovery_on_the_plant():
    pi = tune(ProcessModel(K=13.5, T=1.26, T_f=0.3, delay=0.2), "simc", 1.0)
    flow = flow_at(CONFIG, 3.0, ROOM)
    # demand far beyond what 5 V can deliver for 40 s, then back to the start
    setpoint = InputProfile(np.array([0.0, 5.0, 45.0]), np.array([flow, 500.0, flow]), 90.0)
    run = simulate_closed_loop(CONFIG, pi, setpoint, T_fuel=ROOM)
    assert run.time_at_limits >= 35.0
    assert run.command.max() == pytest.approx(5.0)
    back = run.events[-1]
    assert back.kind == "setpoint"
    # with anti-windup the recovery is as quick as an ordinary step: no minutes of wind-down
    assert back.settling_time < 15.0
    max_flow = flow_at(CONFIG, 5.0, ROOM)
    assert np.max(run.flow) <= max_flow * 1.001  # the drive's limit, not more


def test_detuned_loop_is_simulated_until_it_settles():
    """Kc·K ≪ 1: the loop is first order with τ = Ti/(K·Kc); 2 % settling is ln 50·τ."""
    model = ProcessModel(K=1.0, T=2.0, delay=1.0)
    pi = PISettings(rule="simc", Kc=1e-3, Ti=2.0, control_period=1.0)
    res = linear_closed_loop(model, pi)
    tau = pi.Ti / (model.K * pi.Kc)
    assert res.setpoint.settling_time == pytest.approx(math.log(50.0) * tau, rel=0.01)
    assert res.setpoint.overshoot_percent == 0.0


# --- the nonlinear run with and without the meter's lag --------------------------------------

NO_LAG = CONFIG.model_copy(
    update={"flowmeter": CONFIG.flowmeter.model_copy(update={"time_constant_s": 0.0})}
)
#: the standard test from 3 V at 20 °C, 60.5 s (a tail after the last control instant): the
#: numbers of the integration written out in closedloop.py, before it moved to integrate_held
PINNED = {
    "lag": {
        "overshoot_percent": 14.547175814575585,
        "settling_time": 7.523574552523765,
        "iae": 16.383555801907512,
        "disturbance_peak": 1.6790650977440151,
        "disturbance_settling_time": 3.98,
        "last_flow": 46.94655503436324,
    },
    "no lag": {
        "overshoot_percent": 6.182993581394247,
        "settling_time": 7.27667860553164,
        "iae": 13.238718500876665,
        "disturbance_peak": 1.5645618168760649,
        "disturbance_settling_time": 3.48,
        "last_flow": 46.94609780903029,
    },
}


def _standard_run(config: PlantConfig) -> ClosedLoopResult:
    pi = tune(ProcessModel(K=13.5, T=1.26, T_f=0.3, delay=0.2), "simc", 1.0)
    setpoint, load = standard_scenario(flow_at(config, 3.0, ROOM), 5.0, duration=60.5)
    return simulate_closed_loop(config, pi, setpoint, T_fuel=ROOM, disturbance=load)


@pytest.mark.parametrize(("case", "config"), [("lag", CONFIG), ("no lag", NO_LAG)])
def test_closed_loop_numbers_with_and_without_meter_lag(case: str, config: PlantConfig):
    run = _standard_run(config)
    pinned = dict(PINNED[case])
    assert run.flow[-1] == pytest.approx(pinned.pop("last_flow"), rel=1e-6)
    summary = run.summary()
    assert summary["time_at_limits"] == 0.0
    grid_valued = pinned.pop("disturbance_settling_time")  # a time of the 0.02 s output grid
    assert summary["disturbance_settling_time"] == pytest.approx(grid_valued, abs=1e-9)
    for name, value in pinned.items():
        assert summary[name] == pytest.approx(value, rel=1e-6), name


@pytest.mark.parametrize("config", [CONFIG, NO_LAG], ids=["lag", "no lag"])
def test_closed_loop_reading_is_the_open_loop_simulation_of_its_commands(config: PlantConfig):
    """Replaying the commands the PI applied through simulate gives the reading it logged.

    Both integrate the plant with integrate_held and read the state measured_state names: the
    lagged meter q_m, or the line flow q when T_f = 0.
    """
    run = _standard_run(config)
    instants = np.searchsorted(run.time, np.arange(61.0))
    applied = np.clip(run.command[instants] + run.disturbance[instants], 1.0, 5.0)
    profile = InputProfile(np.arange(61.0), applied, 60.5)
    replay = simulate(
        config,
        profile,
        T_fuel=ROOM,
        sample_time=0.02,
        control_period=0.0,
        noise_std=0.0,
        resolution=0.0,
    )
    assert replay.time == pytest.approx(run.time, abs=1e-12)
    assert replay.q_meter * LPM_PER_M3S == pytest.approx(run.flow, abs=1e-6)


@pytest.mark.parametrize(("setting", "value"), [("MAX_STEPS", 1), ("RTOL", -1.0)])
def test_closed_loop_solver_failure_is_a_fuelid_error(
    monkeypatch: pytest.MonkeyPatch, setting: str, value: object
):
    # the closed loop integrates with fuelid.plant.simulate.integrate_held: a failed solve is
    # refused there too, not passed on as a made-up flow
    monkeypatch.setattr(fuelid.plant.simulate, setting, value)
    with pytest.raises(FuelidError, match="ODE solver failed on 0…1 s"):
        _standard_run(CONFIG)
