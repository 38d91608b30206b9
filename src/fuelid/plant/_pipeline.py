"""Long pipeline as a lumped line: inductance, capacitance and a flow-dependent resistance.

The line from the pump to the combustor is modelled by one lumped inductance L (the fuel mass
that must be accelerated), one lumped capacitance C at the pump outlet (compressibility of the
fuel in the whole line) and a resistance from the Darcy–Weisbach pressure drop. At realistic flows
the line is turbulent (Re ~ 10⁴–10⁵); the friction factor comes from the ``fluids`` package. The
default correlation, Churchill (1977), spans the laminar, transitional and turbulent regimes with
one smooth expression, so the pressure drop (and the ODE) stay differentiable through the
transition; its laminar limit is Hagen–Poiseuille, f = 64/Re. See ``docs/explanation/physics.md``
§3.5.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import fluids.friction
from pydantic import Field, field_validator

from fuelid.plant._section import Section
from fuelid.units import M_PER_MM, PA_PER_MPA

DEFAULT_FRICTION_METHOD = "Churchill_1977"
_churchill_1977 = fluids.friction.Churchill_1977
ZERO_FLOW_RE = 1e-6
"""Zero-flow cut-off of the Reynolds number [-]: below it (the flow at rest, to rounding)
:func:`pipe_pressure_drop` and :func:`pipe_pressure_drop_slope` use the Hagen–Poiseuille
resistance directly, the exact limit of f_D·Re → 64, which avoids the 0/0 of Darcy–Weisbach at
q = 0. It is not the laminar–turbulent transition (Re ≈ 2040,
``fluids.friction.LAMINAR_TRANSITION_PIPE``): the friction correlation handles that itself."""


@dataclass(frozen=True, slots=True)
class PipelineCoefficients:
    """The line's parameters in SI at one fuel state (:meth:`PipelineConfig.coefficients`)."""

    rho: float
    """Fuel density [kg/m³]."""
    mu: float
    """Fuel dynamic viscosity [Pa·s]."""
    length: float
    """Line length l [m]."""
    d: float
    """Inner diameter [m]."""
    roughness: float
    """Absolute wall roughness ε [m]."""
    method: str
    """Friction-factor correlation, see :func:`darcy_friction_factor`."""
    L: float
    """Lumped inductance (inertance) [kg/m⁴], see :func:`pipe_inductance`."""
    C: float
    """Lumped capacitance at the pump outlet [m³/Pa], see :func:`pipe_capacitance`."""


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
        return self.inner_diameter_mm * M_PER_MM

    @property
    def roughness(self) -> float:
        """Absolute roughness [m]."""
        return self.roughness_mm * M_PER_MM

    @property
    def beta(self) -> float:
        """Effective bulk modulus [Pa]."""
        return self.bulk_modulus_MPa * PA_PER_MPA

    def coefficients(self, rho: float, mu: float) -> PipelineCoefficients:
        """The line's parameters in SI for a fuel of density ``rho`` and viscosity ``mu`` (SI)."""
        return PipelineCoefficients(
            rho=rho,
            mu=mu,
            length=self.length_m,
            d=self.d,
            roughness=self.roughness,
            method=self.friction_method,
            L=pipe_inductance(rho, self.length_m, self.d),
            C=pipe_capacitance(self.length_m, self.d, self.beta),
        )


def circle_area(d: float) -> float:
    r"""Area of a circle of diameter ``d``: a pipe's bore, an orifice.

    .. math:: A = \frac{\pi d^2}{4}

    Parameters
    ----------
    d : float
        Diameter [m].

    Returns
    -------
    float
        A [m²].

    Examples
    --------
    >>> f"{circle_area(0.032):.6e}"
    '8.042477e-04'
    """
    return math.pi * d**2 / 4.0


