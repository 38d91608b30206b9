"""The registry of fuels and the one-call state of a fuel at one temperature.

A :class:`Fuel` pairs a density with a viscosity correlation (:mod:`fuelid.fuel._correlations`)
over the intersection of their ranges and keeps μ = ρ·ν exact; :data:`FUELS` holds the
registered ones, :func:`get_fuel` finds one by name or alias, and :func:`fuel_properties` gives
ρ, μ and ν of a fuel at one temperature.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol, cast

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import FuelidError
from fuelid.fuel._correlations import (
    _JETA_NU_RANGE_C,
    _JETA_RHO_RANGE_C,
    _JP8_RANGE_C,
    _TS1_RANGE_C,
    _as_kelvin_array,
    _check_range,
    _FloatOrArray,
    _like,
    mu_JP8_table,
    nu_JetA_CRC,
    nu_TS1,
    rho_JetA,
    rho_TS1,
)
from fuelid.units import T0

__all__ = [
    "DEFAULT_FUEL",
    "FUELS",
    "Correlation",
    "Fuel",
    "FuelProperties",
    "fuel_properties",
    "get_fuel",
    "list_fuels",
]


class Correlation(Protocol):
    """A fuel-property correlation: temperature array [K] in, property array (SI) out."""

    def __call__(
        self, T: NDArray[np.float64], *, allow_extrapolation: bool = False
    ) -> NDArray[np.float64]:
        """Evaluate the property at the temperatures T [K]."""
        ...


@dataclass(frozen=True)
class Fuel:
    """A fuel: a density correlation and one viscosity correlation over a common range.

    Exactly one of ``nu_correlation`` (the source gives ν) and ``mu_correlation`` (the source
    gives μ) is set; the other viscosity follows from μ = ρ·ν, so the three properties are always
    consistent.

    Parameters
    ----------
    name : str
        Display name, e.g. ``"RP-3"``.
    T_min, T_max : float
        Validity range of the fuel model [K]: the intersection of its correlations' ranges.
    reference : str
        Where the correlations come from, in one or two sentences.
    rho_correlation : Correlation
        Density [kg/m^3] as a function of temperature [K].
    nu_correlation : Correlation or None
        Kinematic viscosity [m^2/s] as a function of temperature [K].
    mu_correlation : Correlation or None
        Dynamic viscosity [Pa·s] as a function of temperature [K].

    Examples
    --------
    >>> fuel = get_fuel("RP-3")
    >>> round(fuel.mu(20 + 273.15) * 1e3, 4)
    1.021
    """

    name: str
    T_min: float
    T_max: float
    reference: str
    rho_correlation: Correlation = field(repr=False, compare=False)
    nu_correlation: Correlation | None = field(default=None, repr=False, compare=False)
    mu_correlation: Correlation | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.T_min) and np.isfinite(self.T_max) and self.T_min < self.T_max):
            raise FuelidError(
                f"fuel {self.name!r}: need finite T_min < T_max, got {self.T_min} K, {self.T_max} K"
            )
        if (self.nu_correlation is None) == (self.mu_correlation is None):
            raise FuelidError(
                f"fuel {self.name!r}: give exactly one of nu_correlation and mu_correlation"
            )

    def _checked(
        self, T: float | NDArray[np.float64], quantity: str, allow_extrapolation: bool
    ) -> NDArray[np.float64]:
        """Return T as an array after checking it against the fuel's range."""
        label = f"{self.name} {quantity}"
        T_arr = _as_kelvin_array(T, label)
        t_range_C = (round(self.T_min - T0, 9), round(self.T_max - T0, 9))
        _check_range(T_arr, t_range_C, label, allow_extrapolation)
        return T_arr

    def rho(self, T: _FloatOrArray, *, allow_extrapolation: bool = False) -> _FloatOrArray:
        """Return the density [kg/m^3] at the fuel temperature T [K].

        Parameters
        ----------
        T : float or ndarray
            Fuel temperature [K].
        allow_extrapolation : bool, optional
            Evaluate outside [T_min, T_max] instead of raising. Default False.

        Returns
        -------
        rho : float or ndarray
            Density [kg/m^3].

        Examples
        --------
        >>> round(get_fuel("Jet A").rho(15 + 273.15), 1)
        804.0
        """
        T_arr = self._checked(T, "density", allow_extrapolation)
        return _like(T, self.rho_correlation(T_arr, allow_extrapolation=allow_extrapolation))

    def nu(self, T: _FloatOrArray, *, allow_extrapolation: bool = False) -> _FloatOrArray:
        """Return the kinematic viscosity [m^2/s] at the fuel temperature T [K].

        ν from the source when it gives ν, μ/ρ otherwise.

        Parameters
        ----------
        T : float or ndarray
            Fuel temperature [K].
        allow_extrapolation : bool, optional
            Evaluate outside [T_min, T_max] instead of raising. Default False.

        Returns
        -------
        nu : float or ndarray
            Kinematic viscosity [m^2/s].

        Examples
        --------
        >>> round(get_fuel("RP-3").nu(20 + 273.15) * 1e6, 4)
        1.3096
        """
        T_arr = self._checked(T, "kinematic viscosity", allow_extrapolation)
        if self.nu_correlation is not None:
            nu = self.nu_correlation(T_arr, allow_extrapolation=allow_extrapolation)
        else:
            mu = cast(Correlation, self.mu_correlation)(
                T_arr, allow_extrapolation=allow_extrapolation
            )
            nu = mu / self.rho_correlation(T_arr, allow_extrapolation=allow_extrapolation)
        return _like(T, nu)

    def mu(self, T: _FloatOrArray, *, allow_extrapolation: bool = False) -> _FloatOrArray:
        """Return the dynamic viscosity [Pa·s] at the fuel temperature T [K].

        μ from the source when it gives μ, ρ·ν otherwise.

        Parameters
        ----------
        T : float or ndarray
            Fuel temperature [K].
        allow_extrapolation : bool, optional
            Evaluate outside [T_min, T_max] instead of raising. Default False.

        Returns
        -------
        mu : float or ndarray
            Dynamic viscosity [Pa·s].

        Examples
        --------
        >>> round(get_fuel("JP-8").mu(20 + 273.15) * 1e3, 3)
        1.368
        """
        T_arr = self._checked(T, "dynamic viscosity", allow_extrapolation)
        if self.mu_correlation is not None:
            mu = self.mu_correlation(T_arr, allow_extrapolation=allow_extrapolation)
        else:
            nu = cast(Correlation, self.nu_correlation)(
                T_arr, allow_extrapolation=allow_extrapolation
            )
            mu = self.rho_correlation(T_arr, allow_extrapolation=allow_extrapolation) * nu
        return _like(T, mu)


