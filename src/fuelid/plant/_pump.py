"""Fixed-displacement pump with laminar (viscosity-dependent) internal leakage.

Fuel compressibility is negligible at about 1 MPa (bulk modulus 1000–1300 MPa), so the pump is a
flow source: geometric flow minus a leakage through the clearances that is laminar and therefore
proportional to pressure and inversely proportional to viscosity. Warm, thin fuel leaks more; this
is what makes the loop gain drift with fuel temperature. See ``docs/explanation/physics.md``
§3.3–3.4.
"""

from __future__ import annotations

from dataclasses import dataclass

from pydantic import Field

from fuelid.plant._section import Section
from fuelid.units import LPM_PER_M3S, M3_PER_CM3, PA_PER_MPA, PA_S_PER_MPA_S, TWO_PI


@dataclass(frozen=True, slots=True)
class PumpCoefficients:
    """The pump's parameters in SI at one fuel viscosity (:meth:`PumpConfig.coefficients`)."""

    D_p: float
    """Displacement [m³/rev]."""
    C_p: float
    """Leakage coefficient at the fuel's viscosity [m³/(s·Pa)], see :func:`leakage_coefficient`."""
    eta_m: float
    """Mechanical (torque) efficiency [-]."""


class PumpConfig(Section):
    """Pump data (TOML section ``[pump]``)."""

    displacement_cm3_per_rev: float = Field(
        gt=0.0, le=10_000.0, description="geometric displacement D_p [cm³/rev]"
    )
    leakage_Lpm_per_MPa: float = Field(
        ge=0.0,
        description="internal leakage per unit outlet pressure at the reference viscosity "
        "[(L/min)/MPa]",
    )
    leakage_ref_viscosity_mPa_s: float = Field(
        gt=0.0, description="dynamic viscosity at which leakage_Lpm_per_MPa was measured [mPa·s]"
    )
    mechanical_efficiency: float = Field(
        gt=0.0, le=1.0, description="mechanical (torque) efficiency η_m [-]"
    )

    @property
    def D_p(self) -> float:
        """Displacement [m³/rev]."""
        return self.displacement_cm3_per_rev * M3_PER_CM3

    @property
    def C_p_ref(self) -> float:
        """Leakage coefficient at the reference viscosity [m³/(s·Pa)]."""
        return self.leakage_Lpm_per_MPa / LPM_PER_M3S / PA_PER_MPA

    @property
    def mu_ref(self) -> float:
        """Reference viscosity of the leakage coefficient [Pa·s]."""
        return self.leakage_ref_viscosity_mPa_s * PA_S_PER_MPA_S

    def coefficients(self, mu: float) -> PumpCoefficients:
        """The pump's parameters in SI for fuel of dynamic viscosity ``mu`` [Pa·s]."""
        return PumpCoefficients(
            D_p=self.D_p,
            C_p=leakage_coefficient(mu, self.C_p_ref, self.mu_ref),
            eta_m=self.mechanical_efficiency,
        )


def leakage_coefficient(mu: float, C_p_ref: float, mu_ref: float) -> float:
    r"""Laminar leakage coefficient at viscosity ``mu``.

    .. math:: C_p(\mu) = C_{p,ref}\,\frac{\mu_{ref}}{\mu}

    Parameters
    ----------
    mu : float
        Dynamic viscosity of the fuel [Pa·s].
    C_p_ref : float
        Leakage coefficient measured at ``mu_ref`` [m³/(s·Pa)].
    mu_ref : float
        Viscosity of that measurement [Pa·s].

    Returns
    -------
    float
        C_p [m³/(s·Pa)].

    References
    ----------
    Merritt, *Hydraulic Control Systems*, Wiley 1967, §5.2 (laminar leakage flows).

    Examples
    --------
    Fuel half as viscous leaks twice as much:

    >>> leakage_coefficient(0.5e-3, 1e-10, 1e-3)
    2e-10
    """
    return C_p_ref * mu_ref / mu


