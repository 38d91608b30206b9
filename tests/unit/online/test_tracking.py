"""K(T) tracking: the ratio to the reference plant's K(u, T), its line, its intervals."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from functools import cache

import numpy as np
import pytest

from fuelid.errors import FuelidError, NotFittedError
from fuelid.online import GainObservation, KTracker, PlantGain, TrackingError, plant_gain_function
from fuelid.plant import load_plant_config
from fuelid.units import celsius_to_kelvin
from fuelid.workflow import plant_info
from support.bands import coverage_band, rmse_ratio_band

RATIO = 0.85
"""Pump wear: the loop's K is 85 % of the plant model's."""
SE_R = 0.01
"""Relative standard error of one window's K [-] (what identify reports on 10-min windows)."""


@cache
def k_ref() -> PlantGain:
    """The reference plant's K(u [V], T [°C]), cached over (u, T)."""
    k = plant_gain_function(load_plant_config())
    return cache(k)


def observations(
    rng: np.random.Generator,
    T_C: np.ndarray,
    ratio: float | Callable[[float], float] = RATIO,
    se_r: float = SE_R,
    extra_sd: float = 0.0,
) -> list[GainObservation]:
    """Windows at commands 1.25–4.75 V whose K is ratio(T)·K_plant(u, T) plus Gaussian noise."""
    u = rng.choice([1.25, 2.0, 3.0, 4.0, 4.75], size=T_C.size)
    out = []
    for i, (T, ui) in enumerate(zip(T_C, u, strict=True)):
        r = ratio(float(T)) if callable(ratio) else float(ratio)
        Kp = k_ref()(float(ui), float(T))
        r_obs = r + rng.normal(scale=se_r) + (rng.normal(scale=extra_sd) if extra_sd else 0.0)
        out.append(GainObservation(600.0 * i, float(T), float(ui), r_obs * Kp, se_r * Kp))
    return out


def test_plant_gain_is_plant_info_K() -> None:
    """The helper's K is the K ``fuelid plant info`` prints; T is in °C at this interface."""
    config = load_plant_config()
    info = plant_info(config, celsius_to_kelvin(20.0), 3.0)
    assert k_ref()(3.0, 20.0) == pytest.approx(info.equivalent.model.K, rel=1e-12)
    # theory: K falls ~13 % over 1.25–4.75 V and ~11 % over −20…50 °C on the reference plant
    assert 0.8 < k_ref()(4.75, 20.0) / k_ref()(1.25, 20.0) < 0.95
    assert 0.8 < k_ref()(3.0, 50.0) / k_ref()(3.0, -20.0) < 0.95


def test_constant_ratio_recovered_and_extrapolated() -> None:
    """Fit on 0–30 °C: ratio 0.85 and slope 0 within 3 se; K at −10 and 45 °C within 3 se."""
    rng = np.random.default_rng(1)
    tr = KTracker(k_plant=k_ref()).fit(observations(rng, rng.uniform(0.0, 30.0, 40)))
    assert tr.mode_ == "ratio"
    assert tr.fit_ is not None
    assert tr.fit_.slope is not None
    se_a, se_b = tr.fit_.se
    assert se_b is not None
    r_ref, se_ref = tr.predict_ratio(tr.fit_.T_ref)
    assert abs(r_ref - RATIO) < 3 * se_ref
    assert abs(tr.fit_.slope) < 3 * se_b
    ses = []
    for T in (-10.0, 45.0):
        for u in (1.25, 4.75):
            K, se = tr.predict(T, u=u)
            assert abs(K - RATIO * k_ref()(u, T)) < 3 * se
        ses.append(tr.predict_ratio(T)[1])
    # the prediction's se grows with the distance from the data's mean temperature
    mid = tr.predict_ratio(tr.fit_.T_ref)[1]
    assert mid == pytest.approx(se_a)
    assert mid < tr.predict_ratio(tr.fit_.T_ref + 10.0)[1] < ses[1]
    assert mid < tr.predict_ratio(tr.fit_.T_ref - 10.0)[1] < ses[0]


