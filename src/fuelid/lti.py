"""Exact responses of linear time-invariant state-space models (zero-order-hold discretisation).

Everything here is exact for piecewise-constant inputs: the state is propagated with the matrix
exponential, never with Euler steps, and dead time is applied by evaluating the delay-free response
at ``t − θ`` (not by a Padé approximation).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def zoh_discretise(A: ArrayLike, B: ArrayLike, h: float) -> tuple[FloatArray, FloatArray]:
    r"""Exact zero-order-hold discretisation of ``dx/dt = A x + B u`` over a step ``h``.

    .. math:: A_d = e^{A h}, \qquad B_d = \int_0^h e^{A\tau}\,d\tau\; B

    both read off one matrix exponential of the augmented matrix ``[[A, B], [0, 0]]·h``
    (Van Loan 1978), which also works when ``A`` is singular.

    Parameters
    ----------
    A : array, shape (n, n)
        State matrix [1/s].
    B : array, shape (n, m)
        Input matrix.
    h : float
        Step [s], non-negative.

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
    n, m = B.shape
    M = np.zeros((n + m, n + m))
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
    tau = np.asarray(t, dtype=float) - delay
    y = np.zeros_like(tau)
    active = np.flatnonzero(tau >= 0.0)
    if active.size == 0:
        return y
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


def settling_time(t: ArrayLike, y: ArrayLike, final: float, band: float = 0.02) -> float:
    """Time after which a step response stays within ``band`` of its final value.

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
