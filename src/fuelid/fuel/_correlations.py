"""The published fuel-property correlations: one small pure function each, SI in and out.

Temperature in K, density in kg/m^3, μ in Pa·s, ν in m^2/s, vectorised over numpy arrays. Each
has a documented validity range and raises :class:`~fuelid.errors.OutOfRangeError` outside it
unless ``allow_extrapolation=True``. The sources are listed in :mod:`fuelid.fuel`.
"""

from __future__ import annotations

from typing import TypeVar, overload

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import OutOfRangeError
from fuelid.units import T0

__all__ = [
    "mu_JP8_table",
    "mu_RP3_Andrade",
    "nu_JetA_CRC",
    "nu_TS1",
    "rho_JetA",
    "rho_TS1",
]

_FloatOrArray = TypeVar("_FloatOrArray", float, NDArray[np.float64])

# Validity ranges in °C, (low, high).
_TS1_RANGE_C = (-20.0, 60.0)
_JETA_NU_RANGE_C = (-40.0, 100.0)
_JETA_RHO_RANGE_C = (-40.0, 100.0)
_JP8_RANGE_C = (20.0, 100.0)
_RP3_ANDRADE_RANGE_C = (-20.0, 60.0)

# Tolerance on the range check, so that t + T0 round-off never trips it [K].
_RANGE_TOL_K = 1e-9

# Jet A density: typical density at 15 °C [kg/m^3] and the ASTM D1250 (Table 54B) jet-fuel group
# constant K0 [(kg/m^3)^2/°C], alpha_15 = K0/rho_15^2 (K1 = 0 for that group).
_RHO15_JETA = 804.0
_K0_JET = 594.5418

# JP-8 dynamic viscosity table: temperature [°C] and viscosity [mPa·s].
_JP8_T_C = np.array([20.0, 30.0, 40.0, 50.0, 60.0, 80.0, 100.0])
_JP8_MU_MPAS = np.array([1.368, 1.156, 0.993, 0.866, 0.763, 0.605, 0.494])


# --------------------------------------------------------------------------------------------
# helpers


def _as_kelvin_array(T: float | NDArray[np.float64], quantity: str) -> NDArray[np.float64]:
    """Return T as a float array, refusing values that are not absolute temperatures."""
    T_arr = np.asarray(T, dtype=np.float64)
    bad = ~(np.isfinite(T_arr) & (T_arr > 0.0))
    if np.any(bad):
        T_bad = float(T_arr[bad].flat[0])
        raise OutOfRangeError(
            f"{quantity}: T = {T_bad!r} K is not an absolute temperature "
            "(temperatures are in kelvin, T = t + 273.15)"
        )
    return T_arr


def _check_range(
    T_arr: NDArray[np.float64],
    t_range_C: tuple[float, float],
    quantity: str,
    allow_extrapolation: bool,
) -> None:
    """Raise OutOfRangeError when a temperature lies outside ``t_range_C`` (in °C)."""
    if allow_extrapolation:
        return
    t_lo, t_hi = t_range_C
    outside = (t_lo + T0 - T_arr > _RANGE_TOL_K) | (T_arr - (t_hi + T0) > _RANGE_TOL_K)
    if np.any(outside):
        t_bad = float(T_arr[outside].flat[0]) - T0
        raise OutOfRangeError(
            f"{quantity}: fuel temperature {t_bad:.2f} °C is outside the valid range "
            f"{t_lo:g} to {t_hi:g} °C; pass allow_extrapolation=True to extrapolate"
        )


@overload
def _like(T: float, value: NDArray[np.float64]) -> float: ...


@overload
def _like(T: NDArray[np.float64], value: NDArray[np.float64]) -> NDArray[np.float64]: ...


def _like(
    T: float | NDArray[np.float64], value: NDArray[np.float64]
) -> float | NDArray[np.float64]:
    """Return ``value`` as a float for scalar input, as an array of T's shape otherwise."""
    if isinstance(T, np.ndarray) or np.ndim(T) > 0:
        return np.asarray(value, dtype=np.float64)
    return float(value)


