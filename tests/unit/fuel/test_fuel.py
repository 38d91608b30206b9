"""Tests of fuelid.fuel against hand calculations, specifications and physics.

Every expected number below was worked out by hand from the published formula (not by calling
the code), e.g. TS-1 ν at 20 °C: 1e-8·20⁴ − 4e-6·20³ + 5e-4·20² − 0.0374·20 + 1.888
= 0.0016 − 0.032 + 0.2 − 0.748 + 1.888 = 1.3096 mm²/s.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from fuelid.errors import FuelidError, OutOfRangeError
from fuelid.fuel import (
    DEFAULT_FUEL,
    FUELS,
    Fuel,
    FuelProperties,
    fuel_properties,
    get_fuel,
    list_fuels,
    mu_JP8_table,
    mu_RP3_Andrade,
    nu_JetA_CRC,
    nu_TS1,
    rho_JetA,
    rho_TS1,
)
from fuelid.units import T0

MM2S = 1e-6  # 1 mm²/s in m²/s
MPAS = 1e-3  # 1 mPa·s in Pa·s

# name, function, validity range in °C
CORRELATIONS: list[tuple[str, Callable[..., Any], tuple[float, float]]] = [
    ("rho_TS1", rho_TS1, (-20.0, 60.0)),
    ("nu_TS1", nu_TS1, (-20.0, 60.0)),
    ("nu_JetA_CRC", nu_JetA_CRC, (-40.0, 100.0)),
    ("rho_JetA", rho_JetA, (-40.0, 100.0)),
    ("mu_JP8_table", mu_JP8_table, (20.0, 100.0)),
    ("mu_RP3_Andrade", mu_RP3_Andrade, (-20.0, 60.0)),
]
CORR_IDS = [c[0] for c in CORRELATIONS]


def _grid(t_lo: float, t_hi: float, n: int = 161) -> np.ndarray:
    """Temperatures [K] spanning a range given in °C."""
    return np.linspace(t_lo, t_hi, n) + T0


# --------------------------------------------------------------------------------------------
# values against hand calculations


@pytest.mark.parametrize(
    ("t_C", "rho_expected"),
    [(-20.0, 808.4), (20.0, 779.6), (60.0, 750.8)],  # 794 − 0.72·t
)
def test_rho_TS1_hand_values(t_C: float, rho_expected: float) -> None:
    assert rho_TS1(t_C + T0) == pytest.approx(rho_expected, abs=1e-9)


@pytest.mark.parametrize(
    ("t_C", "nu_mm2s"),
    [
        # 1.6e-3 + 0.032 + 0.2 + 0.748 + 1.888
        (-20.0, 2.8696),
        (0.0, 1.888),
        # 1.6e-3 − 0.032 + 0.2 − 0.748 + 1.888
        (20.0, 1.3096),
        # 0.1296 − 0.864 + 1.8 − 2.244 + 1.888
        (60.0, 0.7096),
    ],
)
def test_nu_TS1_hand_values(t_C: float, nu_mm2s: float) -> None:
    assert nu_TS1(t_C + T0) == pytest.approx(nu_mm2s * MM2S, rel=1e-9)


@pytest.mark.parametrize(
    ("t_C", "nu_mm2s"),
    [
        # T = 253.15 K: 225697.23·e^(−10.792043) = 4.640895; −0.0030984177·T = −0.784364
        (-20.0, 5.7583),
        # T = 293.15 K: 0.843379 − 0.908301 + 1.901755
        (20.0, 1.8368),
        # T = 313.15 K: 0.359529 − 0.970270 + 1.901755
        (40.0, 1.2910),
    ],
)
def test_nu_JetA_CRC_hand_values(t_C: float, nu_mm2s: float) -> None:
    assert nu_JetA_CRC(t_C + T0) == pytest.approx(nu_mm2s * MM2S, abs=1e-4 * MM2S)


@pytest.mark.parametrize(
    ("t_C", "rho_expected"),
    [
        # α15 = 594.5418/804² = 9.19751e-4 1/°C, dρ/dt = −804·α15 = −0.739480 kg/m³/K
        (15.0, 804.0),
        (20.0, 800.3026),
        (-20.0, 829.8818),
        (100.0, 741.1442),
    ],
)
def test_rho_JetA_hand_values(t_C: float, rho_expected: float) -> None:
    assert rho_JetA(t_C + T0) == pytest.approx(rho_expected, abs=1e-3)


def test_rho_JetA_slope_matches_TS1_within_3_percent() -> None:
    # Two independent kerosene sources (ASTM D1250 jet group, Dubovkin TS-1) must agree on the
    # thermal expansion: −0.7395 vs −0.72 kg/m³/K.
    slope = (rho_JetA(40.0 + T0) - rho_JetA(0.0 + T0)) / 40.0
    assert slope == pytest.approx(-0.7395, abs=1e-4)
    assert slope == pytest.approx(-0.72, rel=0.03)


@pytest.mark.parametrize(("t_C", "mu_mPas"), [(0.0, 1.59), (20.0, 1.10), (60.0, 0.60)])
def test_mu_RP3_Andrade_anchor_values(t_C: float, mu_mPas: float) -> None:
    assert mu_RP3_Andrade(t_C + T0) == pytest.approx(mu_mPas * MPAS, rel=0.02)


def test_RP3_Andrade_and_TS1_models_agree_within_15_percent() -> None:
    # Both describe RP-3 kerosene; theirs is the spread between sources (5–12 %).
    T = _grid(-20.0, 60.0)
    ratio = mu_RP3_Andrade(T) / (rho_TS1(T) * nu_TS1(T))
    assert np.all(ratio > 1.0)
    assert np.all(ratio < 1.15)


def test_JetA_viscosity_is_40_percent_above_RP3_at_20C() -> None:
    # the fuels' viscosities differ by about 40 % at 20 °C (docs/explanation/physics.md, "Fuel
    # properties"). By hand: 1.8368 / 1.3096 = 1.4026.
    T = 20.0 + T0
    assert nu_JetA_CRC(T) / nu_TS1(T) == pytest.approx(1.40, rel=0.01)


# --------------------------------------------------------------------------------------------
# JP-8 table


JP8_NODES = [
    (20.0, 1.368),
    (30.0, 1.156),
    (40.0, 0.993),
    (50.0, 0.866),
    (60.0, 0.763),
    (80.0, 0.605),
    (100.0, 0.494),
]


@pytest.mark.parametrize(("t_C", "mu_mPas"), JP8_NODES)
def test_mu_JP8_table_reproduces_nodes(t_C: float, mu_mPas: float) -> None:
    assert mu_JP8_table(t_C + T0) == pytest.approx(mu_mPas * MPAS, rel=1e-12)


def test_mu_JP8_table_is_Andrade_between_nodes() -> None:
    # ln μ linear in 1/T: at the harmonic mean of two node temperatures, μ is the geometric mean
    # of the node viscosities. 60 and 80 °C: sqrt(0.763·0.605) = 0.67942 mPa·s.
    T1, T2 = 60.0 + T0, 80.0 + T0
    T_mid = 2.0 / (1.0 / T1 + 1.0 / T2)
    assert mu_JP8_table(T_mid) == pytest.approx(np.sqrt(0.763 * 0.605) * MPAS, rel=1e-12)


def test_mu_JP8_table_interpolates_monotonically() -> None:
    T = _grid(20.0, 100.0, 801)
    mu = mu_JP8_table(T)
    assert np.all(np.diff(mu) < 0.0)
    assert mu[0] == pytest.approx(1.368 * MPAS, rel=1e-12)
    assert mu[-1] == pytest.approx(0.494 * MPAS, rel=1e-12)


# --------------------------------------------------------------------------------------------
# physics over each range


@pytest.mark.parametrize(("name", "func", "t_range"), CORRELATIONS, ids=CORR_IDS)
def test_property_decreases_with_temperature(
    name: str, func: Callable[..., Any], t_range: tuple[float, float]
) -> None:
    # Liquids expand and thin as they warm: both density and viscosity fall over the range.
    values = func(_grid(*t_range))
    assert isinstance(values, np.ndarray)
    assert np.all(np.isfinite(values))
    assert np.all(values > 0.0)
    assert np.all(np.diff(values) < 0.0), name


@pytest.mark.parametrize("fuel_name", list(FUELS))
def test_fuel_mu_equals_rho_times_nu(fuel_name: str) -> None:
    fuel = FUELS[fuel_name]
    T = np.linspace(fuel.T_min, fuel.T_max, 50)
    np.testing.assert_allclose(fuel.mu(T), fuel.rho(T) * fuel.nu(T), rtol=1e-12)


@pytest.mark.parametrize("fuel_name", list(FUELS))
def test_fuel_properties_decrease_and_stay_kerosene_like(fuel_name: str) -> None:
    # Over each fuel's range: ρ between 700 and 850 kg/m³ (kerosene, spec band 775–840 at 15 °C
    # widened by the thermal expansion), ν between 0.5 and 15 mm²/s, both falling with T.
    fuel = FUELS[fuel_name]
    T = np.linspace(fuel.T_min, fuel.T_max, 101)
    rho, nu, mu = fuel.rho(T), fuel.nu(T), fuel.mu(T)
    for values in (rho, nu, mu):
        assert np.all(np.diff(values) < 0.0)
    assert np.all((rho > 700.0) & (rho < 850.0))
    assert np.all((nu > 0.5 * MM2S) & (nu < 15.0 * MM2S))


def test_RP3_default_meets_GB6537_specification() -> None:
    rp3 = get_fuel(DEFAULT_FUEL)
    assert rp3.nu(20.0 + T0) >= 1.25 * MM2S
    assert rp3.nu(-20.0 + T0) <= 8.0 * MM2S
    assert 775.0 <= rp3.rho(20.0 + T0) <= 830.0


def test_JetA_meets_ASTM_D1655_viscosity_limit() -> None:
    # ASTM D1655: ν(−20 °C) ≤ 8.0 mm²/s; the fit gives 5.76 mm²/s.
    assert nu_JetA_CRC(-20.0 + T0) <= 8.0 * MM2S


def test_RP3_dynamic_viscosity_is_rho_times_nu_by_hand() -> None:
    # 779.6 kg/m³ · 1.3096e-6 m²/s = (1013.48 + 7.48416)e-6 = 1.02096416e-3 Pa·s
    assert get_fuel("RP-3").mu(20.0 + T0) == pytest.approx(1.02096416e-3, rel=1e-9)


# --------------------------------------------------------------------------------------------
# ranges and extrapolation


@pytest.mark.parametrize(("name", "func", "t_range"), CORRELATIONS, ids=CORR_IDS)
@pytest.mark.parametrize("side", ["below", "above"])
def test_out_of_range_raises_with_range_in_message(
    name: str, func: Callable[..., Any], t_range: tuple[float, float], side: str
) -> None:
    t_lo, t_hi = t_range
    t_bad = t_lo - 5.0 if side == "below" else t_hi + 5.0
    with pytest.raises(OutOfRangeError) as excinfo:
        func(t_bad + T0)
    message = str(excinfo.value)
    assert "\n" not in message
    assert f"{t_lo:g} to {t_hi:g} °C" in message
    assert f"{t_bad:.2f} °C" in message
    assert "allow_extrapolation=True" in message


@pytest.mark.parametrize(("name", "func", "t_range"), CORRELATIONS, ids=CORR_IDS)
def test_range_ends_are_inside(
    name: str, func: Callable[..., Any], t_range: tuple[float, float]
) -> None:
    values = func(np.array(t_range) + T0)
    assert np.all(np.isfinite(values))
    assert np.all(values > 0.0)


@pytest.mark.parametrize(("name", "func", "t_range"), CORRELATIONS, ids=CORR_IDS)
def test_allow_extrapolation_returns_finite_positive_value(
    name: str, func: Callable[..., Any], t_range: tuple[float, float]
) -> None:
    for t_C in (t_range[0] - 5.0, t_range[1] + 5.0):
        value = func(t_C + T0, allow_extrapolation=True)
        assert isinstance(value, float)
        assert np.isfinite(value)
        assert value > 0.0


def test_array_with_one_bad_value_is_refused() -> None:
    T = np.array([0.0, 20.0, 70.0]) + T0
    with pytest.raises(OutOfRangeError, match=r"70\.00 °C"):
        nu_TS1(T)


@pytest.mark.parametrize("T_bad", [-20.0, 0.0, float("nan"), float("inf")])
def test_non_absolute_temperature_is_refused_even_when_extrapolating(T_bad: float) -> None:
    # A Celsius value passed as kelvin, zero or NaN is a bug, not an extrapolation.
    with pytest.raises(OutOfRangeError, match="kelvin"):
        mu_RP3_Andrade(T_bad, allow_extrapolation=True)


def test_fuel_range_is_intersection_of_its_correlations() -> None:
    assert FUELS["RP-3"].T_min == pytest.approx(-20.0 + T0)
    assert FUELS["RP-3"].T_max == pytest.approx(60.0 + T0)
    # Jet A: ν fit −40…100 °C ∩ density −40…100 °C; JP-8: table 20…100 °C ∩ density.
    assert FUELS["Jet A"].T_min == pytest.approx(-40.0 + T0)
    assert FUELS["Jet A"].T_max == pytest.approx(100.0 + T0)
    assert FUELS["JP-8"].T_min == pytest.approx(20.0 + T0)
    assert FUELS["JP-8"].T_max == pytest.approx(100.0 + T0)


def test_fuel_method_refuses_outside_its_range_naming_the_fuel() -> None:
    with pytest.raises(OutOfRangeError, match=r"JP-8 kinematic viscosity.*20 to 100 °C"):
        get_fuel("JP-8").nu(10.0 + T0)
    assert np.isfinite(get_fuel("JP-8").nu(10.0 + T0, allow_extrapolation=True))


# --------------------------------------------------------------------------------------------
# shapes


@pytest.mark.parametrize(("name", "func", "t_range"), CORRELATIONS, ids=CORR_IDS)
def test_array_input_keeps_shape_and_scalar_gives_float(
    name: str, func: Callable[..., Any], t_range: tuple[float, float]
) -> None:
    T = np.linspace(*t_range, 6).reshape(2, 3) + T0
    values = func(T)
    assert isinstance(values, np.ndarray)
    assert values.shape == (2, 3)
    scalar = func(float(T[1, 2]))
    assert isinstance(scalar, float)
    assert scalar == pytest.approx(values[1, 2], rel=1e-15)


def test_fuel_methods_keep_array_shape() -> None:
    fuel = get_fuel("Jet A")
    T = np.full((3, 1), 20.0 + T0)
    for method in (fuel.rho, fuel.mu, fuel.nu):
        assert method(T).shape == (3, 1)


# --------------------------------------------------------------------------------------------
# registry


@pytest.mark.parametrize(
    ("alias", "name"),
    [
        ("rp3", "RP-3"),
        ("RP-3", "RP-3"),
        ("rp 3", "RP-3"),
        ("jet-a", "Jet A"),
        ("Jet A", "Jet A"),
        ("JETA", "Jet A"),
        ("jp8", "JP-8"),
    ],
)
def test_get_fuel_aliases(alias: str, name: str) -> None:
    assert get_fuel(alias) is FUELS[name]


def test_get_fuel_unknown_name_lists_known_names() -> None:
    with pytest.raises(FuelidError) as excinfo:
        get_fuel("Jet B")
    message = str(excinfo.value)
    assert "Jet B" in message
    for name in ("RP-3", "Jet A", "JP-8"):
        assert name in message


def test_list_fuels_starts_with_the_default() -> None:
    names = list_fuels()
    assert names[0] == DEFAULT_FUEL == "RP-3"
    assert set(names) == set(FUELS)
    assert "Jet A" in names


def test_default_fuel_uses_the_TS1_correlations() -> None:
    T = _grid(-20.0, 60.0, 9)
    rp3 = get_fuel(DEFAULT_FUEL)
    np.testing.assert_array_equal(rp3.rho(T), rho_TS1(T))
    np.testing.assert_array_equal(rp3.nu(T), nu_TS1(T))


def test_fuel_needs_exactly_one_viscosity_source() -> None:
    with pytest.raises(FuelidError, match="exactly one"):
        Fuel(name="x", T_min=260.0, T_max=300.0, reference="", rho_correlation=rho_TS1)
    with pytest.raises(FuelidError, match="T_min < T_max"):
        Fuel(
            name="x",
            T_min=300.0,
            T_max=260.0,
            reference="",
            rho_correlation=rho_TS1,
            nu_correlation=nu_TS1,
        )


# --------------------------------------------------------------------------------------------
# fuel_properties


def test_fuel_properties_default_is_RP3_hand_values() -> None:
    props = fuel_properties(20.0 + T0)
    assert isinstance(props, FuelProperties)
    assert props.fuel == "RP-3"
    assert abs(props.T - 293.15) < 1e-9
    assert props.rho == pytest.approx(779.6, abs=1e-9)
    assert props.nu == pytest.approx(1.3096 * MM2S, rel=1e-9)
    assert props.mu == pytest.approx(props.rho * props.nu, rel=1e-12)
    with pytest.raises(dataclasses.FrozenInstanceError):
        props.rho = 800.0  # type: ignore[misc]


def test_fuel_properties_accepts_alias_and_fuel_object() -> None:
    by_alias = fuel_properties(20.0 + T0, "jet-a")
    by_object = fuel_properties(20.0 + T0, FUELS["Jet A"])
    assert by_alias == by_object
    assert by_alias.nu == pytest.approx(1.8368 * MM2S, abs=1e-4 * MM2S)
    assert by_alias.rho == pytest.approx(800.3026, abs=1e-3)


def test_fuel_properties_refuses_out_of_range_and_arrays() -> None:
    with pytest.raises(OutOfRangeError, match="-20 to 60 °C"):
        fuel_properties(-30.0 + T0)
    props = fuel_properties(-30.0 + T0, allow_extrapolation=True)
    assert np.isfinite(props.mu)
    assert props.mu > fuel_properties(-20.0 + T0).mu  # colder is more viscous
    with pytest.raises(FuelidError, match="single temperature"):
        fuel_properties(np.array([290.0, 300.0]))  # type: ignore[arg-type]
