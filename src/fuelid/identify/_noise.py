"""The noise model of the prediction-error fit: polynomials, filters, the order choice.

The noise v = C(q)/D(q)·e of :class:`~fuelid.identify._pem.PredictionError` has monic
polynomials in q⁻¹ of degree nc and nd (0…2 each). They are parametrised by reflection
coefficients κ = tanh η (the Levinson step-up recursion turns them into coefficients), so D is
always stable and C minimum-phase without clipping or constraints. Filters restart at every
segment of a record with gaps. The order (nc, nd) is chosen by the Hannan–Rissanen method: one
long autoregression estimates the innovations, then every candidate is a linear regression, and
the candidates are ranked by an information criterion.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.signal
from numpy.typing import NDArray

from fuelid.errors import FuelidError
from fuelid.identify._variable_projection import solve_linear

FloatArray = NDArray[np.float64]
Bounds = list[tuple[int, int]]
NoiseOrder = tuple[int, int]
"""(nc, nd): the degrees of the noise model's numerator C and denominator D in q⁻¹."""

MAX_NOISE_DEGREE = 2
"""Highest degree of C and of D [samples]."""
NOISE_ORDERS: tuple[NoiseOrder, ...] = tuple(
    (nc, nd) for nd in range(MAX_NOISE_DEGREE + 1) for nc in range(MAX_NOISE_DEGREE + 1)
)
"""The (nc, nd) candidates of ``noise_order="auto"``: every pair with degrees 0…2."""
SELECTION_WARMUP = MAX_NOISE_DEGREE
"""Samples of each segment left out of the order-selection criterion, for every candidate
alike (so their criteria are sums over the same samples)."""
MAX_REFLECTION = 0.9999
"""Largest |κ| a warm start is clipped to (a pole or zero of at most 0.9999 in modulus)."""
LONG_AR_ORDER = 20
"""Order of the long autoregression that estimates the innovations for the noise-order choice
(Hannan–Rissanen) [samples]."""
ETA_BOUND = 8.0  # |η| ≤ 8: |κ| ≤ 1 − 2·10⁻⁷, a pole as close to 1 as double precision needs


# ---------------------------------------------------------------------- noise polynomials
def step_up(kappa: FloatArray) -> FloatArray:
    """Monic polynomial in q⁻¹ from reflection coefficients (Levinson step-up recursion).

    a_m(q) = a_{m−1}(q) + κ_m·q⁻ᵐ·a_{m−1}(q⁻¹): every root lies inside the unit circle iff
    every |κ_m| < 1 (Schur–Cohn), so D is stable and C minimum-phase for any κ = tanh(η).

    Examples
    --------
    >>> step_up(np.array([-0.9])).tolist()
    [1.0, -0.9]
    """
    a = np.array([1.0])
    for k in kappa:
        a = np.r_[a, 0.0] + k * np.r_[0.0, a[::-1]]
    return a


def step_down(a: Sequence[float]) -> FloatArray:
    """Reflection coefficients of a monic polynomial (inverse of :func:`step_up`), clipped.

    A polynomial with a root on or outside the unit circle has some |κ| ≥ 1; clipping to
    :data:`MAX_REFLECTION` maps it to a nearby stable one (a warm start from another record).
    """
    poly = np.asarray(a, dtype=float)
    kappa: list[float] = []
    while poly.size > 1:
        k = float(np.clip(poly[-1], -MAX_REFLECTION, MAX_REFLECTION))
        kappa.append(k)
        poly = (poly[:-1] - k * poly[:0:-1]) / (1.0 - k * k)
    return np.array(kappa[::-1])