# --------------------------------------------------------------------------------------------
# correlations


def rho_TS1(T: _FloatOrArray, *, allow_extrapolation: bool = False) -> _FloatOrArray:
    r"""Return the density of TS-1 kerosene (Dubovkin correlation).

    .. math::
        \rho = 794 - 0.72\,t, \qquad t = T - 273.15

    with ρ in kg/m^3 and t in °C.

    Parameters
    ----------
    T : float or ndarray
        Fuel temperature [K].
    allow_extrapolation : bool, optional
        Evaluate outside the validity range instead of raising. Default False.

    Returns
    -------
    rho : float or ndarray
        Density [kg/m^3]; a float for a scalar T, an array of T's shape otherwise.

    Raises
    ------
    OutOfRangeError
        If T is outside −20…60 °C and ``allow_extrapolation`` is False, or is not a positive
        finite kelvin temperature.

    Notes
    -----
    Valid for −20 °C to 60 °C (the span quoted with the correlation). TS-1 is the Russian
    GOST 10227 kerosene; Chinese RP-3 and Jet A-1 are close to it. ρ(20 °C) = 779.6 kg/m^3 lies
    inside the RP-3 specification 775–830 kg/m^3.

    References
    ----------
    .. [1] Dubovkin N.F., Malanicheva V.G., Massur Yu.P., Fedorov E.P., *Physicochemical and
       operational properties of jet fuels* (handbook, in Russian). Moscow: Khimiya, 1985;
       correlation as quoted in fuelid's theory notes, §2.

    Examples
    --------
    >>> round(rho_TS1(20 + 273.15), 2)
    779.6
    """
    quantity = "TS-1 density"
    T_arr = _as_kelvin_array(T, quantity)
    _check_range(T_arr, _TS1_RANGE_C, quantity, allow_extrapolation)
    t = T_arr - T0
    return _like(T, 794.0 - 0.72 * t)


def nu_TS1(T: _FloatOrArray, *, allow_extrapolation: bool = False) -> _FloatOrArray:
    r"""Return the kinematic viscosity of TS-1 kerosene (Dubovkin correlation).

    .. math::
        \nu\,[\mathrm{mm^2/s}] = 10^{-8} t^4 - 4\cdot10^{-6} t^3 + 5\cdot10^{-4} t^2
        - 0.0374\,t + 1.888, \qquad t = T - 273.15

    returned in m^2/s (1 mm^2/s = 1e-6 m^2/s).

    Parameters
    ----------
    T : float or ndarray
        Fuel temperature [K].
    allow_extrapolation : bool, optional
        Evaluate outside the validity range instead of raising. Default False.

    Returns
    -------
    nu : float or ndarray
        Kinematic viscosity [m^2/s]; a float for a scalar T, an array of T's shape otherwise.

    Raises
    ------
    OutOfRangeError
        If T is outside −20…60 °C and ``allow_extrapolation`` is False, or is not a positive
        finite kelvin temperature.

    Notes
    -----
    Valid for −20 °C to 60 °C. A quartic is a fit, not a law: it decreases monotonically over
    its range but must not be trusted outside it. ν(20 °C) = 1.3096 mm^2/s and
    ν(−20 °C) = 2.8696 mm^2/s satisfy the RP-3 specification (≥ 1.25 and ≤ 8.0 mm^2/s).

    References
    ----------
    .. [1] Dubovkin N.F., Malanicheva V.G., Massur Yu.P., Fedorov E.P., *Physicochemical and
       operational properties of jet fuels* (handbook, in Russian). Moscow: Khimiya, 1985;
       correlation as quoted in fuelid's theory notes, §2.

    Examples
    --------
    >>> round(nu_TS1(20 + 273.15) * 1e6, 4)
    1.3096
    >>> import numpy as np
    >>> (nu_TS1(np.array([-20.0, 60.0]) + 273.15) * 1e6).round(4).tolist()
    [2.8696, 0.7096]
    """
    quantity = "TS-1 kinematic viscosity"
    T_arr = _as_kelvin_array(T, quantity)
    _check_range(T_arr, _TS1_RANGE_C, quantity, allow_extrapolation)
    t = T_arr - T0
    nu_mm2s = (((1e-8 * t - 4e-6) * t + 5e-4) * t - 0.0374) * t + 1.888
    return _like(T, nu_mm2s * 1e-6)


