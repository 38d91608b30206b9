r"""The process model family used everywhere in fuelid.

.. math:: G(s) = \frac{K\,e^{-\theta s}}{(T s + 1)(T_2 s + 1)(T_f s + 1)}

``T2 = 0`` for a first-order process, ``T_f = 0`` without a flowmeter prior, θ the total dead
time (it includes the flowmeter's delay). For the fuel loop K is in (L/min)/V and times are in s;
the class itself is unit-agnostic (output unit per input unit).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fuelid import lti
from fuelid.errors import DataError, FuelidError
from fuelid.lti import discretise, lag_chain
from fuelid.numerics_mode import DEFAULT_NUMERICS, Numerics

__all__ = [
    "DISTINCT_LAGS",
    "MODEL_KEYS",
    "Z95",
    "FloatArray",
    "ProcessModel",
    "check_gain_identified",
    "gain_not_identified",
    "model_covariance",
    "nrmse_fit",
    "nrmse_fit_columns",
    "simulate_model",
]

if TYPE_CHECKING:
    import control

FloatArray = NDArray[np.float64]

MODEL_KEYS = ("K", "T", "T2", "T_f", "delay")
"""The model family's parameters, in the one order every JSON object and table uses."""

Z95 = 1.959963984540054
"""Two-sided 95 % quantile of the standard normal distribution."""


@dataclass(frozen=True)
class ProcessModel:
    """K·e^(−θs)/((T·s+1)(T2·s+1)(T_f·s+1)).

    Parameters
    ----------
    K : float
        Static gain [output unit / input unit].
    T : float
        Main process time constant [s], > 0.
    T2 : float
        Second process time constant [s], 0 for a first-order process.
    T_f : float
        Flowmeter time constant [s], 0 without one.
    delay : float
        Total dead time θ [s].

    Examples
    --------
    >>> m = ProcessModel(K=2.0, T=1.0)
    >>> round(float(m.step_response([3.912023005428146])[0]), 4)
    1.96
    """

    K: float
    T: float
    T2: float = 0.0
    T_f: float = 0.0
    delay: float = 0.0

    def __post_init__(self) -> None:
        for name in MODEL_KEYS:
            value = getattr(self, name)
            if not math.isfinite(value):
                raise FuelidError(f"model parameter {name} must be finite, got {value}")
        if self.T <= 0.0:
            raise FuelidError(f"model time constant T must be positive, got {self.T:g} s")
        for name in ("T2", "T_f", "delay"):
            if getattr(self, name) < 0.0:
                raise FuelidError(f"model parameter {name} must not be negative")

    @property
    def time_constants(self) -> tuple[float, ...]:
        """The non-zero lags T, T2, T_f [s]."""
        return tuple(tc for tc in (self.T, self.T2, self.T_f) if tc > 0.0)

    def to_control(self) -> control.TransferFunction:
        """Delay-free part as a :class:`control.TransferFunction`; the dead time is ``.delay``.

        The dead time is kept explicit and never Padé-approximated here; use
        ``control.pade(model.delay, n)`` yourself if a rational approximation is wanted.

        Examples
        --------
        >>> ProcessModel(K=2.0, T=4.0, delay=1.0).to_control().num[0][0].tolist()
        [2.0]
        """
        import control  # python-control is slow to import: only where a model is converted

        den = np.array([1.0])
        for tc in self.time_constants:
            den = np.polymul(den, [tc, 1.0])
        return control.tf([self.K], den.tolist())

    def state_space(self) -> tuple[NDArray[np.float64], ...]:
        """(A, B, C, D) of the delay-free part as a chain of first-order lags."""
        A, B, C = lag_chain(self.time_constants)
        return A, self.K * B, C, np.zeros((1, 1))

    def step_response(self, t: ArrayLike) -> NDArray[np.float64]:
        """Response to a unit step at t = 0, exact, dead time included.

        Parameters
        ----------
        t : array
            Sorted times [s].

        Returns
        -------
        ndarray
            Output deviation [output unit].
        """
        A, B, C, _ = self.state_space()
        return lti.step_response(A, B, C, 0.0, t, delay=self.delay)

    def settling_time(
        self, band: float = lti.SETTLING_BAND, numerics: Numerics = DEFAULT_NUMERICS
    ) -> float:
        """Time for a unit step response to enter and stay within ``band`` of K [s].

        Distinct lags from the closed-form step response; with ``numerics.reference`` (the
        numerics before issue 26) always on the grid of :func:`fuelid.lti.step_settling_time`,
        which agrees to its interpolation error (under 1e-7 s).

        Examples
        --------
        >>> round(ProcessModel(K=1.0, T=1.0, delay=0.5).settling_time(), 3)
        4.412
        """
        return _settling_time(self.K, self.time_constants, self.delay, band, not numerics.reference)

    def describe(self, gain_unit: str = "(L/min)/V") -> str:
        """The parameters for titles and tables: K, every lag the model has, the dead time.

        Examples
        --------
        >>> ProcessModel(K=15.56, T=1.249, T2=0.947, delay=0.703).describe()
        'K = 15.56 (L/min)/V, T = 1.25 s, T2 = 0.947 s, delay = 0.703 s'
        """
        parts = [f"K = {self.K:.4g} {gain_unit}", f"T = {self.T:.3g} s"]
        if self.T2 > 0.0:
            parts.append(f"T2 = {self.T2:.3g} s")
        if self.T_f > 0.0:
            parts.append(f"T_f = {self.T_f:.3g} s")
        parts.append(f"delay = {self.delay:.3g} s")
        return ", ".join(parts)

    def to_json(self) -> dict[str, float]:
        """Parameters as a plain dictionary (for JSON)."""
        return asdict(self)


