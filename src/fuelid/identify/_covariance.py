"""Covariance of a least-squares fit with coloured residuals: the sandwich with their spectrum.

The output-error fit minimises Σ ε(k)²; its estimate moves with the noise as
δp ≈ (JᵀJ)⁻¹ Jᵀ v, so its covariance is

    cov(p̂) = (JᵀJ)⁻¹ · Jᵀ Σ_v J · (JᵀJ)⁻¹,

with J = ∂ŷ/∂p and Σ_v the covariance of the noise. Under white noise Σ_v = σ²·I and this is
the familiar σ²(JᵀJ)⁻¹ ("white"). PLC flow readings carry coloured noise (pump ripple, pressure
pulsation, slow drifts): then σ²(JᵀJ)⁻¹ is several times too small. The middle Jᵀ Σ_v J is the
heteroscedasticity-and-autocorrelation-consistent (HAC) part; it is estimated here from the
residuals' own spectrum, through an autoregressive model of them (a parametric, "prewhitened" HAC
in the sense of Andrews & Monahan 1992, which unlike Newey–West's truncated sum stays accurate when
the correlation lasts hundreds of samples, as a 0.99 pole at 50 Hz does):

1. fit A(q)·v(k) = e(k), A(q) = 1 + a₁q⁻¹ + … + a_p q⁻ᵖ, to the residuals by Levinson–Durbin on
   their autocovariance (pooled within segments), the order p ≤ :data:`MAX_AR_ORDER` chosen by
   the Bayesian information criterion;
2. v = Ψ·e with Ψ the lower-triangular Toeplitz matrix of 1/A(q)'s impulse response, so
   Σ_v = σ_e²·ΨΨᵀ and Jᵀ Σ_v J = σ_e²·(ΨᵀJ)ᵀ(ΨᵀJ); ΨᵀJ is J filtered by 1/A(q) backwards in
   time (reverse, filter, reverse), segment by segment;
3. the bread (JᵀJ)⁻¹ through the SVD of the column-scaled J, the directions the data do not
   determine left out (NaN), as for the white covariance.

References: D. W. K. Andrews, J. C. Monahan, "An improved heteroskedasticity and autocorrelation
consistent covariance matrix estimator", Econometrica 60 (1992) 953–966; L. Ljung, System
Identification, 2nd ed. (1999), §9.3 (the covariance of an output-error estimate under coloured
noise).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.signal

from fuelid.io.timeseries import FloatArray
from fuelid.numerics_mode import DEFAULT_NUMERICS, Numerics

MAX_AR_ORDER = 20
"""Highest order of the residuals' autoregressive model [samples]."""

SINGULAR_INFORMATION = 1e-9
"""Smallest singular value of the column-scaled Jacobian, relative to its largest, whose
direction still counts as determined by the data (condition number of the information 1e18)."""


@dataclass(frozen=True)
class ResidualAR:
    """An autoregressive model A(q)·v = e of the residuals."""

    a: FloatArray
    """[1, a₁, …, a_p]: A(q) = 1 + a₁q⁻¹ + … + a_p q⁻ᵖ."""
    sigma_e: float
    """Standard deviation of the white innovation e [output unit]."""
    bic: dict[int, float]
    """Bayesian information criterion by order tried."""

    @property
    def order(self) -> int:
        """p, the number of coefficients (0: white)."""
        return int(self.a.size - 1)

    @property
    def variance_ratio(self) -> float:
        """Long-run variance of v over its variance: how much slower the noise averages out [-].

        σ_v²(ω=0)/σ_v² = (σ_e²/A(1)²)/σ_v²; 1 for white noise, (1+ρ)/(1−ρ) for an AR(1) with
        pole ρ (39 for 0.95).
        """
        impulse = scipy.signal.lfilter([1.0], self.a, np.r_[1.0, np.zeros(4095)])
        variance = self.sigma_e**2 * float(impulse @ impulse)
        return float(self.sigma_e**2 / float(np.sum(self.a)) ** 2 / variance)

    def to_json(self) -> dict[str, Any]:
        """``{"order", "coefficients" (a₁…a_p), "sigma_e", "long_run_variance_ratio"}``."""
        return {
            "order": self.order,
            "coefficients": self.a[1:].tolist(),
            "sigma_e": self.sigma_e,
            "long_run_variance_ratio": self.variance_ratio,
        }