def pipe_inductance(rho: float, length: float, d: float) -> float:
    r"""Hydraulic inductance (inertance) of a pipe.

    .. math:: L = \frac{\rho l}{A} = \frac{4\rho l}{\pi d^2}

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
    return rho * length / circle_area(d)


def pipe_capacitance(length: float, d: float, beta: float) -> float:
    r"""Hydraulic capacitance of the fuel volume in a pipe.

    .. math:: C = \frac{A l}{\beta} = \frac{\pi d^2 l}{4\beta}

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
    return circle_area(d) * length / beta


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

    .. math:: Re = \frac{\rho v d}{\mu},\qquad v = \frac{q}{A} = \frac{4 q}{\pi d^2}

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
    return rho * abs(q) * d / (circle_area(d) * mu)


def darcy_friction_factor(Re: float, eD: float, method: str = DEFAULT_FRICTION_METHOD) -> float:
    r"""Darcy friction factor from the ``fluids`` package.

    Parameters
    ----------
    Re : float
        Reynolds number [-], positive.
    eD : float
        Relative roughness ε/d [-].
    method : str
        ``"Churchill_1977"`` (default: one smooth expression for all regimes, evaluated by
        :func:`fluids.friction.Churchill_1977` at every Re) or any other correlation name of
        :data:`fluids.friction.fmethods`, evaluated by :func:`fluids.friction.friction_factor`,
        which returns the laminar f = 64/Re below Re = 2040
        (``fluids.friction.LAMINAR_TRANSITION_PIPE``, after Avila et al. 2011) and the named
        correlation from there on.

    Returns
    -------
    float
        f_D [-].

    Notes
    -----
    Churchill (1977):

    .. math:: f_D = 8\left[\left(\frac{8}{Re}\right)^{12} + (A + B)^{-3/2}\right]^{1/12},
              \quad A = \left[2.457 \ln\left(\left(\frac{7}{Re}\right)^{0.9}
              + 0.27\frac{\varepsilon}{d}\right)\right]^{16},
              \quad B = \left(\frac{37530}{Re}\right)^{16}

    References
    ----------
    Churchill, S. W., "Friction factor equation spans all fluid flow regimes", Chem. Eng. 84(24),
    91–92 (1977); Avila, K. et al., "The onset of turbulence in pipe flow", Science 333,
    192–196 (2011); Bell, C., *fluids* (friction module).

    Examples
    --------
    Laminar limit and a turbulent value:

    >>> round(darcy_friction_factor(1000.0, 0.0), 4)
    0.064
    >>> round(darcy_friction_factor(1e5, 1e-4), 5)
    0.01846
    """
    if method == DEFAULT_FRICTION_METHOD:
        f_D: float = _churchill_1977(Re, eD)  # a float for float arguments (inner loop)
        return f_D
    return float(fluids.friction.friction_factor(Re, eD, Method=method))


