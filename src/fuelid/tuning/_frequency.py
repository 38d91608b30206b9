r"""Loop frequency responses and robustness margins, dead time exact, sampled controller included.

For a continuous controller the loop is L(jω) = C(jω)·G(jω) with G's dead time applied as the
exact factor e^(−jωθ) (never a Padé approximation). For a controller with period h the loop is
analysed as the sampled-data system it is at the sampling instants: the plant is discretised
exactly with a zero-order hold and its fractional dead time (modified z-transform, see
:mod:`fuelid.lti`), the controller is the PI the PLC runs, with the integral
updated after the output (forward Euler, Åström & Hägglund's PID code),

.. math:: C(z) = K_c\left(1 + \frac{h}{T_i}\,\frac{z^{-1}}{1 - z^{-1}}\right),

and L is evaluated on the unit circle z = e^(jωh) up to the Nyquist frequency π/h.

Margins: gain margin (a ratio, 1/|L| where the Nyquist curve crosses the negative real axis, the
smallest over all crossings), phase margin (180° + ∠L where |L| = 1, the smallest), maximum
sensitivity Ms = max |1/(1 + L)| (refined around the grid peak), and closed-loop stability from
the winding of 1 + L around the origin (the integrator's indentation included).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import scipy.optimize
import scipy.signal
from numpy.typing import ArrayLike, NDArray

from fuelid.errors import FuelidError
from fuelid.lti import discretise, modified_z
from fuelid.model import ProcessModel
from fuelid.tuning._rules import PISettings

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
LoopFunction = Callable[[FloatArray], ComplexArray]


class StateSpacePlant(Protocol):
    """Anything with a delay-free state-space part and an explicit dead time (a LinearPlant)."""

    @property
    def A(self) -> FloatArray: ...
    @property
    def B(self) -> FloatArray: ...
    @property
    def C(self) -> FloatArray: ...
    @property
    def D(self) -> FloatArray: ...
    @property
    def delay(self) -> float: ...


@dataclass(frozen=True)
class TransferFunctionPlant:
    """num(s)/den(s)·e^(−s·delay) in the controllable canonical state space (a StateSpacePlant).

    A model file's full-order ``linear_model`` (``fuelid plant info --json``): the gains are
    certified on it rather than on its reduction to the model family.
    """

    A: FloatArray
    B: FloatArray
    C: FloatArray
    D: FloatArray
    delay: float
    """Dead time [s]."""

    @classmethod
    def from_coefficients(
        cls, num: Sequence[float], den: Sequence[float], delay: float
    ) -> TransferFunctionPlant:
        """From polynomial coefficients in descending powers of s (proper: len(num) ≤ len(den)).

        Examples
        --------
        >>> plant = TransferFunctionPlant.from_coefficients([2.0], [1.0, 1.0], 0.5)
        >>> complex(state_space_response(plant, [0.0])[0])
        (2+0j)
        """
        A, B, C, D = scipy.signal.tf2ss(np.asarray(num, float), np.asarray(den, float))
        return cls(A=A, B=B, C=C, D=D, delay=float(delay))


def process_response(model: ProcessModel, omega: ArrayLike, h: float = 0.0) -> ComplexArray:
    """Frequency response of the model family, continuous (h = 0) or ZOH-sampled at period h.

    Parameters
    ----------
    model : ProcessModel
        K·e^(−θs)/((T·s+1)(T2·s+1)(T_f·s+1)).
    omega : array
        Angular frequencies [rad/s] (≤ π/h when sampled).
    h : float
        Sample period [s]; 0 for the continuous response.

    Returns
    -------
    ndarray of complex
        G(jω), or G(e^(jωh)) of the exact zero-order-hold discretisation.

    Examples
    --------
    1/(s+1) at ω = 1 rad/s: magnitude 1/√2, phase −45°.

    >>> g = process_response(ProcessModel(K=1.0, T=1.0), [1.0])[0]
    >>> round(float(abs(g)), 6), round(float(np.degrees(np.angle(g))), 3)
    (0.707107, -45.0)
    """
    w = np.asarray(omega, dtype=float)
    if h == 0.0:
        s = 1j * w
        g = np.asarray(model.K * np.exp(-s * model.delay), dtype=np.complex128)
        for tc in model.time_constants:
            g = g / (tc * s + 1.0)
        return np.asarray(g, dtype=complex)
    d = discretise(model.time_constants, model.delay, h)
    return np.asarray(model.K * d.frequency_response(w, h), dtype=complex)


def state_space_response(plant: StateSpacePlant, omega: ArrayLike, h: float = 0.0) -> ComplexArray:
    """Frequency response of a state-space plant with dead time (e.g. a linearised plant).

    Continuous: (C (jωI − A)⁻¹ B + D)·e^(−jωθ). Sampled: z^(−d)·C (zI − A_d)⁻¹ (Γ₀ + Γ₁ z⁻¹)
    with θ = d·h + τ' the modified z-transform; a feedthrough D ≠ 0 (no plant here has one) is
    refused there rather than silently dropped.
    """
    w = np.asarray(omega, dtype=float)
    A = np.asarray(plant.A, dtype=float)
    B = np.asarray(plant.B, dtype=float).reshape(-1, 1)
    C = np.asarray(plant.C, dtype=float).reshape(1, -1)
    n = A.shape[0]
    eye = np.eye(n)
    if h == 0.0:
        M = 1j * w[:, None, None] * eye - A
        x = np.linalg.solve(M, np.broadcast_to(B.astype(complex), (w.size, n, 1)))
        g = (C @ x)[:, 0, 0] + float(np.asarray(plant.D).ravel()[0])
        return np.asarray(g * np.exp(-1j * w * plant.delay), dtype=complex)
    if np.any(np.asarray(plant.D, dtype=float) != 0.0):
        raise FuelidError("the sampled frequency response of a plant with feedthrough D ≠ 0")
    mz = modified_z(A, B, h, plant.delay)
    z = np.exp(1j * w * h)
    M = z[:, None, None] * eye - mz.Ad
    rhs = mz.G0[None, :, :] + mz.G1[None, :, :] / z[:, None, None]
    x = np.linalg.solve(M, rhs)
    return np.asarray((C @ x)[:, 0, 0] * z ** (-mz.shift), dtype=complex)


def controller_response(pi: PISettings, omega: ArrayLike) -> ComplexArray:
    """C(jω) of the ideal PI, or C(e^(jωh)) of the forward-Euler PI for h > 0.

    Examples
    --------
    >>> pi = PISettings(rule="x", Kc=2.0, Ti=1.0, control_period=0.0)
    >>> complex(controller_response(pi, [1.0])[0])
    (2-2j)
    """
    w = np.asarray(omega, dtype=float)
    h = pi.control_period
    if h == 0.0:
        return np.asarray(pi.Kc * (1.0 + 1.0 / (1j * w * pi.Ti)), dtype=complex)
    q0, q1 = pi.velocity_coefficients()
    zi = np.exp(-1j * w * h)
    return np.asarray((q0 + q1 * zi) / (1.0 - zi), dtype=complex)


def loop_function(plant: ProcessModel | StateSpacePlant, pi: PISettings) -> LoopFunction:
    """L(ω) = C·G for the controller's period (continuous when ``pi.control_period`` is 0)."""
    h = pi.control_period
    if isinstance(plant, ProcessModel):
        if h > 0.0:
            # discretise once; evaluating the rational function is then cheap
            d = discretise(plant.time_constants, plant.delay, h)
            K = plant.K

            def sampled(w: FloatArray) -> ComplexArray:
                g = K * d.frequency_response(w, h)
                return np.asarray(g * controller_response(pi, w), dtype=complex)

            return sampled

        def continuous(w: FloatArray) -> ComplexArray:
            return np.asarray(process_response(plant, w) * controller_response(pi, w))

        return continuous

    def state_space(w: FloatArray) -> ComplexArray:
        return np.asarray(state_space_response(plant, w, h) * controller_response(pi, w))

    return state_space


