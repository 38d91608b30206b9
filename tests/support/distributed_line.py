r"""A test plant outside fuelid's model family: a fuel loop with a distributed (wave) pipeline.

Issue 37: the robustness fuelid prints (Ms) must be true for the user's loop, not only for the
model it identified. This module is the truth to check that against. It does not import
fuelid at all (its physics is written here from scratch); the tests cross-check it against
``fuelid.tuning`` in the one case where the two must coincide.

The loop
--------
command u [V] → VFD: speed set point n* = n_min + k_n·(u − 1 V), first-order drive lag T_d →
fixed-displacement pump with laminar leakage q_p = D·n − C_leak·p_1 → pipeline (length l,
diameter d, fuel density ρ, effective wave speed a with the pipe's wall compliance included,
quadratic Darcy–Weisbach friction with a constant friction factor f) → nozzles
p_2 = ρ/2·(q_2/(C_d·A_N))² → turbine meter (lag T_m, dead time τ) reading q_2 in L/min.

Everything inside is SI (m³/s, Pa, rev/s, s); the command is in V and the meter reading in L/min,
as in a PLC log.

Small-signal model (:func:`frequency_response`): about the steady state at a command u0 the
friction is linearised to R' = 2·Δp_line/(q·l) per metre (Pa·s/m⁴; exact for a constant friction
factor), the nozzle to R_N = 2·p_2/q (Pa·s/m³), and the line is the exact two-port of the
telegrapher's equations

.. math::

    \begin{pmatrix} p_1 \\ q_1 \end{pmatrix} =
    \begin{pmatrix} \cosh\gamma l & Z_c \sinh\gamma l \\ \sinh(\gamma l)/Z_c & \cosh\gamma l
    \end{pmatrix} \begin{pmatrix} p_2 \\ q_2 \end{pmatrix},\quad
    \gamma = \sqrt{(L's + R')\,C's},\quad Z_c = \sqrt{(L's + R')/(C's)},

L' = ρ/A, C' = A/(ρa²). With q_1 = D·n − C_leak·p_1 at the pump and p_2 = R_N·q_2 at the nozzle,

.. math::

    \frac{q_2}{D\,n} = \frac{1}{(1 + C_{leak} R_N)\cosh\gamma l
        + \left(R_N C' s\,l + C_{leak}(L's + R')\,l\right)\,\mathrm{sinhc}\,\gamma l},

sinhc x = sinh(x)/x. cosh and sinhc are even in γl, so the branch of the square root does not
matter and s = 0 needs no special case.

Why the loop is most aggressive at the LOW end of the drive
-----------------------------------------------------------
Both resistances are quadratic: p_1 = (k_line·l + k_N)·q², so the incremental resistance
R = dp_1/dq = 2·p_1/q grows in proportion to the flow. The static gain is

    dq/du = k_n·D / (1 + C_leak·(R'·l + R_N)),

so at low flow the pump's leakage hardly changes when the flow changes (R small: the leakage
admittance sees almost no incremental pressure) and nearly all of the extra displacement reaches
the nozzles, while at high flow a part C_leak·R/(1 + C_leak·R) of it leaks back. The parameters
below give C_leak·R ≈ 0.13 at 1.1 V, 0.34 at 3 V, 0.47 at 4.5 V: the gain at 1.1 V
(5.29 (L/min)/V) is 17.7 % above that at 3 V (4.50) and 30 % above that at 4.5 V (4.07).

The line is also least damped there: its characteristic impedance Z_0 = ρa/A ≈ 2.8e9 Pa·s/m³
is matched by the nozzles near full flow (R_N ≈ 2.5e9 at 4.5 V: the waves are absorbed) but not
at low flow (R_N ≈ 0.71e9 at 1.1 V: the nozzle end reflects 59 % of a wave, inverted), so the
line's first mode (near its quarter-wave frequency a/(4l) ≈ 1.4 Hz; 0.93 Hz in the lumped
estimate, ζ ≈ 0.35 at 1.1 V, 0.54 at 3 V, 0.66 at 4.5 V) lifts |G| by up to 62 % near 6 rad/s at
1.1 V (14 % at 3 V, none at 4.5 V). For a PI tuned by SIMC on a mid-range model that mode sits
above the crossover (about 2 rad/s), where it costs little: it is the gain that moves Ms. With
SIMC gains from a first-order model identified at 3 V (h = 0.1 s) the true Ms is about 1.78 at
1.1 V against about 1.68 printed on the model (and about 1.67 true at 3 V, 1.61 at 4.5 V).

Parameters (:class:`DistributedLoop`, defaults) and why
-------------------------------------------------------
A small test-stand loop, 0–30 L/min meter span, about 0.7 MPa at the pump at full flow:

- VFD 10–50 Hz on a 4-pole motor over 1–5 V: n_min = 5 rev/s (300 rpm, the minimum frequency
  that keeps the motor cooled and the pump lubricated: u = 1 V already delivers), k_n = 5 rev/s
  per V (10 Hz/V → 1500 rpm at 5 V; the few % slip of the motor is left out, the drive being
  speed-controlled); T_d = 0.5 s, the acceleration ramp of a 1.5 kW drive.
- Gear pump D = 20 cm³/rev: 30 L/min geometric at 1500 rpm, the meter's full scale.
  C_leak = 1.4e-10 m³/(s·Pa): 8.4 L/min slip at 1 MPa, 6.2 L/min at the 0.73 MPa of full speed,
  i.e. a volumetric efficiency of 79 % there: a small gear pump rated on oil running on a fuel
  of about 1.5 mm²/s (laminar slip through the clearances ∝ Δp/μ). This leakage is what makes
  the gain fall with the flow (above).
- Line l = 200 m of 20 mm bore tube (velocity 1.3 m/s at 24 L/min, Re ≈ 2e4: turbulent);
  ρ = 790 kg/m³ (RP-3 near 5 °C, 794 − 0.72·T); a = 1100 m/s: kerosene's bulk modulus
  1.1–1.3 GPa gives 1180–1280 m/s in a rigid pipe, the steel wall (d/e = 10) and a few hose
  sections bring the effective value to 1100 m/s, so 2l/a ≈ 0.36 s. Friction factor f = 0.030
  held constant: Colebrook for drawn tube gives 0.040 at 5 L/min and 0.026 at 27 L/min; the
  constant value is what makes the plant's friction exactly quadratic (R' = 2·Δp/(q·l) is then
  the exact slope) and the line loses 0.19 MPa at full flow (a quarter of the pump pressure;
  the nozzles take the rest).
- Nozzles C_d·A_N = 1.07e-5 m² (six 1.8 mm orifices, C_d ≈ 0.7): 0.54 MPa at full flow.
- Turbine meter (1/2"): lag T_m = 0.15 s, dead time τ = 0.1 s (its gate time and the PLC's
  scan). The lag is held constant (a real turbine's lag shrinks as the flow grows).

With these, u = 1 V gives 5.65 L/min (0.04 MPa), 5 V gives 23.8 L/min at 0.73 MPa at the pump:
the flow stays inside the meter's 0–30 L/min span over the whole drive range.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.optimize
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

LPM = 60000.0
"""L/min per m³/s."""


@dataclass(frozen=True)
class DistributedLoop:
    """Parameters of the distributed fuel loop, SI (the defaults are justified in the module)."""

    u_span: tuple[float, float] = (1.0, 5.0)
    """The drive's command range [V] (the standard 1–5 V signal)."""
    q_span_Lpm: tuple[float, float] = (0.0, 30.0)
    """The flowmeter's span [L/min]."""
    n_min: float = 5.0
    """Pump speed at u = 1 V [rev/s]."""
    k_n: float = 5.0
    """Speed per volt [rev/s per V]."""
    T_d: float = 0.5
    """Drive (acceleration) lag [s]; 0 for none."""
    displacement: float = 20e-6
    """Pump displacement D [m³/rev]."""
    C_leak: float = 1.4e-10
    """Pump leakage (slip) coefficient [m³/(s·Pa)]."""
    length: float = 200.0
    """Pipeline length l [m]."""
    diameter: float = 0.020
    """Pipeline bore d [m]."""
    rho: float = 790.0
    """Fuel density [kg/m³]."""
    wave_speed: float = 1100.0
    """Effective wave speed a, the pipe's compliance included [m/s]."""
    friction_factor: float = 0.030
    """Darcy friction factor f, constant (quadratic friction) [-]."""
    CdA: float = 1.07e-5
    """Nozzles' discharge coefficient times total area C_d·A_N [m²]."""
    T_m: float = 0.15
    """Flowmeter lag [s]; 0 for none."""
    tau: float = 0.10
    """Flowmeter dead time [s]."""

    @property
    def area(self) -> float:
        """Bore area A [m²]."""
        return math.pi * self.diameter**2 / 4.0

    @property
    def inertance(self) -> float:
        """L' = ρ/A per metre [Pa·s²/m³ per m]."""
        return self.rho / self.area

    @property
    def compliance(self) -> float:
        """C' = A/(ρa²) per metre [m³/Pa per m]."""
        return self.area / (self.rho * self.wave_speed**2)

    @property
    def z0(self) -> float:
        """Lossless characteristic impedance ρa/A [Pa·s/m³]."""
        return self.rho * self.wave_speed / self.area

    @property
    def k_line(self) -> float:
        """Friction per metre: Δp/l = k_line·q|q| [Pa·s²/m⁷]."""
        return self.friction_factor * self.rho / (2.0 * self.diameter * self.area**2)

    @property
    def k_nozzle(self) -> float:
        """Nozzle law p_2 = k_nozzle·q|q| [Pa·s²/m⁶]."""
        return self.rho / (2.0 * self.CdA**2)

    @property
    def echo_period(self) -> float:
        """Round trip of a pressure wave along the line, 2l/a [s]."""
        return 2.0 * self.length / self.wave_speed


