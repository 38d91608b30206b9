"""Gain proposals of the online service (fuelid.online._proposals), against numbers theory fixes.

Plant FOPDT K = 13 (L/min)/V, T = 1 s, θ = 0.5 s, PLC period h = 1 s. SIMC with the default
τc = θ_eff works on θ_eff = θ + h/2 = 1 s (half rule plus the hold), so
Kc = T/(K·(τc + θ_eff)) = 1/(13·2) V per L/min and Ti = min(T, 4·(τc + θ_eff)) = 1 s.
"""

from __future__ import annotations

import json
import math

import pytest

from fuelid.errors import FuelidError
from fuelid.model import ProcessModel
from fuelid.online import Gains, Online
from fuelid.online._proposals import (
    ProposalDecision,
    WindowModel,
    independent_windows,
    propose,
    weighted_mean_model,
)
from fuelid.plc.site import Controller
from fuelid.tuning import BlockForm, PISettings, robustness

H = 1.0  # PLC period [s]
K, T, THETA = 13.0, 1.0, 0.5
MODEL = ProcessModel(K=K, T=T, delay=THETA)
THETA_EFF = THETA + H / 2.0
KC_SIMC = T / (K * (THETA_EFF + THETA_EFF))  # τc = θ_eff
TI_SIMC = min(T, 4.0 * (THETA_EFF + THETA_EFF))


def window(
    model_id: int,
    events: tuple[float, ...],
    model: ProcessModel = MODEL,
    se_K: float | None = 0.1,
    t_to: float | None = None,
) -> WindowModel:
    end = t_to if t_to is not None else 600.0 * model_id
    return WindowModel(
        model_id=model_id,
        t_from=end - 600.0,
        t_to=end,
        model=model,
        stderr={"K": se_K, "T": 0.01},
        T_fuel_C=20.0,
        u_mean=3.0,
        events=events,
    )


TWO_WINDOWS = [window(1, (100.0,)), window(2, (700.0,))]


def decide(
    windows: list[WindowModel],
    current: Gains,
    commissioning: Gains | None = None,
    *,
    settings: Online | None = None,
    tuned_for: ProcessModel | None = None,
    K_range: tuple[float, float] | None = None,
    oscillating: bool = False,
) -> ProposalDecision:
    """propose() at h = 1 s; the commissioning gains default to the current ones."""
    return propose(
        windows,
        current,
        current if commissioning is None else commissioning,
        Online() if settings is None else settings,
        control_period=H,
        tuned_for=tuned_for,
        K_range=K_range,
        oscillating=oscillating,
    )


def max_ms(model: ProcessModel, gains: Gains) -> float:
    return robustness(model, PISettings("simc", gains.Kc, gains.Ti, H)).Ms


# --- independence ---------------------------------------------------------------------------------


def test_independent_windows_newest_first_and_shared_events_count_once():
    ws = [
        window(1, (100.0,)),
        window(2, (100.0 + 1e-9, 700.0)),  # shares the step at 100 s with window 1
        window(3, ()),  # no event: never evidence
        window(4, (1900.0,)),
    ]
    assert [w.model_id for w in independent_windows(ws, 5)] == [4, 2]
    assert [w.model_id for w in independent_windows(ws, 1)] == [4]
    assert [w.model_id for w in independent_windows(list(reversed(ws)), 5)] == [4, 2]
    assert independent_windows([], 2) == []


def test_weighted_mean_model_inverse_variance_and_equal_without_stderr():
    a = window(1, (1.0,), ProcessModel(K=12.0, T=1.0, delay=0.4), se_K=0.1)
    b = window(2, (2.0,), ProcessModel(K=13.0, T=2.0, delay=0.6), se_K=0.2)
    mean, weights = weighted_mean_model([a, b])
    # weights 1/0.01 = 100 and 1/0.04 = 25: 0.8 and 0.2
    assert weights == pytest.approx([0.8, 0.2])
    assert pytest.approx(0.8 * 12.0 + 0.2 * 13.0) == mean.K
    assert pytest.approx(0.8 * 1.0 + 0.2 * 2.0) == mean.T
    assert mean.delay == pytest.approx(0.8 * 0.4 + 0.2 * 0.6)
    c = window(2, (2.0,), ProcessModel(K=13.0, T=2.0, delay=0.6), se_K=None)
    mean, weights = weighted_mean_model([a, c])
    assert weights == pytest.approx([0.5, 0.5])
    assert pytest.approx(12.5) == mean.K


# --- proposals ------------------------------------------------------------------------------------