FUELS: dict[str, Fuel] = {
    "RP-3": Fuel(
        name="RP-3",
        T_min=_TS1_RANGE_C[0] + T0,
        T_max=_TS1_RANGE_C[1] + T0,
        reference=(
            "TS-1 correlations of Dubovkin et al. (1985) for density and kinematic viscosity; "
            "RP-3 (GB 6537) is close to TS-1 and Jet A-1."
        ),
        rho_correlation=rho_TS1,
        nu_correlation=nu_TS1,
    ),
    "Jet A": Fuel(
        name="Jet A",
        T_min=max(_JETA_NU_RANGE_C[0], _JETA_RHO_RANGE_C[0]) + T0,
        T_max=min(_JETA_NU_RANGE_C[1], _JETA_RHO_RANGE_C[1]) + T0,
        reference=(
            "Kinematic viscosity: fit to the CRC Handbook of Aviation Fuel Properties (CRC 663, "
            "2004); density: 804 kg/m^3 at 15 °C with the ASTM D1250 jet-fuel expansion, "
            "linearised by fuelid."
        ),
        rho_correlation=rho_JetA,
        nu_correlation=nu_JetA_CRC,
    ),
    "JP-8": Fuel(
        name="JP-8",
        T_min=max(_JP8_RANGE_C[0], _JETA_RHO_RANGE_C[0]) + T0,
        T_max=min(_JP8_RANGE_C[1], _JETA_RHO_RANGE_C[1]) + T0,
        reference=(
            "Dynamic viscosity: the tabulated JP-8 data of docs/explanation/physics.md (Andrade "
            "interpolation); density: the Jet A model (JP-8 is Jet A-1 with military "
            "additives, same 775–840 kg/m^3 band), "
            "not the table sample's own density, so ν carries the ±4 % band spread."
        ),
        rho_correlation=rho_JetA,
        mu_correlation=mu_JP8_table,
    ),
}
"""The registered fuels by display name; :func:`get_fuel` resolves aliases."""

