"""The closed-loop window's estimator choice, and the cheap test that skips a doomed pem fit.

In AUTO the window fits the prediction-error (Box–Jenkins) model after the output-error one and
keeps it unless its noise pole is nearly integrating (above :data:`NEAR_INTEGRATING_POLE`) or
it fails (:func:`closed_loop_choice`). With a slow fed-back disturbance (a drift of a minute's
time constant, pole e^(−h/60 s) ≈ 0.9997 at 50 Hz) the pole is nearly integrating on nearly
every window, so the joint search (half to three quarters of an AUTO window's cost) was run to
be thrown away.

The cheap decision (:func:`noise_screen`) fits pem's noise model to the output-error residuals
alone, by the Hannan–Rissanen regressions pem itself uses to choose its noise order
(:func:`fuelid.identify._noise.hannan_rissanen`: a long autoregression for the innovations,
then one linear regression for C and D), with the order pem would use (the last window's, as
pem's warm start keeps it; else pem's own BIC choice among
:data:`~fuelid.identify._noise.NOISE_ORDERS`). Why it predicts pem's pole: pem starts from the
output-error process model and the noise model is a function of the process residual
y − ŷ_p; at a fixed process model the prediction-error estimate of C/D is the conditional
maximum-likelihood ARMA fit of that residual, which the Hannan–Rissanen estimate approximates
consistently, and the joint search moves the process parameters by about their standard
errors, which changes the residual by a fast, small signal next to a drift whose pole sits at
0.9997. pem is skipped only when the screened pole exceeds :data:`SKIP_POLE`, a margin above
:data:`NEAR_INTEGRATING_POLE`; below it pem runs and today's rule decides. So a disagreement
with the full decision needs a screened pole above the margin and a fitted one at or below
0.999. Measured on held-out windows (``benchmarks/bench_window.py``, and
``tests/unit/online/test_pem_screen.py``): see docs/explanation/online.md.

Units: residuals [L/min]; poles per sample [-].
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import FuelidError
from fuelid.identify import (
    NOISE_ORDERS,
    SELECTION_WARMUP,
    NoiseOrder,
    NoiseShape,
    OutputError,
    PredictionError,
    filter_segments,
    hannan_rissanen,
    information_criterion,
    noise_coefficients,
    used_samples,
)
from fuelid.io.timeseries import IOData
from fuelid.numerics_mode import DEFAULT_NUMERICS, TIGHT_TOLERANCES, Numerics, SearchTolerances

FloatArray = NDArray[np.float64]

NEAR_INTEGRATING_POLE = 0.999
"""A pem noise pole above this (per sample) keeps the output-error fit (as ``identify --method
auto`` does): pem would fit the differenced data and lose the low-frequency gain."""
SKIP_POLE = 0.9991
"""The screened noise pole above which pem is not fitted [-]: a margin of 10⁻⁴ above
:data:`NEAR_INTEGRATING_POLE`. On the 36 tuning windows (seeds 1–2, disturbances 0.1, 0.3 and
1.0 L/min, 20 °C, setpoint steps and the demo's runs) the screened pole was never above pem's
by more than 10⁻⁵ and below it by up to 7·10⁻⁴ (the screen errs towards running pem);
docs/explanation/online.md has the held-out study."""


@dataclass(frozen=True)
class NoiseScreen:
    """The noise model of the output-error residuals, as pem's start would choose it."""

    pole: float
    """Largest |pole| of D [-] (0 for no autoregressive part)."""
    C: list[float]
    """Moving-average polynomial in q⁻¹, leading 1."""
    D: list[float]
    """Autoregressive polynomial in q⁻¹, leading 1."""

    @property
    def skip_pem(self) -> bool:
        """True when pem's own noise pole would be nearly integrating (its fit discarded)."""
        return self.pole > SKIP_POLE

    def noise_model(self) -> dict[str, Any]:
        """As ``PredictionError.noise_model_`` for a warm start (``C`` and ``D`` only)."""
        return {"C": list(self.C), "D": list(self.D)}


def noise_screen(
    residuals: FloatArray,
    bounds: Sequence[tuple[int, int]],
    last_noise: Mapping[str, Any] | None,
    *,
    refine: bool = True,
    tolerances: SearchTolerances = TIGHT_TOLERANCES,
) -> NoiseScreen:
    """Pem's noise model fitted to the output-error residuals alone (module docstring).

    Parameters
    ----------
    residuals : ndarray
        y − ŷ of the output-error fit [L/min].
    bounds : list of (int, int)
        The record's segments (the filters restart at each).
    last_noise : mapping or None
        The last window's pem noise model (its order is the one pem would keep); None: the
        order by BIC, as pem's cold start chooses it.
    refine : bool
        Refine the Hannan–Rissanen estimate by a search (stopped at ``tolerances``: the
        window's numerics pass :data:`~fuelid.numerics_mode.STATISTICAL_TOLERANCES`).

    Returns
    -------
    NoiseScreen

    Examples
    --------
    >>> import scipy.signal
    >>> e = np.random.default_rng(0).normal(size=30_000)
    >>> drift = scipy.signal.lfilter([1.0], [1.0, -0.9997], 0.05 * e)
    >>> screen = noise_screen(drift + e, [(0, e.size)], {"C": [1.0, 0.0], "D": [1.0, 0.0]})
    >>> screen.skip_pem, noise_screen(e, [(0, e.size)], None).skip_pem
    (True, False)
    """
    spans = [(int(a), int(b)) for a, b in bounds]
    n = residuals.size
    candidates: tuple[NoiseOrder, ...] = NOISE_ORDERS
    if last_noise is not None:
        C0, D0 = noise_coefficients(last_noise)
        candidates = ((len(C0) - 1, len(D0) - 1),)
    etas = hannan_rissanen(residuals, candidates, spans)
    if len(candidates) > 1:
        # pem's cold-start choice: BIC over the same samples; the process parameters' count is
        # common to every candidate and does not change which one wins
        n_used = int(used_samples(spans, n, SELECTION_WARMUP).sum())
        chosen = min(
            candidates,
            key=lambda c: information_criterion(etas[c][1], n_used, c[0] + c[1], "bic"),
        )
    else:
        chosen = candidates[0]
    shape = NoiseShape(*chosen)
    eta = etas[chosen][0]
    if refine and shape.size:
        eta = _refine(residuals, spans, shape, eta, tolerances)
    C, D = shape.polys(eta)
    roots = np.roots(D) if D.size > 1 else np.zeros(0)
    pole = float(np.max(np.abs(roots))) if roots.size else 0.0
    return NoiseScreen(pole=pole, C=[float(c) for c in C], D=[float(d) for d in D])


def _refine(
    residuals: FloatArray,
    spans: list[tuple[int, int]],
    shape: NoiseShape,
    eta0: FloatArray,
    tolerances: SearchTolerances,
) -> FloatArray:
    """η minimising Σ(D/C·r)², the noise model alone, from the Hannan–Rissanen start."""
    from scipy.optimize import least_squares  # slow to import: only when screening

    used = used_samples(spans, residuals.size, shape.nd)

    def errors(eta: FloatArray) -> FloatArray:
        C, D = shape.polys(eta)
        return filter_segments(D, C, residuals, spans)[used]

    sol = least_squares(errors, eta0, method="trf", max_nfev=50, **tolerances.as_kwargs())
    return np.asarray(sol.x, dtype=float)


@dataclass
class ClosedLoopChoice:
    """The AUTO window's estimator and why."""

    estimator: OutputError | PredictionError
    residuals: FloatArray
    method: str
    covariance: str
    reason: str
    noise: dict[str, Any] | None
    """The noise model to warm-start the next window's pem with (None: keep the last)."""
    screen: NoiseScreen | None = None


def closed_loop_choice(
    data: IOData,
    oe: OutputError,
    settings: Mapping[str, Any],
    last_noise: Mapping[str, Any] | None,
    *,
    screen: bool,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> ClosedLoopChoice:
    """The closed-loop window's estimator, oe or pem, by the rule above; ``screen``: cheaply first.

    Parameters
    ----------
    data : IOData
        The window's samples.
    oe : OutputError
        Its output-error fit.
    settings : mapping
        The estimators' settings (order, delay, T_f).
    last_noise : mapping or None
        The last window's noise model (pem's warm start).
    screen : bool
        Skip pem when :func:`noise_screen` says its noise pole would be nearly integrating;
        False runs pem on every window (the path before the screen existed).
    numerics : Numerics
        The screen's search tolerances and pem's numerics (:mod:`fuelid.numerics_mode`): the
        window's.

    Returns
    -------
    ClosedLoopChoice
    """
    residuals = data.y - oe.y_hat_
    checked: NoiseScreen | None = None
    if screen:
        try:
            checked = noise_screen(
                residuals, data.segment_bounds(), last_noise, tolerances=numerics.tolerances
            )
        except (FuelidError, ValueError, np.linalg.LinAlgError):
            checked = None  # the screen cannot tell: the full decision decides
        if checked is not None and checked.skip_pem:
            # pem's result would be discarded (its pole above NEAR_INTEGRATING_POLE): not
            # fitted; the screened model warm-starts the next window's pem instead of pem's
            return ClosedLoopChoice(
                oe,
                residuals,
                "oe",
                oe.covariance_,
                f"AUTO (closed loop): the noise model of the output errors has a pole "
                f"{checked.pole:.5f}, nearly integrating (pem's would be too, and it would fit "
                "the differenced data): pem not fitted, output error kept",
                checked.noise_model(),
                checked,
            )
    try:
        # from oe's optimum and the last window's noise model: one joint search
        pem = PredictionError(**settings, numerics=numerics).fit(
            data, init=oe.model_, noise_init=last_noise
        )
    except FuelidError as error:
        return ClosedLoopChoice(
            oe,
            residuals,
            "oe",
            oe.covariance_,
            f"AUTO (closed loop): pem failed ({error}); output error kept",
            None,
            checked,
        )
    poles = [abs(complex(*p)) if isinstance(p, list) else abs(p) for p in _poles(pem)]
    if any(p > NEAR_INTEGRATING_POLE for p in poles):
        return ClosedLoopChoice(
            oe,
            residuals,
            "oe",
            oe.covariance_,
            f"AUTO (closed loop): pem's noise pole {max(poles):.5f} is nearly integrating "
            "(it would fit the differenced data); output error kept",
            pem.noise_model_,
            checked,
        )
    return ClosedLoopChoice(
        pem,
        pem.residuals_,
        "pem",
        "noise-model",
        "AUTO (closed loop): prediction error with its noise model",
        pem.noise_model_,
        checked,
    )


def _poles(pem: PredictionError) -> list[Any]:
    poles = pem.noise_model_.get("poles", [])
    return list(poles) if isinstance(poles, list | tuple) else []


__all__ = [
    "NEAR_INTEGRATING_POLE",
    "SKIP_POLE",
    "ClosedLoopChoice",
    "NoiseScreen",
    "closed_loop_choice",
    "noise_screen",
]