@dataclass(frozen=True)
class NoiseShape:
    """Noise model C/D for one (nc, nd), parametrised by η (κ = tanh η), D's first."""

    nc: int
    nd: int

    @property
    def size(self) -> int:
        """Number of noise parameters, nc + nd."""
        return self.nc + self.nd

    @property
    def names(self) -> tuple[str, ...]:
        """Parameter names: ``noise_d1…`` then ``noise_c1…``."""
        return (
            *(f"noise_d{i}" for i in range(1, self.nd + 1)),
            *(f"noise_c{i}" for i in range(1, self.nc + 1)),
        )

    def polys(self, eta: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(C, D) coefficient arrays in powers of q⁻¹ (leading 1)."""
        kappa = np.tanh(eta)
        return step_up(kappa[self.nd :]), step_up(kappa[: self.nd])

    def eta(self, C: Sequence[float], D: Sequence[float]) -> FloatArray:
        """η of given polynomials, padded with zeros (or truncated) to this order."""
        kd = np.zeros(self.nd)
        kc = np.zeros(self.nc)
        d, c = step_down(D), step_down(C)
        kd[: min(d.size, self.nd)] = d[: self.nd]
        kc[: min(c.size, self.nc)] = c[: self.nc]
        return np.asarray(np.arctanh(np.r_[kd, kc]), dtype=float)


def filter_segments(num: FloatArray, den: FloatArray, x: FloatArray, bounds: Bounds) -> FloatArray:
    """num(q)/den(q)·x along axis 0, restarted from zero initial conditions at each segment."""
    if num.size == 1 and den.size == 1:
        return x if num[0] == 1.0 else num[0] * x
    out = np.empty_like(x)
    for a, b in bounds:
        out[a:b] = scipy.signal.lfilter(num, den, x[a:b], axis=0)
    return out


def shift_segments(x: FloatArray, lag: int, bounds: Bounds) -> FloatArray:
    """q⁻ˡᵃᵍ·x within each segment (zeros where the lagged sample lies before the segment)."""
    out = np.zeros_like(x)
    for a, b in bounds:
        if b - a > lag:
            out[a + lag : b] = x[a : b - lag]
    return out


def used_samples(bounds: Bounds, n: int, warmup: int) -> NDArray[np.bool_]:
    """Samples in the criterion: all but the first ``warmup`` of each segment."""
    keep = np.ones(n, dtype=bool)
    for a, b in bounds:
        keep[a : min(a + warmup, b)] = False
    return keep


def information_criterion(sse: float, n: int, k: int, kind: str) -> float:
    """N·ln(SSE/N) + k·ln N (BIC) or + 2k (AIC)."""
    penalty = math.log(n) if kind == "bic" else 2.0
    return n * math.log(max(sse, 1e-300) / n) + penalty * k


def roots_json(poly: FloatArray) -> list[float | list[float]]:
    """Roots in z of a monic polynomial in q⁻¹ (complex ones as [real, imaginary]: JSON)."""
    out: list[float | list[float]] = []
    for root in np.roots(poly) if poly.size > 1 else []:
        real, imag = float(root.real), float(root.imag)
        out.append(real if abs(imag) < 1e-12 else [real, imag])
    return out


def lagged(
    x: FloatArray, lags: int, bounds: Bounds, skip: int
) -> tuple[NDArray[np.intp], FloatArray]:
    """Rows k (at least ``skip`` after their segment's start) and [x(k−1) … x(k−lags)]."""
    parts = [np.arange(a + skip, b, dtype=np.intp) for a, b in bounds if b > a + skip]
    rows = np.concatenate(parts) if parts else np.zeros(0, dtype=np.intp)
    return rows, x[rows[:, None] - np.arange(1, lags + 1)]


def hannan_rissanen(
    r: FloatArray, candidates: Sequence[NoiseOrder], bounds: Bounds
) -> dict[NoiseOrder, tuple[FloatArray, float]]:
    """η of each candidate (nc, nd) fitted to the residual r, and Σ(D/C·r)² on common samples.

    The Hannan–Rissanen method (Hannan & Rissanen, *Biometrika* 69, 1982): a long
    autoregression (order :data:`LONG_AR_ORDER`) by least squares estimates the innovations ê;
    then each candidate is one linear regression

        r(k) = −Σ d_i r(k−i) + Σ c_j ê(k−j) + e(k)

    (exact conditional least squares for the autoregressive ones), its polynomials are made
    stable and minimum-phase (reflection coefficients clipped to :data:`MAX_REFLECTION`), and
    its criterion is Σε² over every sample but the first :data:`SELECTION_WARMUP` of each
    segment. Nothing iterative: the order choice costs a handful of filter passes, and the
    joint search refines the chosen candidate.
    """
    keep = used_samples(bounds, r.size, SELECTION_WARMUP)
    out: dict[NoiseOrder, tuple[FloatArray, float]] = {}
    skip = LONG_AR_ORDER + MAX_NOISE_DEGREE
    rows, X = lagged(r, LONG_AR_ORDER, bounds, LONG_AR_ORDER)
    e_hat = r.copy()  # where the long autoregression has no past: the residual itself
    if rows.size > 2 * LONG_AR_ORDER:
        e_hat[rows] = r[rows] - X @ solve_linear(X, r[rows]).beta
    rows, R = lagged(r, MAX_NOISE_DEGREE, bounds, skip)
    _, E = lagged(e_hat, MAX_NOISE_DEGREE, bounds, skip)
    for nc, nd in candidates:
        noise = NoiseShape(nc, nd)
        eta = np.zeros(noise.size)
        if noise.size and rows.size > 10 * noise.size:
            regressors = np.column_stack([-R[:, :nd], E[:, :nc]])
            coef = solve_linear(regressors, r[rows]).beta
            eta = noise.eta(np.r_[1.0, coef[nd:]], np.r_[1.0, coef[:nd]])
        C, D = noise.polys(eta)
        e = filter_segments(D, C, r, bounds)[keep]
        out[(nc, nd)] = (eta, float(e @ e))
    return out


def noise_coefficients(noise_init: Mapping[str, Any]) -> tuple[list[float], list[float]]:
    """The lists C and D of a noise model given as a mapping (``noise_model_``'s keys)."""
    try:
        return (
            [float(c) for c in noise_init["C"]],
            [float(d) for d in noise_init["D"]],
        )
    except (KeyError, TypeError, ValueError) as err:
        raise FuelidError(
            "noise_init needs coefficient lists 'C' and 'D' (as in noise_model_)"
        ) from err


def check_noise_start(C: Sequence[float], D: Sequence[float]) -> None:
    """Refuse a starting noise model that is not monic or beyond :data:`MAX_NOISE_DEGREE`."""
    if not C or not D or C[0] != 1.0 or D[0] != 1.0:
        raise FuelidError("noise_init: C and D must be monic lists ([1.0, …])")
    if len(C) - 1 > MAX_NOISE_DEGREE or len(D) - 1 > MAX_NOISE_DEGREE:
        raise FuelidError(f"noise_init: C and D may have degree {MAX_NOISE_DEGREE} at most")