def _autocovariance(
    v: FloatArray,
    bounds: Sequence[tuple[int, int]],
    max_lag: int,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> FloatArray:
    """Biased autocovariance r(0…max_lag) of v, each lag summed within segments only.

    A dot product per lag; by FFT with ``numerics.reference`` (as before issue 26).
    """
    n = sum(b - a for a, b in bounds)
    r = np.zeros(max_lag + 1)
    for a, b in bounds:
        x = v[a:b]
        m = x.size
        if m == 0:
            continue
        if not numerics.reference:
            # a dot product per lag: twenty of them cost a twentieth of the FFT of a
            # 30,000-sample window padded to 65,536 (0.1 ms against 2 ms; the same sums to
            # rounding)
            for k in range(min(max_lag, m - 1) + 1):
                r[k] += x[k:] @ x[: m - k]
            continue
        size = 1 << math.ceil(math.log2(2 * m))
        spectrum = np.fft.rfft(x, size)
        full = np.fft.irfft(spectrum * np.conj(spectrum), size)
        lags = min(max_lag, m - 1)
        r[: lags + 1] += full[: lags + 1]
    return r / max(n, 1)


def residual_ar(
    residuals: FloatArray,
    bounds: Sequence[tuple[int, int]] | None = None,
    max_order: int = MAX_AR_ORDER,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> ResidualAR:
    """The autoregressive model of the residuals, its order chosen by BIC (Levinson–Durbin).

    BIC (n·ln σ_p² + p·ln n) rather than AIC: with tens of thousands of samples AIC keeps adding
    coefficients that describe nothing but this record. ``numerics``: how the autocovariance is
    summed (:mod:`fuelid.numerics_mode`).

    Examples
    --------
    >>> from scipy.signal import lfilter
    >>> e = np.random.default_rng(0).normal(size=20000)
    >>> model = residual_ar(lfilter([1.0], [1.0, -0.9], e))
    >>> model.order, round(float(model.a[1]), 2), round(model.sigma_e, 2)
    (1, -0.9, 1.0)
    >>> residual_ar(e).order
    0
    """
    v = np.asarray(residuals, dtype=float)
    spans = list(bounds) if bounds else [(0, v.size)]
    n = sum(b - a for a, b in spans)
    max_order = max(0, min(max_order, n // 10))
    r = _autocovariance(v, spans, max_order, numerics)
    a = np.array([1.0])
    error = float(r[0])
    best = (a.copy(), error)
    bic = {0: n * math.log(max(error, 1e-300))}
    for k in range(1, max_order + 1):
        if error <= 0.0:
            break
        reflection = -float(r[k] + a[1:] @ r[k - 1 : 0 : -1]) / error
        if not abs(reflection) < 1.0:
            break
        a = np.r_[a, 0.0] + reflection * np.r_[a, 0.0][::-1]
        error *= 1.0 - reflection**2
        bic[k] = n * math.log(max(error, 1e-300)) + k * math.log(n)
        if bic[k] < min(v for order, v in bic.items() if order < k):
            best = (a.copy(), error)
    best_a, variance = best
    return ResidualAR(a=best_a, sigma_e=math.sqrt(max(variance, 0.0)), bic=bic)


ROW_BLOCK = 1 << 20
"""Rows of J handled at once by :func:`bread` and :func:`sandwich_covariance` [-]: a day at
50 Hz is done in five blocks of 1 M × k rather than with whole N × k copies (240 MB each for
k = 7); a record of up to a million samples is one block, computed exactly as before."""


def _r_factor(J: FloatArray, scale: FloatArray) -> FloatArray:
    """R of the QR factorisation of J/scale, by blocks of :data:`ROW_BLOCK` rows (TSQR).

    The R of the stacked R factors of the blocks is the R of the whole (up to the signs of its
    rows, which the SVD of R does not see): Demmel et al., "Communication-optimal parallel and
    sequential QR and LU factorizations", SIAM J. Sci. Comput. 34 (2012) A206–A239.
    """
    if J.shape[0] <= ROW_BLOCK:
        return np.asarray(np.linalg.qr(J / scale, mode="r"), dtype=float)
    stacked = [
        np.linalg.qr(J[a : a + ROW_BLOCK] / scale, mode="r")
        for a in range(0, J.shape[0], ROW_BLOCK)
    ]
    return np.asarray(np.linalg.qr(np.vstack(stacked), mode="r"), dtype=float)


def column_norms(J: FloatArray) -> FloatArray:
    """‖J[:, c]‖ for every column: a dot product per column past :data:`ROW_BLOCK` rows.

    ``np.linalg.norm(J, axis=0)`` squares all of J first (an N × k temporary, 240 MB for a
    day's Jacobian); a record of up to :data:`ROW_BLOCK` rows keeps it (the same numbers as
    before, to the last bit).
    """
    if J.shape[0] <= ROW_BLOCK:
        return np.asarray(np.linalg.norm(J, axis=0), dtype=float)
    return np.asarray(np.sqrt([float(column @ column) for column in J.T]), dtype=float)


def least_squares(Phi: FloatArray, y: FloatArray) -> FloatArray:
    """β of y ≈ Φ·β, columns scaled: ``np.linalg.lstsq``, by blocks past :data:`ROW_BLOCK` rows.

    Past it, the R factor of [Φ/scale, y] by blocks (:func:`_r_factor`'s TSQR) holds Φ's R and
    Qᵀy in its last column, and the small triangular problem gives β, with ``lstsq``'s
    threshold for the singular values (machine precision times the longer side); a record of
    up to a million rows is solved exactly as before.
    """
    scale = column_norms(Phi)
    scale[scale == 0.0] = 1.0
    rcond = np.finfo(float).eps * max(Phi.shape)
    if Phi.shape[0] <= ROW_BLOCK:
        beta, *_ = np.linalg.lstsq(Phi / scale, y, rcond=None)
        return np.asarray(beta / scale, dtype=float)
    k = Phi.shape[1]
    stacked = [
        np.linalg.qr(np.column_stack([Phi[a : a + ROW_BLOCK] / scale, y[a : a + ROW_BLOCK]]), "r")
        for a in range(0, Phi.shape[0], ROW_BLOCK)
    ]
    R: FloatArray = np.asarray(np.linalg.qr(np.vstack(stacked), mode="r"), dtype=float)
    beta, *_ = np.linalg.lstsq(R[:k, :k], R[:k, k], rcond=rcond)
    return np.asarray(beta / scale, dtype=float)


def bread(J: FloatArray, numerics: Numerics = DEFAULT_NUMERICS) -> tuple[FloatArray, list[int]]:
    """(JᵀJ)⁻¹ through the SVD of the column-scaled J, and the parameters it cannot give.

    Directions whose singular value is below :data:`SINGULAR_INFORMATION` of the largest are
    not inverted; every parameter with weight in them gets a NaN row and column and is listed.
    The SVD is of R of J = QR; of J itself with ``numerics.reference`` (as before issue 26).
    """
    scale = column_norms(J)
    scale[scale == 0.0] = 1.0
    if not numerics.reference and J.shape[0] > J.shape[1]:
        # the SVD of R of J = QR: the same singular values and right vectors, without forming
        # the tall left ones (0.6 ms against 2–5 ms for a 30,000 × 6 Jacobian)
        scaled = _r_factor(J, scale)
    else:
        scaled = J / scale
    _, singular, vt = np.linalg.svd(scaled, full_matrices=False)
    determined = singular > SINGULAR_INFORMATION * singular[0]
    null = vt[~determined]
    weight = np.sum(null**2, axis=0) if null.size else np.zeros(J.shape[1])
    unidentified = [int(i) for i in np.flatnonzero(weight > 1e-6)]
    inner = (vt[determined].T / singular[determined] ** 2) @ vt[determined]
    inverse = inner / np.outer(scale, scale)
    inverse[unidentified, :] = np.nan
    inverse[:, unidentified] = np.nan
    return np.asarray(inverse, dtype=float), unidentified


def white_covariance(
    J: FloatArray, sigma: float, numerics: Numerics = DEFAULT_NUMERICS
) -> tuple[FloatArray, list[int]]:
    """σ²·(JᵀJ)⁻¹: the covariance when the residuals are white (:func:`bread`'s ``numerics``)."""
    inverse, unidentified = bread(J, numerics)
    return sigma**2 * inverse, unidentified


def _support(column: FloatArray) -> int:
    """One past the last nonzero entry of ``column`` (0 when it is all zero)."""
    nonzero = np.flatnonzero(column[-1:])
    if nonzero.size:  # the usual case: nonzero to the end, found without a pass over it
        return int(column.size)
    nonzero = np.flatnonzero(column)
    return int(nonzero[-1]) + 1 if nonzero.size else 0


def sandwich_covariance(
    J: FloatArray,
    noise: ResidualAR,
    bounds: Sequence[tuple[int, int]] | None = None,
    bread_of_J: tuple[FloatArray, list[int]] | None = None,
    *,
    overwrite: bool = False,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> tuple[FloatArray, list[int]]:
    """(JᵀJ)⁻¹·σ_e²(ΨᵀJ)ᵀ(ΨᵀJ)·(JᵀJ)⁻¹: the covariance under the residuals' AR noise ``noise``.

    ``overwrite=True`` filters J in place (ΨᵀJ replaces it) instead of into a copy: the
    caller's J is spent, and a day's N × k copy (240 MB) is not made. The product is formed as
    a Gram matrix; as (JᵀJ)⁻¹·M·(JᵀJ)⁻¹ with ``numerics.reference`` (as before issue 26), whose
    :func:`bread` ``numerics`` also sets when ``bread_of_J`` is not given.

    Examples
    --------
    The mean of n AR(1) samples (J = ones): its variance is the long-run variance over n.

    >>> noise = ResidualAR(a=np.array([1.0, -0.9]), sigma_e=1.0, bic={})
    >>> cov, _ = sandwich_covariance(np.ones((100000, 1)), noise)
    >>> round(float(cov[0, 0]) * 100000, 1)  # σ_e²/(1 − 0.9)² = 100
    100.0
    """
    # ``bread_of_J``: bread(J) when the caller has it already (the same SVD, not done twice)
    inverse, unidentified = bread(J, numerics) if bread_of_J is None else bread_of_J
    spans = list(bounds) if bounds else [(0, J.shape[0])]
    filtered = J if overwrite else np.zeros_like(J)
    for a, b in spans:
        # Ψᵀ acts backwards in time: reverse, filter by 1/A(q), reverse; a column at a time
        # in place (the same numbers as the whole block at once)
        for c in range(J.shape[1]):
            # a column that is zero from some sample on (a free response, underflowed) stays
            # zero there: the backward filter starts at rest and meets only zeros until then,
            # so only the part before is filtered (the same numbers; on a day at 50 Hz the
            # initial states' columns are 4,000 samples, not 4.3 million)
            stop = a + _support(J[a:b, c])
            filtered[stop:b, c] = 0.0
            filtered[a:stop, c] = scipy.signal.lfilter([1.0], noise.a, J[a:stop, c][::-1])[::-1]
    clean = np.nan_to_num(inverse)
    if numerics.reference:
        middle = noise.sigma_e**2 * (filtered.T @ filtered)
        cov = clean @ middle @ clean
    else:
        # as a Gram matrix BᵀB, B = ΨᵀJ·(JᵀJ)⁻¹: its diagonal is a sum of squares, never
        # negative by rounding as (JᵀJ)⁻¹·M·(JᵀJ)⁻¹ can be when two lags nearly coincide
        # (entries of 10⁴ cancelling to a variance); the same cost, N·k² either way; summed
        # over blocks of rows, each sum still one of squares
        gram = np.zeros((J.shape[1], J.shape[1]))
        for a in range(0, J.shape[0], ROW_BLOCK):
            scaled = filtered[a : a + ROW_BLOCK] @ clean
            gram += scaled.T @ scaled
        cov = noise.sigma_e**2 * gram
    cov[unidentified, :] = np.nan
    cov[:, unidentified] = np.nan
    return np.asarray(cov, dtype=float), unidentified