def _check_command(loop: DistributedLoop, u: float) -> None:
    lo, hi = loop.u_span
    if not lo <= u <= hi:
        raise ValueError(f"command {u:g} V outside the drive's range {lo:g}…{hi:g} V")


def _speed_setpoint(loop: DistributedLoop, u: FloatArray | float) -> FloatArray:
    lo, hi = loop.u_span
    return np.asarray(loop.n_min + loop.k_n * (np.clip(u, lo, hi) - lo), dtype=float)


def steady_state(loop: DistributedLoop, u: float) -> dict[str, float]:
    """Steady operating point at command ``u`` [V].

    The pump flow D·n − C_leak·p_1 equals the nozzle flow q, p_1 = (k_line·l + k_nozzle)·q²,
    solved in closed form.

    Returns
    -------
    dict
        ``u_V``, ``n_rps`` (pump speed), ``q_m3s``, ``q_Lpm`` (flow, also what the meter reads),
        ``p1_Pa`` (pump outlet), ``p2_Pa`` (at the nozzles), ``leak_m3s``, ``R_line`` (linearised
        friction of the whole line, R'·l), ``R_nozzle`` (R_N) [Pa·s/m³].

    Examples
    --------
    >>> s = steady_state(DistributedLoop(), 5.0)
    >>> round(s["q_Lpm"], 1), round(s["p1_Pa"] / 1e6, 2)
    (23.8, 0.73)
    """
    _check_command(loop, u)
    n = float(_speed_setpoint(loop, u))
    k_total = loop.k_line * loop.length + loop.k_nozzle
    displaced = loop.displacement * n
    # q + C_leak·k_total·q² = D·n, the positive root in its cancellation-free form
    q = 2.0 * displaced / (1.0 + math.sqrt(1.0 + 4.0 * loop.C_leak * k_total * displaced))
    p2 = loop.k_nozzle * q * q
    p1 = k_total * q * q
    return {
        "u_V": u,
        "n_rps": n,
        "q_m3s": q,
        "q_Lpm": q * LPM,
        "p1_Pa": p1,
        "p2_Pa": p2,
        "leak_m3s": loop.C_leak * p1,
        "R_line": 2.0 * (p1 - p2) / q,
        "R_nozzle": 2.0 * p2 / q,
    }


