"""Exact sampled-data form of the model family: ZOH input, fractional dead time, lfilter speed.

For a chain of first-order lags with unit static gain and dead time θ = d·h + τ' (0 ≤ τ' < h),
a zero-order-held input delayed by θ switches inside each sample interval, so the exact
discretisation has two input matrices (the modified z-transform):

    x[k+1] = A_d x[k] + Γ₀ v[k] + Γ₁ v[k−1],   v[k] = u[k−d],
    Γ₀ = ∫₀^{h−τ'} e^{As} ds B,   Γ₁ = e^{A(h−τ')} ∫₀^{τ'} e^{As} ds B.

This is continuous in θ (at τ' → h it becomes the next integer delay), which the delay search
relies on. The result is a rational filter in z⁻¹ applied with :func:`scipy.signal.lfilter`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.signal
from numpy.typing import NDArray

from fuelid.lti import zoh_discretise

FloatArray = NDArray[np.float64]


def lag_chain(lags: Sequence[float]) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(A, B, C) of 1/Π(T_i s + 1) as a chain of first-order lags (unit static gain).

    Examples
    --------
    >>> A, B, C = lag_chain([2.0])
    >>> A.tolist(), B.tolist(), C.tolist()
    ([[-0.5]], [[0.5]], [[1.0]])
    """
    n = len(lags)
    A = np.zeros((n, n))
    B = np.zeros((n, 1))
    C = np.zeros((1, n))
    for i, tc in enumerate(lags):
        A[i, i] = -1.0 / tc
        if i == 0:
            B[0, 0] = 1.0 / tc
        else:
            A[i, i - 1] = 1.0 / tc
    C[0, n - 1] = 1.0
    return A, B, C


@dataclass(frozen=True)
class DiscreteLagModel:
    """Unit-gain lag chain with dead time, sampled with a zero-order hold at interval ``h``."""

    b: FloatArray
    """Numerator in powers of z⁻¹ (after the integer delay)."""
    a: FloatArray
    """Denominator in powers of z⁻¹, a[0] = 1."""
    shift: int
    """Integer part d of the delay in samples."""
    poles: FloatArray
    """Discrete poles e^(−h/T_i), one per lag."""

    def response(self, du: FloatArray) -> FloatArray:
        """Output for the input deviation ``du`` (zero before the record: the model at rest)."""
        v = np.zeros_like(du)
        if self.shift < du.size:
            v[self.shift :] = du[: du.size - self.shift]
        return np.asarray(scipy.signal.lfilter(self.b, self.a, v), dtype=float)

    def modes(self, n: int) -> FloatArray:
        """Free-response basis p_i^k, k = 0…n−1, one column per pole (shape (n, n_poles))."""
        out = np.zeros((n, self.poles.size))
        for j, p in enumerate(self.poles):
            # p^k falls below 1e-18 after log(1e-18)/log(p) samples: only compute that far
            length = n if p <= 0.0 or p >= 1.0 else min(n, math.ceil(-41.5 / math.log(p)) + 1)
            out[:length, j] = np.exp(np.arange(length) * math.log(p)) if p > 0.0 else 0.0
            if p <= 0.0:
                out[0, j] = 1.0
        return out


def discretise(lags: Sequence[float], delay: float, h: float) -> DiscreteLagModel:
    """Exact ZOH discretisation of ``e^(−θs)/Π(T_i s + 1)`` at sample interval ``h``.

    Parameters
    ----------
    lags : sequence of float
        Time constants T_i [s], all positive.
    delay : float
        Dead time θ [s], non-negative (fractional multiples of h are exact).
    h : float
        Sample interval [s].

    Returns
    -------
    DiscreteLagModel

    Examples
    --------
    One lag T = 1 s, no delay, h = 1 s: y[k] = e⁻¹ y[k−1] + (1 − e⁻¹) u[k−1].

    >>> m = discretise([1.0], 0.0, 1.0)
    >>> [round(float(v), 6) for v in m.b], [round(float(v), 6) for v in m.a]
    ([0.0, 0.632121, 0.0], [1.0, -0.367879, 0.0])
    """
    A, B, C = lag_chain(lags)
    n = A.shape[0]
    d = math.floor(delay / h + 1e-12)
    frac = max(delay - d * h, 0.0)
    E1, G0 = zoh_discretise(A, B, h - frac)
    E2, G2 = zoh_discretise(A, B, frac)
    Ad = E1 @ E2
    G1 = E1 @ G2
    num0, den = scipy.signal.ss2tf(Ad, G0, C, np.zeros((1, 1)))
    num1, _ = scipy.signal.ss2tf(Ad, G1, C, np.zeros((1, 1)))
    b = np.zeros(n + 2)
    b[: n + 1] += np.ravel(num0)
    b[1:] += np.ravel(num1)
    a = np.zeros(n + 2)
    a[: n + 1] = np.ravel(den)
    poles = np.exp(-h / np.asarray(lags, dtype=float))
    return DiscreteLagModel(b=b, a=a, shift=d, poles=poles)