DEFAULT_FUEL: str = "RP-3"
"""The default fuel: RP-3, the kerosene of the source article's wind tunnel."""


def _normalise(name: str) -> str:
    """Return ``name`` lower-cased with everything but letters and digits removed."""
    return "".join(ch for ch in name.lower() if ch.isalnum())


_ALIASES: Mapping[str, str] = {_normalise(key): key for key in FUELS}


def list_fuels() -> list[str]:
    """Return the names of the registered fuels, the default first.

    Returns
    -------
    names : list of str
        Display names, keys of :data:`FUELS`.

    Examples
    --------
    >>> list_fuels()
    ['RP-3', 'Jet A', 'JP-8']
    """
    return [DEFAULT_FUEL, *(name for name in FUELS if name != DEFAULT_FUEL)]


def get_fuel(name: str) -> Fuel:
    """Return the registered fuel called ``name``.

    The look-up ignores case, spaces, hyphens and other punctuation: ``"rp3"``, ``"RP-3"`` and
    ``"rp 3"`` all give RP-3; ``"jet-a"``, ``"Jet A"`` and ``"JETA"`` give Jet A.

    Parameters
    ----------
    name : str
        Fuel name or alias.

    Returns
    -------
    fuel : Fuel
        The registered fuel.

    Raises
    ------
    FuelidError
        If no registered fuel matches; the message lists the known names.

    Examples
    --------
    >>> get_fuel("jet-a").name
    'Jet A'
    """
    key = _ALIASES.get(_normalise(name))
    if key is None:
        raise FuelidError(f"unknown fuel {name!r}; known fuels: {', '.join(list_fuels())}")
    return FUELS[key]


@dataclass(frozen=True)
class FuelProperties:
    """The state of a fuel at one temperature.

    Parameters
    ----------
    T : float
        Fuel temperature [K].
    rho : float
        Density [kg/m^3].
    mu : float
        Dynamic viscosity [Pa·s].
    nu : float
        Kinematic viscosity [m^2/s].
    fuel : str
        Name of the fuel.
    """

    T: float
    rho: float
    mu: float
    nu: float
    fuel: str


def fuel_properties(
    T: float, fuel: str | Fuel = DEFAULT_FUEL, *, allow_extrapolation: bool = False
) -> FuelProperties:
    """Return density and viscosities of a fuel at one temperature.

    Parameters
    ----------
    T : float
        Fuel temperature [K].
    fuel : str or Fuel, optional
        A registered fuel name or alias, or a :class:`Fuel`. Default :data:`DEFAULT_FUEL`.
    allow_extrapolation : bool, optional
        Evaluate outside the fuel's validity range instead of raising. Default False.

    Returns
    -------
    props : FuelProperties
        ρ [kg/m^3], μ [Pa·s] and ν [m^2/s], with μ = ρ·ν.

    Raises
    ------
    FuelidError
        If the fuel is unknown or T is not a single number.
    OutOfRangeError
        If T is outside the fuel's range and ``allow_extrapolation`` is False.

    Examples
    --------
    >>> p = fuel_properties(20 + 273.15)
    >>> p.fuel, round(p.rho, 1), round(p.nu * 1e6, 4)
    ('RP-3', 779.6, 1.3096)
    """
    if np.ndim(T) != 0:
        raise FuelidError(
            "fuel_properties takes a single temperature; use Fuel.rho/mu/nu for arrays"
        )
    fuel_obj = fuel if isinstance(fuel, Fuel) else get_fuel(fuel)
    T_K = float(T)
    return FuelProperties(
        T=T_K,
        rho=fuel_obj.rho(T_K, allow_extrapolation=allow_extrapolation),
        mu=fuel_obj.mu(T_K, allow_extrapolation=allow_extrapolation),
        nu=fuel_obj.nu(T_K, allow_extrapolation=allow_extrapolation),
        fuel=fuel_obj.name,
    )