def _sinhc(x: ComplexArray) -> ComplexArray:
    small = np.abs(x) < 1e-4
    safe = np.where(small, 1.0, x)
    x2 = x * x
    return np.asarray(np.where(small, 1.0 + x2 / 6.0 + x2 * x2 / 120.0, np.sinh(safe) / safe))


def line_response(loop: DistributedLoop, u: float, s: ArrayLike) -> ComplexArray:
    """q_2/(D·n): nozzle flow per displaced flow of the line with its terminations at s.

    The distributed two-port between the leaky pump (flow source with admittance C_leak) and the
    nozzles (resistance R_N). ``s`` may be any complex Laplace variable (used for jω and for
    the aliased frequencies of the sampled loop).
    """
    st = steady_state(loop, u)
    s = np.asarray(s, dtype=complex)
    l = loop.length  # noqa: E741
    r_per_m = st["R_line"] / l
    series = (loop.inertance * s + r_per_m) * l  # (L's + R')·l = γ·Z_c·l
    shunt = loop.compliance * s * l  # C's·l = γ·l/Z_c
    gl = np.sqrt(series * shunt)
    g, rn = loop.C_leak, st["R_nozzle"]
    den = (1.0 + g * rn) * np.cosh(gl) + (rn * shunt + g * series) * _sinhc(gl)
    return np.asarray(1.0 / den, dtype=complex)


