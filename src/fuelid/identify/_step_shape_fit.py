r"""Stage 2 of the article's method: K and T of the step shape fitted to the coefficients â.

The model step response with the flowmeter's T_f and dead time τ known,

.. math:: s(t) = K\left[1 - \frac{T e^{-t'/T} - T_f e^{-t'/T_f}}{T - T_f}\right],
          \qquad t' = t - \tau \;(s = 0 \text{ for } t' \le 0),

is fitted to :math:`\hat a_i` at :math:`t_i = i\,T_s` (K(1 − e^(−t'/T)) when T_f = 0, and the
repeated-root limit when T → T_f). K enters linearly and is eliminated in closed form for each T;
T solves the nonlinear normal equation of the concentrated cost by a safeguarded Newton
iteration in ln T (:func:`fit_step_shape`). Stage 1, the coefficients, is
:class:`~fuelid.identify._step_ls.StepResponseLS`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

#: relative gap |T − T_f|/T_f below which the shape uses its Taylor series about T = T_f
_NEAR_TF = 1e-3
#: N above which the method is warned to be a poor fit for the sample time
_MANY_COEFFICIENTS = 60
#: search range of T relative to T_s (lower) and N·T_s (upper)
_T_LOWER, _T_UPPER = 1e-3, 1e3
#: Newton: maximum iterations, step limit in ln T, convergence tolerance in ln T
_MAX_ITER, _MAX_STEP, _TOL = 100, 1.0, 1e-13


def step_shape(t: ArrayLike, T: float, T_f: float = 0.0, delay: float = 0.0) -> FloatArray:
    """Unit-gain step response of e^(−τs)/((T s+1)(T_f s+1)) at the times ``t``.

    Parameters
    ----------
    t : array
        Times after the step [s].
    T : float
        Process time constant [s], > 0.
    T_f : float
        Flowmeter time constant [s], ≥ 0 (0: first order).
    delay : float
        Dead time τ [s].

    Returns
    -------
    ndarray
        s(t)/K [-], 0 for t ≤ τ; robust for T close to or equal to T_f.

    Examples
    --------
    >>> [round(float(v), 6) for v in step_shape([0.5, 2.0], T=1.0, delay=1.0)]
    [0.0, 0.632121]
    >>> a = step_shape([3.0], T=2.0, T_f=2.0)  # repeated root: 1 − (1 + t/T)·e^(−t/T)
    >>> round(float(a[0]), 9) == round(1 - 2.5 * math.exp(-1.5), 9)
    True
    """
    x = np.maximum(np.asarray(t, dtype=float) - delay, 0.0)
    return _shape(x, T, T_f)[0]


def _shape(x: FloatArray, T: float, T_f: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Unit-gain shape g(x; T) and its first two derivatives with respect to T.

    ``x`` is the time since the delayed step [s] (≥ 0). With h(T) = T·e^(−x/T) the shape is
    g = 1 − D, D = (h(T) − h(T_f))/(T − T_f), a divided difference; near T = T_f it is evaluated
    from its Taylor series about T_f (cancellation-free), at T_f = 0 it is 1 − e^(−x/T).
    """
    if T_f == 0.0:
        z = x / T
        e = np.exp(-z)
        return 1.0 - e, -e * z / T, -e * z * (z - 2.0) / T**2
    delta = T - T_f
    if abs(delta) < _NEAR_TF * T_f:
        # derivatives of h at T_f: h1 = E(1+z), h2 = E z²/T_f, h3 = E z²(z−3)/T_f²,
        # h4 = E z²(z²−8z+12)/T_f³ with z = x/T_f, E = e^(−z)
        z = x / T_f
        e = np.exp(-z)
        h1 = e * (1.0 + z)
        h2 = e * z**2 / T_f
        h3 = e * z**2 * (z - 3.0) / T_f**2
        h4 = e * z**2 * (z**2 - 8.0 * z + 12.0) / T_f**3
        d0 = h1 + delta * h2 / 2.0 + delta**2 * h3 / 6.0 + delta**3 * h4 / 24.0
        d1 = h2 / 2.0 + delta * h3 / 3.0 + delta**2 * h4 / 8.0
        d2 = h3 / 3.0 + delta * h4 / 4.0
        return 1.0 - d0, -d1, -d2
    z = x / T
    e = np.exp(-z)
    h_t = T * e
    h1_t = e * (1.0 + z)
    h2_t = e * z**2 / T
    d0 = (h_t - T_f * np.exp(-x / T_f)) / delta
    d1 = (h1_t - d0) / delta
    d2 = (h2_t - 2.0 * d1) / delta
    return 1.0 - d0, -d1, -d2


@dataclass
class _Profile:
    """Concentrated cost J(φ) = min_K Σ(â − K g)², φ = ln T, with its derivatives in φ."""

    cost: float
    grad: float
    hess: float
    K: float
    g: FloatArray
    g1: FloatArray