#: lags closer than this (relative) are not told apart by the closed form of the step response
#: (its coefficients T_i/(T_i − T_j) lose digits): the grid's settling time instead
DISTINCT_LAGS = 1e-3


@functools.lru_cache(maxsize=256)
def _settling_time(
    K: float, lags: tuple[float, ...], delay: float, band: float, exact: bool = False
) -> float:
    # a model's settling time is asked for several times per window (the colour test of each
    # order, the step-ls length, the residual gate's lags): 1.5-2 ms each on a 24,001-point
    # grid, for the same few models; cached by value (the same number, computed once)
    if exact and K != 0.0 and 0 < len(lags) <= 3 and _distinct(lags):
        # the error of a chain of distinct real lags, e(t) = Σ c_i·e^(−t/T_i) with
        # c_i = Π_(j≠i) T_i/(T_i − T_j), falls monotonically from 1 to 0 (no overshoot): its
        # crossing of the band, found to 1e-12 s, is the grid's interpolated crossing to its
        # interpolation error (under 1e-7 s), 0.05 ms instead of 1.5 ms
        from scipy.optimize import brentq

        c = [math.prod(ti / (ti - tj) for tj in lags if tj is not ti) for ti in lags]

        def excess(t: float) -> float:
            return sum(ci * math.exp(-t / ti) for ci, ti in zip(c, lags, strict=True)) - band

        return delay + float(brentq(excess, 0.0, 12.0 * sum(lags), xtol=1e-12))
    A, B, C = lag_chain(lags)
    return lti.step_settling_time(A, K * B, C, 0.0, delay, band)


def _distinct(lags: tuple[float, ...]) -> bool:
    return all(
        abs(a - b) > DISTINCT_LAGS * max(a, b) for i, a in enumerate(lags) for b in lags[i + 1 :]
    )


def simulate_model(model: ProcessModel, u: ArrayLike, h: float) -> FloatArray:
    """Exact ZOH response of ``model`` to ``u − u[0]`` sampled at ``h``, starting at rest.

    Parameters
    ----------
    model : ProcessModel
        The model.
    u : array
        Held input samples [input unit].
    h : float
        Sample interval [s].

    Returns
    -------
    ndarray
        Output deviation from the initial steady state [output unit].

    Examples
    --------
    >>> y = simulate_model(ProcessModel(K=2.0, T=1.0), np.r_[0.0, np.ones(99)], 0.1)
    >>> round(float(y[-1]), 4)
    1.9999
    """
    u_arr = np.asarray(u, dtype=float)
    discrete = discretise(model.time_constants, model.delay, h)
    return model.K * discrete.response(u_arr - float(u_arr[0]))