def _transfer(loop: DistributedLoop, u: float, s: ComplexArray) -> ComplexArray:
    g = loop.k_n * loop.displacement * LPM * line_response(loop, u, s)
    g = g * np.exp(-s * loop.tau)
    if loop.T_d > 0.0:
        g = g / (loop.T_d * s + 1.0)
    if loop.T_m > 0.0:
        g = g / (loop.T_m * s + 1.0)
    return np.asarray(g, dtype=complex)


def frequency_response(loop: DistributedLoop, u: float, omega: ArrayLike) -> ComplexArray:
    """Exact small-signal G(jω) from the command [V] to the meter reading [L/min] about ``u``.

    G(s) = k_n·D·60000 / (T_d·s + 1) · q_2/(D·n)(s) · e^(−τs)/(T_m·s + 1), the line's factor
    from :func:`line_response` (see the module docstring). Vectorised over ``omega`` [rad/s]
    (negative frequencies give the complex conjugate).

    Examples
    --------
    >>> loop = DistributedLoop()
    >>> g0 = frequency_response(loop, 3.0, [0.0])[0]
    >>> round(float(g0.real), 3), float(g0.imag)
    (4.496, 0.0)
    """
    _check_command(loop, u)
    w = np.asarray(omega, dtype=float)
    return _transfer(loop, u, 1j * w)


def static_gain(loop: DistributedLoop, u: float) -> float:
    """dq/du at ``u`` [(L/min)/V], closed form: k_n·D·60000/(1 + C_leak·(R'·l + R_N))."""
    st = steady_state(loop, u)
    return (
        loop.k_n * loop.displacement * LPM / (1.0 + loop.C_leak * (st["R_line"] + st["R_nozzle"]))
    )


# ------------------------------------------------------------------------------------------
# The sampled-data loop and the maximum sensitivity


ALIAS_TERMS = 1000
"""Aliases k = −N…N summed in the zero-order-hold equivalent (see :func:`zoh_response`)."""


