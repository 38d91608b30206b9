"""From a loaded log to an identified model with diagnostics: what ``fuelid identify`` runs.

The CLI only parses options and prints; everything computed lives here, so scripts get the same
numbers through :func:`identify`.

A log with gaps (an :class:`~fuelid.io.timeseries.IOData` with segments) is identified jointly,
as toolboxes merge experiments: one model for all segments, each with its own initial state
(:mod:`fuelid.identify.segments`). Segments shorter than
:data:`~fuelid.identify.segments.MIN_SEGMENT_SAMPLES` are left out with a warning; ``y_hat``
is the concatenation of the per-segment simulations over the kept samples, ``fit_percent``
their NRMSE over all of them, the residual tests run within segments, and the held-out part of
``validate_split`` is the last fraction of the kept samples, wherever the gaps fall.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Literal, get_args

import numpy as np
from numpy.typing import NDArray

from fuelid.blas import single_threaded_blas
from fuelid.errors import FuelidError
from fuelid.identify import diagnostics
from fuelid.identify.nonlinearity import NonlinearityCheck, gain_bands
from fuelid.identify.oe import OutputError
from fuelid.identify.pem import PredictionError
from fuelid.identify.preprocess import decimate
from fuelid.identify.segments import MIN_SEGMENT_SAMPLES, drop_short_segments
from fuelid.identify.step_ls import StepResponseLS
from fuelid.io.timeseries import IOData
from fuelid.model import MODEL_KEYS, Z95, ProcessModel, gain_not_identified, nrmse_fit

FloatArray = NDArray[np.float64]
Method = Literal["oe", "step-ls", "pem", "auto"]
METHODS: tuple[Method, ...] = get_args(Method)
"""The identification methods, the one registry of their names: ``("oe", "step-ls")``."""
POSITIVE_PARAMETERS = frozenset({"T", "T2", "delay", "T_f"})
"""Model parameters that cannot be negative: their 95 % intervals respect the bound 0."""
CiMethod = Literal["normal", "log", "clipped"]


@dataclass(frozen=True)
class IdentifyOptions:
    """Settings of one identification (see ``fuelid identify --help`` for their meaning).

    The defaults assume nothing about the plant: the number of lags chosen by the rule of
    :mod:`fuelid.identify.order` (``order="auto"``: BIC and the second lag's own evidence),
    the dead time estimated, no flowmeter prior. A meter lag that is not given as
    ``flowmeter_T`` can only be estimated as a second process lag (T, T2 and T_f enter the
    model symmetrically), which ``order="auto"`` picks when the data show it.
    """

    method: Method = "oe"
    """One of :data:`METHODS`; anything else is refused."""
    order: Literal[1, 2, "auto"] = "auto"
    """Process lags for ``oe`` and ``pem``: 1, 2, or "auto" (both fitted, one kept by the rule
    of :mod:`fuelid.identify.order`). ``step-ls``
    has one fixed structure (one lag and the flowmeter prior): for it "auto" means that
    structure, and an order is not applied."""
    delay: float | Literal["auto"] | None = None
    """Fixed dead time [s], "auto" to estimate it, None: the flowmeter delay if given, else auto."""
    flowmeter_T: float | None = None
    """Flowmeter lag T_f [s], a fixed prior; None: no meter lag in the model."""
    flowmeter_delay: float | None = None
    """Flowmeter dead time [s]: the fixed total dead time when ``delay`` is None."""
    N: int | None = None
    settling_time: float | None = None
    """Prior model's 98 % settling time [s] (chooses N for step-ls)."""
    control_period: float = 1.0
    validate_split: float | None = None
    u_before: float | None = None
    covariance: Literal["auto", "white", "hac"] = "auto"
    """oe's parameter covariance: "white" σ²(JᵀJ)⁻¹, "hac" the sandwich with the residuals'
    spectrum, "auto" the sandwich whenever the residuals fail the whiteness test."""
    validation_initial: Literal["estimate", "rest"] = "estimate"
    """How a separate validation record starts: "estimate" (offset and initial state fitted to
    it, as a record that does not start at rest needs) or "rest" (at rest at its first input)."""

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise FuelidError(
                f"unknown identification method {self.method!r}: use one of {', '.join(METHODS)}"
            )
        if self.covariance not in ("auto", "white", "hac"):
            raise FuelidError(f"covariance {self.covariance!r}: use auto, white or hac")
        if self.covariance != "auto" and self.method in ("step-ls", "pem"):
            raise FuelidError(
                f"the covariance choice is oe's: {self.method} has its own ("
                + ("white, from the regression" if self.method == "step-ls" else "noise-model")
                + ")"
            )

        if self.validation_initial not in ("estimate", "rest"):
            raise FuelidError(
                f"validation initial condition {self.validation_initial!r}: use estimate or rest"
            )

    def resolved_delay(self) -> float | None:
        """The fixed dead time [s], or None when it is to be estimated."""
        if self.delay == "auto":
            return None
        if self.delay is not None:
            return float(self.delay)
        return self.flowmeter_delay


def interval95(
    value: float, se: float | None, *, positive: bool = False
) -> tuple[list[float], CiMethod] | None:
    """95 % confidence interval [low, high] of one parameter, and the method that made it.

    - ``"normal"``: value ± 1.96·se, for a parameter of either sign (K);
    - ``"log"``: exp(ln value ± 1.96·se/value) for a positive parameter (T, T2, the delay): the
      normal interval of ln value, whose standard error is se/value by the delta method. It lies
      above 0, contains the estimate, and reaches further above it than below;
    - ``"clipped"``: [max(0, value − 1.96·se), value + 1.96·se] for a positive parameter whose
      estimate is 0 (a delay at its bound, where ln is undefined) or whose log interval is
      unbounded (se far larger than the estimate).

    None when there is no finite standard error (a fixed parameter).

    Examples
    --------
    >>> def show(ci):
    ...     return [round(v, 4) for v in ci[0]], ci[1]
    >>> show(interval95(13.1, 0.1))
    ([12.904, 13.296], 'normal')
    >>> show(interval95(0.5, 0.5, positive=True))  # 0.5·e^(∓1.96)
    ([0.0704, 3.5495], 'log')
    >>> show(interval95(0.0, 0.7, positive=True))
    ([0.0, 1.372], 'clipped')
    """
    if se is None or not math.isfinite(se):
        return None
    if not positive:
        return [value - Z95 * se, value + Z95 * se], "normal"
    if value > 0.0:
        with np.errstate(over="ignore"):
            spread = float(np.exp(Z95 * se / value))
        if math.isfinite(value * spread):
            return [value / spread, value * spread], "log"
    return [max(0.0, value - Z95 * se), value + Z95 * se], "clipped"


@dataclass
class IdentificationResult:
    """Everything ``identify`` found, ready for JSON (:meth:`to_json`) and plots."""

    method: Method
    model: ProcessModel
    fixed: tuple[str, ...]
    stderr: dict[str, float | None]
    cov_names: tuple[str, ...]
    cov: FloatArray
    fit_percent: float
    validation_fit_percent: float | None
    """Free-run fit on the held-out part or the validation record; None without one, or when
    it has no excitation (the reason is then among the warnings)."""
    n_samples: int
    sample_time: float
    warnings: list[str]
    time: FloatArray
    y: FloatArray
    y_hat: FloatArray
    """The model output: the free-run simulation over the whole record (fit and held-out)."""
    split_time: float | None
    diagnostics: dict[str, Any] = field(default_factory=dict)
    n_segments: int = 1
    """Contiguous segments of the record fitted (1 for a log without gaps)."""
    validation_initial: str | None = None
    """How the validation was simulated: "continued" (the held-out end of the record, simulated on
    from the fit), "estimate" or "rest" (a separate record); None without validation."""
    extra: dict[str, Any] = field(default_factory=dict)
    prediction_errors: FloatArray | None = None
    """pem's one-step prediction errors on the fitted samples (what its residual tests use);
    None for the free-run methods, whose residuals are y − y_hat."""

    def _intervals(self) -> dict[str, tuple[list[float], CiMethod] | None]:
        values = self.model.as_dict()
        return {
            key: interval95(values[key], self.stderr.get(key), positive=key in POSITIVE_PARAMETERS)
            for key in MODEL_KEYS
        }

    def ci95(self) -> dict[str, list[float] | None]:
        """95 % confidence intervals of the model parameters (:func:`interval95`).

        Symmetric for K; log-transformed for the positive T, T2 and delay (never below 0).
        """
        return {key: None if ci is None else ci[0] for key, ci in self._intervals().items()}

    def ci95_method(self) -> dict[str, CiMethod | None]:
        """How each interval of :meth:`ci95` was made: "normal", "log" or "clipped"."""
        return {key: None if ci is None else ci[1] for key, ci in self._intervals().items()}

    def to_json(self) -> dict[str, Any]:
        """The documented JSON object of ``fuelid identify --json`` (without provenance)."""
        return {
            "method": self.method,
            "model": {key: self.model.as_dict()[key] for key in MODEL_KEYS},
            "fixed": list(self.fixed),
            "stderr": {key: self.stderr.get(key) for key in MODEL_KEYS},
            "ci95": self.ci95(),
            "ci95_method": self.ci95_method(),
            "cov": {"names": list(self.cov_names), "matrix": self.cov.tolist()},
            "fit_percent": self.fit_percent,
            "validation_fit_percent": self.validation_fit_percent,
            "validation_initial": self.validation_initial,
            "n_samples": self.n_samples,
            "sample_time": self.sample_time,
            "segments": self.n_segments,
            "diagnostics": self.diagnostics,
            "warnings": self.warnings,
            **self.extra,
        }


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


def _unmodelled_dynamics(
    p_value: float,
    options: IdentifyOptions,
    delay: float | None,
    gain_varies: bool | None = None,
    noise_white: bool | None = None,
    kept_order: int = 2,
) -> str:
    """The input-correlation warning, suggesting only structures this fit did not already try.

    ``kept_order`` is the fitted model's number of lags (with ``order="auto"`` a second lag
    may have been tried and not kept).
    ``gain_varies`` is what the nonlinearity check found (None: the log has too few command
    levels to check): it decides whether a nonlinearity is named as a possible cause.
    ``noise_white`` is whether the residuals are white where the output has settled
    (:func:`~fuelid.identify.diagnostics.settled_whiteness`; None: not judged): white noise is
    then not named as a cause.

    Examples
    --------
    >>> _unmodelled_dynamics(1e-9, IdentifyOptions(order=1, delay=0.2), 0.2).split(": ")[1]
    'unmodelled dynamics; a second lag (order 2) or an estimated dead time may fit better'
    >>> "nonlinearity" in _unmodelled_dynamics(1e-9, IdentifyOptions(order=2), None)
    True
    """
    untried = []
    if options.order == 1:
        untried.append("a second lag (order 2)")
    if delay is not None:
        untried.append("an estimated dead time")
    head = f"residuals correlate with past inputs (p = {p_value:.2g})"
    if options.method == "step-ls":
        return (
            f"{head}: unmodelled dynamics or a nonlinearity; the article's method has a fixed "
            "structure, the output-error fit (method oe) can try a second lag and a free delay"
        )
    if untried:
        return f"{head}: unmodelled dynamics; {' or '.join(untried)} may fit better"
    tried = (
        "the fit already has a second lag and an estimated dead time"
        if kept_order == 2
        else "a second lag was tried and not kept (see the order choice), and the dead time is "
        "estimated"
    )
    # the noise's colour is a cause only when the settled residuals do not show it white
    noise = "" if noise_white else " or coloured noise"
    white = " (the noise is white where the output has settled)" if noise_white else ""
    if gain_varies is False:
        return (
            f"{head}: {tried}, and the gain does not change with the command, so the cause is "
            f"more likely dynamics outside the model family{noise}{white}"
        )
    if gain_varies:
        return (
            f"{head}: {tried}, and a gain per command band does not remove it either: dynamics "
            f"that change with the operating point{noise}{white}"
        )
    return (
        f"{head}: {tried}, so the cause is more likely a nonlinearity (the gain changing with "
        f"the operating point) or dynamics outside the model family{noise}{white}"
    )


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


def _residual_warnings(
    options: IdentifyOptions,
    delay: float | None,
    tests: tuple[diagnostics.CorrelationTest, diagnostics.CorrelationTest],
    residuals: FloatArray,
    nonlinearity: NonlinearityCheck | None,
    fit_data: IOData,
    lag_and_settle: tuple[int, float],
    K_unit: str,
    kept_order: int = 2,
) -> list[str]:
    """The nonlinearity and residual-test warnings, each saying what the data show.

    When the gain changes significantly with the command (:mod:`fuelid.identify.nonlinearity`)
    that is said first, and the residual tests are repeated on the band model (a gain per
    command band, the same dynamics): if its residuals pass, the residual warnings name the
    nonlinearity as the cause instead of noise colour or a missing lag. If they still fail,
    the whiteness warning says whether the noise itself is coloured: residuals white where the
    output has settled (:func:`~fuelid.identify.diagnostics.settled_whiteness`) mean white noise
    and a transient the model misses; coloured there, coloured noise or a drift.
    """
    white, cross = tests
    max_lag, settle = lag_and_settle
    out: list[str] = []
    starts = fit_data.segment_starts
    band_white: diagnostics.CorrelationTest | None = None
    band_cross: diagnostics.CorrelationTest | None = None
    if nonlinearity is not None and nonlinearity.significant:
        out.append(nonlinearity.warning(K_unit, fit_data.u_unit))
        band_white = diagnostics.residual_whiteness(nonlinearity.residuals, segment_starts=starts)
        band_cross = diagnostics.input_residual_correlation(
            fit_data.u, nonlinearity.residuals, max_lag, starts
        )
    noise_white: bool | None = None
    settled: diagnostics.CorrelationTest | None = None
    significant = band_white is not None and nonlinearity is not None
    if not (white.passed and cross.passed):
        # is the noise itself white? judged where the output has settled, on the residuals of
        # the best model at hand (the band model's when the gain changes with the command)
        e = nonlinearity.residuals if significant and nonlinearity is not None else residuals
        settled = diagnostics.settled_whiteness(
            e, fit_data.u, fit_data.sample_time, settle, fit_data.segment_starts
        )
        noise_white = None if settled is None else settled.passed
    if not white.passed:
        if band_white is not None and band_white.passed:
            out.append(
                f"residuals are not white (p = {white.p_value:.2g}) because the gain changes "
                "with the command: with a gain per command band they are "
                f"(p = {band_white.p_value:.2g}); standard errors may be optimistic"
            )
        else:
            out.append(_not_white(white, band_white, settled, significant))
    # a zero-phase filter smears each output step backwards in time, which looks like feedback
    # to the test below: it is only meaningful on unfiltered (oe) data
    if options.method == "oe" and diagnostics.feedback_suspected(cross):
        out.append(
            "the input reacts to the output residual: the data look closed-loop; an output-error "
            "fit is then biased when the noise is coloured: use the prediction-error fit with "
            "a noise model (method pem), which is consistent in closed loop, or log open-loop "
            "steps"
        )
    elif not cross.passed:
        if band_cross is not None and band_cross.passed:
            out.append(
                f"residuals correlate with past inputs (p = {cross.p_value:.2g}) because the "
                "gain changes with the command: with a gain per command band they do not "
                f"(p = {band_cross.p_value:.2g}); another lag or dead time would not remove it"
            )
        else:
            gain_varies = None if nonlinearity is None else nonlinearity.significant
            out.append(
                _unmodelled_dynamics(
                    cross.p_value, options, delay, gain_varies, noise_white, kept_order
                )
            )
    return out


def _not_white(
    white: diagnostics.CorrelationTest,
    band_white: diagnostics.CorrelationTest | None,
    settled: diagnostics.CorrelationTest | None,
    significant: bool,
) -> str:
    """The whiteness warning when the gain's change with the command does not explain it.

    ``settled`` is the whiteness test where the output has settled (None: too little settled
    output to judge); ``significant`` whether the gain changes with the command.
    """
    head = f"residuals are not white (p = {white.p_value:.2g})"
    if band_white is not None:
        head += f", not even with a gain per command band (p = {band_white.p_value:.2g})"
    tail = "standard errors may be optimistic"
    if settled is None:
        return f"{head}: coloured noise or unmodelled dynamics; {tail}"
    if settled.passed:
        also = (
            ", and with the gain the dynamics may change with the command too"
            if significant
            else ""
        )
        return (
            f"{head}, but only after command changes: where the output has settled they are "
            f"(p = {settled.p_value:.2g}), so the noise is white and the model misses part of "
            f"the transient response{also}; {tail}"
        )
    return (
        f"{head}, also where the output has settled (p = {settled.p_value:.2g}): coloured "
        f"noise or a drift; {tail}"
    )


def identify(
    data: IOData, options: IdentifyOptions, validation: IOData | None = None
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
    """
    with single_threaded_blas():
        if options.method == "auto":
            return _identify_auto(data, options, validation)
        return _identify(data, options, validation)


AUTO_VALIDATION_MARGIN = 2.0
"""pem's validation fit may be this many points below oe's before ``auto`` keeps oe [%]."""
NEAR_INTEGRATING_POLE = 0.999
"""A noise pole above this (per sample) makes pem fit the differenced data: ``auto`` keeps oe."""


LAGS_NOT_SEPARATED = 0.999
"""|corr(T, T2)| above which the two lags' separate intervals are withheld."""


def _lags_not_separated(names: tuple[str, ...], cov: FloatArray) -> float | None:
    """corr(T, T2) when it is beyond ±:data:`LAGS_NOT_SEPARATED`, else None."""
    if "T" not in names or "T2" not in names:
        return None
    i, j = names.index("T"), names.index("T2")
    c = np.asarray(cov, dtype=float)
    denominator = math.sqrt(abs(c[i, i] * c[j, j]))
    if not (math.isfinite(denominator) and denominator > 0.0):
        return None
    corr = float(c[i, j] / denominator)
    return corr if abs(corr) > LAGS_NOT_SEPARATED else None


def _identify_auto(
    data: IOData, options: IdentifyOptions, validation: IOData | None
) -> IdentificationResult:
    """``method="auto"``: the output-error fit, or pem when the noise model is significant.

    pem is chosen when oe's residuals fail the whiteness test and pem's information criterion
    picks a noise model other than white (its own significance test), unless a noise pole is so
    close to 1 that pem would fit the differenced data and lose the low-frequency fit.
    """
    oe = _identify(data, replace(options, method="oe"), validation)
    if oe.diagnostics["residual_whiteness"]["passed"]:
        oe.extra["method_choice"] = "auto: oe (its residuals are white)"
        return oe
    pem = _identify(data, replace(options, method="pem"), validation)
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


def _identify(
    data: IOData, options: IdentifyOptions, validation: IOData | None
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
    estimator: StepResponseLS | OutputError | PredictionError
    if options.method == "step-ls":
        work = _decimated(data, options.control_period)
        if delay is None:
            warnings.append(
                "step-ls needs the dead time as prior knowledge: none given (--flowmeter-delay or "
                "--delay SECONDS), assumed 0"
            )
            delay = 0.0
        fit_data, n_fit = _split(work, options.validate_split)
        ls = StepResponseLS(
            N=options.N, T_f=T_f, delay=delay, settling_time=options.settling_time
        ).fit(fit_data)
        estimator = ls
        cov_names: tuple[str, ...] = ("K", "T")
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
    elif options.method == "pem":
        work = data
        fit_data, n_fit = _split(work, options.validate_split)
        pem = PredictionError(
            order=options.order, delay=delay, T_f=T_f, u_before=options.u_before
        ).fit(fit_data)
        estimator = pem
        cov_names, cov = pem.param_names_, pem.cov_
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
    else:
        work = data
        if options.order not in (1, 2, "auto"):
            raise FuelidError(f"--order must be 1, 2 or auto, got {options.order!r}")
        fit_data, n_fit = _split(work, options.validate_split)
        oe = OutputError(
            order=options.order,
            delay=delay,
            T_f=T_f,
            u_before=options.u_before,
            covariance=options.covariance,
        ).fit(fit_data)
        estimator = oe
        cov_names, cov = oe.param_names_, oe.cov_
        warnings.extend(oe.warnings_)
        extra = {
            "covariance": oe.covariance_,
            "residual_colour": oe.residual_colour_,
            "residual_noise_model": oe.residual_ar_.to_json(),
            "aic": {str(k): v for k, v in oe.aic_.items()},
            "bic": {str(k): v for k, v in oe.bic_.items()},
            "structure": oe.order_choice_.to_json(),
            "noise_std": oe.sigma_,
        }
        if "T2" in oe.param_names_ and "delay" in oe.param_names_:
            names = oe.param_names_
            extra["correlation_T2_delay"] = float(
                oe.correlation_[names.index("T2"), names.index("delay")]
            )
    model = estimator.model_
    stderr = dict(estimator.stderr_)
    if isinstance(estimator, OutputError | PredictionError):
        # the intervals hold within the structure the rule kept: say so when they trade or
        # when another structure fits nearly as well
        note = estimator.order_choice_.conditional_note()
        if note:
            warnings.append(note)
    lags_merged = _lags_not_separated(cov_names, cov)
    if lags_merged is not None:
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
    y_model = estimator.simulate(work, initial="fitted")
    time = work.t
    y = work.y
    fit_percent = nrmse_fit(y[:n_fit], y_model[:n_fit])
    validation_fit: float | None = None
    validation_initial: str | None = None
    if n_fit < work.n_samples:
        validation_initial = "continued"
        reason = _no_excitation(work.u[n_fit:], "the held-out part of the record")
        if reason:
            warnings.append(reason)
        else:
            validation_fit = nrmse_fit(y[n_fit:], y_model[n_fit:])
    if validation is not None:
        if options.method == "step-ls":
            validation = _decimated(validation, options.control_period)
        validation_initial = options.validation_initial
        reason = _no_excitation(validation.u, "the validation record")
        if reason:
            warnings.append(reason)
        else:
            validation_fit = estimator.score(validation, initial=options.validation_initial)
    # pem's tests are on its prediction errors: white when its noise model is right
    residuals = (
        np.asarray(estimator.residuals_[:n_fit], dtype=float)
        if isinstance(estimator, PredictionError)
        else y[:n_fit] - y_model[:n_fit]
    )
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
    diag: dict[str, Any] = {
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
    }
    warnings.extend(
        _residual_warnings(
            options,
            delay,
            (white, cross),
            residuals,
            nonlinearity,
            fit_data,
            (max_lag, settle),
            gain_unit(work),
            kept_order=2 if model.T2 > 0.0 else 1,
        )
    )
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
    no_gain = gain_not_identified(model.K, stderr.get("K"))
    if no_gain:
        warnings.append(f"{no_gain} in this log; do not tune from it")
    advice = diagnostics.sample_time_advice(settle, work.sample_time, data.sample_time)
    if advice:
        warnings.append(advice)
    return IdentificationResult(
        n_segments=work.n_segments,
        method=options.method,
        model=model,
        fixed=estimator.fixed_,
        stderr=stderr,
        cov_names=cov_names,
        cov=cov,
        fit_percent=fit_percent,
        validation_fit_percent=validation_fit,
        validation_initial=validation_initial,
        n_samples=fit_data.n_samples,
        sample_time=work.sample_time,
        warnings=list(dict.fromkeys(warnings)),
        time=time,
        y=y,
        y_hat=y_model,
        split_time=float(time[n_fit]) if n_fit < work.n_samples else None,
        diagnostics=diag,
        extra=extra,
        prediction_errors=residuals if isinstance(estimator, PredictionError) else None,
    )
