"""The loop over fuel temperature: plant cases, one fixed PI, the gain schedule, the sweep."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from fuelid.errors import FuelidError
from fuelid.model import ProcessModel, model_covariance
from fuelid.plant import load_plant_config
from fuelid.tuning import (
    Anchor,
    band_edges,
    evaluate_fixed,
    gain_schedule,
    plant_cases,
    robustness,
    tune,
    uncertainty_sweep,
)
from fuelid.units import celsius_to_kelvin, kelvin_to_celsius

CONFIG = load_plant_config()
TEMPS = tuple(celsius_to_kelvin(t) for t in (-20.0, 0.0, 20.0, 35.0, 50.0))
COLD, ROOM, WARM = celsius_to_kelvin(-20.0), celsius_to_kelvin(20.0), celsius_to_kelvin(50.0)
IDENTIFIED = ProcessModel(K=13.5, T=1.26, T_f=0.3, delay=0.2)
ANCHOR = Anchor(IDENTIFIED, T_fuel=ROOM, u=3.0)


def test_gain_falls_as_the_fuel_warms():
    # docs/explanation/physics.md (the pump): its leakage grows as viscosity falls, so less flow per
    # volt
    cases = plant_cases(CONFIG, TEMPS, (3.0,))
    gains = [c.model.K for c in cases]
    assert np.all(np.diff(gains) < 0.0)
    assert [c.T_fuel for c in cases] == list(TEMPS)
    rows = evaluate_fixed(tune(IDENTIFIED), cases).rows()
    assert [row["fuel_temperature"] for row in rows] == [-20.0, 0.0, 20.0, 35.0, 50.0]  # JSON: °C


def test_anchor_reproduces_the_identified_model_at_its_conditions():
    (case,) = plant_cases(CONFIG, (ROOM,), (3.0,), ANCHOR)
    assert pytest.approx(IDENTIFIED.K, rel=1e-12) == case.model.K
    assert pytest.approx(IDENTIFIED.T, rel=1e-12) == case.model.T
    assert case.anchored
    assert case.margin_plant is case.model
    # and moves with temperature as the physics does (same ratio)
    cold_phys, ref_phys = plant_cases(CONFIG, (COLD, ROOM), (3.0,))
    (cold,) = plant_cases(CONFIG, (COLD,), (3.0,), ANCHOR)
    assert (
        pytest.approx(cold_phys.model.K / ref_phys.model.K, rel=1e-12)
        == cold.model.K / IDENTIFIED.K
    )


def test_fixed_pi_over_temperature_and_a_gain_three_times_larger():
    pi = tune(IDENTIFIED, "simc", 1.0)
    cases = plant_cases(CONFIG, TEMPS, (1.0, 3.0, 5.0), ANCHOR)
    check = evaluate_fixed(pi, cases)
    nominal = robustness(IDENTIFIED, pi)
    assert check.all_stable
    assert check.worst_Ms >= nominal.Ms - 1e-9  # the nominal case is among them
    hot = evaluate_fixed(pi.with_gain_factor(3.0), cases)
    assert hot.worst_Ms > check.worst_Ms
    # a gain margin is a ratio: three times the gain leaves a third of it, case by case
    assert hot.worst_gain_margin == pytest.approx(check.worst_gain_margin / 3.0, rel=1e-6)
    rows = check.rows()
    assert len(rows) == len(cases)
    json.dumps(rows)


@pytest.fixture(scope="module")
def schedule():
    return gain_schedule(CONFIG, "simc", 1.0, ms_target=1.6, band_width=20.0, anchor=ANCHOR)


def test_schedule_meets_its_target_when_checked_independently(schedule):
    assert schedule.bands
    for band in schedule.bands:
        T_mid = 0.5 * (band.T_low + band.T_high)
        u_mid = 0.5 * (band.u_low + band.u_high)
        cases = plant_cases(
            CONFIG, (band.T_low, T_mid, band.T_high), (band.u_low, u_mid, band.u_high), ANCHOR
        )
        worst = max(robustness(c.margin_plant, band.pi).Ms for c in cases)
        assert worst <= 1.6 + 1e-6
        assert band.detune <= 1.0


def test_a_tight_target_detunes_and_still_holds():
    tight = gain_schedule(CONFIG, "simc", 1.0, ms_target=1.45, band_width=35.0, flow_bands=1)
    assert any(b.detune < 1.0 for b in tight.bands)
    assert tight.worst_Ms <= 1.45 + 1e-6
    with pytest.raises(FuelidError, match="greater than 1"):
        gain_schedule(CONFIG, ms_target=1.0)


def test_schedule_covers_the_range_and_lookup_finds_the_band(schedule):
    temps = sorted({(b.T_low, b.T_high) for b in schedule.bands})
    assert temps[0][0] == COLD
    assert temps[-1][1] == WARM
    assert all(a[1] == b[0] for a, b in itertools.pairwise(temps))
    for t in (-20.0, -3.0, 17.5, 50.0):
        T = celsius_to_kelvin(t)
        for u in (1.2, 3.0, 4.9):
            band = schedule.lookup(T, u)
            assert band.T_low <= T <= band.T_high
            assert band.u_low <= u <= band.u_high
    # beyond the range the nearest end applies
    assert schedule.lookup(celsius_to_kelvin(70.0), 3.0).T_high == WARM
    data = json.loads(json.dumps(schedule.to_json()))
    assert data["worst_Ms"] <= 1.6 + 1e-6
    assert len(data["bands"]) == len(schedule.bands)


def test_band_edges():
    edges = band_edges(COLD, WARM, 10.0)
    assert [kelvin_to_celsius(T) for T in edges] == pytest.approx([-20, -10, 0, 10, 20, 30, 40, 50])
    assert (edges[0], edges[-1]) == (COLD, WARM)  # the ends exactly
    edges = band_edges(273.15, 283.15, 4.0)  # 2.5 bands rounds to 2 equal ones
    assert edges.tolist() == pytest.approx([273.15, 278.15, 283.15])
    with pytest.raises(FuelidError, match=r"low < high, got 10…0 °C"):
        band_edges(283.15, 273.15, 1.0)
    with pytest.raises(FuelidError):
        band_edges(273.15, 283.15, 0.0)


def test_uncertainty_sweep():
    pi = tune(IDENTIFIED, "simc", 1.0)
    names = ("K", "T")
    none = uncertainty_sweep(pi, ANCHOR, names, np.zeros((2, 2)), CONFIG, n=60, seed=3)
    # no parameter uncertainty: only temperature moves the plant, as the physics says
    lo, hi = (c.model.K for c in plant_cases(CONFIG, (WARM, COLD), (3.0,), ANCHOR))
    assert np.all((lo - 1e-9 <= none.K) & (hi + 1e-9 >= none.K))
    wide_cov = np.diag([(0.15 * IDENTIFIED.K) ** 2, (0.15 * IDENTIFIED.T) ** 2])
    wide = uncertainty_sweep(pi, ANCHOR, names, wide_cov, CONFIG, n=60, seed=3)
    assert wide.summary()["worst_Ms"] > none.summary()["worst_Ms"]
    assert np.std(wide.K) > 3 * np.std(none.K)
    again = uncertainty_sweep(pi, ANCHOR, names, wide_cov, CONFIG, n=60, seed=3)
    assert np.array_equal(again.Ms, wide.Ms)  # reproducible with a seed
    assert set(wide.summary()) >= {"worst_Ms", "Ms_p95", "unstable_fraction"}


def test_model_covariance_is_the_model_parameters_block():
    cov = np.array([[4.0, np.nan, 0.5], [np.nan, 9.0, 0.1], [0.5, 0.1, 1.0]])
    names, block = model_covariance(["K", "T", "offset"], cov)
    assert names == ["K", "T"]
    assert block.tolist() == [[4.0, 0.0], [0.0, 9.0]]  # unknown correlation taken as zero
    names, block = model_covariance(["K", "delay"], np.diag([1.0, np.nan]))
    assert names == ["K"]  # no variance known: held at its estimate
    # a sweep given the nuisance parameters draws exactly what the block alone draws
    pi = tune(IDENTIFIED, "simc", 1.0)
    kt = np.diag([(0.1 * IDENTIFIED.K) ** 2, (0.1 * IDENTIFIED.T) ** 2])
    full = np.zeros((4, 4))
    full[:2, :2] = kt
    full[2, 2] = full[3, 3] = 1.0
    with_nuisance = uncertainty_sweep(
        pi, ANCHOR, ("K", "T", "offset", "c0"), full, CONFIG, n=30, seed=5
    )
    block_only = uncertainty_sweep(pi, ANCHOR, ("K", "T"), kt, CONFIG, n=30, seed=5)
    assert np.array_equal(with_nuisance.K, block_only.K)
    assert np.array_equal(with_nuisance.Ms, block_only.Ms)


def test_schedule_gives_kc_in_percent_of_span_per_band(schedule):
    data = json.loads(json.dumps(schedule.to_json()))
    assert (data["u_span"], data["y_span"]) == (4.0, CONFIG.flowmeter.span_Lpm)
    for band, row in zip(schedule.bands, data["bands"], strict=True):
        # as PISettings.plc_form: Kc·y_span/u_span
        assert row["Kc_percent_of_span"] == pytest.approx(band.pi.Kc * 100.0 / 4.0, rel=1e-12)
    # 20 °C bands over −20…50 °C with flow bands: the gains differ, a schedule is needed
    assert not schedule.single_set_suffices
    assert data["single_set_suffices"] is False
    assert data["single_set"] is None
    wider = gain_schedule(CONFIG, "simc", 1.0, band_width=35.0, flow_bands=1, y_span=80.0)
    assert wider.to_json()["bands"][0]["Kc_percent_of_span"] == pytest.approx(
        wider.bands[0].pi.Kc * 80.0 / 4.0, rel=1e-12
    )


def test_one_set_of_gains_suffices_where_the_bands_agree():
    narrow = gain_schedule(
        CONFIG,
        "simc",
        1.0,
        T_range=(celsius_to_kelvin(10.0), celsius_to_kelvin(30.0)),
        band_width=10.0,
        flow_bands=1,
    )
    assert len(narrow.bands) == 2
    Kc = [b.pi.Kc for b in narrow.bands]
    assert (max(Kc) - min(Kc)) / max(Kc) <= 0.01
    assert narrow.single_set_suffices
    single = narrow.single_set
    assert single is not None
    assert single.pi.Kc == min(Kc)  # the most cautious of the bands' gains
    assert single.worst_Ms <= narrow.ms_target
    assert len(single.cases) == 5 * 3  # every band's temperatures × commands, shared edge once
    data = json.loads(json.dumps(narrow.to_json()))
    assert data["single_set_suffices"] is True
    assert data["single_set"]["Kc"] == single.pi.Kc
    assert data["single_set"]["Ti"] == single.pi.Ti
    assert data["single_set"]["Kc_percent_of_span"] == pytest.approx(single.pi.Kc * 25.0)