def test_two_independent_windows_propose_the_geometric_partial_move():
    current = Gains(0.02, 1.5)  # bounds 0.01–0.04 V per L/min, 0.75–3 s: target inside
    d = decide(TWO_WINDOWS, current)
    assert d.propose, d.reason
    assert d.target is not None
    assert d.new is not None
    assert d.target.Kc == pytest.approx(KC_SIMC, rel=1e-12)
    assert d.target.Ti == pytest.approx(TI_SIMC, rel=1e-12)
    f = Online().move_fraction
    assert d.new.Kc == pytest.approx(current.Kc * (KC_SIMC / current.Kc) ** f, rel=1e-12)
    assert d.new.Ti == pytest.approx(current.Ti * (TI_SIMC / current.Ti) ** f, rel=1e-12)
    assert not d.clipped
    assert d.model_ids == (2, 1)
    assert d.old == current
    assert set(d.Ms) == {"newest"}
    assert d.Ms["newest"] == pytest.approx(max_ms(MODEL, d.new), rel=1e-9)
    assert d.Ms["newest"] <= Online().ms_target
    assert set(d.detail["skipped"]) == {"tuned_for", "K_low", "K_high"}
    json.dumps(d.to_json(), allow_nan=False)


def test_weighted_target_is_the_rule_on_the_mean_model():
    a = window(1, (100.0,), ProcessModel(K=12.0, T=T, delay=THETA), se_K=0.1)
    b = window(2, (700.0,), ProcessModel(K=13.0, T=T, delay=THETA), se_K=0.2)
    d = decide([a, b], Gains(0.02, 1.5), Gains(0.025, 1.5))  # Kc bound 0.05: inside
    assert d.propose, d.reason
    assert d.target is not None
    assert not d.clipped
    K_mean = 0.8 * 12.0 + 0.2 * 13.0
    assert d.target.Kc == pytest.approx(T / (K_mean * 2.0 * THETA_EFF), rel=1e-12)


def test_windows_sharing_one_event_are_one_piece_of_evidence():
    ws = [window(1, (100.0,)), window(2, (100.0, 500.0))]
    d = decide(ws, Gains(0.02, 1.5))
    assert not d.propose
    assert d.new is None
    assert d.reason.startswith("only 1 independent window of 2")
    assert d.model_ids == (2,)


def test_three_windows_needed():
    d = decide(TWO_WINDOWS, Gains(0.02, 1.5), settings=Online(agree_windows=3))
    assert not d.propose
    assert d.reason.startswith("only 2 independent windows of 3")


def test_disagreeing_windows_give_no_proposal():
    # Kc ∝ 1/K: 14/12 − 1 = 16.7 % > 10 %
    a = window(1, (100.0,), ProcessModel(K=12.0, T=T, delay=THETA))
    b = window(2, (700.0,), ProcessModel(K=14.0, T=T, delay=THETA))
    d = decide([a, b], Gains(0.02, 1.5))
    assert not d.propose
    assert d.reason.startswith("windows disagree: Kc")
    assert "Ti" not in d.reason.split("(")[0]  # Ti = T in both
    assert d.detail["spread"]["Kc"] == pytest.approx(14.0 / 12.0 - 1.0)


def test_change_below_hysteresis_gives_no_proposal():
    current = Gains(KC_SIMC * 1.04, TI_SIMC)  # 4 % from the target
    d = decide(TWO_WINDOWS, current)
    assert not d.propose
    assert d.new is None
    assert d.target is not None
    assert d.reason == "change 3.8 % ≤ hysteresis 10 %"  # |1/1.04 − 1| = 3.85 %
    assert d.detail["change_to_target"]["Kc"] == pytest.approx(1.0 - 1.0 / 1.04)


def test_oscillating_loop_gives_no_proposal():
    d = decide(TWO_WINDOWS, Gains(0.02, 1.5), oscillating=True)
    assert not d.propose
    assert d.reason.startswith("loop oscillating")


def test_target_beyond_the_bound_is_clipped():
    current = Gains(0.015, TI_SIMC)  # the target 0.0385 is above 2 × 0.015 = 0.03
    d = decide(TWO_WINDOWS, current)
    assert d.propose, d.reason
    assert d.clipped
    assert "clipped" in d.reason
    assert d.target is not None
    assert d.new is not None
    assert d.target.Kc == pytest.approx(2.0 * current.Kc, rel=1e-12)
    assert d.detail["target_unclipped"]["Kc"] == pytest.approx(KC_SIMC, rel=1e-12)
    assert d.new.Kc == pytest.approx(current.Kc * 2.0**0.5, rel=1e-12)
    assert d.new.Ti == pytest.approx(TI_SIMC, rel=1e-12)


