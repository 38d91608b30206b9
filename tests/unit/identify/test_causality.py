"""Issue 37: a flow that moves before its command is named, and ordinary logs are left alone.

The logs are the built-in reference plant's (``fuelid simulate``'s chain): its response to a
command change peaks about 0.9 s later (dead time 0.2 s, meter delay and lags), and it settles in
about 6 s.

Acceptance, stated before running:

* reversed rows (no time column to sort them by), swapped input and output columns, and the
  output shifted 3 s ahead of its input: ``leads`` True, the warning first among the
  identification's warnings naming both causes, the peak at a negative lag (reversed and
  swapped: −2 … −0.3 s, the mirror of +0.9 s; shifted 3 s: −3 … −1.5 s, about 0.9 − 3 s);
* ordinary logs, open loop (a step, a staircase, random levels, the plant's noise and 5 and 20
  times it) and closed loop (a PI following setpoint steps; a PI holding a setpoint against slow
  coloured disturbances): ``leads`` False and z < 0, the peak at +0.3 … +2 s where the response is
  clear (not on the noisiest, where only the sign of z is asked);
* false alarms: the statistic z is nearly standard normal when the output has nothing to do with
  the command, so 200 such logs (white noise and a random walk) give no alarm (the 4σ threshold
  is a 3·10⁻⁵ chance each; the mean of z within ±0.3 and its spread 0.7 … 1.3). A causal log
  sits on the other side of zero (−4 to −170 σ measured), so its false-alarm chance is far
  smaller still: noise would have to move the flow more before the command changes than the
  plant's response moves it after them.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.signal

from fuelid.identify import IdentifyOptions, identify, lead_check
from fuelid.identify._causality import LEAD_Z
from fuelid.io.timeseries import IOData
from fuelid.lti import discretise
from fuelid.model import ProcessModel
from fuelid.plant import load_plant_config
from fuelid.workflow import SimulationRequest, simulate_log

H = 0.02
LPM_PER_M3S = 60_000.0
CAUSES = ("reversed clock", "swapped input and output columns")


def _log(**settings: object) -> tuple[np.ndarray, np.ndarray]:
    log = simulate_log(load_plant_config(), SimulationRequest(**settings)).to_log()  # type: ignore[arg-type]
    return np.asarray(log["u_V"]), np.asarray(log["q_Lpm"])


def _closed_loop(sigma: float, pole: float, setpoints: np.ndarray, seed: int) -> tuple:
    """A discrete PI (1 s period, SIMC) on a linear model of the loop; it reads the logged flow."""
    truth = ProcessModel(K=13.12, T=1.268, T_f=0.3, delay=0.2)
    rng = np.random.default_rng(seed)
    per = round(1.0 / H)
    theta = truth.delay + truth.T_f + 0.5
    Kc, Ti = truth.T / (truth.K * 2 * theta), min(truth.T, 8 * theta)
    model = discretise(truth.time_constants, truth.delay, H)
    n = setpoints.size * per
    u, y = np.full(n, 3.0), np.empty(n)
    v = np.zeros(n + model.shift)
    zi = np.zeros(max(model.a.size, model.b.size) - 1)
    noise = rng.normal(0.0, sigma, n)
    if pole:
        noise = scipy.signal.lfilter([math.sqrt(1 - pole**2)], [1.0, -pole], noise)
    u_prev, e_prev = 3.0, 0.0
    for j, r in enumerate(setpoints):
        k0 = j * per
        e = r - ((y[k0 - 1] + noise[k0 - 1]) if k0 else 40.0 + noise[0])
        u_j = float(np.clip(u_prev + Kc * (e - e_prev + 1.0 / Ti * e), 1.0, 5.0))
        u[k0 : k0 + per] = u_j
        v[k0 + model.shift : k0 + per + model.shift] = u_j - 3.0
        out, zi = scipy.signal.lfilter(model.b, model.a, v[k0 : k0 + per], zi=zi)
        y[k0 : k0 + per] = 40.0 + truth.K * out
        u_prev, e_prev = u_j, e
    return u, y + noise


@pytest.fixture(scope="module")
def step() -> tuple[np.ndarray, np.ndarray]:
    return _log()


@pytest.fixture(scope="module")
def ordinary() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    sp = np.repeat([40.0, 46.0, 36.0, 44.0, 38.0, 47.0, 40.0], 20)
    return {
        "step": _log(),
        "staircase": _log(profile="steps"),
        "random levels": _log(profile="random"),
        "random levels, 1 s holds": _log(profile="random", hold=1.0, seed=2),
        "step, 5x noise": _log(noise_std=0.5 / LPM_PER_M3S, seed=3),
        "step, 20x noise": _log(noise_std=2.0 / LPM_PER_M3S, seed=4),
        "closed loop, setpoint steps": _closed_loop(0.1, 0.0, sp, 0),
        "closed loop, coloured disturbances": _closed_loop(1.0, 0.99, np.full(200, 40.0), 1),
    }


@pytest.mark.parametrize(
    "name",
    [
        "step",
        "staircase",
        "random levels",
        "random levels, 1 s holds",
        "step, 5x noise",
        "step, 20x noise",
        "closed loop, setpoint steps",
        "closed loop, coloured disturbances",
    ],
)
def test_ordinary_logs_do_not_lead(ordinary, name: str) -> None:
    u, y = ordinary[name]
    check = lead_check(u, y, H)
    assert not check.leads
    assert check.z < 0.0
    assert check.warning() is None
    if "20x" not in name:
        assert 0.3 <= check.peak_lag <= 2.0


def test_reversed_swapped_and_shifted_logs_lead(step) -> None:
    u, y = step
    shift = round(3.0 / H)
    cases = {
        "reversed": (u[::-1], y[::-1], (-2.0, -0.3)),
        "swapped": (y, u, (-2.0, -0.3)),
        "shifted 3 s": (u[:-shift], y[shift:], (-3.0, -1.5)),
    }
    for name, (uu, yy, (low, high)) in cases.items():
        check = lead_check(uu, yy, H)
        assert check.leads, name
        assert check.z >= LEAD_Z, name
        assert low <= check.peak_lag <= high, (name, check.peak_lag)
        warning = check.warning()
        assert warning is not None
        assert warning.startswith("the flow moves before its command")
        assert all(cause in warning for cause in CAUSES)
        assert "meaningless" in warning


def test_the_reversed_log_leads_even_with_5x_noise(ordinary) -> None:
    u, y = ordinary["step, 5x noise"]
    assert lead_check(u[::-1], y[::-1], H).leads


def test_unrelated_output_gives_no_false_alarms(step) -> None:
    u, _ = step
    rng = np.random.default_rng(2037)
    z = []
    for _ in range(100):
        for y in (rng.normal(size=u.size), np.cumsum(rng.normal(size=u.size))):
            check = lead_check(u, y, H)
            assert not check.leads
            z.append(check.z)
    assert abs(np.mean(z)) < 0.3
    assert 0.7 < np.std(z) < 1.3


def test_a_negative_gain_is_followed_with_its_sign(step) -> None:
    u, y = step
    assert not lead_check(u, -y, H, sign=-1.0).leads
    assert lead_check(u[::-1], -y[::-1], H, sign=-1.0).leads
    # without the gain's sign the flow's fall after the command looks like nothing after it
    assert lead_check(u, -y, H).z > 0.0


def test_changes_are_not_paired_across_a_gap(step) -> None:
    u, y = step
    # the log twice, as two segments: the join (u from 1.5 back to 1 V, the flow from 21.6 back
    # to 14.6 L/min) is no command change, and no lag pairs samples of both copies
    one = lead_check(u, y, H)
    two = lead_check(np.r_[u, u], np.r_[y, y], H, segment_starts=(u.size,))
    assert two.response_before == pytest.approx(one.response_before, rel=1e-9, abs=1e-12)
    assert two.response_after == pytest.approx(one.response_after, rel=1e-9)
    assert two.peak_lag == one.peak_lag
    assert two.z == pytest.approx(math.sqrt(2.0) * one.z, rel=1e-6)  # twice the evidence


def test_a_command_that_never_changes_is_not_judged() -> None:
    check = lead_check(np.ones(500), np.random.default_rng(0).normal(size=500), H)
    assert not check.leads
    assert math.isnan(check.peak_lag)
    assert check.to_json()["leads"] is False


# --- through identify -------------------------------------------------------------------------


@pytest.fixture(scope="module")
def identified(step) -> dict[str, object]:
    u, y = step
    options = IdentifyOptions()
    return {
        "ordinary": identify(IOData(u, y, H), options),
        "reversed rows": identify(IOData(u[::-1].copy(), y[::-1].copy(), H), options),
        "swapped columns": identify(IOData(y, u, H), options),
    }


def test_identify_names_a_reversed_or_swapped_log_first(identified) -> None:
    for name in ("reversed rows", "swapped columns"):
        result = identified[name]
        lead = result.diagnostics["lead"]
        assert lead["leads"] is True, name
        assert -2.0 <= lead["peak_lag_s"] <= -0.3, name
        assert set(lead) == {
            "leads",
            "peak_lag_s",
            "response_before",
            "response_after",
            "z",
            "span_s",
        }
        assert result.warnings[0].startswith("the flow moves before its command"), name
        # the same evidence is not also read as feedback, nor a model's settling time advised on
        assert not any("closed-loop" in w for w in result.warnings), name
        assert not any("settling time" in w and "samples" in w for w in result.warnings), name


def test_identify_leaves_an_ordinary_log_alone(identified) -> None:
    result = identified["ordinary"]
    lead = result.diagnostics["lead"]
    assert lead["leads"] is False
    assert lead["z"] < -LEAD_Z
    assert 0.3 <= lead["peak_lag_s"] <= 2.0
    # the plant's gain after the command changes, nothing before: K ≈ 13–14 (L/min)/V
    assert 12.0 < lead["response_after"] < 15.0
    assert abs(lead["response_before"]) < 0.5
    assert not any("moves before" in w for w in result.warnings)


def test_step_ls_looks_at_the_raw_record(step) -> None:
    # its zero-phase filter smears each output step backwards: the check must not see that
    u, y = step
    options = IdentifyOptions(
        method="step-ls", flowmeter_T=0.3, flowmeter_delay=0.2, settling_time=6.0
    )
    result = identify(IOData(u, y, H), options)
    assert result.diagnostics["lead"]["leads"] is False
    assert result.diagnostics["lead"]["peak_lag_s"] > 0.3
