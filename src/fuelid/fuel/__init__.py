"""Kerosene properties against temperature: density, dynamic and kinematic viscosity.

The flow-loop model needs three fuel properties, all functions of the fuel temperature: the
density ρ (line inertance, Darcy–Weisbach pressure drop, nozzle), the dynamic viscosity μ
(laminar pump leakage C_p ∝ 1/μ, Reynolds number) and the kinematic viscosity ν = μ/ρ. This
module holds

* the published correlations, one small pure function each, SI in and out (temperature in K,
  density in kg/m^3, μ in Pa·s, ν in m^2/s), vectorised over numpy arrays:
  :func:`rho_TS1`, :func:`nu_TS1` (TS-1, Dubovkin), :func:`nu_JetA_CRC` (Jet A, CRC handbook
  fit), :func:`rho_JetA` (Jet A, linearised ASTM D1250 expansion), :func:`mu_JP8_table`
  (JP-8 table, Andrade interpolation) and :func:`mu_RP3_Andrade` (RP-3, two-parameter Andrade);
* a registry of fuels (:class:`Fuel`, :data:`FUELS`, :func:`get_fuel`, :func:`list_fuels`) that
  pairs a density with a viscosity correlation over the intersection of their ranges, and keeps
  μ = ρ·ν exact;
* :func:`fuel_properties`, the one-call state of a fuel at one temperature.

Import every name from here (the correlations are implemented in ``fuel/_correlations.py``,
the registry in ``fuel/_registry.py``).

Every correlation has a documented validity range and refuses to extrapolate silently: outside it
raises :class:`~fuelid.errors.OutOfRangeError` unless ``allow_extrapolation=True`` is passed.

RP-3 is the default fuel (:data:`DEFAULT_FUEL`). It is the kerosene the source article's wind
tunnel burns; it is close to TS-1 and Jet A-1, so it uses the TS-1 (Dubovkin) correlations. The
choice matters: at 20 °C the Jet A fit gives a kinematic viscosity 40 % above the TS-1 one, and the
viscosity sets the pump leakage and so the loop gain K(T) (docs/explanation/physics.md, "Fuel
properties").

Sources
-------
* TS-1: Dubovkin N.F. et al., *Physicochemical and operational properties of jet fuels*
  (handbook, in Russian), Moscow: Khimiya, 1985.
* Jet A viscosity: curve fit of the Jet A data of the CRC *Handbook of Aviation Fuel
  Properties*, CRC report 663, 3rd ed., 2004 (AFRL-PR-WP-TR-2004-2127).
* Jet A density: typical 804 kg/m^3 at 15 °C (inside the ASTM D1655 limits 775–840 kg/m^3) with
  the jet-fuel thermal expansion coefficient of ASTM D1250 / API MPMS 11.1 (Table 54B).
* JP-8 dynamic viscosity table (tabulated JP-8 data, 20–100 °C) and the RP-3 Andrade fit
  μ ≈ 7.05e-6·exp(1480/T): the values listed in docs/explanation/physics.md, "Fuel properties".
* RP-3 specification: GB 6537 (No. 3 jet fuel).
"""

from fuelid.fuel._correlations import (
    mu_JP8_table,
    mu_RP3_Andrade,
    nu_JetA_CRC,
    nu_TS1,
    rho_JetA,
    rho_TS1,
)
from fuelid.fuel._registry import (
    DEFAULT_FUEL,
    FUELS,
    Correlation,
    Fuel,
    FuelProperties,
    fuel_properties,
    get_fuel,
    list_fuels,
)

__all__ = [
    "DEFAULT_FUEL",
    "FUELS",
    "Correlation",
    "Fuel",
    "FuelProperties",
    "fuel_properties",
    "get_fuel",
    "list_fuels",
    "mu_JP8_table",
    "mu_RP3_Andrade",
    "nu_JetA_CRC",
    "nu_TS1",
    "rho_JetA",
    "rho_TS1",
]
