"""The Harris (minimum-variance) performance index of a regulatory stretch.

L. Desborough, T. Harris, "Performance assessment measures for univariate feedback control",
Can. J. Chem. Eng. 70 (1992) 1186–1197. B. Huang, S. L. Shah, *Performance Assessment of Control
Loops* (Springer, 1999), ch. 2–3.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.signal
from numpy.typing import ArrayLike

from fuelid.identify import residual_ar
from fuelid.numerics_mode import DEFAULT_NUMERICS, Numerics
from fuelid.online.health._shares import AUTO

MAX_AR_ORDER = 30
"""Highest order of the error's AR model for the Harris index [-]."""
SAMPLES_PER_AR_ORDER = 20
"""A Harris index needs at least this many samples per AR coefficient tried [-]."""


@dataclass(frozen=True)
class HarrisIndex:
    """The minimum-variance performance index of a regulatory stretch, or why there is none."""

    index: float | None
    """η = σ²_mv / var(e) in (0, 1]; 1 is minimum-variance control; None when refused."""
    order: int
    """Order of the error's AR model (0: white) [-]."""
    delay_samples: int
    """b, the process dead time in samples (at least 1) [-]."""
    samples: int
    """Length of the stretch [-]."""
    variance: float
    """var(e) [(L/min)²]."""
    minimum_variance: float
    """σ²_mv = σ²_a·Σ_{i<b} ψ_i² [(L/min)²]."""
    reason: str
    """Why the index was refused ("" when it was computed)."""


def harris_refusal(reason: str, b: int, n: int) -> HarrisIndex:
    """No index, with the reason (b: the delay [samples], n: the samples of the stretch)."""
    return HarrisIndex(None, 0, b, n, math.nan, math.nan, reason)


def harris_index(
    error: ArrayLike,
    delay_samples: int,
    *,
    order: int | None = None,
    max_order: int = MAX_AR_ORDER,
    mode: ArrayLike | None = None,
    setpoint: ArrayLike | None = None,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> HarrisIndex:
    """Harris's minimum-variance index of the control error of a regulatory stretch.

    The mean-removed error is modelled as an autoregression A(q)·e = a (Yule–Walker by the
    Levinson–Durbin recursion of :func:`fuelid.identify._covariance.residual_ar`, the order
    chosen by BIC up to ``max_order``, or a given ``order``). Its impulse response ψ (the
    error's moving-average form e = Σ ψ_i a_{t−i}, ψ_0 = 1) splits the error into the part no
    controller can affect, the first b terms (the feedback-invariant part), and the rest. So
    σ²_mv = σ²_a·Σ_{i<b} ψ_i² is the variance under minimum-variance control and
    η = σ²_mv / var(e) the index: 1 for a loop at minimum variance, near 0 for a poor one.

    Parameters
    ----------
    error : array
        Control error setpoint − y of one stretch, equally sampled [L/min].
    delay_samples : int
        b: the process dead time in samples, including the sample-and-hold's one (at least 1).
    order : int, optional
        AR order; default chosen by BIC.
    max_order : int
        Highest order tried [-].
    mode, setpoint : arrays, optional
        When given, the stretch must be all AUTO with a constant setpoint (regulatory).
    numerics : Numerics
        How the AR model's autocovariance is summed (:mod:`fuelid.numerics_mode`).

    Returns
    -------
    HarrisIndex
        With ``index`` None and a ``reason`` when the stretch has non-finite values, is shorter
        than 20 samples per AR order tried, has no variance, or is not regulatory.

    Notes
    -----
    BIC rather than AIC: with the tens of thousands of samples of a window AIC keeps adding
    coefficients (covariance.py), which at most lower σ²_a and raise ψ's tail, both
    of which leave the first b ψ's and so η essentially unchanged. The Yule–Walker model
    reproduces the sample variance exactly, so η ≤ 1 by construction.

    References
    ----------
    L. Desborough, T. Harris, "Performance assessment measures for univariate feedback
    control", Can. J. Chem. Eng. 70 (1992) 1186–1197; B. Huang, S. L. Shah, *Performance
    Assessment of Control Loops* (Springer, 1999), §3.3.

    Examples
    --------
    An AR(1) error with pole φ = 0.5 and b = 1: η = 1 − φ² = 0.75.

    >>> a = np.random.default_rng(0).normal(size=50_000)
    >>> e = scipy.signal.lfilter([1.0], [1.0, -0.5], a)
    >>> h = harris_index(e, 1)
    >>> h.order, round(h.index, 2)
    (1, 0.75)
    """
    e = np.asarray(error, dtype=float)
    b = max(1, int(delay_samples))
    n = e.size
    if not np.all(np.isfinite(e)):
        return harris_refusal("the error has non-finite values", b, n)
    if mode is not None and np.any(np.asarray(mode) != AUTO):
        return harris_refusal("not regulatory: the stretch has samples in MAN", b, n)
    if setpoint is not None and np.ptp(np.asarray(setpoint, dtype=float)) > 0.0:
        return harris_refusal("not regulatory: the setpoint changes in the stretch", b, n)
    tried = order if order is not None else max_order
    if n < SAMPLES_PER_AR_ORDER * max(tried, 1):
        return harris_refusal(
            f"{n} samples: too short for an AR model of order {tried} "
            f"(needs {SAMPLES_PER_AR_ORDER * max(tried, 1)})",
            b,
            n,
        )
    v = e - e.mean()
    variance = float(v @ v) / n
    if not variance > 0.0:
        return harris_refusal("the error does not vary", b, n)
    if order is None:
        model = residual_ar(v, max_order=max_order, numerics=numerics)
        a, sigma2 = model.a, model.sigma_e**2
    elif order == 0:
        a, sigma2 = np.array([1.0]), variance
    else:
        r = np.fft.irfft(np.abs(np.fft.rfft(v, 2 * n)) ** 2)[: order + 1] / n
        phi = scipy.linalg.solve_toeplitz(r[:order], r[1 : order + 1])
        a, sigma2 = np.r_[1.0, -phi], float(r[0] - phi @ r[1 : order + 1])
    psi = scipy.signal.lfilter([1.0], a, np.r_[1.0, np.zeros(b - 1)])
    sigma2_mv = sigma2 * float(psi @ psi)
    index = min(max(sigma2_mv / variance, 0.0), 1.0)
    return HarrisIndex(index, int(a.size - 1), b, n, variance, sigma2_mv, "")


__all__ = ["MAX_AR_ORDER", "SAMPLES_PER_AR_ORDER", "HarrisIndex", "harris_index"]