@dataclass(frozen=True)
class Robustness:
    """Stability margins of one loop."""

    gain_margin: float
    """Factor by which the loop gain may grow before instability [-]; inf if the phase never
    reaches −180°."""
    phase_margin_deg: float
    """Phase margin [°]; inf if |L| never reaches 1."""
    Ms: float
    """Maximum sensitivity max |1/(1+L)| [-] (1.2–2 is the usual range; 1/Ms is the smallest
    distance of the Nyquist curve to −1)."""
    Mt: float
    """Maximum complementary sensitivity max |L/(1+L)| [-]."""
    crossover_frequency: float
    """Gain crossover ω_c, where |L| = 1 (the lowest) [rad/s]; nan if none."""
    phase_crossover_frequency: float
    """Where the gain margin is read [rad/s]; nan if none."""
    Ms_frequency: float
    """Where |S| peaks [rad/s]."""
    stable: bool
    """Closed-loop stability from the Nyquist winding number (open-loop stable plant)."""

    def to_json(self) -> dict[str, float | bool]:
        """Plain dictionary for JSON."""
        return {
            "gain_margin": self.gain_margin,
            "phase_margin_deg": self.phase_margin_deg,
            "Ms": self.Ms,
            "Mt": self.Mt,
            "crossover_frequency": self.crossover_frequency,
            "phase_crossover_frequency": self.phase_crossover_frequency,
            "Ms_frequency": self.Ms_frequency,
            "stable": self.stable,
        }


