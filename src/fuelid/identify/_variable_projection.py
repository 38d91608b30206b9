"""The output-error model as a linear regression for given time constants and delay.

For fixed (T, T2, θ) the model ŷ = b + K·s(T, T2, θ) + Σ c_i·p_i^k of :mod:`fuelid.identify._oe`
is linear in (K, b, c_i): :func:`regressors` builds its columns Φ, :func:`solve_linear` its
least-squares solution, so the nonlinear search runs over the time constants and the delay only
(variable projection). :func:`jacobian` gives ∂ŷ/∂p for the covariance, and
:func:`cramer_rao_bound` the best covariance any fit of this model can reach. Shared by
:mod:`~fuelid.identify._oe`, :mod:`~fuelid.identify._pem` and :mod:`~fuelid.identify._noise`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.signal
from numpy.typing import NDArray

from fuelid.io.timeseries import IOData
from fuelid.lti import discretise
from fuelid.model import ProcessModel
from fuelid.numerics_mode import DEFAULT_NUMERICS, Numerics

FloatArray = NDArray[np.float64]
#: longest record used for the coarse grid of starting values (subsampled above this)
GRID_SAMPLES = 20_000


@dataclass(frozen=True)
class Structure:
    """What is free and what is fixed in one fit."""

    order: int
    T_f: float
    delay: float | None  # None: estimated
    initial: str  # of the first segment ("rest" when u_before is given)
    u_before: float | None
    later: str = "estimate"  # initial condition of every segment after a gap

    @property
    def nonlinear_names(self) -> tuple[str, ...]:
        """The parameters of the nonlinear search, in the search vector's order."""
        names = ("T", "T2")[: self.order]
        return (*names, "delay") if self.delay is None else names

    def unpack(self, z: FloatArray) -> tuple[float, float, float]:
        """(T, T2, delay) from the search vector [log T, (log T2), (delay)]."""
        T = math.exp(z[0])
        T2 = math.exp(z[1]) if self.order == 2 else 0.0
        delay = float(z[-1]) if self.delay is None else self.delay
        return T, T2, delay


@dataclass
class LinearFit:
    """Regressors and linear least-squares solution for one (T, T2, delay)."""

    Phi: FloatArray
    beta: FloatArray
    residual: FloatArray

    @property
    def sse(self) -> float:
        """Sum of squared residuals."""
        return float(self.residual @ self.residual)


Bounds = list[tuple[int, int]]


def n_modes(st: Structure, n_lags: int, segment: int) -> int:
    """Free-response amplitudes estimated for segment ``segment`` (0 for one at rest)."""
    initial = st.initial if segment == 0 else st.later
    return n_lags if initial == "estimate" else 0