def zoh_response(
    loop: DistributedLoop, u: float, omega: ArrayLike, h: float, terms: int = ALIAS_TERMS
) -> ComplexArray:
    r"""Exact zero-order-hold equivalent G_d(e^(jωh)) of the distributed plant, sampled at h.

    fuelid's convention for a sampled loop (fuelid.tuning._frequency): the plant seen from the
    PLC, a zero-order hold on u and the output sampled at the same instants, i.e.
    G_d(z) = (1 − z⁻¹)·Z{G(s)/s}. For a rational plant fuelid computes it in closed form (the
    modified z-transform); for the distributed plant it is the aliasing (Poisson) sum

    .. math:: G_d(e^{j\omega h}) = \frac{1 - e^{-j\omega h}}{h}
        \sum_{k=-N}^{N} \frac{G(j\omega_k)}{j\omega_k},\qquad \omega_k = \omega + 2\pi k/h,

    exact as N → ∞ (the step response is continuous and zero at t = 0, so the Poisson sum of its
    samples has no half-jump term). With both lags G/s falls as ω⁻³ and the tail beyond N is
    O(N⁻²); with one lag (T_d = 0) as ω⁻² and the tail is O(N⁻¹), at most about
    2·K/(T_m·ω_s²·N) in the sum, i.e. K·h/(π²·T_m·N) in G_d. Measured against N = 32000 at
    h = 0.1 s: the default loop (two lags) within 1e-9 relative for N = 600; one lag
    (T_m = 0.15 s, τ = h, the worst case: the dead time's phase then does not rotate from alias
    to alias) within 5e-5 relative for N = 1000, the default. ``omega`` must be in (0, π/h].
    """
    w = np.asarray(omega, dtype=float)
    if np.any(w <= 0.0):
        raise ValueError("the sampled response is evaluated at positive frequencies")
    ws = 2.0 * math.pi / h
    total = np.zeros(w.shape, dtype=complex)
    # chunks of aliases keep the memory small (n_omega × chunk complex numbers)
    ks = np.arange(-terms, terms + 1, dtype=float)
    for start in range(0, ks.size, 256):
        k = ks[start : start + 256]
        wk = w[:, None] + k[None, :] * ws
        s = np.asarray(1j * wk, dtype=np.complex128)
        total += (_transfer(loop, u, s) / s).sum(axis=1)
    z_inv = np.exp(-1j * w * h)
    return np.asarray((1.0 - z_inv) / h * total, dtype=complex)


def pi_response(Kc: float, Ti: float, omega: ArrayLike, h: float) -> ComplexArray:
    """C(jω) = Kc(1 + 1/(Ti·jω)) for h = 0, else the PLC's forward-Euler PI at z = e^(jωh).

    C(z) = Kc·(1 + (h/Ti)·z⁻¹/(1 − z⁻¹)): the integral is updated after the output, the form
    fuelid's ``PISettings.velocity_coefficients`` states.
    """
    w = np.asarray(omega, dtype=float)
    if h == 0.0:
        return np.asarray(Kc * (1.0 + 1.0 / (1j * w * Ti)), dtype=complex)
    z_inv = np.exp(-1j * w * h)
    return np.asarray(Kc * (1.0 + (h / Ti) * z_inv / (1.0 - z_inv)), dtype=complex)


def loop_response(
    loop: DistributedLoop, u: float, Kc: float, Ti: float, h: float, omega: ArrayLike
) -> ComplexArray:
    """L = C·G (continuous, h = 0) or C(z)·G_d(z) at z = e^(jωh) (sampled)."""
    w = np.asarray(omega, dtype=float)
    g = frequency_response(loop, u, w) if h == 0.0 else zoh_response(loop, u, w, h)
    return np.asarray(pi_response(Kc, Ti, w, h) * g, dtype=complex)


def _grid(loop: DistributedLoop, Ti: float, h: float, n: int) -> FloatArray:
    rates = [1.0 / Ti, math.pi * loop.wave_speed / (2.0 * loop.length)]
    rates += [1.0 / tc for tc in (loop.T_d, loop.T_m, loop.tau) if tc > 0.0]
    lo = 1e-3 * min(rates)
    if h > 0.0:
        return np.geomspace(min(lo, 1e-4 / h), math.pi / h, n)
    # continuous: well beyond the fastest of the lags, the reset and the line's first modes
    # (rates holds the quarter-wave mode πa/(2l); 30 times it covers its first 15 harmonics)
    return np.geomspace(lo, 30.0 * max(rates), n)