def nu_JetA_CRC(T: _FloatOrArray, *, allow_extrapolation: bool = False) -> _FloatOrArray:
    r"""Return the kinematic viscosity of Jet A (fit to the CRC handbook data).

    .. math::
        \nu\,[\mathrm{mm^2/s}] = 225697.23\,e^{-0.042631022\,T} - 0.0030984177\,T + 1.9017552

    with T in K; returned in m^2/s.

    Parameters
    ----------
    T : float or ndarray
        Fuel temperature [K].
    allow_extrapolation : bool, optional
        Evaluate outside the validity range instead of raising. Default False.

    Returns
    -------
    nu : float or ndarray
        Kinematic viscosity [m^2/s]; a float for a scalar T, an array of T's shape otherwise.

    Raises
    ------
    OutOfRangeError
        If T is outside −40…100 °C and ``allow_extrapolation`` is False, or is not a positive
        finite kelvin temperature.

    Notes
    -----
    The fit comes without a stated range or data span, so the range −40 °C to 100 °C is
    fuelid's choice: −40 °C is the Jet A freezing-point limit of ASTM D1655 (below it wax can
    separate and a viscosity curve of the liquid means little); 100 °C covers any fuel loop with
    margin, and over 20–100 °C the fit stays within 17 % of the independent JP-8 table
    (:func:`mu_JP8_table` divided by :func:`rho_JetA`), the gap growing with temperature. Beyond,
    the linear term takes over and the fit falls towards zero near 340 °C, which no kerosene
    does. Checks: ν(−20 °C) = 5.76 mm^2/s (ASTM D1655 maximum 8.0 mm^2/s); at 20 °C the fit is
    1.40 times the TS-1 value, the 40 % spread between these fuels at 20 °C.

    References
    ----------
    .. [1] Coordinating Research Council, *Handbook of Aviation Fuel Properties*, CRC report
       No. 663, 3rd ed., 2004 (AFRL-PR-WP-TR-2004-2127). Curve fit of its Jet A viscosity as
       quoted in fuelid's theory notes, §2 (the same coefficients appear in open-source aircraft
       thermal-management code that credits this handbook).
    .. [2] ASTM D1655, *Standard Specification for Aviation Turbine Fuels*.

    Examples
    --------
    >>> round(nu_JetA_CRC(20 + 273.15) * 1e6, 4)
    1.8368
    """
    quantity = "Jet A kinematic viscosity (CRC fit)"
    T_arr = _as_kelvin_array(T, quantity)
    _check_range(T_arr, _JETA_NU_RANGE_C, quantity, allow_extrapolation)
    nu_mm2s = 225697.23 * np.exp(-0.042631022 * T_arr) - 0.0030984177 * T_arr + 1.9017552
    return _like(T, nu_mm2s * 1e-6)