def darcy_friction_factor_log_slope(
    Re: float, eD: float, method: str = DEFAULT_FRICTION_METHOD
) -> float:
    r"""Logarithmic derivative d ln f_D / d ln Re of :func:`darcy_friction_factor`.

    For Churchill (1977) (the default) it is analytic: with the symbols of
    :func:`darcy_friction_factor`, :math:`a = (7/Re)^{0.9} + 0.27\,\varepsilon/d` and
    :math:`S = (8/Re)^{12} + (A + B)^{-3/2}`,

    .. math:: \frac{d \ln f_D}{d \ln Re} = \frac{1}{12 S}\left[-12\left(\frac{8}{Re}\right)^{12}
              - \frac{3}{2}(A + B)^{-5/2}\left(Re\frac{dA}{dRe} + Re\frac{dB}{dRe}\right)\right],

    .. math:: Re\frac{dA}{dRe} = -16 \cdot 0.9 \cdot 2.457^{16} (\ln a)^{15}
              \frac{(7/Re)^{0.9}}{a}, \qquad Re\frac{dB}{dRe} = -16 B.

    For the other correlations it is a central difference in Re (relative step 1e-5).

    Parameters
    ----------
    Re : float
        Reynolds number [-], positive.
    eD : float
        Relative roughness ε/d [-].
    method : str
        As in :func:`darcy_friction_factor`.

    Returns
    -------
    float
        d ln f_D / d ln Re [-]: −1 in laminar flow, about −1/4 for a smooth turbulent pipe
        (Blasius), 0 when fully rough.

    References
    ----------
    Churchill, S. W. (1977), see :func:`darcy_friction_factor`.

    Examples
    --------
    >>> round(darcy_friction_factor_log_slope(100.0, 0.0), 9)
    -1.0
    >>> round(darcy_friction_factor_log_slope(1e9, 0.05), 4)
    -0.0
    """
    if method != DEFAULT_FRICTION_METHOD:
        h = 1e-5
        hi = darcy_friction_factor(Re * (1.0 + h), eD, method)
        lo = darcy_friction_factor(Re * (1.0 - h), eD, method)
        return (hi - lo) / (2.0 * h * darcy_friction_factor(Re, eD, method))
    laminar = (8.0 / Re) ** 12
    r: float = (7.0 / Re) ** 0.9
    a = r + 0.27 * eD
    log_a = math.log(a)
    A = (2.457 * log_a) ** 16
    B = (37530.0 / Re) ** 16
    Re_dA = -16.0 * 0.9 * 2.457**16 * log_a**15 * r / a
    Re_dB = -16.0 * B
    turbulent: float = (A + B) ** -1.5
    S = laminar + turbulent
    Re_dS = -12.0 * laminar - 1.5 * turbulent * (Re_dA + Re_dB) / (A + B)
    return Re_dS / (12.0 * S)


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
              \qquad v = \frac{q}{A} = \frac{4 q}{\pi d^2}

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
        Absolute roughness ε [m].
    method : str
        Friction correlation, see :func:`darcy_friction_factor`.

    Returns
    -------
    float
        Δp [Pa]; the Hagen–Poiseuille value R_L·q (:func:`laminar_resistance`) below the
        zero-flow cut-off :data:`ZERO_FLOW_RE`, which is the limit of f_D = 64/Re.

    Notes
    -----
    Fully developed, incompressible flow in a straight round pipe; valid in every regime with the
    default correlation.

    References
    ----------
    White, F. M., *Fluid Mechanics*, 7th ed., McGraw-Hill 2011, ch. 6 (head loss and the friction
    factor);
    ``docs/explanation/physics.md`` §3.5.

    Examples
    --------
    With f_D = 64/Re (laminar) the drop is exactly Hagen–Poiseuille:

    >>> q = 1e-5
    >>> dp = pipe_pressure_drop(q, 800.0, 1e-3, 80.0, 0.032)
    >>> round(dp / (laminar_resistance(1e-3, 80.0, 0.032) * q), 6)
    1.0
    """
    Re = reynolds_number(q, d, rho, mu)
    if Re < ZERO_FLOW_RE:  # at rest f·Re → 64: Hagen–Poiseuille, exact and free of 0/0
        return laminar_resistance(mu, length, d) * q
    v = q / circle_area(d)
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
    r"""Incremental resistance d(Δp)/dq of the pipe at flow ``q``.

    Differentiating :func:`pipe_pressure_drop` with Re ∝ |q|:

    .. math:: \frac{d\Delta p}{dq} = \frac{\Delta p}{q}
              \left(2 + \frac{d \ln f_D}{d \ln Re}\right)

    with the logarithmic slope of the friction factor from
    :func:`darcy_friction_factor_log_slope` (analytic for the default Churchill correlation).

    Parameters
    ----------
    q : float
        Volume flow [m³/s].
    rho, mu, length, d, roughness, method
        As in :func:`pipe_pressure_drop`.

    Returns
    -------
    float
        d(Δp)/dq [Pa·s/m³]; the laminar resistance R_L below the zero-flow cut-off
        :data:`ZERO_FLOW_RE` (and, to the correlation's accuracy, in laminar flow).

    Examples
    --------
    Fully rough turbulent flow tends to Δp ∝ q², so the slope tends to 2·Δp/q:

    >>> q = 5e-2
    >>> r = pipe_pressure_drop_slope(q, 800.0, 1e-3, 80.0, 0.032, roughness=3e-3)
    >>> round(r / (2 * pipe_pressure_drop(q, 800.0, 1e-3, 80.0, 0.032, 3e-3) / q), 2)
    1.0
    """
    Re = reynolds_number(q, d, rho, mu)
    if Re < ZERO_FLOW_RE:
        return laminar_resistance(mu, length, d)
    dp = pipe_pressure_drop(q, rho, mu, length, d, roughness, method)
    return dp / q * (2.0 + darcy_friction_factor_log_slope(Re, roughness / d, method))


def pipe_pressure_rate(q_in: float, q_out: float, C: float) -> float:
    r"""Rate of change of the pressure in the line's lumped capacitance (continuity).

    .. math:: C\,\dot p = q_{in} - q_{out}

    Parameters
    ----------
    q_in : float
        Flow into the volume (the pump's delivery) [m³/s].
    q_out : float
        Flow out of it (the line flow) [m³/s].
    C : float
        Hydraulic capacitance [m³/Pa], positive, see :func:`pipe_capacitance`.

    Returns
    -------
    float
        dp/dt [Pa/s].

    References
    ----------
    Merritt, *Hydraulic Control Systems*, Wiley 1967 (the continuity equation of a compressed
    volume); ``docs/explanation/physics.md`` §3.5.

    Examples
    --------
    A 0.1 L/s surplus into 5e-11 m³/Pa raises the pressure by 2 MPa/s:

    >>> round(pipe_pressure_rate(1.1e-3, 1.0e-3, 5e-11))
    2000000
    """
    return (q_in - q_out) / C


def pipe_pressure_rate_partials(C: float) -> tuple[float, float]:
    r"""Partial derivatives of :func:`pipe_pressure_rate` (constant).

    .. math:: \left(\frac{\partial \dot p}{\partial q_{in}},\
              \frac{\partial \dot p}{\partial q_{out}}\right)
              = \left(\frac{1}{C},\ -\frac{1}{C}\right)

    Parameters
    ----------
    C : float
        Hydraulic capacitance [m³/Pa].

    Returns
    -------
    tuple of float
        (∂ṗ/∂q_in, ∂ṗ/∂q_out) [Pa/m³].

    Examples
    --------
    >>> pipe_pressure_rate_partials(0.5)
    (2.0, -2.0)
    """
    return (1.0 / C, -1.0 / C)


def pipe_flow_rate(p_in: float, p_out: float, dp_friction: float, L: float) -> float:
    r"""Rate of change of the flow of the line's fuel column (momentum balance).

    .. math:: L\,\dot q = p_{in} - p_{out} - \Delta p_f(q)

    Parameters
    ----------
    p_in : float
        Pressure at the line's inlet (the pump outlet) [Pa].
    p_out : float
        Pressure at its outlet (upstream of the nozzles) [Pa].
    dp_friction : float
        Friction drop along the line at the present flow [Pa], see :func:`pipe_pressure_drop`.
    L : float
        Hydraulic inductance [kg/m⁴], positive, see :func:`pipe_inductance`.

    Returns
    -------
    float
        dq/dt [m³/s²].

    References
    ----------
    Merritt, *Hydraulic Control Systems*, Wiley 1967 (lumped fluid inertance);
    ``docs/explanation/physics.md`` §3.5.

    Examples
    --------
    >>> pipe_flow_rate(1.0e6, 0.9e6, 0.06e6, 8e7)
    0.0005
    """
    return (p_in - p_out - dp_friction) / L


def pipe_flow_rate_partials(L: float) -> tuple[float, float, float]:
    r"""Partial derivatives of :func:`pipe_flow_rate` (constant).

    .. math:: \left(\frac{\partial \dot q}{\partial p_{in}},\
              \frac{\partial \dot q}{\partial p_{out}},\
              \frac{\partial \dot q}{\partial \Delta p_f}\right)
              = \left(\frac{1}{L},\ -\frac{1}{L},\ -\frac{1}{L}\right)

    Parameters
    ----------
    L : float
        Hydraulic inductance [kg/m⁴].

    Returns
    -------
    tuple of float
        (∂q̇/∂p_in, ∂q̇/∂p_out, ∂q̇/∂Δp_f) [m⁴/kg].

    Examples
    --------
    >>> pipe_flow_rate_partials(0.5)
    (2.0, -2.0, -2.0)
    """
    return (1.0 / L, -1.0 / L, -1.0 / L)