def nrmse_fit(y: ArrayLike, y_hat: ArrayLike) -> float:
    """NRMSE fit [%]: 100·(1 − ‖y − ŷ‖/‖y − mean(y)‖); nan for a constant ``y``.

    Examples
    --------
    >>> nrmse_fit([0.0, 1.0, 2.0], [0.0, 1.0, 2.0])
    100.0
    """
    y_arr = np.asarray(y, dtype=float)
    spread = float(np.linalg.norm(y_arr - y_arr.mean()))
    if spread == 0.0:
        return float("nan")
    return 100.0 * (1.0 - float(np.linalg.norm(y_arr - np.asarray(y_hat, dtype=float))) / spread)


def nrmse_fit_columns(y: ArrayLike, y_hat: ArrayLike) -> FloatArray:
    """:func:`nrmse_fit` [%] of each output column (N × n_y), over that column's finite samples.

    A logged output may have gaps (NaN) where the prediction has none; each column is scored on
    the samples it has, and a column with none (or constant) scores nan.

    Examples
    --------
    >>> y = [[0.0, 1.0], [np.nan, 2.0], [2.0, 3.0]]
    >>> nrmse_fit_columns(y, [[0.0, 1.0], [5.0, 2.0], [2.0, 3.0]])  # the 5.0 faces a gap
    array([100., 100.])
    """
    y_arr = np.asarray(y, dtype=float)
    y_hat_arr = np.asarray(y_hat, dtype=float)
    out = np.full(y_arr.shape[1], np.nan)
    for column in range(y_arr.shape[1]):
        keep = np.isfinite(y_arr[:, column])
        if keep.any():
            out[column] = nrmse_fit(y_arr[keep, column], y_hat_arr[keep, column])
    return out


def gain_not_identified(K: float, se_K: float | None) -> str | None:
    """Why the gain does not differ from zero (|K| < 1.96 standard errors), or None.

    A log in which the output does not follow the input gives K ≈ 0 with a wide interval;
    tuning rules would then return gains thousands of times too high.

    Examples
    --------
    >>> gain_not_identified(13.5, 0.1) is None
    True
    >>> gain_not_identified(0.04, 0.04)
    'K = 0.04 ± 0.078 (95 %) does not differ from zero: the output does not respond to the input'
    """
    if se_K is None or not math.isfinite(se_K) or abs(K) >= Z95 * se_K:
        return None
    return (
        f"K = {K:.3g} ± {Z95 * se_K:.2g} (95 %) does not differ from zero: the output does not "
        "respond to the input"
    )


def model_covariance(names: Sequence[str], cov: ArrayLike) -> tuple[list[str], FloatArray]:
    """The model parameters' block of an identification covariance.

    An identification estimates nuisance parameters too (the output offset, initial-state
    amplitudes); the marginal distribution of the model parameters is the matching block of the
    covariance. A parameter with no variance (NaN or ≤ 0 on the diagonal) is left out (held at its
    estimate); an unknown correlation (NaN off the diagonal, as ``step-ls`` reports for K and T)
    is taken as zero.

    Examples
    --------
    >>> names, block = model_covariance(["K", "T", "offset"], np.diag([1.0, 4.0, 9.0]))
    >>> names, block.tolist()
    (['K', 'T'], [[1.0, 0.0], [0.0, 4.0]])
    """
    full = np.asarray(cov, dtype=float).reshape(len(names), len(names))
    keep = [
        i
        for i, name in enumerate(names)
        if name in MODEL_KEYS and np.isfinite(full[i, i]) and full[i, i] > 0.0
    ]
    block = np.nan_to_num(full[np.ix_(keep, keep)], nan=0.0)
    return [str(names[i]) for i in keep], block


def check_gain_identified(K: float, se_K: float | None, source: str) -> None:
    """Refuse a model whose gain does not differ from zero (:func:`gain_not_identified`).

    Raises
    ------
    DataError
        Saying so, with ``source`` (the model file or the fit).
    """
    reason = gain_not_identified(K, se_K)
    if reason:
        raise DataError(f"{source}: {reason}, so no gains can be tuned from it")
