"""Sampled-data tools for linear time-invariant models: the bottom of fuelid's numerics.

Everything here is exact for zero-order-held (piecewise-constant) inputs: states are propagated
with the matrix exponential, never with Euler steps, and a dead time θ = d·h + τ' (0 ≤ τ' < h)
is applied exactly with the modified z-transform, never with a Padé approximation. A held input
delayed by θ switches inside each sample interval, so the exact discretisation has two input
matrices:

    x[k+1] = A_d x[k] + Γ₀ v[k] + Γ₁ v[k−1],   v[k] = u[k−d],
    Γ₀ = ∫₀^{h−τ'} e^{As} ds B,   Γ₁ = e^{A(h−τ')} ∫₀^{τ'} e^{As} ds B

(Åström & Wittenmark, *Computer-Controlled Systems*, 3rd ed., 1997, §2.3). The result is
continuous in θ (at τ' → h it becomes the next whole-sample delay), which the delay search of
the output-error fit relies on. Used by the model family (:mod:`fuelid.model`), the plant's
linearisation, the estimators and the tuning layer alike, so there is one implementation of each.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from fuelid.errors import FuelidError
from fuelid.numerics_mode import DEFAULT_NUMERICS, Numerics

__all__ = [
    "MAX_CONTROL_PERIOD",
    "SETTLING_BAND",
    "DiscreteLagModel",
    "FloatArray",
    "ModifiedZ",
    "StepMeasures",
    "check_control_period",
    "discretise",
    "lag_chain",
    "modified_z",
    "settling_time",
    "step_measures",
    "step_response",
    "step_settling_time",
    "zoh_discretise",
]

FloatArray = NDArray[np.float64]

SETTLING_BAND = 0.02
"""Relative band of the settling time fuelid reports everywhere: 2 %, the 98 % settling time."""

_UNIFORM_TOLERANCE = 1e-9
"""Relative spread of the time steps below which a grid counts as uniform."""

MAX_CONTROL_PERIOD = 10.0
"""Longest PLC control period [s] fuelid takes (a flow loop's PLC runs in 0.01…1 s)."""


def check_control_period(control_period: object, name: str = "control period") -> None:
    """Refuse a control period that is negative, not finite or beyond :data:`MAX_CONTROL_PERIOD`.

    The one check of every control period fuelid is given (options, site files, model files,
    the simulator, the tuning rules): 0 means a continuous controller (in a simulation, a
    command applied at once). ``name`` says where the value came from, e.g. ``--control-period``
    or ``the site file's [sampling] control_period_s``.

    Raises
    ------
    FuelidError
        One line: ``name``, the allowed range and the value found.

    Examples
    --------
    >>> check_control_period(1.0)
    >>> check_control_period(0.0)
    >>> check_control_period(-1.0, "--control-period")
    Traceback (most recent call last):
    ...
    fuelid.errors.FuelidError: --control-period must be 0 (continuous) or up to 10 s, got -1 s
    >>> check_control_period(float("nan"))
    Traceback (most recent call last):
    ...
    fuelid.errors.FuelidError: control period must be 0 (continuous) or up to 10 s, got nan s
    """
    if isinstance(control_period, bool) or not isinstance(control_period, int | float):
        raise FuelidError(f"{name} must be a number of seconds, got {control_period!r}")
    if not (math.isfinite(control_period) and 0.0 <= control_period <= MAX_CONTROL_PERIOD):
        raise FuelidError(
            f"{name} must be 0 (continuous) or up to {MAX_CONTROL_PERIOD:g} s, "
            f"got {control_period:g} s"
        )


def zoh_discretise(A: ArrayLike, B: ArrayLike, h: float) -> tuple[FloatArray, FloatArray]:
    r"""Exact zero-order-hold discretisation of ``dx/dt = A x + B u`` over a step ``h``.

    .. math:: A_d = e^{A h}, \qquad B_d = \int_0^h e^{A\tau}\,d\tau\; B

    both read off one matrix exponential of the augmented matrix ``[[A, B], [0, 0]]·h``
    (Van Loan 1978), which also works when ``A`` is singular; this is
    :func:`scipy.signal.cont2discrete` with ``method="zoh"``.

    Parameters
    ----------
    A : array, shape (n, n)
        State matrix [1/s].
    B : array, shape (n, m)
        Input matrix.
    h : float
        Step [s], non-negative (0 gives the identity and a zero input matrix).

    Returns
    -------
    (Ad, Bd) : tuple of arrays

    Examples
    --------
    A first-order lag 1/(2s+1) over one second: a = e^{-1/2}, b = 1 − a.

    >>> Ad, Bd = zoh_discretise([[-0.5]], [[0.5]], 1.0)
    >>> round(float(Ad[0, 0]), 6), round(float(Bd[0, 0]), 6)
    (0.606531, 0.393469)
    """
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.asarray(B, dtype=float).reshape(A.shape[0], -1)
    if h == 0.0:
        return np.eye(A.shape[0]), np.zeros_like(B)
    C = np.zeros((1, A.shape[0]))
    D = np.zeros((1, B.shape[1]))
    import scipy.signal  # 0.35 s to import (with scipy.stats): only where it is used

    Ad, Bd, _, _, _ = scipy.signal.cont2discrete((A, B, C, D), h, method="zoh")
    return np.asarray(Ad, dtype=float), np.asarray(Bd, dtype=float)


@dataclass(frozen=True)
class ModifiedZ:
    """Exact sampled form of ``dx/dt = A x + B u(t − θ)`` with ``u`` held over each period."""

    Ad: FloatArray
    """e^{Ah}."""
    G0: FloatArray
    """Input matrix of v[k] = u[k−d] (the part of the period after the switch)."""
    G1: FloatArray
    """Input matrix of v[k−1] (the part before the switch); zero for a whole-sample delay."""
    shift: int
    """Whole-sample part d of the delay."""


def modified_z(A: ArrayLike, B: ArrayLike, h: float, delay: float) -> ModifiedZ:
    """Modified z-transform of a state-space model with a fractional dead time.

    Parameters
    ----------
    A : array, shape (n, n)
        State matrix [1/s].
    B : array, shape (n, 1)
        Input matrix.
    h : float
        Sample interval [s], positive.
    delay : float
        Dead time θ [s], non-negative; θ = d·h + τ' with 0 ≤ τ' < h.

    Returns
    -------
    ModifiedZ

    Examples
    --------
    Half a sample of delay on 1/(s+1) splits the input between this and the previous sample:

    >>> m = modified_z([[-1.0]], [[1.0]], 1.0, 0.5)
    >>> m.shift, round(float(m.G0[0, 0] + m.G1[0, 0]), 6)
    (0, 0.632121)
    """
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.asarray(B, dtype=float).reshape(A.shape[0], -1)
    d = math.floor(delay / h + 1e-12)
    frac = max(delay - d * h, 0.0)
    E1, G0 = zoh_discretise(A, B, h - frac)
    E2, G2 = zoh_discretise(A, B, frac)
    return ModifiedZ(Ad=E1 @ E2, G0=G0, G1=E1 @ G2, shift=d)


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
        import scipy.signal

        return np.asarray(scipy.signal.lfilter(self.b, self.a, v), dtype=float)

    def frequency_response(self, omega: ArrayLike, h: float) -> NDArray[np.complex128]:
        """G(e^(jωh)) of this unit-gain sampled model at angular frequencies ``omega`` [rad/s]."""
        zi = np.exp(-1j * np.asarray(omega, dtype=float) * h)  # z⁻¹
        num = np.polyval(self.b[::-1], zi)
        den = np.polyval(self.a[::-1], zi)
        return np.asarray(zi**self.shift * num / den, dtype=complex)

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


def discretise(
    lags: Sequence[float], delay: float, h: float, numerics: Numerics = DEFAULT_NUMERICS
) -> DiscreteLagModel:
    """Exact ZOH discretisation of ``e^(−θs)/Π(T_i s + 1)`` at sample interval ``h``.

    Parameters
    ----------
    lags : sequence of float
        Time constants T_i [s], all positive.
    delay : float
        Dead time θ [s], non-negative (fractional multiples of h are exact).
    h : float
        Sample interval [s].
    numerics : Numerics
        ``reference=True``: through scipy's ``cont2discrete`` and ``ss2tf``, as before issue 26
        (:mod:`fuelid.numerics_mode`); the same coefficients to rounding, slower.

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
    if numerics.reference:
        return _discretise_reference(A, B, C, lags, delay, h)
    d = math.floor(delay / h + 1e-12)
    frac = max(delay - d * h, 0.0)
    # modified_z with expm on the block matrix, the transfer function from the Markov
    # parameters: cont2discrete's and ss2tf's checks and eigenvalue searches were a quarter of
    # a window's output-error fit (issue 26). Same numbers to rounding.
    E1, G0 = _zoh(A, B, h - frac)
    E2, G2 = _zoh(A, B, frac)
    Ad, G1 = E1 @ E2, E1 @ G2
    poles = np.exp(-h / np.asarray(lags, dtype=float))
    den = np.poly(poles) if n else np.ones(1)  # Ad is triangular, the poles on its diagonal
    # impulse response g_k = C·Ad^(k−1)·G0 + C·Ad^(k−2)·G1 (g_0 = 0), k = 0…n+1; the numerator
    # of H = b/a is the first n+2 terms of a·g (H is strictly proper: b_0 = 0)
    g = np.zeros(n + 2)
    row = C.copy()  # C·Ad^(k−1)
    previous = None  # C·Ad^(k−2)
    for k in range(1, n + 2):
        g[k] = (row @ G0).item() + ((previous @ G1).item() if previous is not None else 0.0)
        previous, row = row, row @ Ad
    b = np.convolve(den, g)[: n + 2]
    a = np.zeros(n + 2)
    a[: n + 1] = den
    return DiscreteLagModel(b=b, a=a, shift=d, poles=poles)


def _discretise_reference(
    A: FloatArray, B: FloatArray, C: FloatArray, lags: Sequence[float], delay: float, h: float
) -> DiscreteLagModel:
    """:func:`discretise` as before issue 26 (scipy's conversions; ``Numerics(reference=True)``)."""
    import scipy.signal

    n = A.shape[0]
    mz = modified_z(A, B, h, delay)
    num0, den = scipy.signal.ss2tf(mz.Ad, mz.G0, C, np.zeros((1, 1)))
    num1, _ = scipy.signal.ss2tf(mz.Ad, mz.G1, C, np.zeros((1, 1)))
    b = np.zeros(n + 2)
    b[: n + 1] += np.ravel(num0)
    b[1:] += np.ravel(num1)
    a = np.zeros(n + 2)
    a[: n + 1] = np.ravel(den)
    poles = np.exp(-h / np.asarray(lags, dtype=float))
    return DiscreteLagModel(b=b, a=a, shift=mz.shift, poles=poles)


def _zoh(A: FloatArray, B: FloatArray, h: float) -> tuple[FloatArray, FloatArray]:
    """(e^{Ah}, ∫₀ʰ e^{As} ds·B) from one matrix exponential (``zoh_discretise`` without checks)."""
    n = A.shape[0]
    if h == 0.0:
        return np.eye(n), np.zeros_like(B)
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = A * h
    M[:n, n:] = B * h
    E = scipy.linalg.expm(M)
    return E[:n, :n], E[:n, n:]


def step_response(
    A: ArrayLike,
    B: ArrayLike,
    C: ArrayLike,
    D: float,
    t: ArrayLike,
    delay: float = 0.0,
) -> FloatArray:
    """Unit-step response of a single-input single-output state-space model with dead time.

    The model starts at rest; the step is applied at t = 0 and reaches the output at ``delay``.
    On a uniform grid from t = 0 the response is the exact sampled model (modified
    z-transform) propagated in a few vectorised matrix products; on any other grid each time is
    propagated with the matrix exponential.

    Parameters
    ----------
    A, B, C : arrays
        State-space matrices (B a column, C a row).
    D : float
        Feedthrough.
    t : array
        Sorted times at which to evaluate the response [s].
    delay : float
        Dead time θ [s], applied exactly.

    Returns
    -------
    ndarray
        y(t), zero before the delay.

    Examples
    --------
    1/(s+1) with one second of dead time, at t = 1 and t = 2 s:

    >>> step_response([[-1.0]], [[1.0]], [[1.0]], 0.0, [1.0, 2.0], delay=1.0).round(6).tolist()
    [0.0, 0.632121]
    """
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.asarray(B, dtype=float).reshape(-1, 1)
    C = np.asarray(C, dtype=float).reshape(1, -1)
    times = np.asarray(t, dtype=float)
    tau = times - delay
    active = np.flatnonzero(tau >= 0.0)
    y = np.zeros_like(tau)
    if active.size == 0:
        return y
    if _is_uniform_from_zero(times) and times.size > 2:
        return _uniform_step_response(A, B, C, D, float(times[1] - times[0]), delay, times.size)
    x = np.zeros((A.shape[0], 1))
    cache: dict[float, tuple[FloatArray, FloatArray]] = {}
    t_prev = 0.0
    for k in active:
        dt = float(tau[k] - t_prev)
        key = round(dt, 12)
        if key not in cache:
            cache[key] = zoh_discretise(A, B, dt)
        Ad, Bd = cache[key]
        x = Ad @ x + Bd
        y[k] = float((C @ x)[0, 0]) + D
        t_prev = float(tau[k])
    return y


def _is_uniform_from_zero(times: FloatArray) -> bool:
    if times.size < 2 or times[0] != 0.0:
        return False
    dt = np.diff(times)
    return bool(dt[0] > 0.0 and np.all(np.abs(dt - dt[0]) <= _UNIFORM_TOLERANCE * dt[0]))


def _uniform_step_response(
    A: FloatArray, B: FloatArray, C: FloatArray, D: float, h: float, delay: float, n: int
) -> FloatArray:
    """Step response at t = k·h, k = 0…n−1: the exact sampled model driven by a held unit step.

    With v[k] = u[k−d] = 1 from k = d on, the modified-z recursion gives x[k] = 0 up to d,
    x[d+1] = Γ₀ and then x[k+1] = A_d x[k] + (Γ₀ + Γ₁): an affine map, i.e. powers of
    M = [[A_d, Γ₀ + Γ₁], [0, 1]] applied to [x; 1]. The powers are built by doubling (about
    log₂ n matrix products), which stays exact where polynomial filter coefficients would lose
    accuracy with every pole near z = 1 on a fine grid.
    """
    mz = modified_z(A, B, h, delay)
    order = A.shape[0]
    y = np.zeros(n)
    first = mz.shift + 1  # the first sample at which the state has moved
    if first < n:
        M = np.eye(order + 1)
        M[:order, :order] = mz.Ad
        M[:order, order:] = mz.G0 + mz.G1
        states = np.vstack((mz.G0, np.ones((1, 1))))  # [x; 1] at k = first
        power = M
        while states.shape[1] < n - first:
            states = np.hstack((states, power @ states))
            power = power @ power
        y[first:] = (C @ states[:order, : n - first])[0]
    # the feedthrough acts from the instant the delayed step arrives
    if D != 0.0:
        y = y + D * (np.arange(n) * h >= delay - 1e-12 * max(h, 1.0))
    return y


def settling_time(t: ArrayLike, y: ArrayLike, final: float, band: float = SETTLING_BAND) -> float:
    """Time after which a response stays within ``band`` of its final value.

    The one settling-time rule of fuelid: model step responses, linearised plants and closed-loop
    runs all use it.

    Parameters
    ----------
    t : array
        Times [s], sorted.
    y : array
        Response at those times.
    final : float
        Final (steady-state) value.
    band : float
        Relative tolerance (0.02 for the 98 % settling time).

    Returns
    -------
    float
        Settling time [s], interpolated linearly between the last sample outside the band and
        the next one; ``nan`` if the response has not settled by the last sample.

    Examples
    --------
    A first-order lag with T = 1 s settles to 2 % at ln(50) = 3.912 s:

    >>> import numpy as np
    >>> t = np.linspace(0.0, 10.0, 100_001)
    >>> round(settling_time(t, 1 - np.exp(-t), 1.0), 3)
    3.912
    """
    t = np.asarray(t, dtype=float)
    err = np.abs(np.asarray(y, dtype=float) - final) - band * abs(final)
    outside = np.flatnonzero(err > 0.0)
    if outside.size == 0:
        return float(t[0])
    k = int(outside[-1])
    if k == t.size - 1:
        return float("nan")
    # linear interpolation of the crossing of the band edge between samples k and k+1
    frac = err[k] / (err[k] - err[k + 1])
    return float(t[k] + frac * (t[k + 1] - t[k]))


@dataclass(frozen=True)
class StepMeasures:
    """The measures of one response to a step of known final value (:func:`step_measures`)."""

    overshoot_percent: float
    """Peak beyond the final value in % of the step (0 without overshoot) [%]."""
    settling_time: float
    """Time after the step from which the response stays within the band [s]; nan when it has
    not settled by the last sample."""
    rise_time: float
    """Time between the first crossings of the rise limits (10 % and 90 % of the step) [s];
    nan when the upper limit is not reached."""
    iae: float
    """∫|reference − y| dt over the samples given [output unit·s]."""


def step_measures(
    t: ArrayLike,
    y: ArrayLike,
    start: float,
    final: float,
    *,
    band: float = SETTLING_BAND,
    step_time: float | None = None,
    reference: ArrayLike | float | None = None,
    rise_limits: tuple[float, float] = (0.1, 0.9),
) -> StepMeasures:
    """Overshoot, settling time, rise time and IAE of a response y(t) to a step start → final.

    The one implementation of fuelid's step-response measures: the closed-loop simulations of
    the tuning layer (:func:`fuelid.tuning._metrics.setpoint_step_metrics`) and the setpoint
    moves the online service records (:func:`fuelid.online.health.step_response_measures`)
    both call it.

    Parameters
    ----------
    t : array
        Times [s], sorted.
    y : array
        Response at those times.
    start, final : float
        Value before the step and the final (target) value; they must differ.
    band : float
        Settling band relative to the step (0.02 for the 98 % settling time) [-].
    step_time : float, optional
        When the step was applied [s]; the settling and rise times count from it. Default
        ``t[0]``.
    reference : array or float, optional
        What y should be at each time, for the IAE (a ramped setpoint); default ``final``.
    rise_limits : (float, float)
        The rise time's limits as fractions of the step [-].

    Returns
    -------
    StepMeasures

    Notes
    -----
    ``control.step_info`` of python-control fits a step response with a known final value, but
    its numbers are not fuelid's, so it is the cross-check of this function in the tests and
    not its implementation: its settling and rise times are sample instants, whereas fuelid
    interpolates the band crossing between samples (:func:`settling_time`; the model settling
    times that set step-ls's N by a ceiling, and the 20 ms samples of the online service, would
    move by up to a sample); its rise time fails (IndexError) when 90 % is never reached, which
    a recorded move cut short by MAN does; and its overshoot is taken from |peak|, so a
    response driven more than one step the wrong way reads as overshoot.

    Examples
    --------
    A first-order response with τ = 1 s: no overshoot, 2 % settling at ln 50, rise τ·ln 9,
    IAE = τ per unit step.

    >>> t = np.linspace(0.0, 20.0, 200_001)
    >>> m = step_measures(t, 1.0 - np.exp(-t), 0.0, 1.0)
    >>> m.overshoot_percent, round(m.settling_time, 3), round(m.rise_time, 3), round(m.iae, 4)
    (0.0, 3.912, 2.197, 1.0)
    """
    tt = np.asarray(t, dtype=float)
    yy = np.asarray(y, dtype=float)
    step = final - start
    if step == 0.0:
        raise ValueError("a step needs a non-zero size")
    t0 = float(tt[0]) if step_time is None else float(step_time)
    since = tt - t0
    rel = (yy - start) / step
    lower = _first_crossing(since, rel, rise_limits[0])
    upper = _first_crossing(since, rel, rise_limits[1])
    ref = final if reference is None else np.asarray(reference, dtype=float)
    return StepMeasures(
        overshoot_percent=max(0.0, float(np.max(rel)) - 1.0) * 100.0,
        settling_time=settling_time(since, rel, 1.0, band),
        rise_time=math.nan if lower is None or upper is None else upper - lower,
        iae=float(np.trapezoid(np.abs(ref - yy), tt)),
    )


def _first_crossing(t: FloatArray, rel: FloatArray, level: float) -> float | None:
    """Time at which ``rel`` first reaches ``level`` (linear interpolation), None if never."""
    above = np.flatnonzero(rel >= level)
    if above.size == 0:
        return None
    k = int(above[0])
    if k == 0:
        return float(t[0])
    r0, r1 = float(rel[k - 1]), float(rel[k])
    return float(t[k - 1] + (level - r0) / (r1 - r0) * (t[k] - t[k - 1]))


def step_settling_time(
    A: ArrayLike,
    B: ArrayLike,
    C: ArrayLike,
    D: float = 0.0,
    delay: float = 0.0,
    band: float = SETTLING_BAND,
    points: int = 24_001,
) -> float:
    """Settling time of the unit-step response of a stable state-space model with dead time.

    The response is evaluated exactly on a uniform grid from 0 to θ + 12·Σ 1/|Re λᵢ| (twelve
    times the sum of the model's time constants, far past any settling of an over-damped
    chain) and :func:`settling_time` is applied with the exact static gain as the final value.

    Parameters
    ----------
    A, B, C : arrays
        State-space matrices (B a column, C a row); A must be Hurwitz.
    D : float
        Feedthrough.
    delay : float
        Dead time θ [s].
    band : float
        Relative tolerance (0.02 for the 98 % settling time).
    points : int
        Grid size.

    Returns
    -------
    float
        Settling time [s]; ``nan`` if the model has a pole on or right of the imaginary axis.

    Examples
    --------
    1/(s+1) with 0.5 s of dead time settles to 2 % at 0.5 + ln 50 = 4.412 s:

    >>> round(step_settling_time([[-1.0]], [[1.0]], [[1.0]], delay=0.5), 3)
    4.412
    """
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.asarray(B, dtype=float).reshape(-1, 1)
    C = np.asarray(C, dtype=float).reshape(1, -1)
    rates = -np.linalg.eigvals(A).real
    if np.any(rates <= 0.0):
        return float("nan")
    horizon = delay + 12.0 * float(np.sum(1.0 / rates))
    t = np.linspace(0.0, horizon, points)
    final = D - float((C @ np.linalg.solve(A, B))[0, 0])
    return settling_time(t, step_response(A, B, C, D, t, delay), final, band)
