"""The prediction-error criterion of :mod:`fuelid.identify._pem` and what follows from its optimum.

ε = (D/C)·(y − ŷ_p) with the process part ŷ_p of :mod:`fuelid.identify._variable_projection`:
:func:`joint_fit` minimises Σε² over the process and noise parameters jointly (the linear ones
by projection on the filtered regressors), :func:`prediction_error_jacobian` gives Ψ = ∂ε/∂p
for the covariance, and :func:`noise_model_summary` and :func:`noise_model_warnings` describe
the fitted noise model C(q)/D(q). The equations are in :mod:`fuelid.identify._pem`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.signal
from numpy.typing import NDArray

from fuelid.identify._noise import (
    ETA_BOUND,
    NoiseShape,
    filter_segments,
    roots_json,
    shift_segments,
    used_samples,
)
from fuelid.identify._variable_projection import (
    Bounds,
    Structure,
    regressors,
    solve_linear,
)
from fuelid.io.timeseries import IOData
from fuelid.numerics_mode import DEFAULT_NUMERICS, Numerics

FloatArray = NDArray[np.float64]


@dataclass
@dataclass
class JointFit:
    """One joint fit: the search vector, its structures, and the evaluation at the optimum."""

    st: Structure
    noise: NoiseShape
    x: FloatArray
    Phi: FloatArray
    beta: FloatArray
    eps: FloatArray  # prediction errors over all samples (zero-initialised filter)
    used: NDArray[np.bool_]
    criterion: dict[str, float]

    @property
    def sse(self) -> float:
        """Σε² over the criterion's samples."""
        e = self.eps[self.used]
        return float(e @ e)