def frequency_grid(
    plant: ProcessModel | StateSpacePlant, pi: PISettings, n: int = 1500
) -> FloatArray:
    """Log-spaced frequencies covering the loop: from far below 1/Ti to π/h (or far above).

    The top is the Nyquist frequency π/h for a sampled loop, else 300 times the fastest of
    1/θ, 1/Ti and the plant's fastest pole.
    """
    if isinstance(plant, ProcessModel):
        rates = [1.0 / tc for tc in plant.time_constants]
        dc_gain = abs(plant.K)
    else:
        A = np.asarray(plant.A)
        rates = [float(r) for r in np.abs(np.linalg.eigvals(A).real) if r > 0]
        dc_gain = float(np.abs(np.asarray(plant.D) - plant.C @ np.linalg.solve(A, plant.B)).sum())
    rates.append(1.0 / pi.Ti)
    # a heavily detuned loop crosses over near K·Kc/Ti, where L ≈ K·Kc/(Ti·s): far below 1/Ti
    # and the plant's poles; the grid must start well below it for the winding to count
    if dc_gain > 0.0:
        rates.append(dc_gain * pi.Kc / pi.Ti)
    if plant.delay > 0.0:
        rates.append(1.0 / plant.delay)
    lo = 1e-3 * min(rates)
    if pi.control_period > 0.0:
        hi = math.pi / pi.control_period
        lo = min(lo, 1e-3 * hi)
    else:
        hi = 300.0 * max(rates)
    return np.geomspace(lo, hi, n)


def robustness(plant: ProcessModel | StateSpacePlant, pi: PISettings, n: int = 1500) -> Robustness:
    """Gain margin, phase margin, Ms and stability of PI ``pi`` on ``plant``.

    Parameters
    ----------
    plant : ProcessModel or LinearPlant
        The process (K positive, open-loop stable).
    pi : PISettings
        The controller; its ``control_period`` selects continuous or sampled analysis.
    n : int
        Grid size before the crossings and the peak are refined.

    Examples
    --------
    The worked example with AMIGO's gains (continuous): Ms ≈ 1.21.

    >>> from fuelid.tuning._rules import amigo
    >>> model = ProcessModel(K=1.0, T=2.0, delay=1.0)
    >>> round(robustness(model, amigo(model)).Ms, 2)
    1.21
    """
    return margins(loop_function(plant, pi), frequency_grid(plant, pi, n))


@dataclass(frozen=True)
class RobustPeak:
    """The worst Ms over a multiplicative model error |Δ(jω)| ≤ ℓ(ω)."""

    Ms: float
    """The worst Ms over the misfit [-]; inf when the misfit can make the loop unstable, or when
    the log does not bound it up to the loop's crossover."""
    omega: float
    """Where it is reached, or where the bound fails [rad/s]."""
    up_to: float
    """The frequencies it covers: those the log excites [rad/s]."""

    def to_json(self) -> dict[str, float | None]:
        """``Ms`` (null when not bounded), ``omega`` and ``up_to`` [rad/s]."""
        return {
            "Ms": self.Ms if math.isfinite(self.Ms) else None,
            "omega": self.omega,
            "up_to": self.up_to,
        }


def robust_peak(
    plant: ProcessModel | StateSpacePlant,
    pi: PISettings,
    misfit: Callable[[FloatArray], tuple[NDArray[np.complex128], FloatArray]],
    up_to: float = math.inf,
    n: int = 1500,
) -> RobustPeak:
    """The worst Ms of ``pi`` on every plant G·(1 + Δ) with Δ within ρ(ω) of Δ̂(jω).

    ``misfit(ω)`` returns (Δ̂, ρ): the model's relative error as estimated, with its phase, and
    the radius of its uncertainty (:class:`fuelid.identify.MisfitBound`). With
    S = 1/(1 + L) and T = L·S on the nominal loop the perturbed sensitivity is S/(1 + T·Δ), so

        |S_Δ| ≤ |S|/(|1 + T·Δ̂| − |T|·ρ)

    wherever the denominator is positive, and the loop stays stable when it is positive at every
    frequency (the small-gain theorem about the estimate). Only frequencies up to ``up_to`` (those
    the log excites) are covered: when the nominal loop's gain crossover lies above it, the log
    says nothing about the misfit where it matters and the result is inf. For a sampled PI the
    continuous
    plant's error is applied to the sampled loop at the same frequency, which holds well below
    the Nyquist frequency π/h, where the loop's crossover lies.

    Examples
    --------
    No error: the nominal Ms (the worked AMIGO example, 1.21); a 10 % error of unknown phase
    everywhere makes it worse.

    >>> from fuelid.tuning._rules import amigo
    >>> model = ProcessModel(K=1.0, T=2.0, delay=1.0)
    >>> pi = amigo(model)
    >>> none = lambda w: (0j * w, 0.0 * w)
    >>> round(robust_peak(model, pi, none).Ms, 2)
    1.21
    >>> robust_peak(model, pi, lambda w: (0j * w, 0.1 + 0.0 * w)).Ms > 1.21
    True
    """
    crossover = robustness(plant, pi, n).crossover_frequency
    if not crossover <= up_to:
        return RobustPeak(math.inf, crossover, up_to)
    omega = frequency_grid(plant, pi, n)
    omega = omega[omega <= up_to]
    loop = loop_function(plant, pi)(omega)
    sensitivity = 1.0 / (1.0 + loop)
    complementary = loop * sensitivity
    delta, radius = misfit(omega)
    room = np.abs(1.0 + complementary * delta) - np.abs(complementary) * radius
    if np.any(room <= 0.0):
        return RobustPeak(math.inf, float(omega[np.argmax(room <= 0.0)]), up_to)
    ratio = np.abs(sensitivity) / room
    peak = int(np.argmax(ratio))
    return RobustPeak(float(ratio[peak]), float(omega[peak]), up_to)