def pump_flow(omega_m: float, p: float, D_p: float, C_p: float) -> float:
    r"""Delivered flow of a fixed-displacement pump, incompressible fluid.

    .. math:: q_p = \frac{D_p\,\omega_m}{2\pi} - C_p\,p

    Parameters
    ----------
    omega_m : float
        Shaft speed [rad/s].
    p : float
        Outlet pressure (gauge, inlet at 0) [Pa].
    D_p : float
        Displacement [m³/rev].
    C_p : float
        Leakage coefficient [m³/(s·Pa)].

    Returns
    -------
    float
        Flow [m³/s]. The internal leakage is the difference between the flows at zero pressure
        (the geometric flow) and at ``p``.

    Notes
    -----
    Valid where the fuel's compressibility inside the pump is negligible (p ≪ β) and the
    clearance flow is laminar.

    References
    ----------
    Merritt, *Hydraulic Control Systems*, Wiley 1967 (the chapter on hydraulic pumps
    and motors: delivery with leakage);
    ``docs/explanation/physics.md`` §3.4.

    Examples
    --------
    At zero pressure the pump delivers its geometric flow: 50 cm³/rev at 1450 rpm is
    72.5 L/min.

    >>> from fuelid.units import LPM_PER_M3S, RAD_S_PER_RPM
    >>> round(pump_flow(1450 * RAD_S_PER_RPM, 0.0, 50e-6, 1e-10) * LPM_PER_M3S, 6)
    72.5
    """
    return D_p * omega_m / TWO_PI - C_p * p


def pump_flow_partials(D_p: float, C_p: float) -> tuple[float, float]:
    r"""Partial derivatives of :func:`pump_flow` (constant: the law is linear).

    .. math:: \left(\frac{\partial q_p}{\partial \omega_m},\ \frac{\partial q_p}{\partial p}\right)
              = \left(\frac{D_p}{2\pi},\ -C_p\right)

    Parameters
    ----------
    D_p : float
        Displacement [m³/rev].
    C_p : float
        Leakage coefficient [m³/(s·Pa)].

    Returns
    -------
    tuple of float
        (∂q_p/∂ω_m [m³/rad], ∂q_p/∂p [m³/(s·Pa)]).

    Examples
    --------
    >>> from fuelid.units import TWO_PI
    >>> dq_domega, dq_dp = pump_flow_partials(TWO_PI * 1e-5, 1e-10)
    >>> round(dq_domega, 15), dq_dp
    (1e-05, -1e-10)
    """
    return (D_p / TWO_PI, -C_p)


def pump_torque(p: float, D_p: float, eta_m: float) -> float:
    r"""Shaft torque the pump needs at outlet pressure ``p``.

    .. math:: T_p = \frac{D_p\,p}{2\pi\,\eta_m}

    Parameters
    ----------
    p : float
        Outlet pressure [Pa].
    D_p : float
        Displacement [m³/rev].
    eta_m : float
        Mechanical efficiency [-].

    Returns
    -------
    float
        Torque [N·m].

    References
    ----------
    Merritt, *Hydraulic Control Systems*, Wiley 1967 (the chapter on hydraulic pumps
    and motors: torque with mechanical losses); ``docs/explanation/physics.md`` §3.3.

    Examples
    --------
    50 cm³/rev at 1 MPa with 90 % mechanical efficiency:

    >>> round(pump_torque(1e6, 50e-6, 0.9), 3)
    8.842
    """
    return D_p * p / (TWO_PI * eta_m)


def pump_torque_slope(D_p: float, eta_m: float) -> float:
    r"""Derivative of :func:`pump_torque` with respect to the outlet pressure (constant).

    .. math:: \frac{\partial T_p}{\partial p} = \frac{D_p}{2\pi\,\eta_m}

    Parameters
    ----------
    D_p : float
        Displacement [m³/rev].
    eta_m : float
        Mechanical efficiency [-], in (0, 1].

    Returns
    -------
    float
        ∂T_p/∂p [N·m/Pa = m³/rad].

    Examples
    --------
    >>> from fuelid.units import TWO_PI
    >>> round(pump_torque_slope(TWO_PI * 1e-5, 0.5), 15)
    2e-05
    """
    return D_p / (TWO_PI * eta_m)