def joint_fit(
    data: IOData,
    st: Structure,
    noise: NoiseShape,
    z0: FloatArray,
    eta0: FloatArray,
    criterion: dict[str, float],
    max_delay: float | None,
    search: bool = True,
    *,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> JointFit:
    """Minimise Σε² over (process nonlinear parameters, η); linear ones by projection.

    ``z0`` and ``eta0`` start the search; ``criterion`` (the noise orders' information
    criterion) is carried into the result; ``max_delay`` [s] bounds a free delay (None:
    a quarter of the record, at most 60 s). ``search=False`` only evaluates the start (to
    screen starting points). ``numerics``: the search's tolerances and how the model is
    discretised (scipy's ``trf`` with finite differences whatever its Jacobians).
    """
    from scipy.optimize import least_squares  # slow to import: only when fitting

    u, y, h = data.u, data.y, data.sample_time
    bounds = data.segment_bounds()
    n = data.n_samples
    u_ref = st.u_before if st.u_before is not None else float(u[0])
    used = used_samples(bounds, n, noise.nd)
    n_z = z0.size
    record = n * h
    lo = [math.log(h / 20.0)] * st.order
    hi = [math.log(20.0 * record)] * st.order
    if st.delay is None:
        bound = max_delay if max_delay is not None else min(0.25 * record, 60.0)
        lo.append(0.0)
        hi.append(max(bound, 1e-9))
    lo += [-ETA_BOUND] * noise.size
    hi += [ETA_BOUND] * noise.size

    def evaluate(x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        T, T2, delay = st.unpack(x[:n_z])
        C, D = noise.polys(x[n_z:])
        Phi = regressors(st, T, T2, delay, u, h, u_ref, bounds, numerics=numerics)
        m = Phi.shape[1]
        stacked = np.empty((n, m + 1), order="F")
        stacked[:, :m] = Phi
        stacked[:, m] = y
        filtered = filter_segments(D, C, stacked, bounds)
        beta = solve_linear(filtered[used, :m], filtered[used, m]).beta
        eps = filtered[:, m] - filtered[:, :m] @ beta
        return Phi, beta, np.asarray(eps, dtype=float)

    x0 = np.clip(np.r_[z0, eta0], np.array(lo) + 1e-9, np.array(hi) - 1e-9)
    if noise.size == 0 or not search:
        x = x0  # the output-error optimum already (the fit equals OE's), or a screening
    else:
        sol = least_squares(
            lambda x: evaluate(x)[2][used],
            x0,
            bounds=(lo, hi),
            method="trf",
            x_scale=1.0,
            max_nfev=100,
            **numerics.tolerances.as_kwargs(),
        )
        x = np.asarray(sol.x, dtype=float)
    Phi, beta, eps = evaluate(x)
    return JointFit(st, noise, x, Phi, beta, eps, used, criterion)


def prediction_error_jacobian(
    J: FloatArray,
    fit: JointFit,
    r: FloatArray,
    C: FloatArray,
    D: FloatArray,
    bounds: Bounds,
) -> FloatArray:
    """Ψ = ∂ε/∂p on the criterion's samples: process columns −(D/C)·J, noise columns exact.

    ``J`` is ∂ŷ_p/∂p of the process part (:func:`~fuelid.identify._variable_projection.jacobian`)
    and ``r`` = y − ŷ_p at the optimum; ∂ε/∂d_i = q⁻ⁱ·r/C and ∂ε/∂c_i = −q⁻ⁱ·ε/C.
    """
    noise = fit.noise
    n = r.size
    r_over_C = filter_segments(np.array([1.0]), C, r, bounds)
    eps_over_C = filter_segments(np.array([1.0]), C, fit.eps, bounds)
    noise_cols = [shift_segments(r_over_C, i, bounds) for i in range(1, noise.nd + 1)]
    noise_cols += [-shift_segments(eps_over_C, i, bounds) for i in range(1, noise.nc + 1)]
    Psi = np.empty((n, J.shape[1] + noise.size), order="F")
    Psi[:, : J.shape[1]] = -filter_segments(D, C, J, bounds)
    for j, col in enumerate(noise_cols):
        Psi[:, J.shape[1] + j] = col
    return np.asarray(Psi[fit.used], dtype=float)


def noise_model_summary(
    C: FloatArray,
    D: FloatArray,
    noise: NoiseShape,
    sigma_e: float,
    criterion: dict[str, float],
    criterion_name: str,
) -> dict[str, Any]:
    """The fitted noise model C(q)/D(q) as JSON types (``noise_model_`` of the estimator).

    ``sigma_e`` is the innovation's standard deviation; ``sigma_v`` that of the noise v itself
    (from the first 2000 samples of its impulse response).
    """
    impulse = np.zeros(2000)
    impulse[0] = 1.0
    psi_v = scipy.signal.lfilter(C, D, impulse)
    return {
        "C": [float(c) for c in C],
        "D": [float(d) for d in D],
        "nc": noise.nc,
        "nd": noise.nd,
        "poles": roots_json(D),
        "zeros": roots_json(C),
        "sigma_e": sigma_e,
        "sigma_v": sigma_e * float(np.sqrt(psi_v @ psi_v)),
        "criterion": dict(criterion),
        "criterion_name": criterion_name,
    }


def noise_model_warnings(C: FloatArray, D: FloatArray, noise: NoiseShape) -> list[str]:
    """What to say about a fitted noise model: a drift, or a pole and zero that cancel."""
    out = []
    if np.any(np.abs(np.roots(D)) > 0.999):
        out.append(
            "the noise model has a pole within 0.001 of 1 (a drift, nearly integrating): "
            "the offset and the slowest dynamics are poorly determined; detrend or give "
            "a longer record"
        )
    if noise.nc and noise.nd and np.min(np.abs(np.subtract.outer(np.roots(C), np.roots(D)))) < 0.01:
        out.append(
            "a pole and a zero of the noise model nearly cancel: a lower noise order "
            "would do (noise_order)"
        )
    return out


def predicted_noise(
    v: FloatArray, C: FloatArray, D: FloatArray, horizon: int, bounds: Bounds
) -> FloatArray:
    """k-step-ahead prediction (1 − H̄_k·D/C)·v of the noise v = C/D·e, k = ``horizon``.

    H̄_k is the first k terms of C/D's impulse response; the filter restarts at each segment.
    """
    k = horizon
    # (1 − H̄_k D/C) = (C − H̄_k D)/C, and C − H̄_k D = q⁻ᵏ·N(q) with N of degree < nd, nc
    impulse = np.zeros(k)
    impulse[0] = 1.0
    h_bar = scipy.signal.lfilter(C, D, impulse)
    full = np.zeros(k + max(C.size, D.size))
    full[: C.size] += C
    full[: k + D.size - 1] -= np.convolve(h_bar, D)
    N = full[k:]
    return filter_segments(N, C, shift_segments(v, k, bounds), bounds)
