"""Long pipeline as a lumped line: inductance, capacitance and a flow-dependent resistance.

The line from the pump to the combustor is modelled by one lumped inductance L (the fuel mass
that must be accelerated), one lumped capacitance C at the pump outlet (compressibility of the
fuel in the whole line) and a resistance from the Darcy–Weisbach pressure drop. At realistic flows
the line is turbulent (Re ~ 10⁴–10⁵); the friction factor comes from the ``fluids`` package. The
default correlation, Churchill (1977), spans the laminar, transitional and turbulent regimes with
one smooth expression, so the pressure drop (and the ODE) stay differentiable through the
transition; its laminar limit is Hagen–Poiseuille, f = 64/Re.
"""

from __future__ import annotations

import math

import fluids.friction
from pydantic import Field, field_validator

from fuelid.plant._section import Section

DEFAULT_FRICTION_METHOD = "Churchill_1977"


class PipelineConfig(Section):
    """Geometry and material of the line (TOML section ``[pipeline]``)."""

    length_m: float = Field(gt=0.0, le=100_000.0, description="line length l [m]")
    inner_diameter_mm: float = Field(gt=0.0, le=2_000.0, description="inner diameter d [mm]")
    roughness_mm: float = Field(
        0.045, ge=0.0, description="absolute wall roughness ε [mm] (commercial steel 0.045)"
    )
    bulk_modulus_MPa: float = Field(
        1200.0,
        gt=0.0,
        description="effective bulk modulus of fuel in the line β, wall elasticity included [MPa]",
    )
    friction_method: str = Field(
        DEFAULT_FRICTION_METHOD,
        description="friction-factor correlation of the fluids package (default Churchill_1977)",
    )

    @field_validator("friction_method")
    @classmethod
    def _known_method(cls, value: str) -> str:
        if value not in fluids.friction.fmethods:
            known = ", ".join(sorted(fluids.friction.fmethods))
            raise ValueError(f"unknown friction_method {value!r}; known: {known}")
        return value

    @property
    def d(self) -> float:
        """Inner diameter [m]."""
        return self.inner_diameter_mm * 1e-3

    @property
    def roughness(self) -> float:
        """Absolute roughness [m]."""
        return self.roughness_mm * 1e-3

    @property
    def beta(self) -> float:
        """Effective bulk modulus [Pa]."""
        return self.bulk_modulus_MPa * 1e6


def pipe_inductance(rho: float, length: float, d: float) -> float:
    r"""Hydraulic inductance (inertance) of a pipe.

    .. math:: L = \frac{4\rho l}{\pi d^2}

    Parameters
    ----------
    rho : float
        Fuel density [kg/m³].
    length : float
        Pipe length l [m].
    d : float
        Inner diameter [m].

    Returns
    -------
    float
        L [kg/m⁴] (pressure per rate of change of volume flow, Pa/(m³/s²)).

    Examples
    --------
    >>> f"{pipe_inductance(800.0, 80.0, 0.032):.4e}"
    '7.9577e+07'
    """
    return 4.0 * rho * length / (math.pi * d**2)


def pipe_capacitance(length: float, d: float, beta: float) -> float:
    r"""Hydraulic capacitance of the fuel volume in a pipe.

    .. math:: C = \frac{\pi d^2 l}{4\beta}

    Parameters
    ----------
    length : float
        Pipe length l [m].
    d : float
        Inner diameter [m].
    beta : float
        Effective bulk modulus [Pa].

    Returns
    -------
    float
        C [m³/Pa].

    Examples
    --------
    >>> f"{pipe_capacitance(80.0, 0.032, 1.2e9):.4e}"
    '5.3617e-11'
    """
    return math.pi * d**2 * length / (4.0 * beta)


def laminar_resistance(mu: float, length: float, d: float) -> float:
    r"""Hagen–Poiseuille resistance of a pipe in laminar flow.

    .. math:: R_L = \frac{128 \mu l}{\pi d^4}

    Parameters
    ----------
    mu : float
        Dynamic viscosity [Pa·s].
    length : float
        Pipe length l [m].
    d : float
        Inner diameter [m].

    Returns
    -------
    float
        R_L [Pa·s/m³].

    Examples
    --------
    >>> f"{laminar_resistance(1e-3, 80.0, 0.032):.4e}"
    '3.1085e+06'
    """
    return 128.0 * mu * length / (math.pi * d**4)


def reynolds_number(q: float, d: float, rho: float, mu: float) -> float:
    r"""Reynolds number of volume flow ``q`` in a round pipe.

    .. math:: Re = \frac{\rho v d}{\mu} = \frac{4 \rho q}{\pi d \mu}

    Parameters
    ----------
    q : float
        Volume flow [m³/s] (its magnitude is used).
    d : float
        Inner diameter [m].
    rho : float
        Density [kg/m³].
    mu : float
        Dynamic viscosity [Pa·s].

    Returns
    -------
    float
        Re [-].

    Examples
    --------
    >>> round(reynolds_number(1e-3, 0.032, 800.0, 1e-3))
    31831
    """
    return 4.0 * rho * abs(q) / (math.pi * d * mu)