def test_drifting_ratio_recovered() -> None:
    """A ratio falling 0.2 %/°C (a viscosity curve the model gets wrong) is recovered."""
    rng = np.random.default_rng(2)

    def truth(T: float) -> float:
        return 0.95 - 0.002 * (T - 20.0)

    tr = KTracker(k_plant=k_ref()).fit(observations(rng, rng.uniform(-10.0, 45.0, 40), truth))
    assert tr.fit_ is not None
    assert tr.fit_.slope is not None
    se_b = tr.fit_.se[1]
    assert se_b is not None
    assert abs(tr.fit_.slope - (-0.002)) < 3 * se_b
    assert abs(tr.fit_.slope) > 5 * se_b  # the drift is seen, not lost in the noise
    for T in (-10.0, 20.0, 45.0):
        r, se = tr.predict_ratio(T)
        assert abs(r - truth(T)) < 3 * se
    ratio, se = tr.drift(45.0, K_tuned=k_ref()(3.0, 45.0), u=3.0)
    assert abs(ratio - truth(45.0)) < 3 * se


def test_interval_coverage() -> None:
    """The 95 % interval of the ratio covers 0.85 in 200 seeded repetitions as often as it should.

    Band (pre-registered, tests/bands.py): 2…21 misses, the two-sided binomial band of correct
    95 % intervals at 0.1 % false alarm.
    """
    rng = np.random.default_rng(3)
    T = np.linspace(0.0, 30.0, 15)
    u = rng.choice([1.25, 2.0, 3.0, 4.0, 4.75], size=T.size)
    Kp = np.array([k_ref()(float(a), float(b)) for a, b in zip(u, T, strict=True)])
    hits_a = hits_pred = 0
    for _ in range(200):
        r = RATIO + rng.normal(scale=SE_R, size=T.size)
        obs = [
            GainObservation(600.0 * i, T[i], u[i], r[i] * Kp[i], SE_R * Kp[i], Kp[i])
            for i in range(T.size)
        ]
        tr = KTracker().fit(obs)  # K_plant carried by the observations
        assert tr.fit_ is not None
        a, se_a = tr.predict_ratio(tr.fit_.T_ref)
        hits_a += abs(a - RATIO) < 1.96 * se_a
        rp, se_p = tr.predict_ratio(45.0)
        hits_pred += abs(rp - RATIO) < 1.96 * se_p
    # pre-registered: misses of correct 95 % intervals in 200 repetitions (tests/bands.py)
    lo, hi = coverage_band(200)
    assert lo <= 200 - hits_a <= hi
    assert lo <= 200 - hits_pred <= hi


def test_birge_inflation() -> None:
    """Scatter beyond the windows' standard errors inflates the covariance by χ²/dof."""
    rng = np.random.default_rng(4)
    T = rng.uniform(0.0, 30.0, 40)
    calm = KTracker(k_plant=k_ref()).fit(observations(rng, T))
    rough = KTracker(k_plant=k_ref()).fit(observations(rng, T, extra_sd=3 * SE_R))
    assert calm.fit_ is not None
    assert rough.fit_ is not None
    assert calm.fit_.birge_ratio < 1.5
    # extra sd 3·se: each window's variance 10·se², so χ²/dof ~ 10·χ²(dof)/dof; pre-registered
    # band at 0.1 % false alarm (tests/bands.py: the square of the χ² ratio band)
    low, high = rmse_ratio_band(rough.fit_.dof)
    assert 10.0 * low**2 < rough.fit_.inflation < 10.0 * high**2
    assert rough.fit_.birge_ratio == pytest.approx(math.sqrt(rough.fit_.inflation))
    assert rough.fit_.se[0] > 2.0 * calm.fit_.se[0]
    a, se_a = rough.predict_ratio(rough.fit_.T_ref)
    assert abs(a - RATIO) < 3 * se_a


