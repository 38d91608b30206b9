"""The warnings an identification gives when its residual tests fail, each naming a cause.

The residual tests (:mod:`fuelid.identify._diagnostics`) say that something is missing from the
model; these warnings say what the data point to: the gain changing with the command
(:mod:`fuelid.identify._nonlinearity`), white noise and a missed transient, coloured noise, a
closed loop, or a lag or dead time the fit did not try.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from fuelid.identify import _diagnostics as diagnostics
from fuelid.identify._nonlinearity import NonlinearityCheck
from fuelid.identify._result import IdentifyOptions
from fuelid.io.timeseries import IOData

FloatArray = NDArray[np.float64]


def unmodelled_dynamics_warning(
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
    (:func:`~fuelid.identify._diagnostics.settled_whiteness`; None: not judged): white noise is
    then not named as a cause.

    Examples
    --------
    >>> unmodelled_dynamics_warning(1e-9, IdentifyOptions(order=1, delay=0.2), 0.2).split(": ")[1]
    'unmodelled dynamics; a second lag (order 2) or an estimated dead time may fit better'
    >>> "nonlinearity" in unmodelled_dynamics_warning(1e-9, IdentifyOptions(order=2), None)
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


def residual_warnings(
    options: IdentifyOptions,
    delay: float | None,
    tests: tuple[diagnostics.CorrelationTest, diagnostics.CorrelationTest],
    residuals: FloatArray,
    nonlinearity: NonlinearityCheck | None,
    fit_data: IOData,
    lag_and_settle: tuple[int, float],
    K_unit: str,
    kept_order: int = 2,
    output_leads: bool = False,
    settled_test: diagnostics.CorrelationTest | None = None,
) -> list[str]:
    """The nonlinearity and residual-test warnings, each saying what the data show.

    When the gain changes significantly with the command (:mod:`fuelid.identify._nonlinearity`)
    that is said first, and the residual tests are repeated on the band model (a gain per
    command band, the same dynamics): if its residuals pass, the residual warnings name the
    nonlinearity as the cause instead of noise colour or a missing lag. If they still fail,
    the whiteness warning says whether the noise itself is coloured: residuals white where the
    output has settled (:func:`~fuelid.identify._diagnostics.settled_whiteness`) mean white noise
    and a transient the model misses; coloured there, coloured noise or a drift.

    ``output_leads`` is whether the output moves before its input
    (:func:`~fuelid.identify._causality.lead_check`): a reversed clock or swapped columns. The
    residuals then correlate with the input for that reason, not feedback or a missing lag, and
    neither the closed-loop nor the unmodelled-dynamics warning (whose remedies, a noise model
    or another structure, would not help) is given. ``settled_test``, when given, is the
    settled whiteness already judged elsewhere (a long record fitted on its copy: on the whole
    record, which the copy's covariance followed), used instead of judging it on ``fit_data``.
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
        settled = settled_test or diagnostics.settled_whiteness(
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
            out.append(not_white_warning(white, band_white, settled, significant))
    # a zero-phase filter smears each output step backwards in time, which looks like feedback
    # to the test below: it is only meaningful on unfiltered (oe) data
    if output_leads:
        pass  # the residuals follow the input the wrong way round: said first, by the caller
    elif options.method == "oe" and diagnostics.feedback_suspected(cross):
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
                unmodelled_dynamics_warning(
                    cross.p_value, options, delay, gain_varies, noise_white, kept_order
                )
            )
    return out


def not_white_warning(
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