def regressors(
    st: Structure,
    T: float,
    T2: float,
    delay: float,
    u: FloatArray,
    h: float,
    u_ref: float,
    bounds: Bounds | None = None,
    *,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> FloatArray:
    """Φ = [response, 1, free responses of each segment] for one (T, T2, delay).

    Segment j (samples ``a:b`` of ``bounds``) is simulated on its own: from rest at u_ref for
    the first segment, from rest at its first command u[a] for a later one (its level
    K·(u[a] − u_ref) stays in the response column, so K and the common offset tie the
    segments together); its free-response columns are zero outside it. ``numerics``: how the
    model is discretised (:func:`fuelid.lti.discretise`).
    """
    lags = [tc for tc in (T, T2, st.T_f) if tc > 0.0]
    model = discretise(lags, delay, h, numerics)
    bounds = [(0, u.size)] if bounds is None else bounds
    counts = [n_modes(st, len(lags), j) for j in range(len(bounds))]
    # Fortran order: each regressor is one contiguous column
    Phi = np.empty((u.size, 2 + sum(counts)), order="F")
    col = 2
    for j, ((a, b), m) in enumerate(zip(bounds, counts, strict=True)):
        u_pre = u_ref if j == 0 else float(u[a])
        Phi[a:b, 0] = model.response(u[a:b] - u_pre)
        if j:
            Phi[a:b, 0] += u_pre - u_ref
        if m:
            Phi[:, col : col + m] = 0.0
            Phi[a:b, col : col + m] = model.modes(b - a)
            col += m
    Phi[:, 1] = 1.0
    return Phi


def fitted_output(
    st: Structure,
    T: float,
    T2: float,
    delay: float,
    beta: FloatArray,
    u: FloatArray,
    h: float,
    u_ref: float,
    bounds: Bounds | None = None,
    *,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> FloatArray:
    """Φ(T, T2, θ)·β without forming Φ: one vector of N, not N × (2 + free responses).

    The same sum as ``regressors(...) @ beta``, column by column (so equal to rounding): on a
    day at 50 Hz Φ is 4.3 M × 4 float64 (140 MB), and the finite differences of the Jacobian
    and the long-record polish (:mod:`fuelid.identify._long_record`) need only Φβ.

    Examples
    --------
    >>> st = Structure(2, 0.0, None, "estimate", None)
    >>> u = np.repeat([1.0, 2.0, 1.5], 200)
    >>> beta = np.array([3.0, 10.0, 0.4, -0.2])
    >>> Phi = regressors(st, 1.0, 0.3, 0.25, u, 0.05, 1.0)
    >>> bool(np.allclose(fitted_output(st, 1.0, 0.3, 0.25, beta, u, 0.05, 1.0), Phi @ beta))
    True
    """
    lags = [tc for tc in (T, T2, st.T_f) if tc > 0.0]
    model = discretise(lags, delay, h, numerics)
    bounds = [(0, u.size)] if bounds is None else bounds
    counts = [n_modes(st, len(lags), j) for j in range(len(bounds))]
    out = np.zeros(u.size)
    col = 2
    for j, ((a, b), m) in enumerate(zip(bounds, counts, strict=True)):
        u_pre = u_ref if j == 0 else float(u[a])
        # model.response with the whole-sample delay applied to the output, not the input:
        # the same numbers (zero state before the record), one pass over N fewer
        shift = min(model.shift, b - a)
        out[a + shift : b] = scipy.signal.lfilter(model.b, model.a, u[a : b - shift] - u_pre)
        if j:
            out[a:b] += u_pre - u_ref
        out[a:b] *= beta[0]
        out[a:b] += beta[1]
        add_free_responses(out[a:b], model.poles[:m], beta[col : col + m])
        col += m
    return out


def add_free_responses(out: FloatArray, poles: FloatArray, amplitudes: FloatArray) -> None:
    """``out[k] += Σ_i c_i·p_i^k`` in place, k from 0, for the poles p_i and amplitudes c_i.

    p^k underflows long before a long segment ends: each term only where it does not.
    """
    for c, p in zip(amplitudes, poles, strict=True):
        n = out.size
        length = n if not 0.0 < p < 1.0 else min(n, math.ceil(-41.5 / math.log(p)) + 1)
        if p > 0.0:
            out[:length] += c * np.exp(np.arange(length) * math.log(p))
        else:
            out[0] += c


def subsample(data: IOData, step: int) -> IOData:
    """Every ``step``-th sample of each segment (the segments and their starts kept)."""
    if step == 1:
        return data
    if data.n_segments == 1:
        return IOData(data.u[::step], data.y[::step], data.sample_time * step)
    index = [np.arange(a, b, step) for a, b in data.segment_bounds()]
    starts = np.cumsum([i.size for i in index])[:-1]
    keep = np.concatenate(index)
    return IOData(
        data.u[keep],
        data.y[keep],
        data.sample_time * step,
        segment_starts=tuple(int(k) for k in starts),
        segment_t0=tuple(data.segment_t0),
    )


def solve_linear(Phi: FloatArray, y: FloatArray) -> LinearFit:
    """Least-squares β of y ≈ Φ·β, with the residual."""
    # normal equations with column scaling: Φ has a handful of columns and is well scaled after
    # scaling, and forming ΦᵀΦ is far cheaper than a QR of a 180,000-row matrix
    G = Phi.T @ Phi
    scale = np.sqrt(np.diag(G))
    scale[scale == 0.0] = 1.0
    try:
        beta = np.asarray(
            np.linalg.solve(G / np.outer(scale, scale), (Phi.T @ y) / scale) / scale, dtype=float
        )
    except np.linalg.LinAlgError:
        beta = np.linalg.lstsq(Phi, y, rcond=None)[0]
    return LinearFit(Phi=Phi, beta=beta, residual=y - Phi @ beta)


def continue_fitted(
    st: Structure,
    beta: FloatArray,
    model: ProcessModel,
    u_ref: float,
    n_fitted: int,
    data: IOData,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> FloatArray:
    """The fitted response on a record that continues the fitting one (``initial="fitted"``).

    The fitted linear parameters ``beta`` (K, offset, the fitting record's initial states) carry
    on; a segment that starts after the ``n_fitted`` fitted samples (a held-out tail after a gap)
    gets its initial state fitted on its own samples. Shared by oe and pem.
    """
    h = data.sample_time
    bounds = data.segment_bounds()
    Phi = regressors(
        st, model.T, model.T2, model.delay, data.u, h, u_ref, bounds, numerics=numerics
    )
    if Phi.shape[1] == beta.size:
        return np.asarray(Phi @ beta, dtype=float)
    y_hat = np.asarray(Phi[:, : beta.size] @ beta, dtype=float)
    col = beta.size
    n_lags = len(model.time_constants)
    for j, (a, b) in enumerate(bounds):
        if a < n_fitted:
            continue
        m = n_modes(st, n_lags, j)
        if m:
            block = Phi[a:b, col : col + m]
            y_hat[a:b] += block @ solve_linear(block, data.y[a:b] - y_hat[a:b]).beta
            col += m
    return y_hat


def jacobian(
    st: Structure,
    values: dict[str, float],
    beta: FloatArray,
    u: FloatArray,
    h: float,
    u_ref: float,
    Phi: FloatArray | None = None,
    bounds: Bounds | None = None,
    sens: FloatArray | None = None,
    *,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> tuple[tuple[str, ...], FloatArray]:
    """∂ŷ/∂p for p = (K, nonlinear parameters, offset, initial-state amplitudes).

    The linear parameters' columns are the regressors themselves; the time constants' and the
    delay's are ``sens`` when the caller has them (the search's last Jacobian at this fit, or
    the long-record polish's), else :func:`sensitivities` when ``numerics`` asks for analytic
    Jacobians (the online windows'), else central differences of Φ(T, T2, θ)·β (two
    simulations each).
    With segments, every column runs over all of them (each segment's own simulation), so the
    covariance is that of the joint fit. The amplitudes are named ``c0, c1, …`` for the first
    segment and ``c0_seg2, …`` for the later ones.
    """
    if Phi is None:
        Phi = regressors(
            st, values["T"], values["T2"], values["delay"], u, h, u_ref, bounds, numerics=numerics
        )
    nl_names = st.nonlinear_names
    n_lags = sum(1 for tc in (values["T"], values["T2"], st.T_f) if tc > 0.0)
    amplitudes = [
        f"c{i}" if j == 0 else f"c{i}_seg{j + 1}"
        for j in range(len(bounds) if bounds else 1)
        for i in range(n_modes(st, n_lags, j))
    ]
    names = ("K", *nl_names, "offset", *amplitudes)
    # Fortran order: each column contiguous, as the sandwich filters them one at a time
    J = np.empty((u.size, len(names)), order="F")
    J[:, 0] = Phi[:, 0]
    J[:, len(nl_names) + 1 :] = Phi[:, 1:]
    if sens is not None:  # the caller's, at this very fit
        J[:, 1 : 1 + len(nl_names)] = sens
    elif numerics.analytic_jacobians:
        # the lags' columns as filters of the input (:func:`sensitivities`), not differences
        # of two simulations each
        J[:, 1 : 1 + len(nl_names)] = sensitivities(
            st,
            values["T"],
            values["T2"],
            values["delay"],
            beta,
            u,
            h,
            u_ref,
            bounds,
            Phi,
            numerics=numerics,
        )
    else:
        # the output offset is the same in both simulations: left out of the difference
        moving = np.array(beta, dtype=float)
        moving[1] = 0.0
        for j, name in enumerate(nl_names, start=1):
            step = 1e-6 * max(abs(values[name]), h)
            up, down = dict(values), dict(values)
            up[name] += step
            down[name] = max(down[name] - step, 0.0) if name == "delay" else down[name] - step
            width = up[name] - down[name]
            # Φβ simulated, not Φ formed: a day's regressor matrices are 140 MB each
            J[:, j] = fitted_output(
                st, up["T"], up["T2"], up["delay"], moving, u, h, u_ref, bounds, numerics=numerics
            )
            J[:, j] -= fitted_output(
                st,
                down["T"],
                down["T2"],
                down["delay"],
                moving,
                u,
                h,
                u_ref,
                bounds,
                numerics=numerics,
            )
            J[:, j] /= width
    return names, J


#: relative step of the central differences of the ZOH coefficients in :func:`sensitivities`
#: (a 4-coefficient function, smooth in T: its truncation error ~1e-12, rounding ~1e-10)
COEFFICIENT_STEP = 1e-5


def _coefficient_derivatives(
    lags: list[float],
    delay: float,
    h: float,
    index: list[int],
    numerics: Numerics = DEFAULT_NUMERICS,
) -> tuple[FloatArray, FloatArray]:
    """(∂b/∂T_i, ∂a/∂T_i) of the sampled lag chain for each lag ``i`` in ``index`` (rows).

    Central differences of the few coefficients (the whole-sample delay d does not depend on T).
    """
    db, da = [], []
    for i in index:
        step = COEFFICIENT_STEP * lags[i]
        up, down = list(lags), list(lags)
        up[i] += step
        down[i] -= step
        hi, lo = discretise(up, delay, h, numerics), discretise(down, delay, h, numerics)
        db.append((hi.b - lo.b) / (2.0 * step))
        da.append((hi.a - lo.a) / (2.0 * step))
    return np.array(db), np.array(da)


def sensitivities(
    st: Structure,
    T: float,
    T2: float,
    delay: float,
    beta: FloatArray,
    u: FloatArray,
    h: float,
    u_ref: float,
    bounds: Bounds | None = None,
    Phi: FloatArray | None = None,
    *,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> FloatArray:
    """∂(Φ·β)/∂p at fixed β for the nonlinear parameters p (``st.nonlinear_names``) [unit/s].

    The fast path's replacement of finite differences of Φ (:func:`jacobian`, the searches of
    oe). The response s = (b/a)·v to the (delayed) input v has the sensitivity to a lag
    ∂s = (∂b·v − ∂a·s)/a: two short FIR filters and one pass through 1/a (the one the response
    took), all lags in one call; ∂b, ∂a are central differences of the few sampled coefficients.
    The free responses' sensitivity is k·h/T²·p^k. The delay's is the central difference of the
    response column alone (the free responses do not depend on it). ``Phi`` (the regressors at
    these values) saves recomputing s. ``numerics``: how the model is discretised.
    """
    lags = [tc for tc in (T, T2, st.T_f) if tc > 0.0]
    bounds = [(0, u.size)] if bounds is None else bounds
    counts = [n_modes(st, len(lags), j) for j in range(len(bounds))]
    names = st.nonlinear_names
    index = [0 if name == "T" else 1 for name in names if name != "delay"]
    model = discretise(lags, delay, h, numerics)
    db, da = _coefficient_derivatives(lags, delay, h, index, numerics)
    out = np.zeros((u.size, len(names)), order="F")
    col = 2
    for j, ((a, b), m) in enumerate(zip(bounds, counts, strict=True)):
        du = u[a:b] - (u_ref if j == 0 else float(u[a]))
        # a later segment's response column carries its level u[a] − u_ref
        s = model.response(du) if Phi is None else Phi[a:b, 0] - (float(u[a]) - u_ref if j else 0.0)
        v = np.zeros_like(du)
        if model.shift < du.size:
            v[model.shift :] = du[: du.size - model.shift]
        if index:
            fir = np.array(
                [
                    np.convolve(v, db[r])[: b - a] - np.convolve(s, da[r])[: b - a]
                    for r in range(len(index))
                ]
            )
            lag_part = scipy.signal.lfilter([1.0], model.a, fir, axis=-1)
        k = np.arange(b - a)
        for c, name in enumerate(names):
            if name == "delay":
                step = 1e-6 * max(delay, h)
                lo_delay = max(delay - step, 0.0)
                up = discretise(lags, delay + step, h, numerics).response(du)
                down = discretise(lags, lo_delay, h, numerics).response(du)
                out[a:b, c] = beta[0] * (up - down) / (delay + step - lo_delay)
                continue
            i = index[c]
            out[a:b, c] = beta[0] * lag_part[c]
            if m:
                tc = lags[i]
                p = math.exp(-h / tc)
                # p^k underflows far before the segment ends: only where it does not
                length = min(b - a, math.ceil(-41.5 / math.log(p)) + 1) if p < 1.0 else b - a
                kk = k[:length]
                out[a : a + length, c] += beta[col + i] * kk * h / tc**2 * p**kk
        col += m
    return out


def projected_jacobian(Phi: FloatArray, sens: FloatArray) -> FloatArray:
    """∂r/∂p of the variable-projection residual r = y − Φβ̂ (Kaufman's form): −P⊥·sens.

    Kaufman (1975) drops the term Φ⁺ᵀ·(∂Φ/∂p)ᵀ·r of the exact Jacobian (Golub & Pereyra 1973):
    it vanishes as r → 0 and contributes nothing to the gradient Jᵀr (r ⊥ range Φ), so the
    search has the same stationary points and converges as fast near them.
    """
    G = Phi.T @ Phi
    scale = np.sqrt(np.diag(G))
    scale[scale == 0.0] = 1.0
    try:
        coef = np.linalg.solve(G / np.outer(scale, scale), (Phi.T @ sens) / scale[:, None])
        coef /= scale[:, None]
    except np.linalg.LinAlgError:
        coef = np.linalg.lstsq(Phi, sens, rcond=None)[0]
    return np.asarray(Phi @ coef - sens, dtype=float)


def cramer_rao_bound(
    model: ProcessModel,
    u: FloatArray,
    sample_time: float,
    sigma: float,
    *,
    delay_free: bool = False,
    initial: Literal["estimate", "rest"] = "rest",
    noise_ar: FloatArray | None = None,
) -> tuple[tuple[str, ...], FloatArray]:
    """Cramér–Rao bound σ²(JᵀJ)⁻¹ for the parameters an :class:`OutputError` fit estimates.

    J = ∂ŷ/∂p on the noise-free response of ``model`` to ``u`` (starting at rest at u[0]), for
    exactly the free parameters: K, T (and T2 when ``model.T2 > 0``), the delay when
    ``delay_free``, the offset, and the initial-state amplitudes when ``initial="estimate"``.

    With ``noise_ar`` = [1, a₁, …, a_p], the noise is the AR process A(q)·v = e and ``sigma`` the
    innovation's standard deviation σ_e: the bound is then the Box–Jenkins one (known noise
    model), σ_e²·(J_fᵀJ_f)⁻¹ with J_f = A(q)·J, the best any estimator can do on such noise and
    what a prediction-error fit with the right noise model attains.

    Returns
    -------
    names, covariance
        Parameter names and the bound on their covariance.

    Examples
    --------
    One step of amplitude a = K·Δu = 1, noise σ = 0.01, h = 0.1 s ≪ T = 10 s, delay known.
    With T alone free, the hand estimate of docs/explanation/identification.md §4 gives
    sd(T̂)/T = √(4h/T)·σ/a = 0.0020; estimating K and the offset as well costs a little (their
    columns correlate with ∂ŷ/∂T):

    >>> u = np.r_[np.zeros(100), np.ones(2000)]
    >>> names, cov = cramer_rao_bound(ProcessModel(K=1.0, T=10.0), u, 0.1, 0.01)
    >>> names
    ('K', 'T', 'offset')
    >>> round(float(np.sqrt(cov[1, 1])) / 10.0, 4)
    0.0023
    """
    order = 2 if model.T2 > 0.0 else 1
    st = Structure(order, model.T_f, None if delay_free else model.delay, initial, None)
    u = np.asarray(u, dtype=float)
    n_modes = (order + (1 if model.T_f > 0.0 else 0)) if initial == "estimate" else 0
    beta = np.r_[model.K, 0.0, np.zeros(n_modes)]
    values = {"T": model.T, "T2": model.T2, "delay": model.delay}
    names, J = jacobian(st, values, beta, u, sample_time, float(u[0]))
    if noise_ar is not None:
        J = scipy.signal.lfilter(np.asarray(noise_ar, dtype=float), [1.0], J, axis=0)
    return names, np.asarray(sigma**2 * np.linalg.inv(J.T @ J), dtype=float)


def start_from_model(init: ProcessModel, st: Structure) -> FloatArray:
    """The search vector [log T, (log T2), (delay)] of a previous model: a warm start."""
    z = [math.log(init.T)]
    if st.order == 2:
        z.append(math.log(init.T2 if init.T2 > 0.0 else 0.3 * init.T))
    if st.delay is None:
        z.append(init.delay)
    return np.array(z)


def grid_starts(
    data: IOData,
    st: Structure,
    evaluate: Callable[[FloatArray, IOData], LinearFit],
    max_delay: float,
) -> list[FloatArray]:
    """The best few points of a coarse grid over (T, delay), on a subsampled record.

    ``evaluate(z, record)`` is the linear fit at the search vector ``z``; ``max_delay`` [s] the
    upper bound of a free delay.
    """
    step = max(1, math.ceil(data.n_samples / GRID_SAMPLES))
    coarse = subsample(data, step)
    record = data.n_samples * data.sample_time
    T_grid = np.geomspace(max(data.sample_time, record / 2000.0), record / 3.0, 14)
    delays = np.linspace(0.0, max_delay, 7) if st.delay is None else np.array([math.nan])
    scored: list[tuple[float, FloatArray]] = []
    for T in T_grid:
        for delay in delays:
            z = [math.log(T)]
            if st.order == 2:
                z.append(math.log(0.3 * T))
            if st.delay is None:
                z.append(delay)
            zz = np.array(z)
            ev = evaluate(zz, coarse)
            scored.append((ev.sse, zz))
    scored.sort(key=lambda item: item[0])
    # refine the best grid point, and with a free delay also the best one at another delay
    # (the cost can have a local minimum per integer delay)
    starts = [scored[0][1]]
    if st.delay is not None:
        return starts
    for _, candidate in scored[1:]:
        if abs(candidate[-1] - starts[0][-1]) > 0.5 * data.sample_time:
            starts.append(candidate)
            break
    return starts