def test_high_K_extreme_detunes_kc_until_ms_holds():
    current = Gains(0.06, TI_SIMC)  # aggressive
    commissioning = Gains(0.04, TI_SIMC)
    settings = Online(move_fraction=1.0)
    K_range = (K * 0.9, K * 1.5)
    d = decide(
        TWO_WINDOWS,
        current,
        commissioning,
        settings=settings,
        K_range=K_range,
        tuned_for=MODEL,
    )
    assert d.propose, d.reason
    assert d.new is not None
    undetuned = Gains(KC_SIMC, TI_SIMC)
    high = ProcessModel(K=K_range[1], T=T, delay=THETA)
    assert max_ms(high, undetuned) > settings.ms_target  # the target alone is not robust enough
    assert d.detail["Ms_undetuned"]["K_high"] > settings.ms_target
    assert set(d.Ms) == {"newest", "tuned_for", "K_low", "K_high"}
    assert max(d.Ms.values()) <= settings.ms_target
    assert max_ms(high, d.new) == pytest.approx(d.Ms["K_high"], rel=1e-9)
    assert d.new.Ti == pytest.approx(TI_SIMC, rel=1e-12)  # Ti kept
    assert d.new.Kc < KC_SIMC
    # the largest robust Kc, to the search's tolerance: 1 % more fails
    assert max_ms(high, Gains(d.new.Kc * 1.01, d.new.Ti)) > settings.ms_target
    assert "detuned" in d.reason


def test_no_proposal_when_even_the_lower_bound_fails_ms():
    current = Gains(0.03, TI_SIMC)
    d = decide(TWO_WINDOWS, current, K_range=(K, 5.0 * K))
    assert not d.propose
    assert "even at the Kc lower bound" in d.reason
    assert d.Ms["K_high"] > Online().ms_target


def test_non_positive_K_low_is_skipped():
    d = decide(TWO_WINDOWS, Gains(0.02, 1.5), K_range=(-1.0, K))
    assert d.propose, d.reason
    assert "K_low" in d.detail["skipped"]
    assert "K_low" not in d.Ms
    with pytest.raises(FuelidError):
        decide(TWO_WINDOWS, Gains(0.02, 1.5), K_range=(K, 0.5 * K))


# --- the PLC's form -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("form", "units", "integral", "block", "ideal"),
    [
        ("ideal", "engineering", "s", (0.05, 2.0), (0.05, 2.0)),
        ("ideal", "percent", "min", (1.25, 0.5), (0.05, 30.0)),  # 1.25 %/% × 4 V / 100 L/min
        ("parallel", "engineering", "s", (0.05, 0.025), (0.05, 2.0)),  # Ti = Kp/Ki
        ("parallel", "percent", "s", (1.25, 0.625), (0.05, 2.0)),
        ("parallel", "engineering", "min", (0.05, 0.1), (0.05, 30.0)),  # Ki per min
        ("ideal", "engineering", "min", (0.05, 0.5), (0.05, 30.0)),
        ("ideal", "percent", "s", (1.25, 2.0), (0.05, 2.0)),
        ("parallel", "percent", "min", (1.25, 2.5), (0.05, 30.0)),  # 1.25/2.5 min = 30 s
    ],
)
def test_controller_round_trip(
    form: str,
    units: str,
    integral: str,
    block: tuple[float, float],
    ideal: tuple[float, float],
) -> None:
    """The site's [controller] converts the service's gains to the PLC block's and back."""
    spans = {"u_span_V": 4.0, "y_span_Lpm": 100.0} if units == "percent" else {}
    c = Controller.model_validate(
        {"form": form, "gain_units": units, "integral_unit": integral, **spans}
    )
    plc_block = BlockForm.of(c)
    g = Gains.from_block(*block, plc_block, rule="plc", control_period=H)
    assert (g.Kc, g.Ti) == pytest.approx(ideal, rel=1e-12)
    assert g.to_block(plc_block) == pytest.approx(block, rel=1e-12)
    assert Gains(*ideal).to_block(plc_block) == pytest.approx(block, rel=1e-12)


def test_gains_refuse_non_positive():
    with pytest.raises(FuelidError):
        Gains(0.0, 1.0)
    with pytest.raises(FuelidError):
        Gains(0.05, math.nan)
    assert Gains(0.05, 2.0).to_json() == {"Kc": 0.05, "Ti": 2.0}