def rho_JetA(T: _FloatOrArray, *, allow_extrapolation: bool = False) -> _FloatOrArray:
    r"""Return the density of a typical Jet A (linearised ASTM D1250 thermal expansion).

    .. math::
        \rho = \rho_{15}\,[1 - \alpha_{15}\,(t - 15)], \qquad
        \alpha_{15} = K_0/\rho_{15}^2, \qquad t = T - 273.15

    with ρ_15 = 804 kg/m^3 and K_0 = 594.5418 (kg/m^3)^2/°C, so α_15 = 9.1975e-4 1/°C and
    dρ/dT = −0.7395 kg/m^3/K.

    Parameters
    ----------
    T : float or ndarray
        Fuel temperature [K].
    allow_extrapolation : bool, optional
        Evaluate outside the validity range instead of raising. Default False.

    Returns
    -------
    rho : float or ndarray
        Density [kg/m^3]; a float for a scalar T, an array of T's shape otherwise.

    Raises
    ------
    OutOfRangeError
        If T is outside −40…100 °C and ``allow_extrapolation`` is False, or is not a positive
        finite kelvin temperature.

    Notes
    -----
    This is a linear fit built by fuelid, not a published Jet A correlation: a typical density
    at 15 °C (804 kg/m^3, the value commonly quoted for Jet A/Jet A-1, inside the ASTM D1655
    limits 775–840 kg/m^3) combined with the thermal expansion coefficient that ASTM D1250 /
    API MPMS 11.1 (Table 54B, product group "jet fuels", K_1 = 0) assigns to that density. The
    standard's volume correction exp(−αΔt(1 + 0.8αΔt)) is linearised; the linearisation error is
    below 0.2 % over the range. The slope agrees with TS-1's 0.72 kg/m^3/K within 3 %. A real
    batch differs by up to ±4 % in level (the specification band): use the batch's certificate
    density when it matters.

    Range −40 °C (Jet A freezing-point limit, ASTM D1655) to 100 °C (the span of the other Jet A
    correlation, :func:`nu_JetA_CRC`).

    References
    ----------
    .. [1] ASTM D1250 / API MPMS Chapter 11.1, *Petroleum Measurement Tables*, Table 54B
       (generalized refined products, jet fuel group).
    .. [2] ASTM D1655, *Standard Specification for Aviation Turbine Fuels* (density at 15 °C,
       775–840 kg/m^3).
    .. [3] Coordinating Research Council, *Handbook of Aviation Fuel Properties*, CRC report
       No. 663, 2004: density of Jet A falls roughly linearly with temperature.

    Examples
    --------
    >>> round(rho_JetA(15 + 273.15), 2)
    804.0
    >>> round(rho_JetA(20 + 273.15), 2)
    800.3
    """
    quantity = "Jet A density"
    T_arr = _as_kelvin_array(T, quantity)
    _check_range(T_arr, _JETA_RHO_RANGE_C, quantity, allow_extrapolation)
    alpha_15 = _K0_JET / _RHO15_JETA**2
    t = T_arr - T0
    return _like(T, _RHO15_JETA * (1.0 - alpha_15 * (t - 15.0)))