def margins(loop: LoopFunction, omega: FloatArray) -> Robustness:
    """Margins of a loop with integral action from its frequency response on a grid.

    Crossings found between grid points are refined with Brent's method, the sensitivity peak
    with a bounded scalar search, so the grid only has to separate them.
    """
    w = np.asarray(omega, dtype=float)
    L = loop(w)
    S = 1.0 / (1.0 + L)
    # Ms: grid peak, refined in log ω between its neighbours
    k = int(np.argmax(np.abs(S)))
    lo, hi = w[max(k - 1, 0)], w[min(k + 1, w.size - 1)]
    Ms, w_ms = float(abs(S[k])), float(w[k])
    if hi > lo:

        def neg_s(log_w: float) -> float:
            value = loop(np.array([math.exp(log_w)]))[0]
            return -1.0 / float(abs(1.0 + value))

        best = scipy.optimize.minimize_scalar(
            neg_s, bounds=(math.log(lo), math.log(hi)), method="bounded"
        )
        if -best.fun > Ms:
            Ms, w_ms = float(-best.fun), math.exp(float(best.x))
    Mt = float(np.max(np.abs(L * S)))

    def refine(f: Callable[[float], float], i: int) -> float:
        return float(scipy.optimize.brentq(f, math.log(w[i]), math.log(w[i + 1]), xtol=1e-12))

    # gain crossovers: |L| passes 1
    log_mag = np.log(np.abs(L))
    pms: list[tuple[float, float]] = []
    for i in np.flatnonzero(np.sign(log_mag[:-1]) * np.sign(log_mag[1:]) < 0):
        x = refine(lambda lw: float(np.log(abs(loop(np.array([math.exp(lw)]))[0]))), int(i))
        value = loop(np.array([math.exp(x)]))[0]
        pm = (math.degrees(float(np.angle(value))) + 360.0) % 360.0 - 180.0
        pms.append((pm, math.exp(x)))
    # phase crossovers: the Nyquist curve crosses the negative real axis
    gms: list[tuple[float, float]] = []
    im = L.imag
    for i in np.flatnonzero(np.sign(im[:-1]) * np.sign(im[1:]) < 0):
        x = refine(lambda lw: float(loop(np.array([math.exp(lw)]))[0].imag), int(i))
        value = loop(np.array([math.exp(x)]))[0]
        if value.real < 0.0:
            gms.append((1.0 / abs(value), math.exp(x)))
    if abs(im[-1]) <= 1e-9 * abs(L[-1]) and L[-1].real < 0.0:  # sampled loop at π/h
        gms.append((1.0 / abs(L[-1]), float(w[-1])))
    pm, w_c = min(pms) if pms else (math.inf, math.nan)
    gm, w_pc = min(gms) if gms else (math.inf, math.nan)
    # winding: for a stable plant with an integrator the closed loop is stable exactly when the
    # phase of 1 + L rises by π/2 from ω → 0+ to the top of the grid (see the module docstring)
    turn = float(np.unwrap(np.angle(1.0 + L))[-1] - np.angle(1.0 + L[0]))
    stable = abs(turn - math.pi / 2.0) < math.pi / 4.0
    return Robustness(
        gain_margin=gm,
        phase_margin_deg=pm,
        Ms=Ms,
        Mt=Mt,
        crossover_frequency=w_c,
        phase_crossover_frequency=w_pc,
        Ms_frequency=w_ms,
        stable=stable,
    )