def test_refusals() -> None:
    """< 2 observations refused; a narrow temperature spread gives the constant only."""
    rng = np.random.default_rng(5)
    one = observations(rng, np.array([20.0]))
    with pytest.raises(TrackingError, match="at least 2"):
        KTracker(k_plant=k_ref()).fit(one)
    assert issubclass(TrackingError, FuelidError)
    with pytest.raises(TrackingError):
        KTracker(k_plant=k_ref()).fit([])
    with pytest.raises(NotFittedError):
        KTracker().predict(20.0)
    narrow = KTracker(k_plant=k_ref()).fit(observations(rng, np.linspace(19.5, 20.5, 10)))
    assert narrow.fit_ is not None
    assert narrow.fit_.slope is None
    assert "no slope" in narrow.fit_.note
    r, se = narrow.predict_ratio(20.0)
    assert abs(r - RATIO) < 3 * se
    assert narrow.to_json()["ratio"]["slope_estimated"] is False
    bad = GainObservation(0.0, 20.0, 3.0, -1.0, 0.1)
    with pytest.raises(TrackingError, match="K > 0"):
        KTracker().fit([bad, bad])


def test_incremental_update_and_forgetting() -> None:
    """update() equals fit() on the same set; forgetting follows a step in the ratio."""
    rng = np.random.default_rng(6)
    obs = observations(rng, rng.uniform(0.0, 30.0, 20))
    batch = KTracker(k_plant=k_ref()).fit(obs)
    inc = KTracker(k_plant=k_ref()).fit(obs[:2])
    for o in obs[2:]:
        inc.update(o)
    assert inc.predict_ratio(10.0) == pytest.approx(batch.predict_ratio(10.0))
    # pump wear: 1.0 for 30 windows, then 0.85 for 10 (windows 10 min apart)
    before = observations(rng, rng.uniform(0.0, 30.0, 30), ratio=1.0)
    after = observations(rng, rng.uniform(0.0, 30.0, 10))
    shifted = [GainObservation(o.time + 600.0 * 30, o.T_fuel_C, o.u, o.K, o.se_K) for o in after]
    plain = KTracker(k_plant=k_ref()).fit(before + shifted)
    forget = KTracker(k_plant=k_ref(), forgetting_time_s=1800.0).fit(before + shifted)
    r_plain = plain.predict_ratio(15.0)[0]
    r_forget, se_forget = forget.predict_ratio(15.0)
    assert abs(r_forget - RATIO) < abs(r_plain - RATIO)
    assert abs(r_forget - RATIO) < 0.03
    assert abs(r_forget - RATIO) < 3 * se_forget
    bounded = KTracker(k_plant=k_ref(), max_observations=10).fit(before + shifted)
    assert len(bounded.observations_) == 10


def test_bands_without_plant_model() -> None:
    """Without a plant model K is tracked per 1 V command band against temperature."""
    rng = np.random.default_rng(7)
    obs = observations(rng, rng.uniform(0.0, 30.0, 60))
    tr = KTracker().fit(
        [GainObservation(o.time, o.T_fuel_C, o.u, o.K, o.se_K) for o in obs]
    )  # no K_plant: bands
    assert tr.mode_ == "band"
    assert tr.fit_ is None
    for u in (1.25, 3.0, 4.75):
        K, se = tr.predict(15.0, u=u)
        assert abs(K - RATIO * k_ref()(u, 15.0)) < 3 * se
    with pytest.raises(TrackingError, match="band"):
        tr.predict(15.0, u=0.5)
    with pytest.raises(TrackingError, match="not tracked"):
        tr.predict_ratio(15.0)
    d = json.loads(json.dumps(tr.to_json()))
    assert d["mode"] == "band"
    assert d["bands"][0]["band"] == [1.0, 2.0]


def test_to_dict_is_json() -> None:
    """to_dict() round-trips through JSON with a units map."""
    rng = np.random.default_rng(8)
    tr = KTracker(k_plant=k_ref()).fit(observations(rng, rng.uniform(0.0, 30.0, 10)))
    d = json.loads(json.dumps(tr.to_json()))
    assert d["mode"] == "ratio"
    assert d["ratio"]["slope_estimated"] is True
    assert "units" in d
    assert d["covariance_inflation"].startswith("birge")