def mu_JP8_table(T: _FloatOrArray, *, allow_extrapolation: bool = False) -> _FloatOrArray:
    r"""Return the dynamic viscosity of JP-8 interpolated from a table (Andrade-style).

    Table: 20 °C 1.368, 30 °C 1.156, 40 °C 0.993, 50 °C 0.866, 60 °C 0.763, 80 °C 0.605,
    100 °C 0.494 mPa·s. Between nodes i and i+1, ln μ is linear in 1/T:

    .. math::
        \ln\mu = \ln\mu_i + (\ln\mu_{i+1} - \ln\mu_i)\,
        \frac{1/T - 1/T_i}{1/T_{i+1} - 1/T_i}

    which is exact for an Andrade law μ = A·exp(B/T) and reproduces every node. Extrapolation
    (only with ``allow_extrapolation=True``) continues the end segment.

    Parameters
    ----------
    T : float or ndarray
        Fuel temperature [K].
    allow_extrapolation : bool, optional
        Evaluate outside the validity range instead of raising. Default False.

    Returns
    -------
    mu : float or ndarray
        Dynamic viscosity [Pa·s]; a float for a scalar T, an array of T's shape otherwise.

    Raises
    ------
    OutOfRangeError
        If T is outside 20…100 °C (the table's span) and ``allow_extrapolation`` is False, or
        is not a positive finite kelvin temperature.

    Notes
    -----
    Valid over the span of the table, 20 °C to 100 °C. The interpolant is monotonic because the
    nodes are.

    References
    ----------
    .. [1] JP-8 viscosity table as given in fuelid's theory notes, §2 (the measuring
       laboratory and sample are not recorded there).

    Examples
    --------
    >>> round(mu_JP8_table(40 + 273.15) * 1e3, 3)
    0.993
    """
    quantity = "JP-8 dynamic viscosity (table)"
    T_arr = _as_kelvin_array(T, quantity)
    _check_range(T_arr, _JP8_RANGE_C, quantity, allow_extrapolation)
    # 1/T increases as T decreases: reverse so that the abscissa is increasing.
    x_nodes = 1.0 / (_JP8_T_C[::-1] + T0)
    y_nodes = np.log(_JP8_MU_MPAS[::-1] * 1e-3)
    x = 1.0 / T_arr
    i = np.clip(np.searchsorted(x_nodes, x) - 1, 0, x_nodes.size - 2)
    frac = (x - x_nodes[i]) / (x_nodes[i + 1] - x_nodes[i])
    return _like(T, np.exp(y_nodes[i] + frac * (y_nodes[i + 1] - y_nodes[i])))


def mu_RP3_Andrade(T: _FloatOrArray, *, allow_extrapolation: bool = False) -> _FloatOrArray:
    r"""Return the dynamic viscosity of RP-3 kerosene from a two-parameter Andrade law.

    .. math::
        \mu = 7.05\cdot10^{-6}\,\exp(1480/T)

    with T in K and μ in Pa·s: 1.59 / 1.10 / 0.60 mPa·s at 0 / 20 / 60 °C.

    Parameters
    ----------
    T : float or ndarray
        Fuel temperature [K].
    allow_extrapolation : bool, optional
        Evaluate outside the validity range instead of raising. Default False.

    Returns
    -------
    mu : float or ndarray
        Dynamic viscosity [Pa·s]; a float for a scalar T, an array of T's shape otherwise.

    Raises
    ------
    OutOfRangeError
        If T is outside −20…60 °C and ``allow_extrapolation`` is False, or is not a positive
        finite kelvin temperature.

    Notes
    -----
    Range −20 °C to 60 °C, fuelid's choice: the law is anchored at 0, 20 and 60 °C; at −20 °C it
    gives 2.44 mPa·s, within 5 % of the TS-1 correlations (ρ·ν = 2.32 mPa·s), and
    ν ≈ 3.0 mm^2/s, far inside the RP-3 limit ν(−20 °C) ≤ 8.0 mm^2/s. Below −20 °C there is
    nothing to check it against, and a single activation energy underestimates the steep rise of
    viscosity towards the freezing point. Over the range it lies 5–12 % above the TS-1 ρ·ν, the
    spread between RP-3 batches and sources. It is a smooth alternative to the default RP-3
    model (:data:`FUELS` ``["RP-3"]`` uses TS-1 ρ and ν), not a replacement.

    References
    ----------
    .. [1] Andrade-form fit for RP-3 as given in fuelid's theory notes, §2.
    .. [2] GB 6537, *No. 3 jet fuel* (RP-3 specification): ν(20 °C) ≥ 1.25 mm^2/s,
       ν(−20 °C) ≤ 8.0 mm^2/s, ρ(20 °C) 775–830 kg/m^3.

    Examples
    --------
    >>> round(mu_RP3_Andrade(20 + 273.15) * 1e3, 2)
    1.1
    """
    quantity = "RP-3 dynamic viscosity (Andrade)"
    T_arr = _as_kelvin_array(T, quantity)
    _check_range(T_arr, _RP3_ANDRADE_RANGE_C, quantity, allow_extrapolation)
    return _like(T, 7.05e-6 * np.exp(1480.0 / T_arr))
