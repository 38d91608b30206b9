"""From a loaded log to an identified model with diagnostics: what ``fuelid identify`` runs.

The CLI only parses options and prints; everything computed lives here, so scripts get the same
numbers through :func:`identify`.

A log with gaps (an :class:`~fuelid.io.timeseries.IOData` with segments) is identified jointly,
as toolboxes merge experiments: one model for all segments, each with its own initial state
(:mod:`fuelid.identify._segments`). Segments shorter than
:data:`~fuelid.identify._segments.MIN_SEGMENT_SAMPLES` are left out with a warning; ``y_hat``
is the concatenation of the per-segment simulations over the kept samples, ``fit_percent``
their NRMSE over all of them, the residual tests run within segments, and the held-out part of
``validate_split`` is the last fraction of the kept samples, wherever the gaps fall.

The settings and the result (:class:`IdentifyOptions`, :class:`IdentificationResult`) live in
:mod:`fuelid.identify._result` and the residual warnings in
:mod:`fuelid.identify._residual_warnings`; users import all of them from :mod:`fuelid.identify`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid.blas import single_threaded_blas
from fuelid.errors import FuelidError
from fuelid.identify import _diagnostics as diagnostics
from fuelid.identify._causality import LEAD_MIN_SPAN, lead_check
from fuelid.identify._long_record import long_record_json
from fuelid.identify._misfit import misfit_bound
from fuelid.identify._nonlinearity import gain_bands
from fuelid.identify._oe import OutputError
from fuelid.identify._order import lags_not_separated as _lags_not_separated
from fuelid.identify._pem import PredictionError
from fuelid.identify._progress import DIAGNOSING, FITTING, StageCallback, announce
from fuelid.identify._residual_warnings import residual_warnings
from fuelid.identify._result import (
    METHODS,
    POSITIVE_PARAMETERS,
    CiMethod,
    IdentificationResult,
    IdentifyOptions,
    Method,
    interval95,
)
from fuelid.identify._segments import MIN_SEGMENT_SAMPLES, drop_short_segments
from fuelid.identify._step_ls import StepResponseLS
from fuelid.identify.preprocess import decimate
from fuelid.io.timeseries import IOData
from fuelid.model import gain_not_identified, nrmse_fit

__all__ = [
    "METHODS",
    "POSITIVE_PARAMETERS",
    "CiMethod",
    "IdentificationResult",
    "IdentifyOptions",
    "Method",
    "gain_unit",
    "identify",
    "interval95",
]

FloatArray = NDArray[np.float64]


def _split(data: IOData, fraction: float | None) -> tuple[IOData, int]:
    if fraction is None:
        return data, data.n_samples
    if not 0.0 < fraction < 1.0:
        raise FuelidError(f"--validate-split must lie strictly between 0 and 1, got {fraction:g}")
    n_fit = round(data.n_samples * (1.0 - fraction))
    # a fitted segment needs samples for its own initial state: a split just after a gap
    # moves back to the gap (the held-out part then starts with that segment)
    last_start = max((i for i in data.segment_starts if i < n_fit), default=0)
    if last_start and n_fit - last_start < MIN_SEGMENT_SAMPLES:
        n_fit = last_start
    if n_fit < 20 or data.n_samples - n_fit < 10:
        raise FuelidError(
            f"--validate-split {fraction:g} leaves {n_fit} samples to fit and "
            f"{data.n_samples - n_fit} to validate: too few"
        )
    return data.segment(0, n_fit), n_fit


def _no_excitation(u: FloatArray, what: str) -> str | None:
    """Why ``u`` cannot validate a model (its command never moves), or None.

    A fit % on a stretch where the input is constant only measures how well the model's offset
    matches the plateau: it can be anything from −10 % to 100 % whatever the dynamics.

    Examples
    --------
    >>> _no_excitation(np.r_[np.ones(10), 1.5 * np.ones(10)], "x") is None
    True
    >>> _no_excitation(np.ones(10), "the held-out part").split(":")[0]
    'the held-out part has no excitation (the command does not change)'
    """
    spread = float(np.ptp(u)) if u.size else 0.0
    scale = max(float(np.max(np.abs(u))) if u.size else 0.0, 1.0)
    if spread > 1e-9 * scale:
        return None
    return (
        f"{what} has no excitation (the command does not change): no validation fit is given; "
        "choose a validation part with command changes"
    )


def _decimated(data: IOData, control_period: float) -> IOData:
    if control_period <= data.sample_time * (1.0 + 1e-9):
        return data
    return decimate(data, control_period)


def _check_priors(
    data: IOData,
    T_f: float,
    delay: float | None,
    meter_delay: float | None,
    u_before: float | None,
) -> None:
    """Refuse priors the record contradicts (a unit mix-up, ms for s).

    Lags and delays must be shorter than the record; the input before the record must lie
    within the recorded input's range widened by that range on each side.
    """
    if u_before is not None:
        lo, hi = float(np.min(data.u)), float(np.max(data.u))
        span = hi - lo
        if not (math.isfinite(u_before) and lo - span <= u_before <= hi + span):
            raise FuelidError(
                f"the input before the record {u_before:g} is far outside the recorded input "
                f"({lo:g}…{hi:g}): check its units"
            )
    duration = data.n_samples * data.sample_time
    for name, value in (
        ("flowmeter time constant", T_f),
        ("dead time", delay),
        ("flowmeter delay", meter_delay),
    ):
        if value is not None and value >= duration:
            raise FuelidError(
                f"the {name} {value:g} s is not shorter than the record ({duration:g} s): "
                "check its units"
            )


def gain_unit(data: IOData) -> str:
    """Unit of K for ``data``: output unit per input unit ("(L/min)/V").

    Examples
    --------
    >>> gain_unit(IOData([1.0, 2.0], [3.0, 4.0], 1.0))
    '(L/min)/V'
    """
    y_unit = f"({data.y_unit})" if "/" in data.y_unit else data.y_unit
    return f"{y_unit}/{data.u_unit}"


def identify(
    data: IOData,
    options: IdentifyOptions,
    validation: IOData | None = None,
    *,
    diagnose: bool = True,
    progress: StageCallback | None = None,
) -> IdentificationResult:
    """Identify the model family on ``data`` with ``options``.

    ``oe`` fits the raw samples; ``step-ls`` first low-passes (zero phase) and decimates to the
    control period, as the article does. The model output ``y_hat`` is the estimator's
    ``simulate(work, initial="fitted")`` over the whole record: from the initial state
    estimated by the fit, on through the held-out last fraction of the record when
    ``validate_split`` is given; ``fit_percent`` scores it on the fitted part,
    ``validation_fit_percent`` on the held-out part. A separate ``validation`` record is scored
    by ``simulate(validation, initial=options.validation_initial)``: by default with its offset
    and initial state estimated (a record rarely starts at rest), or from rest at its first input.
    A held-out part or record whose command never changes gets no score, and a warning says why.
    ``diagnose=False`` stops there: the model, its standard errors and fits, without the
    residual tests, steady-state errors, gain bands and their warnings (``diagnostics`` empty;
    what the online windows' step-ls alongside needs). ``method="auto"`` always diagnoses.
    ``progress``, when given, is told as the fit and the diagnostics start, and the fit's steps
    when it can show them (:mod:`fuelid.identify._progress`).
    """
    with single_threaded_blas():
        if options.method == "auto":
            return _identify_auto(data, options, validation, progress)
        return _identify(data, options, validation, diagnose, progress)


AUTO_VALIDATION_MARGIN = 2.0
"""pem's validation fit may be this many points below oe's before ``auto`` keeps oe [%]."""
NEAR_INTEGRATING_POLE = 0.999
"""A noise pole above this (per sample) makes pem fit the differenced data: ``auto`` keeps oe."""


def _identify_auto(
    data: IOData,
    options: IdentifyOptions,
    validation: IOData | None,
    progress: StageCallback | None = None,
) -> IdentificationResult:
    """``method="auto"``: the output-error fit, or pem when the noise model is significant.

    pem is chosen when oe's residuals fail the whiteness test and pem's information criterion
    picks a noise model other than white (its own significance test), unless a noise pole is so
    close to 1 that pem would fit the differenced data and lose the low-frequency fit.
    """
    oe = _identify(data, replace(options, method="oe"), validation, progress=progress)
    if oe.diagnostics["residual_whiteness"]["passed"]:
        oe.extra["method_choice"] = "auto: oe (its residuals are white)"
        return oe
    pem = _identify(data, replace(options, method="pem"), validation, progress=progress)
    noise = pem.extra["noise_model"]
    poles = [abs(complex(*p)) if isinstance(p, list) else abs(p) for p in noise["poles"]]
    if noise["nc"] + noise["nd"] == 0:
        oe.extra["method_choice"] = "auto: oe (no noise model is significant)"
        return oe
    if poles and max(poles) > NEAR_INTEGRATING_POLE:
        oe.extra["method_choice"] = (
            f"auto: oe (pem's noise pole {max(poles):.5f} is nearly integrating: it would fit "
            "the differenced data)"
        )
        return oe
    pem_fit, oe_fit = pem.validation_fit_percent, oe.validation_fit_percent
    if pem_fit is not None and oe_fit is not None and pem_fit < oe_fit - AUTO_VALIDATION_MARGIN:
        # a noise model can buy one-step prediction with low-frequency fit: held-out data decide
        oe.extra["method_choice"] = (
            f"auto: oe (pem's noise model is significant, but its validation fit {pem_fit:.1f} % "
            f"is below oe's {oe_fit:.1f} %)"
        )
        return oe
    pem.extra["method_choice"] = (
        "auto: pem (oe's residuals are coloured and the noise model is significant)"
    )

    return pem


@dataclass(frozen=True)
class _Fit:
    """One estimator fitted: the record it worked on, its covariance and its JSON extras."""

    estimator: StepResponseLS | OutputError | PredictionError
    work: IOData
    """The record the estimator saw (decimated for step-ls)."""
    fit_data: IOData
    n_fit: int
    """Samples of ``work`` fitted on (the rest is held out)."""
    cov_names: tuple[str, ...]
    cov: Any
    extra: dict[str, Any]
    delay: float | None
    """The dead time the fit took (step-ls assumes 0 without one)."""
    copy: tuple[IOData, FloatArray] | None = None
    """oe on a long record fitted on its copy: the copy and its ŷ, which the tests read."""


def _fit_step_ls(
    data: IOData,
    options: IdentifyOptions,
    T_f: float,
    delay: float | None,
    warnings: list[str],
    progress: StageCallback | None = None,
) -> _Fit:
    work = _decimated(data, options.control_period)
    if delay is None:
        warnings.append(
            "step-ls needs the dead time as prior knowledge: none given (--flowmeter-delay or "
            "--delay SECONDS), assumed 0"
        )
        delay = 0.0
    fit_data, n_fit = _split(work, options.validate_split)
    ls = StepResponseLS(N=options.N, T_f=T_f, delay=delay, settling_time=options.settling_time).fit(
        fit_data
    )
    cov = np.diag([ls.K_stderr_**2, ls.T_stderr_**2])
    cov[0, 1] = cov[1, 0] = np.nan  # the two-stage method gives no joint covariance
    # what decimation did is information, not a warning; the loader's notes stay warnings
    preprocessing = [n for n in work.notes if n not in data.notes]
    # a segment the decimation had to leave out is a warning, not just information
    warnings.extend(n for n in preprocessing if n.startswith("segments left out"))
    warnings.extend(w for w in ls.warnings_ if w not in preprocessing)
    extra: dict[str, Any] = {
        "covariance": "white",
        "N": ls.N_,
        "step_coefficients": ls.a_.tolist(),
        "preprocessing": preprocessing,
    }
    return _Fit(ls, work, fit_data, n_fit, ("K", "T"), cov, extra, delay)


def _fit_pem(
    data: IOData,
    options: IdentifyOptions,
    T_f: float,
    delay: float | None,
    warnings: list[str],
    progress: StageCallback | None = None,
) -> _Fit:
    fit_data, n_fit = _split(data, options.validate_split)
    pem = PredictionError(order=options.order, delay=delay, T_f=T_f, u_before=options.u_before).fit(
        fit_data
    )
    warnings.extend(pem.warnings_)
    extra = {
        "covariance": "noise-model",
        "noise_model": pem.noise_model_,
        "one_step_fit_percent": pem.one_step_fit_percent_,
        "aic": {str(k): v for k, v in pem.aic_.items()},
        "bic": {str(k): v for k, v in pem.bic_.items()},
        "structure": pem.order_choice_.to_json(),
        "noise_std": pem.noise_model_["sigma_v"],
        "innovation_std": pem.sigma_,
    }
    return _Fit(pem, data, fit_data, n_fit, pem.param_names_, pem.cov_, extra, delay)


def _fit_oe(
    data: IOData,
    options: IdentifyOptions,
    T_f: float,
    delay: float | None,
    warnings: list[str],
    progress: StageCallback | None = None,
) -> _Fit:
    if options.order not in (1, 2, "auto"):
        raise FuelidError(f"--order must be 1, 2 or auto, got {options.order!r}")
    fit_data, n_fit = _split(data, options.validate_split)
    oe = OutputError(
        order=options.order,
        delay=delay,
        T_f=T_f,
        u_before=options.u_before,
        covariance=options.covariance,
        full_record=options.full_record,
    ).fit(fit_data, progress=progress)
    warnings.extend(oe.warnings_)
    extra: dict[str, Any] = {
        "covariance": oe.covariance_,
        "residual_colour": oe.residual_colour_,
        "residual_noise_model": oe.residual_ar_.to_json(),
        "aic": {str(k): v for k, v in oe.aic_.items()},
        "bic": {str(k): v for k, v in oe.bic_.items()},
        "structure": oe.order_choice_.to_json(),
        "noise_std": oe.sigma_,
        # how a long record was fitted (on a copy, or searched there and polished), else None
        "long_record": long_record_json(oe.long_record_),
    }
    if "T2" in oe.param_names_ and "delay" in oe.param_names_:
        names = oe.param_names_
        extra["correlation_T2_delay"] = float(
            oe.correlation_[names.index("T2"), names.index("delay")]
        )
    copy = None if oe.copy_ is None or oe.copy_y_hat_ is None else (oe.copy_, oe.copy_y_hat_)
    return _Fit(oe, data, fit_data, n_fit, oe.param_names_, oe.cov_, extra, delay, copy)


_FITTERS = {"step-ls": _fit_step_ls, "pem": _fit_pem}
"""The estimators by method; output error for any other (``oe``)."""


def _separate_lags(
    cov_names: tuple[str, ...], cov: Any, stderr: dict[str, float | None], warnings: list[str]
) -> Any:
    """The covariance with T and T2 unknown when the fit cannot tell the two lags apart."""
    lags_merged = _lags_not_separated(cov_names, cov)
    if lags_merged is None:
        return cov
    # two equal lags: only their combination is determined, and the separate intervals,
    # however narrow, mean nothing
    stderr["T"] = stderr["T2"] = None
    i, j = cov_names.index("T"), cov_names.index("T2")
    cov = np.array(cov, dtype=float)
    cov[[i, j], :] = np.nan
    cov[:, [i, j]] = np.nan
    warnings.append(
        f"T and T2 are not separately determined (correlation {lags_merged:+.4f}): no "
        "interval for either; the model's response is, but prefer order 1 or a meter prior "
        "(--flowmeter-T) for the parameters themselves"
    )
    return cov


def _validation_fits(
    fit: _Fit,
    y_model: FloatArray,
    validation: IOData | None,
    options: IdentifyOptions,
    warnings: list[str],
) -> tuple[float | None, str | None]:
    """(validation fit [%], how the validation was simulated) on the held-out part or file."""
    work, n_fit = fit.work, fit.n_fit
    validation_fit: float | None = None
    validation_initial: str | None = None
    if n_fit < work.n_samples:
        validation_initial = "continued"
        reason = _no_excitation(work.u[n_fit:], "the held-out part of the record")
        if reason:
            warnings.append(reason)
        else:
            validation_fit = nrmse_fit(work.y[n_fit:], y_model[n_fit:])
    if validation is not None:
        if options.method == "step-ls":
            validation = _decimated(validation, options.control_period)
        validation_initial = options.validation_initial
        reason = _no_excitation(validation.u, "the validation record")
        if reason:
            warnings.append(reason)
        else:
            validation_fit = fit.estimator.score(validation, initial=options.validation_initial)
    return validation_fit, validation_initial


def _identify(
    data: IOData,
    options: IdentifyOptions,
    validation: IOData | None,
    diagnose: bool = True,
    progress: StageCallback | None = None,
) -> IdentificationResult:
    if validation is not None and options.validate_split is not None:
        raise FuelidError("give either a validation split or a validation file, not both")
    T_f = options.flowmeter_T or 0.0
    delay = options.resolved_delay()
    _check_priors(data, T_f, delay, options.flowmeter_delay, options.u_before)
    warnings: list[str] = []
    data, dropped = drop_short_segments(data)
    warnings.extend(dropped)
    if validation is not None:
        validation, dropped = drop_short_segments(validation)
        warnings.extend(f"validation record: {w}" for w in dropped)
    announce(progress, FITTING)
    fit = _FITTERS.get(options.method, _fit_oe)(data, options, T_f, delay, warnings, progress)
    estimator, work, n_fit = fit.estimator, fit.work, fit.n_fit
    model = estimator.model_
    stderr = dict(estimator.stderr_)
    if isinstance(estimator, OutputError | PredictionError):
        # the intervals hold within the structure the rule kept: say so when they trade or
        # when another structure fits nearly as well
        note = estimator.order_choice_.conditional_note()
        if note:
            warnings.append(note)
    cov = _separate_lags(fit.cov_names, fit.cov, stderr, warnings)
    y_model = estimator.simulate(work, initial="fitted")
    validation_fit, validation_initial = _validation_fits(
        fit, y_model, validation, options, warnings
    )

    def result(diag: dict[str, Any], prediction_errors: Any = None) -> IdentificationResult:
        return IdentificationResult(
            n_segments=work.n_segments,
            method=options.method,
            model=model,
            fixed=estimator.fixed_,
            stderr=stderr,
            cov_names=fit.cov_names,
            cov=cov,
            fit_percent=nrmse_fit(work.y[:n_fit], y_model[:n_fit]),
            validation_fit_percent=validation_fit,
            validation_initial=validation_initial,
            n_samples=fit.fit_data.n_samples,
            sample_time=work.sample_time,
            warnings=list(dict.fromkeys(warnings)),
            time=work.t,
            y=work.y,
            y_hat=y_model,
            split_time=float(work.t[n_fit]) if n_fit < work.n_samples else None,
            diagnostics=diag,
            extra=fit.extra,
            prediction_errors=prediction_errors,
        )

    if not diagnose:
        return result({})
    announce(progress, DIAGNOSING)
    residuals = None
    if fit.copy is not None:
        # a long record fitted on its copy: the tests are the copy's, as its estimates and
        # standard errors are (the lead check still reads the whole record: _diagnose's data)
        copy, copy_y_hat = fit.copy
        on_copy = replace(fit, work=copy, fit_data=copy, n_fit=copy.n_samples)
        diag = _diagnose(data, on_copy, copy_y_hat, copy.y - copy_y_hat, options, warnings)
    else:
        # pem's tests are on its prediction errors: white when its noise model is right
        residuals = (
            np.asarray(estimator.residuals_[:n_fit], dtype=float)
            if isinstance(estimator, PredictionError)
            else work.y[:n_fit] - y_model[:n_fit]
        )
        diag = _diagnose(data, fit, y_model, residuals, options, warnings)
    no_gain = gain_not_identified(model.K, stderr.get("K"))
    if no_gain:
        warnings.append(f"{no_gain} in this log; do not tune from it")
    return result(diag, residuals if isinstance(estimator, PredictionError) else None)


def _diagnose(
    data: IOData,
    fit: _Fit,
    y_model: FloatArray,
    residuals: FloatArray,
    options: IdentifyOptions,
    warnings: list[str],
) -> dict[str, Any]:
    """The diagnostics of a fit (``diagnostics`` in the JSON), their warnings added in place."""
    work, n_fit, fit_data, model = fit.work, fit.n_fit, fit.fit_data, fit.estimator.model_
    y = work.y
    starts = fit_data.segment_starts
    white = diagnostics.residual_whiteness(residuals, segment_starts=starts)
    # lags must span the controller's reaction: two control periods at least
    max_lag = max(25, round(2.0 * options.control_period / work.sample_time))
    max_lag = min(max_lag, n_fit // 4)
    cross = diagnostics.input_residual_correlation(work.u[:n_fit], residuals, max_lag, starts)
    settle = model.settling_time()
    steps = diagnostics.steady_state_errors(
        work.u, y, y_model, work.sample_time, settle, work.segment_starts
    )
    nonlinearity = gain_bands(fit_data, model)
    # the model's error that the command explains, as a bound on |Δ(jω)| (output error: the
    # simulated output's residuals, for pem too)
    misfit = misfit_bound(
        work.u[:n_fit], y[:n_fit] - y_model[:n_fit], work.sample_time, model, starts
    )
    # does the flow move before its command (a reversed clock, swapped columns)? on the raw
    # record: step-ls's zero-phase filter smears each output step backwards in time
    lead = lead_check(
        data.u,
        data.y,
        data.sample_time,
        span=max(LEAD_MIN_SPAN, settle) if math.isfinite(settle) else LEAD_MIN_SPAN,
        segment_starts=data.segment_starts,
        sign=-1.0 if model.K < 0.0 else 1.0,
    )
    lead_warning = lead.warning()
    if lead_warning:
        # first: it makes every number below meaningless
        warnings.insert(0, lead_warning)
    found = residual_warnings(
        options,
        fit.delay,
        (white, cross),
        residuals,
        nonlinearity,
        fit_data,
        (max_lag, settle),
        gain_unit(work),
        kept_order=2 if model.T2 > 0.0 else 1,
        output_leads=lead.leads,
        # a copy's covariance may follow the whole record's settled test: so do the words
        settled_test=getattr(fit.estimator, "whole_record_settled_", None),
    )
    warnings.extend(_what_the_errors_hold(found, fit.extra))
    # a model fitted to a log that runs backwards has no settling time to advise on
    advice = (
        None
        if lead.leads
        else diagnostics.sample_time_advice(settle, work.sample_time, data.sample_time)
    )
    if advice:
        warnings.append(advice)
    return {
        "residual_whiteness": {
            "p_value": white.p_value,
            "passed": white.passed,
            "fraction_outside": white.fraction_outside,
            "bound": white.bound,
        },
        "input_residual_correlation": {
            "p_value": cross.p_value,
            "passed": cross.passed,
            "fraction_outside": cross.fraction_outside,
            "bound": cross.bound,
        },
        "steady_state_error_percent": [e.error_percent for e in steps],
        "settling_time": settle,
        "nonlinearity": None if nonlinearity is None else nonlinearity.to_json(),
        "lead": lead.to_json(),
        "misfit": None if misfit is None else misfit.to_json(),
    }


def _what_the_errors_hold(warnings: list[str], extra: dict[str, Any]) -> list[str]:
    """The residual warnings with "standard errors may be optimistic" said as it is for the fit."""
    if extra.get("residual_colour") == "model":
        # coloured only after command changes: the misfit is the same in every realisation of
        # the noise, so the standard errors count the noise alone (its level where the output
        # has settled); the misfit is a bias they do not hold
        warnings = [
            w.replace(
                "standard errors may be optimistic",
                "the standard errors count the noise (white where the output has settled), not "
                "the misfit: the intervals hold within this structure",
            )
            for w in warnings
        ]
    if extra.get("covariance") in ("hac", "noise-model"):
        # the printed standard errors already allow for the coloured residuals
        warnings = [
            w.replace(
                "standard errors may be optimistic",
                f"the standard errors allow for it (covariance {extra['covariance']})",
            )
            for w in warnings
        ]
    return warnings