def _profile(a: FloatArray, x: FloatArray, T: float, T_f: float) -> _Profile:
    g, g1, g2 = _shape(x, T, T_f)
    Q = float(g @ g)
    if Q <= 0.0:
        return _Profile(float(a @ a), 0.0, 0.0, 0.0, g, g1)
    P = float(a @ g)
    K = P / Q
    P1, P2 = float(a @ g1), float(a @ g2)
    Q1, Q2 = 2.0 * float(g @ g1), 2.0 * float(g1 @ g1 + g @ g2)
    r = a - K * g
    dJ = -2.0 * K * P1 + K**2 * Q1  # dJ/dT (envelope theorem: K(T) is optimal)
    dK = (P1 - K * Q1) / Q
    d2J = -2.0 * dK * P1 - 2.0 * K * P2 + 2.0 * K * dK * Q1 + K**2 * Q2
    return _Profile(float(r @ r), T * dJ, T**2 * d2J + T * dJ, K, g, g1)


def _cost(a: FloatArray, x: FloatArray, T: float, T_f: float) -> float:
    g = _shape(x, T, T_f)[0]
    Q = float(g @ g)
    K = float(a @ g) / Q if Q > 0.0 else 0.0
    r = a - K * g
    return float(r @ r)


def _initial_T(a: FloatArray, t: FloatArray, T_f: float, delay: float, T_s: float) -> float:
    """T from the time â first reaches 63 % of â_N (minus the known lags), at least T_s/10."""
    if a[-1] == 0.0:
        return float(t[-1]) / 4.0
    r = np.concatenate(([0.0], a / a[-1]))
    tt = np.concatenate(([0.0], t))
    above = np.flatnonzero(r >= 1.0 - math.exp(-1.0))
    if above.size == 0 or above[0] == 0:
        return float(t[-1]) / 4.0
    i = int(above[0])
    frac = (1.0 - math.exp(-1.0) - r[i - 1]) / (r[i] - r[i - 1])
    t63 = float(tt[i - 1] + frac * (tt[i] - tt[i - 1]))
    return max(t63 - delay - T_f, 0.1 * T_s)


@dataclass(frozen=True)
class StepShapeFit:
    """K and T of the step shape fitted to â, with what the covariance and warnings need."""

    K: float
    T: float
    g: FloatArray
    """The unit-gain shape at the coefficients' times."""
    g1: FloatArray
    """Its derivative with respect to T."""
    iterations: int
    converged: bool
    at_bound: bool
    """T reached the search range's bound (the coefficients do not determine it)."""


def fit_step_shape(a: FloatArray, T_s: float, T_f: float, delay: float) -> StepShapeFit:
    """K closed-form, T by safeguarded Newton on the concentrated cost in ln T.

    Parameters
    ----------
    a : ndarray
        Step-response coefficients â_1 … â_N at the times i·T_s.
    T_s : float
        Their spacing (the control period) [s].
    T_f, delay : float
        The known flowmeter lag and dead time [s].
    """
    N = a.size
    t = T_s * np.arange(1, N + 1, dtype=float)
    x = np.maximum(t - delay, 0.0)
    lo, hi = math.log(_T_LOWER * T_s), math.log(_T_UPPER * N * T_s)

    # start: the 63 % estimate, or the best point of a coarse ln-T grid if that is better
    start = min(max(math.log(_initial_T(a, t, T_f, delay, T_s)), lo), hi)
    grid = np.linspace(lo, hi, 49)
    costs = [_cost(a, x, math.exp(p), T_f) for p in grid]
    best = int(np.argmin(costs))
    if costs[best] < _cost(a, x, math.exp(start), T_f):
        start = float(grid[best])

    phi = start
    prof = _profile(a, x, math.exp(phi), T_f)
    iterations = 0
    converged = False
    while not converged and iterations < _MAX_ITER:
        iterations += 1
        if prof.hess > 0.0:
            step = -prof.grad / prof.hess
        else:  # not convex here: go downhill
            step = -math.copysign(0.5, prof.grad) if prof.grad != 0.0 else 0.0
        step = max(-_MAX_STEP, min(_MAX_STEP, step))
        lam = 1.0
        while True:  # backtracking (Armijo) within the bounds
            new = min(max(phi + lam * step, lo), hi)
            trial = _profile(a, x, math.exp(new), T_f)
            if trial.cost <= prof.cost + 1e-4 * (new - phi) * prof.grad:
                break
            lam *= 0.5
            if lam < 1e-12:  # no decrease along the step: at the minimum to rounding
                new, trial = phi, prof
                break
        converged = abs(new - phi) < _TOL
        phi, prof = new, trial
    at_bound = phi <= lo + 1e-9 or phi >= hi - 1e-9
    return StepShapeFit(prof.K, math.exp(phi), prof.g, prof.g1, iterations, converged, at_bound)
