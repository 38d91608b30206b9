"""How far two roundings of one number may lie apart: the budgets route-against-route tests use.

A test that checks a fast route against a reference one (dot products against an FFT, a Gram
matrix against a product, powers by doubling against a step at a time) compares two roundings of
the same exact number. Which of them a processor gives depends on its kernels (the BLAS's
blocking, fused multiply-adds, the vector width), so the band is the error analysis's bound for
each route, summed, and never what one machine printed. The bounds are the standard ones
(N. J. Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., SIAM 2002):

- n roundings in a row, each of relative error at most the unit roundoff u = ε/2, multiply a
  result by at most 1 + γ_n, γ_n = n·u/(1 − n·u) (§3.1);
- a sum or dot product of n terms, in any order (pairwise, blocked, vectorised), is off by at
  most γ_n·Σ|terms| (§3.1, eq. 3.5); a matrix product by γ_k·|A||B| entry by entry, k the inner
  dimension, and a chain A₁⋯A_m by γ_(k₁+⋯+k_(m−1))·|A₁|⋯|A_m| to first order (§3.5);
- a radix-2 FFT of length N is off by at most log₂N·η/(1 − log₂N·η) in the 2-norm of its
  result, η = μ + γ₄(√2 + μ), μ ≈ u the error of the computed twiddle factors (Thm 24.2);
- a linear recursion x[k+1] = a·x[k] + … carries an error made at one step to every later one
  with gain at most its impulse response's ℓ₁ norm, ‖g‖₁ ≤ Π 1/(1 − |p_i|) over its poles p_i.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

UNIT_ROUNDOFF = float(np.finfo(float).eps) / 2.0
"""u = 2⁻⁵³: the largest relative error of one rounding to double precision."""


def gamma(n: int) -> float:
    """γ_n = n·u/(1 − n·u): a result's relative error bound after n roundings in a row.

    Examples
    --------
    >>> f"{gamma(10_000):.3g}"
    '1.11e-12'
    """
    nu = n * UNIT_ROUNDOFF
    if nu >= 1.0:
        raise ValueError(f"γ_{n} is unbounded: n·u = {nu:.3g} ≥ 1")
    return nu / (1.0 - nu)


def product_budget(*factors: np.ndarray) -> np.ndarray:
    """Entrywise bound on the rounding of the chain product A₁⋯A_m, in any order and blocking.

    γ_(k₁+⋯+k_(m−1))·|A₁|⋯|A_m|, k_i the inner dimensions (to first order in u). A dot product
    is the chain of a row and a column.

    Examples
    --------
    >>> x = np.array([[1.0, -1.0, 1e-3]])
    >>> f"{float(product_budget(x, x.T)[0, 0]) / UNIT_ROUNDOFF:.7g}"  # γ₃·(1 + 1 + 10⁻⁶)
    '6.000003'
    """
    inner = sum(np.shape(f)[-1] for f in factors[:-1])
    bound = np.abs(factors[0])
    for f in factors[1:]:
        bound = bound @ np.abs(f)
    return gamma(inner) * bound


def fft_relative_error(n: int) -> float:
    """Bound on ‖fl(FFT x) − FFT x‖₂ / ‖FFT x‖₂ for a transform of length n (Higham Thm 24.2).

    Examples
    --------
    >>> f"{fft_relative_error(1 << 14):.2g}"
    '1e-14'
    """
    eta = UNIT_ROUNDOFF + gamma(4) * (math.sqrt(2.0) + UNIT_ROUNDOFF)
    levels = math.ceil(math.log2(n))
    return levels * eta / (1.0 - levels * eta)


def recursion_gain(poles: Iterable[complex]) -> float:
    """Bound on the ℓ₁ norm of the impulse response of 1/Π(1 − p_i·z⁻¹): Π 1/(1 − |p_i|).

    How much an error made at one step of the recursion can add up to over all later steps
    (exact for positive real poles, whose impulse responses never change sign).

    Examples
    --------
    >>> round(recursion_gain([0.5, 0.9]), 6)
    20.0
    """
    gain = 1.0
    for p in poles:
        if abs(p) >= 1.0:
            raise ValueError(f"pole {p} is not inside the unit circle: the error is unbounded")
        gain /= 1.0 - abs(p)
    return gain


def modal_gain(Ad: np.ndarray, C: np.ndarray) -> float:
    """Bound on max_i Σ_j |C·A_d^j·e_i|: how much an error in one state adds up to at the output.

    With A_d = V·diag(p)·V⁻¹ (distinct poles inside the unit circle), C·A_d^j·e_i is
    Σ_l (C·V)_l·p_l^j·(V⁻¹)_(l,i), whose ℓ₁ norm over j is at most
    Σ_l |(C·V)_l·(V⁻¹)_(l,i)|/(1 − |p_l|).

    Examples
    --------
    A slow and a fast lag in series, sampled at 0.1 ms: an error in the slow state adds up
    ~1/(1 − e^(−10⁻⁴)) ≈ 10⁴ times, one in the fast state ~10 times.

    >>> from scipy.linalg import expm
    >>> Ad = expm(np.array([[-1000.0, 0.0], [1.0, -1.0]]) * 1e-4)
    >>> round(modal_gain(Ad, np.array([[0.0, 1.0]])), -2)
    10000.0
    """
    poles, V = np.linalg.eig(Ad)
    if np.any(np.abs(poles) >= 1.0):
        raise ValueError(f"poles {poles} not all inside the unit circle: the error is unbounded")
    weights = np.abs((C @ V).reshape(-1, 1) * np.linalg.inv(V))  # (C·V)_l·(V⁻¹)_(l,i)
    return float(np.max(np.sum(weights / (1.0 - np.abs(poles)).reshape(-1, 1), axis=0)))


def least_squares_budget(X: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Per coefficient: how far two routes' least-squares solutions of X·β ≈ y may differ.

    X (n × p, rows already weighted) is scaled to unit columns, X_s = X/d, of condition κ, and
    β_s = d·β. Both routes are bounded in the scaled problem (Higham §20.1, §20.4), each to
    first order with γ_(np) standing for the bounds' c·n·p·u: the normal equations, forming
    XᵀX and solving or inverting it, by γ_(np)·κ²·‖β_s‖₂; an orthogonal or SVD solve (lstsq)
    by γ_(np)·(κ + κ²·‖r‖₂/(‖X_s‖₂‖β_s‖₂))·‖β_s‖₂. The sum of the two, unscaled by d_j.

    Examples
    --------
    A line through three points, the slope's column 10⁴ times the intercept's:

    >>> X = np.array([[1.0, 0.0], [1.0, 1e4], [1.0, 2e4]])
    >>> budget = least_squares_budget(X, np.array([1.0, 2.0, 3.1]))
    >>> bool(budget[1] < 1e-4 * budget[0])
    True
    """
    d = np.linalg.norm(X, axis=0)
    Xs = X / d
    beta_s, *_ = np.linalg.lstsq(Xs, y, rcond=None)
    singular = np.linalg.svd(Xs, compute_uv=False)
    kappa = singular[0] / singular[-1]
    size = float(np.linalg.norm(beta_s))
    misfit = float(np.linalg.norm(y - Xs @ beta_s)) / (singular[0] * size)
    relative = gamma(X.size) * (kappa**2 + kappa + kappa**2 * misfit)
    return relative * size / d


def inverse_gram_budget(X: np.ndarray) -> np.ndarray:
    """Per entry: how far two routes' (XᵀX)⁻¹ may differ (inverse against pseudo-inverse).

    In the scaled problem (:func:`least_squares_budget`) each route forms X_sᵀX_s within
    γ_n·|X_s|ᵀ|X_s| (at most γ_n·p in the 2-norm, unit columns) and inverts a matrix of
    condition κ², so each is within γ_(np)·κ²·‖(X_sᵀX_s)⁻¹‖₂ = γ_(np)·κ²/σ_min² of the exact
    inverse: twice that apart, unscaled by d_i·d_j.
    """
    d = np.linalg.norm(X, axis=0)
    singular = np.linalg.svd(X / d, compute_uv=False)
    kappa = singular[0] / singular[-1]
    return 2.0 * gamma(X.size) * kappa**2 / singular[-1] ** 2 / np.outer(d, d)
