"""The gates on a fitted model: standard errors, validation fit, residual correlation.

The plant-ratio *event* flags a window and never rejects it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fuelid.errors import NotExcitingError
from fuelid.identify import IdentificationResult, OutputError
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel
from fuelid.numerics_mode import DEFAULT_NUMERICS, Numerics
from fuelid.online._residual_acf import (
    MIN_SETTLED_SAMPLES,
    acf_lags,
    largest_residual_acf,
    prewhiten,
)
from fuelid.online._settings import Online
from fuelid.online.gates._verdict import WindowVerdict

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def _rel(value: float, se: float | None) -> float:
    if se is None or not math.isfinite(se) or value == 0.0:
        return math.nan
    return abs(se / value)


def postfit_gates(
    model: ProcessModel,
    stderr: Mapping[str, float | None],
    fit_percent: float | None,
    residuals: ArrayLike,
    sample_time: float,
    settings: Online,
    *,
    segment_starts: Sequence[int] = (),
    plant_K: float | None = None,
    u: ArrayLike | None = None,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> WindowVerdict:
    """Gates on a fitted model of one window.

    1. **Standard errors**: se(K)/|K| > ``max_rel_stderr_K`` or se(T)/T > ``max_rel_stderr_T``
       (a missing or non-finite standard error fails: the parameter is not determined).
    2. **Validation fit**: ``fit_percent`` < ``min_fit_percent`` (a missing fit fails).
    3. **Residual correlation**: max |ρ(k)|, k = 1…L (:func:`acf_lags`), > ``max_residual_acf``,
       of the residuals prewhitened by the noise's own model
       (:func:`~fuelid.online._residual_acf.prewhiten`) when they are output errors (``u``
       given) and the window has settled stretches enough; else of the residuals as they are
       (prediction errors are whitened by their fit's noise model).
    4. **Plant ratio** (an event, never a rejection): K outside ``plant_ratio_event`` × the
       plant model's K at the window's operating point and temperature.

    Parameters
    ----------
    model : ProcessModel
        The fitted model (K [(L/min)/V], T [s]).
    stderr : mapping
        Standard error by parameter name ("K", "T") [(L/min)/V, s].
    fit_percent : float or None
        Validation fit [%] (the held-out part's, else the fit's own).
    residuals : array
        y − ŷ, or a noise-model fit's one-step prediction errors [L/min].
    sample_time : float
        h [s].
    settings : Online
        The ``[online]`` table.
    segment_starts : sequence of int
        Where each segment after a gap begins (nothing is correlated across a gap).
    plant_K : float, optional
        The plant model's K at the window's operating point and temperature [(L/min)/V].
    u : array, optional
        The command, one per residual [V], when the residuals are output errors y − ŷ: the
        residual correlation is then judged after prewhitening them by the noise's model. None
        for prediction errors (judged as they are).
    numerics : Numerics
        How the model's settling time and the residuals' correlation are computed
        (:mod:`fuelid.numerics_mode`; the window's).

    Returns
    -------
    WindowVerdict
        ``measured`` holds the gated statistic (``residual_acf_max``, ``residual_acf_lag``,
        ``residual_acf_lags``), the raw residuals' (``residual_acf_raw_max``,
        ``residual_acf_raw_lag``), ``residual_acf_basis`` ("prewhitened", "raw: no command
        given (prediction errors)" or "raw: too few settled samples (n < 500)"), and the
        noise's AR order and settled samples (None when not prewhitened).

    Notes
    -----
    Why a bound on the *size* of the residual autocorrelation and not a p-value: a whiteness
    test (Box–Jenkins, Ljung 1999 §16.6) bounds each ρ(k) by ±1.96/√N, which for a 10-minute
    window at 50 Hz (N = 30 000) is ±0.011. Every real window has residual colour larger than
    that (a slightly nonlinear gain, quantisation, slow drifts), so the test rejects every
    window whatever the model's use. What matters for tuning is whether the colour is large
    enough to bias the model or make its standard errors meaningless. The lags span a few
    settling times of the model, where unmodelled dynamics and closed-loop colour show; a
    residual correlated beyond that is drift, which the output offset and the covariance absorb.

    Why prewhitened: output errors carry the meter noise's colour whatever the model (AR(1)
    noise with pole 0.8 per sample gives ρ(1) = 0.8 on a perfect model), and in open loop that
    colour is no reason to reject: the output-error estimate stays consistent and its HAC
    covariance keeps the standard errors honest. The noise's model is fitted where the output
    has settled, not on the whole residual, which would whiten the model's error away too;
    what correlation is left after it is the model's. A smooth misfit is scaled by about A(1)
    as well, so under strongly coloured noise a small misfit shows less: the noise has more
    power where the misfit lies.

    Where the default comes from: docs/explanation/gate-study.md
    (``benchmarks/bench_gate_study.py``), on two plants the gate was not tuned on
    (``benchmarks/gate_plants/``), 100 ten-minute windows per plant × noise (white; AR(1), pole 0.8)
    × loop (MAN, output error; AUTO, prediction error), fitted by the service's own analyser. 0.7 is
    the smallest value that in every condition rejects at most 5 % of the good windows (|K error| ≤
    3 %) and keeps the 95th percentile of the accepted windows' |K error| at or below 5 %. The
    binding condition is white noise in MAN on the fast plant: windows spanning most of the drive's
    range reach 0.66 (95th percentile) from the gain's nonlinearity, with K still within 0.5 %;
    coloured noise needs only 0.2 once prewhitened (the raw statistic, ≥ 0.79, rejected every MAN
    window with it). At 0.7 the gate catches 38 % of the MAN windows whose fit misses the
    meter's lag (step response off by 8–15 % of K, K itself within a few per cent), those with
    large moves, and 15 % of the AUTO ones: prediction errors are whitened by their noise
    model, which absorbs the misfit of a missing lag too, so in closed loop this gate does not
    see a wrong structure.
    """
    reasons: list[str] = []
    events: list[str] = []
    se_K, se_T = stderr.get("K"), stderr.get("T")
    rel_K, rel_T = _rel(model.K, se_K), _rel(model.T, se_T)
    measured: dict[str, Any] = {
        "K": model.K,
        "T_s": model.T,
        "rel_stderr_K": rel_K,
        "rel_stderr_T": rel_T,
    }
    for name, rel, bound in (
        ("K", rel_K, settings.max_rel_stderr_K),
        ("T", rel_T, settings.max_rel_stderr_T),
    ):
        if math.isnan(rel):
            reasons.append(f"{name} is not determined: no standard error")
        elif rel > bound:
            reasons.append(
                f"relative standard error of {name} {100.0 * rel:.1f} % > {100.0 * bound:g} %"
            )
    measured["fit_percent"] = fit_percent
    if fit_percent is None or not math.isfinite(fit_percent):
        reasons.append("no validation fit")
    elif fit_percent < settings.min_fit_percent:
        reasons.append(f"poor validation fit: {fit_percent:.1f} % < {settings.min_fit_percent:g} %")
    e = np.asarray(residuals, dtype=float)
    settle = model.settling_time(numerics=numerics)
    lags = acf_lags(e.size, settle, sample_time)
    raw_rho, raw_lag = largest_residual_acf(e, lags, segment_starts, numerics=numerics)
    rho, lag = raw_rho, raw_lag
    white = (
        None
        if u is None
        else prewhiten(e, u, sample_time, settle, segment_starts, numerics=numerics)
    )
    if white is not None:
        rho, lag = largest_residual_acf(
            white.residuals, lags, white.segment_starts, numerics=numerics
        )
        basis = "prewhitened"
        how = f", prewhitened by the noise's AR({white.noise.order})"
    elif u is None:
        basis = "raw: no command given (prediction errors)"
        how = ""
    else:
        basis = f"raw: too few settled samples (n < {MIN_SETTLED_SAMPLES})"
        how = ", raw: too few settled samples to model the noise"
    measured["residual_acf_max"] = rho
    measured["residual_acf_lag"] = lag
    measured["residual_acf_lags"] = lags
    measured["residual_acf_raw_max"] = raw_rho
    measured["residual_acf_raw_lag"] = raw_lag
    measured["residual_acf_basis"] = basis
    measured["residual_acf_noise_ar_order"] = None if white is None else white.noise.order
    measured["residual_acf_settled_samples"] = None if white is None else white.settled_samples
    if not rho <= settings.max_residual_acf:
        reasons.append(
            f"residual correlation too large: |ρ({lag})| = {rho:.3f} > "
            f"{settings.max_residual_acf:g} (lags 1–{lags}{how})"
        )
    if plant_K is not None and plant_K != 0.0 and math.isfinite(plant_K):
        ratio = model.K / plant_K
        low, high = settings.plant_ratio_event
        measured["plant_K"] = plant_K
        measured["plant_ratio"] = ratio
        if not low <= ratio <= high:
            events.append(
                f"plant_ratio: the identified K is {ratio:.2f} × the plant model's "
                f"(outside {low:g}–{high:g}): pump wear or a model far from the plant"
            )
    return WindowVerdict.of(reasons, measured, events=events)


def gate_estimator(
    estimator: OutputError,
    data: IOData,
    settings: Online,
    *,
    validation_fit_percent: float | None = None,
    plant_K: float | None = None,
) -> WindowVerdict:
    """:func:`postfit_gates` on an :class:`~fuelid.identify.OutputError` fitted to ``data``.

    The residuals are ``data.y − estimator.y_hat_``, judged after prewhitening by the noise's
    model (``u = data.u``); the fit is ``validation_fit_percent`` when given, else the
    estimator's own ``fit_percent_``.

    Parameters
    ----------
    estimator : OutputError
        Fitted on ``data``.
    data : IOData
        The fitting record.
    settings : Online
        The ``[online]`` table.
    validation_fit_percent : float, optional
        Fit on held-out data [%].
    plant_K : float, optional
        The plant model's K [(L/min)/V].

    Returns
    -------
    WindowVerdict
    """
    fit = estimator.fit_percent_ if validation_fit_percent is None else validation_fit_percent
    return postfit_gates(
        estimator.model_,
        estimator.stderr_,
        fit,
        data.y - estimator.y_hat_,
        estimator.sample_time_,
        settings,
        segment_starts=data.segment_starts,
        plant_K=plant_K,
        u=data.u,
    )


def gate_result(
    result: IdentificationResult,
    settings: Online,
    *,
    plant_K: float | None = None,
    u: ArrayLike | None = None,
) -> WindowVerdict:
    """:func:`postfit_gates` on an ``identify`` result.

    The fit is ``validation_fit_percent`` when the result has one, else ``fit_percent``; the
    residuals are the one-step prediction errors of a noise-model fit, else y − ŷ over the
    fitted samples.

    Parameters
    ----------
    result : IdentificationResult
        What :func:`fuelid.identify.identify` returned.
    settings : Online
        The ``[online]`` table.
    plant_K : float, optional
        The plant model's K [(L/min)/V].
    u : array, optional
        The command over the fitted samples [V]: y − ŷ residuals are then judged after
        prewhitening (ignored for prediction errors, which their noise model whitens).

    Returns
    -------
    WindowVerdict
    """
    command = None
    if result.prediction_errors is not None:
        residuals = np.asarray(result.prediction_errors, dtype=float)
    else:
        n = result.n_samples
        residuals = np.asarray(result.y[:n] - result.y_hat[:n], dtype=float)
        command = None if u is None else np.asarray(u, dtype=float)[:n]
    fit = (
        result.validation_fit_percent
        if result.validation_fit_percent is not None
        else result.fit_percent
    )
    return postfit_gates(
        result.model,
        result.stderr,
        fit,
        residuals,
        result.sample_time,
        settings,
        plant_K=plant_K,
        u=command,
    )


def excitation_refusal(error: NotExcitingError) -> WindowVerdict:
    """The estimator refused the window for lack of excitation: a rejection with its message.

    Examples
    --------
    >>> excitation_refusal(NotExcitingError("the input never changes")).reasons
    ('no excitation: the input never changes',)
    """
    return WindowVerdict.of([f"no excitation: {error}"], {"estimator_refused": True})


__all__ = ["excitation_refusal", "gate_estimator", "gate_result", "postfit_gates"]