def darcy_friction_factor(Re: float, eD: float, method: str = DEFAULT_FRICTION_METHOD) -> float:
    """Darcy friction factor from the ``fluids`` package.

    Parameters
    ----------
    Re : float
        Reynolds number [-], positive.
    eD : float
        Relative roughness ε/d [-].
    method : str
        ``"Churchill_1977"`` (default: one smooth expression for all regimes) or any other
        correlation name of :data:`fluids.friction.fmethods`, which ``fluids`` applies above
        Re = 2320 with f = 64/Re below.

    Returns
    -------
    float
        f_D [-].

    References
    ----------
    Churchill, S. W., "Friction factor equation spans all fluid flow regimes", Chem. Eng. 84(24),
    91–92 (1977); Bell, C., *fluids* (friction module).

    Examples
    --------
    Laminar limit and a turbulent value:

    >>> round(darcy_friction_factor(1000.0, 0.0), 4)
    0.064
    >>> round(darcy_friction_factor(1e5, 1e-4), 5)
    0.01846
    """
    if method == DEFAULT_FRICTION_METHOD:
        return float(fluids.friction.Churchill_1977(Re, eD))
    return float(fluids.friction.friction_factor(Re, eD, Method=method))


def pipe_pressure_drop(
    q: float,
    rho: float,
    mu: float,
    length: float,
    d: float,
    roughness: float = 0.0,
    method: str = DEFAULT_FRICTION_METHOD,
) -> float:
    r"""Friction pressure drop along a pipe (Darcy–Weisbach), signed with the flow.

    .. math:: \Delta p = f_D(Re, \varepsilon/d)\,\frac{l}{d}\,\frac{\rho\, v |v|}{2},
              \qquad v = \frac{4 q}{\pi d^2}

    Parameters
    ----------
    q : float
        Volume flow [m³/s].
    rho : float
        Density [kg/m³].
    mu : float
        Dynamic viscosity [Pa·s].
    length : float
        Pipe length l [m].
    d : float
        Inner diameter [m].
    roughness : float
        Absolute roughness [m].
    method : str
        Friction correlation, see :func:`darcy_friction_factor`.

    Returns
    -------
    float
        Δp [Pa]; tends to the Hagen–Poiseuille value R_L·q as q → 0.

    Examples
    --------
    With f_D = 64/Re (laminar) the drop is exactly Hagen–Poiseuille:

    >>> q = 1e-5
    >>> dp = pipe_pressure_drop(q, 800.0, 1e-3, 80.0, 0.032)
    >>> round(dp / (laminar_resistance(1e-3, 80.0, 0.032) * q), 6)
    1.0
    """
    Re = reynolds_number(q, d, rho, mu)
    if Re < 1e-6:  # f·Re → 64: the laminar limit, exact and free of 0/0
        return laminar_resistance(mu, length, d) * q
    v = 4.0 * q / (math.pi * d**2)
    f = darcy_friction_factor(Re, roughness / d, method)
    return f * (length / d) * 0.5 * rho * v * abs(v)


def pipe_pressure_drop_slope(
    q: float,
    rho: float,
    mu: float,
    length: float,
    d: float,
    roughness: float = 0.0,
    method: str = DEFAULT_FRICTION_METHOD,
) -> float:
    """Incremental resistance d(Δp)/dq of the pipe at flow ``q``.

    A central difference of :func:`pipe_pressure_drop` (relative step 1e-5, truncation error
    ~1e-10 relative); the friction correlations are smooth but their analytic derivatives are not
    worth the code.

    Parameters
    ----------
    q : float
        Volume flow [m³/s].
    rho, mu, length, d, roughness, method
        As in :func:`pipe_pressure_drop`.

    Returns
    -------
    float
        d(Δp)/dq [Pa·s/m³]; the laminar resistance at q = 0.

    Examples
    --------
    Fully rough turbulent flow tends to Δp ∝ q², so the slope tends to 2·Δp/q:

    >>> q = 5e-2
    >>> r = pipe_pressure_drop_slope(q, 800.0, 1e-3, 80.0, 0.032, roughness=3e-3)
    >>> round(r / (2 * pipe_pressure_drop(q, 800.0, 1e-3, 80.0, 0.032, 3e-3) / q), 2)
    1.0
    """
    if reynolds_number(q, d, rho, mu) < 1.0:
        return laminar_resistance(mu, length, d)
    h = 1e-5 * abs(q)
    hi = pipe_pressure_drop(q + h, rho, mu, length, d, roughness, method)
    lo = pipe_pressure_drop(q - h, rho, mu, length, d, roughness, method)
    return (hi - lo) / (2.0 * h)