def sensitivity_peak(
    loop: DistributedLoop, u: float, Kc: float, Ti: float, h: float, n: int = 1200
) -> float:
    """True maximum sensitivity Ms = max |1/(1 + L)| of the PI (Kc, Ti) on the loop at ``u``.

    The PI is the ideal C(s) = Kc·(1 + 1/(Ti·s)) [Kc in V per L/min, Ti in s]. For h = 0 it is
    continuous and L = C(jω)·G(jω) with the exact G of :func:`frequency_response`. For h > 0
    it is fuelid's convention (fuelid.tuning._frequency.robustness): the PLC's forward-Euler PI
    C(z) = Kc·(1 + (h/Ti)·z⁻¹/(1 − z⁻¹)) on the plant's exact zero-order-hold equivalent
    G_d(z) (:func:`zoh_response`), evaluated on z = e^(jωh) for ω up to the Nyquist frequency
    π/h: the sensitivity at the sampling instants (the ripple between samples is not counted,
    as in fuelid).

    Grid and accuracy: ``n`` log-spaced frequencies from 1e-3 times the slowest of the loop's
    rates (1/Ti, 1/T_d, 1/T_m, 1/τ, the quarter-wave mode πa/(2l)) up to π/h (sampled) or
    30 times the fastest of those (continuous: 15 harmonics of the line and a decade past the
    lags, where |L| < 0.02); then each of the three highest local maxima of |S| is refined by a
    bounded scalar search between its grid neighbours. With n = 1200 the grid steps are about
    1 % in ω for the default loop (1.7 % for a 5 cm line, whose mode sits at 3.5e4 rad/s), far
    finer than any resonance of the loop (the line's modes have relative widths 2ζ ≥ 0.3); the
    refined peak is a local maximum found to 1e-5 in log ω, so Ms is accurate to about 1e-6
    relative (a 4000-point grid gives the same Ms to 1e-11 at 1.1, 3 and 4.5 V), plus the
    alias sum's error for h > 0 (``zoh_response``).
    The loop must be closed-loop stable for Ms to mean anything: that is the caller's to check
    (:func:`closed_loop_stable`).
    """
    _check_command(loop, u)
    w = _grid(loop, Ti, h, n)

    def sens(x: FloatArray) -> FloatArray:
        return np.asarray(1.0 / np.abs(1.0 + loop_response(loop, u, Kc, Ti, h, x)))

    s = sens(w)
    interior = np.flatnonzero((s[1:-1] >= s[:-2]) & (s[1:-1] >= s[2:])) + 1
    candidates = list(interior[np.argsort(s[interior])[::-1][:3]])
    if s[-1] >= s[-2]:
        candidates.append(w.size - 1)
    best = float(s.max())
    for i in candidates:
        lo, hi = math.log(w[max(i - 1, 0)]), math.log(w[min(i + 1, w.size - 1)])
        res = scipy.optimize.minimize_scalar(
            lambda x: -float(sens(np.array([math.exp(x)]))[0]),
            bounds=(lo, hi),
            method="bounded",
            options={"xatol": 1e-5},
        )
        best = max(best, -float(res.fun))
    return best


def closed_loop_stable(
    loop: DistributedLoop, u: float, Kc: float, Ti: float, h: float, n: int = 1200
) -> bool:
    """Nyquist test: 1 + L turns by +π/2 from ω → 0+ to the top of the grid (stable plant, PI).

    The same winding criterion as fuelid.tuning._frequency.margins.
    """
    w = _grid(loop, Ti, h, n)
    one_plus = 1.0 + loop_response(loop, u, Kc, Ti, h, w)
    turn = float(np.unwrap(np.angle(one_plus))[-1] - np.angle(one_plus[0]))
    return abs(turn - math.pi / 2.0) < math.pi / 4.0


# ------------------------------------------------------------------------------------------
# Time domain: the nonlinear loop, the line by the method of characteristics


def default_segments(loop: DistributedLoop, h_sample: float) -> int:
    """MOC reaches: at least 16, and a time step Δt = l/(N·a) of at most h_sample/4."""
    return max(16, math.ceil(4.0 * loop.length / (loop.wave_speed * h_sample)))


