"""Combustor nozzles: a sharp-edged orifice law (``docs/explanation/physics.md`` §3.6).

All nozzles are lumped into one orifice of the total area A_0 discharging against the combustor's
back pressure. :func:`nozzle_inlet_pressure` and its derivative :func:`orifice_resistance` are the
only place the discharge coefficient, the area and the back pressure enter the plant model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pydantic import Field

from fuelid.plant._pipeline import circle_area
from fuelid.plant._section import Section
from fuelid.units import M_PER_MM, PA_PER_MPA


@dataclass(frozen=True, slots=True)
class NozzleCoefficients:
    """The nozzles' parameters in SI at one fuel density (:meth:`NozzleConfig.coefficients`)."""

    rho: float
    """Fuel density [kg/m³]."""
    Cd: float
    """Discharge coefficient [-]."""
    A0: float
    """Total orifice area [m²]."""
    p_back: float
    """Back pressure downstream of the nozzles (gauge) [Pa]."""


class NozzleConfig(Section):
    """The burner nozzles, lumped into one orifice (TOML section ``[nozzle]``)."""

    count: int = Field(ge=1, le=10_000, description="number of identical nozzles [-]")
    diameter_mm: float = Field(gt=0.0, le=500.0, description="orifice diameter of one nozzle [mm]")
    discharge_coefficient: float = Field(gt=0.0, le=1.0, description="discharge coefficient C_d")
    back_pressure_MPa: float = Field(
        0.0, ge=0.0, description="combustor pressure downstream of the nozzles (gauge) [MPa]"
    )

    @property
    def A0(self) -> float:
        """Total orifice area [m²]: ``count`` circles of ``diameter_mm``."""
        return self.count * circle_area(self.diameter_mm * M_PER_MM)

    @property
    def p_back(self) -> float:
        """Back pressure [Pa]."""
        return self.back_pressure_MPa * PA_PER_MPA

    def coefficients(self, rho: float) -> NozzleCoefficients:
        """The nozzles' parameters in SI for fuel of density ``rho`` [kg/m³]."""
        return NozzleCoefficients(
            rho=rho, Cd=self.discharge_coefficient, A0=self.A0, p_back=self.p_back
        )


def orifice_flow(dp: float, rho: float, Cd: float, A0: float) -> float:
    r"""Flow through an orifice, signed with the pressure difference.

    .. math:: q = C_d A_0 \sqrt{\frac{2\,\Delta p}{\rho}}

    Parameters
    ----------
    dp : float
        Pressure difference across the orifice [Pa].
    rho : float
        Density [kg/m³].
    Cd : float
        Discharge coefficient [-].
    A0 : float
        Orifice area [m²].

    Returns
    -------
    float
        Volume flow [m³/s].

    References
    ----------
    ISO 5167-1:2022, eq. (1) (incompressible form, velocity-of-approach factor folded into C_d).

    Examples
    --------
    1 MPa across 30 mm² with C_d = 0.7, ρ = 800 kg/m³: 0.7·30e-6·50 m³/s = 63 L/min.

    >>> from fuelid.units import LPM_PER_M3S
    >>> round(orifice_flow(1e6, 800.0, 0.7, 30e-6) * LPM_PER_M3S, 6)
    63.0
    """
    return math.copysign(Cd * A0 * math.sqrt(2.0 * abs(dp) / rho), dp)


def orifice_pressure_drop(q: float, rho: float, Cd: float, A0: float) -> float:
    r"""Pressure difference that drives flow ``q`` through an orifice (inverse orifice law).

    .. math:: \Delta p = \frac{\rho}{2}\,\frac{q |q|}{(C_d A_0)^2}

    Parameters
    ----------
    q : float
        Volume flow [m³/s].
    rho : float
        Density [kg/m³].
    Cd : float
        Discharge coefficient [-].
    A0 : float
        Orifice area [m²].

    Returns
    -------
    float
        Δp [Pa].

    References
    ----------
    ISO 5167-1:2022, eq. (1), solved for the pressure difference.

    Examples
    --------
    >>> from fuelid.units import LPM_PER_M3S
    >>> round(orifice_pressure_drop(63.0 / LPM_PER_M3S, 800.0, 0.7, 30e-6))
    1000000
    """
    return 0.5 * rho * q * abs(q) / (Cd * A0) ** 2


def orifice_resistance(q: float, rho: float, Cd: float, A0: float) -> float:
    r"""Linearised (incremental) resistance of an orifice at flow ``q``.

    .. math:: R_N = \frac{d\Delta p}{dq} = \frac{\rho |q|}{(C_d A_0)^2} = \frac{2\,\Delta p^*}{q^*}

    Parameters
    ----------
    q : float
        Operating flow [m³/s].
    rho, Cd, A0 : float
        As in :func:`orifice_pressure_drop`.

    Returns
    -------
    float
        R_N [Pa·s/m³]; also the derivative of :func:`nozzle_inlet_pressure` (the back pressure
        is constant).

    Examples
    --------
    >>> from fuelid.units import LPM_PER_M3S
    >>> q = 63.0 / LPM_PER_M3S
    >>> round(orifice_resistance(q, 800.0, 0.7, 30e-6) * q / 2)
    1000000
    """
    return rho * abs(q) / (Cd * A0) ** 2


def nozzle_inlet_pressure(q: float, rho: float, Cd: float, A0: float, p_back: float) -> float:
    r"""Pressure upstream of the nozzles needed to pass flow ``q`` against the back pressure.

    .. math:: p_2 = p_{back} + \frac{\rho}{2}\,\frac{q |q|}{(C_d A_0)^2}

    Parameters
    ----------
    q : float
        Volume flow through the nozzles [m³/s].
    rho : float
        Density [kg/m³].
    Cd : float
        Discharge coefficient [-].
    A0 : float
        Total orifice area [m²].
    p_back : float
        Combustor pressure downstream of the nozzles (gauge) [Pa].

    Returns
    -------
    float
        p_2 (gauge) [Pa]; its derivative with respect to q is :func:`orifice_resistance`.

    References
    ----------
    ISO 5167-1:2022, eq. (1); ``docs/explanation/physics.md`` §3.6.

    Examples
    --------
    63 L/min through 30 mm² (C_d = 0.7) into a combustor at 0.5 MPa:

    >>> from fuelid.units import LPM_PER_M3S
    >>> round(nozzle_inlet_pressure(63.0 / LPM_PER_M3S, 800.0, 0.7, 30e-6, 0.5e6))
    1500000
    """
    return p_back + orifice_pressure_drop(q, rho, Cd, A0)