def simulate(
    loop: DistributedLoop,
    command: Callable[[float], float] | tuple[FloatArray, float],
    duration: float,
    n_segments: int = 32,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Nonlinear loop by the method of characteristics, noise-free, at the MOC's own time step.

    The line's waves travel along the characteristics dx/dt = ±a; with Δt = Δx/a (Courant
    number 1) the MOC carries a wave without any numerical dispersion or damping, so it
    reproduces the echoes (every 2l/a) exactly, which a lumped chain of segments does not (its
    modes are dispersed; it would need hundreds of segments to place the first few modes
    within 1 %). Friction k_line·q|q| acts on each characteristic semi-implicitly
    (k·Δx·Q_P·|Q_A|, Wylie & Streeter's form: stable, exact in steady state, trapezoidal in its
    small-signal part). The boundaries are exact: the leaky pump (Q_0 = D·n − C_leak·p_0), the
    quadratic nozzles (p = k_N·Q|Q|, solved in closed form). The drive lag is integrated
    exactly over the held command (split at the command's switching instants), the meter lag
    exactly for a flow linear over each step (first-order hold), the meter's dead time by
    linear interpolation. Starts in steady state at the first command.

    Parameters
    ----------
    command : callable or (array, h)
        u(t) [V], or commands held for ``h`` each (a PLC's output), the first from t = 0.
    duration : float
        Simulated time [s].

    Returns
    -------
    (t, q_nozzle_Lpm, meter_undelayed_Lpm)
        The MOC time grid [s], the nozzle flow and the meter lag's output (before τ).
    """
    u_of: Callable[[float], float]
    switches: Callable[[float, float], list[float]]
    if isinstance(command, tuple):
        values, held = np.asarray(command[0], dtype=float), float(command[1])

        def held_command(t: float) -> float:
            k = min(math.floor(t / held + 1e-9), values.size - 1)
            return float(values[k])

        def held_switches(t0: float, t1: float) -> list[float]:
            k0 = math.floor(t0 / held + 1e-9) + 1
            k1 = math.floor(t1 / held + 1e-9)
            return [k * held for k in range(k0, k1 + 1)]

        u_of, switches = held_command, held_switches
    else:
        u_of, switches = command, lambda t0, t1: []

    N = n_segments
    dx = loop.length / N
    dt = dx / loop.wave_speed
    B = loop.z0
    kf = loop.k_line * dx
    kn = loop.k_nozzle
    G = loop.C_leak
    D = loop.displacement
    st = steady_state(loop, float(np.clip(u_of(0.0), *loop.u_span)))
    q0 = st["q_m3s"]
    p = st["p1_Pa"] - loop.k_line * q0 * q0 * dx * np.arange(N + 1)
    Q = np.full(N + 1, q0)
    n = st["n_rps"]
    meter = q0 * LPM
    steps = math.ceil(duration / dt)
    t_out = np.asarray(np.arange(steps + 1) * dt, dtype=float)
    q_out = np.empty(steps + 1)
    m_out = np.empty(steps + 1)
    q_out[0], m_out[0] = q0 * LPM, meter
    a_m = math.exp(-dt / loop.T_m) if loop.T_m > 0.0 else 0.0

    def drive(n: float, t0: float, t1: float) -> float:
        if loop.T_d == 0.0:
            return float(_speed_setpoint(loop, u_of(t1)))
        t = t0
        for ts in [*switches(t0, t1), t1]:
            if ts <= t:
                continue
            target = float(_speed_setpoint(loop, u_of(t)))
            n = target + (n - target) * math.exp(-(ts - t) / loop.T_d)
            t = ts
        return n

    for j in range(steps):
        t0, t1 = j * dt, (j + 1) * dt
        n = drive(n, t0, t1)
        # C+ from the left neighbour (nodes 1…N), C− from the right one (nodes 0…N−1)
        cp = p[:-1] + B * Q[:-1]
        bp = B + kf * np.abs(Q[:-1])
        cm = p[1:] - B * Q[1:]
        bm = B + kf * np.abs(Q[1:])
        Qn = np.empty_like(Q)
        pn = np.empty_like(p)
        Qn[1:-1] = (cp[:-1] - cm[1:]) / (bp[:-1] + bm[1:])
        pn[1:-1] = cp[:-1] - bp[:-1] * Qn[1:-1]
        # pump: Q = D·n − G·p, p = C− + B−·Q
        Qn[0] = (D * n - G * cm[0]) / (1.0 + G * bm[0])
        pn[0] = cm[0] + bm[0] * Qn[0]
        # nozzles: kn·Q|Q| = C+ − B+·Q
        c, b = cp[-1], bp[-1]
        Qn[-1] = 2.0 * c / (b + math.sqrt(b * b + 4.0 * kn * abs(c)))
        pn[-1] = kn * Qn[-1] * abs(Qn[-1])
        x0, x1 = Q[-1] * LPM, Qn[-1] * LPM
        if loop.T_m > 0.0:
            slope = (x1 - x0) / dt
            meter = x1 - slope * loop.T_m + (meter - x0 + slope * loop.T_m) * a_m
        else:
            meter = x1
        Q, p = Qn, pn
        q_out[j + 1], m_out[j + 1] = x1, meter
    return t_out, q_out, m_out


def simulate_log(
    loop: DistributedLoop,
    u_profile: ArrayLike,
    h_sample: float = 0.02,
    seed: int = 0,
    noise_std: float = 0.0,
    n_segments: int | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """A PLC log of the loop: commands held for ``h_sample`` each, the meter sampled with noise.

    Parameters
    ----------
    u_profile : array
        The PLC's command [V], one value per sample, each held for ``h_sample`` from t_k = k·h
        (the drive clips it to the 1–5 V range). The loop starts in steady state at u_profile[0].
    h_sample : float
        Sample period [s].
    seed : int
        Seed of the meter noise.
    noise_std : float
        Standard deviation of the white meter noise [L/min].
    n_segments : int, optional
        MOC reaches; default :func:`default_segments`.

    Returns
    -------
    (t, u, q)
        t_k = k·h [s], the commands [V], the meter reading at t_k [L/min]: the meter lag's output
        at t_k − τ (the sample at t_k does not yet see the command written at t_k) plus noise.
    """
    u: FloatArray = np.asarray(u_profile, dtype=float)
    if u.ndim != 1 or u.size < 2:
        raise ValueError("u_profile must be a 1-D array of at least two commands")
    N = default_segments(loop, h_sample) if n_segments is None else n_segments
    t = np.asarray(np.arange(u.size) * h_sample, dtype=float)
    duration = float(t[-1])
    tm, _, meter = simulate(loop, (u, h_sample), duration + 1e-9, N)
    delayed = np.interp(t - loop.tau, tm, meter, left=meter[0])
    rng = np.random.default_rng(seed)
    q = delayed + noise_std * rng.standard_normal(u.size)
    return t, u, np.asarray(q, dtype=float)


def write_log_csv(path: str | Path, t: ArrayLike, u: ArrayLike, q: ArrayLike) -> Path:
    """Write a log with fuelid's default columns ``t_s,u_V,q_Lpm`` (docs/reference/logs.md)."""
    out = Path(path)
    table = np.column_stack([np.asarray(t), np.asarray(u), np.asarray(q)])
    np.savetxt(out, table, delimiter=",", header="t_s,u_V,q_Lpm", comments="", fmt="%.10g")
    return out


# ------------------------------------------------------------------------------------------
# The step response from the frequency response (the tests' reference for the simulation)


def step_from_frequency_response(
    loop: DistributedLoop, u: float, t: ArrayLike, period: float = 64.0, dt: float = 1.0 / 1024
) -> FloatArray:
    """Unit-step response [L/min per V] at times ``t``, from G(jω) by an inverse FFT.

    The impulse response is the inverse Fourier transform of G on the grid 2πm/period up to
    the Nyquist frequency π/dt, integrated (trapezoid) to the step. Errors: time aliasing needs
    the impulse response to vanish within ``period`` (the slowest rate here is 1/T_d: e^(−128));
    the spectrum cut at π/dt ≈ 3200 rad/s leaves |G| ≲ K/(T_d·T_m·ω²) ≈ 1e-5·K, and the
    step's error from it is of that order.
    """
    m = round(period / dt)
    w = 2.0 * math.pi * np.fft.rfftfreq(m, dt)
    g = frequency_response(loop, u, w)
    impulse = np.fft.irfft(g, m) / dt
    ts = np.arange(m) * dt
    step = np.concatenate([[0.0], np.cumsum(0.5 * (impulse[1:] + impulse[:-1]) * dt)])
    return np.asarray(np.interp(np.asarray(t, dtype=float), ts, step), dtype=float)
