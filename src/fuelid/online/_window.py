"""One identification window of the online service: samples in, a gated model and its health out.

Every ``identify_every_s`` of data time the service hands the last ``window_s`` of samples to
:meth:`WindowAnalyser.analyse`, which

1. runs the pre-fit gates (:func:`~fuelid.online.gates.prefit_samples`: lost or flagged samples,
   the output at a limit, excitation judged by the mode the loop was in);
2. fits the process model on the samples whose quality is ok, warm-started from the last
   accepted window (one local Levenberg–Marquardt search per order with the lags' analytic
   sensitivities, :mod:`fuelid.identify._search`, stopped at statistical tolerances:
   :data:`~fuelid.numerics_mode.WINDOW_NUMERICS`):

   - judged in MAN (open loop, or no mode recorded): the output-error fit, whose estimate is
     consistent whatever the colour of the noise when the input does not depend on it (Ljung
     1999, §8.4); its covariance is the HAC sandwich when the residuals are coloured
     (``covariance="auto"``), so the standard errors stay honest;
   - judged in AUTO (closed loop: the command depends on past noise through the PI): the
     prediction-error fit with its noise model (the direct method, Ljung §13.4), warm-started
     with the last window's noise model; when its noise pole is nearly integrating, or it
     fails, the output-error fit is kept and the reason is recorded. First a cheap screen
     (:mod:`fuelid.online._pem_screen`: pem's noise model fitted to the output errors alone)
     skips pem when its pole would be nearly integrating anyway (a margin above 0.999), which
     is most windows with a drifting disturbance; it agreed with the full decision on 623 of
     624 held-out windows, K within its standard error on the other (online.md);

   and the article's ``step-ls`` alongside (its model, errors and fit; not its diagnostics),
   reported but never gated on;
3. runs the post-fit gates (:func:`~fuelid.online.gates.postfit_gates`: relative standard
   errors, the fit, the residual autocorrelation by size, the plant-ratio event);
4. computes the loop's health over the whole window (:func:`~fuelid.online.health.loop_health`).

The fit percentage gated is the model's free-run simulation over the window (not a one-step
prediction): a model that only predicts one step ahead well does not pass it.

Units: time [s UTC], command u [V], flow y and setpoint [L/min], K [(L/min)/V], T and θ [s],
fuel temperature [°C] in this module's results.

References
----------
L. Ljung, *System Identification: Theory for the User* (2nd ed., Prentice Hall, 1999), §8.4
(open-loop consistency of output-error models), §13.4 (closed-loop identification, the direct
prediction-error method).
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from fuelid.errors import FuelidError, NotExcitingError
from fuelid.identify import (
    POSITIVE_PARAMETERS,
    IdentifyOptions,
    OutputError,
    PredictionError,
    interval95,
)
from fuelid.io.jsonsafe import json_ready
from fuelid.io.timeseries import IOData
from fuelid.model import MODEL_KEYS, ProcessModel
from fuelid.numerics_mode import REFERENCE_NUMERICS, WINDOW_NUMERICS, Numerics
from fuelid.online._pem_screen import NEAR_INTEGRATING_POLE, closed_loop_choice
from fuelid.online._settings import Online
from fuelid.online._tracking import PlantGain
from fuelid.online.excitation._cost import measured_cost
from fuelid.online.gates import (
    WindowVerdict,
    excitation_refusal,
    postfit_gates,
    prefit_samples,
)
from fuelid.online.health import U_LIMITS_V, LoopHealth, loop_health
from fuelid.store import Quality, SampleArrays, iodata_from_samples
from fuelid.units import DEFAULT_FUEL_TEMPERATURE_C

MIN_GOOD_SAMPLES = 100
"""Fewer good samples than this in a window: nothing is fitted [-]."""
DEFAULT_SIGNAL_TAIL_S = 10.0
"""How long the loop answers after a test signal when no model gives its settling time [s]."""
MIN_SEGMENT_SAMPLES = 50
"""A run of good samples between gaps shorter than this is left out of the fit [-]."""


@dataclass(frozen=True)
class WindowPriors:
    """What the service knows before fitting: the plant file's meter, the controller's limits.

    Parameters
    ----------
    flowmeter_T : float
        Flowmeter lag held fixed in the fit [s] (0: none, the plant file gives it).
    delay : float or None
        Fixed dead time [s]; None estimates it.
    settling_time : float or None
        The plant's 98 % settling time [s], which sizes step-ls's response length; None: the
        output-error model's.
    u_limits : (float, float)
        The command's limits [V].
    y_span : float
        The flow measurement span [L/min] (Hägglund's acceptable oscillation amplitude).
    control_period : float
        The PLC's PI period [s].
    source : str
        Where the priors came from ("plant file PATH", or "none: no plant file").
    """

    flowmeter_T: float = 0.0
    delay: float | None = None
    settling_time: float | None = None
    u_limits: tuple[float, float] = U_LIMITS_V
    y_span: float = 120.0
    control_period: float = 1.0
    source: str = "none: no plant file"


@dataclass
class WindowResult:
    """What one window gave: the verdict, the model (when fitted), step-ls's, the loop's health."""

    t_from: float
    """Start of the window [s UTC]."""
    t_to: float
    """End of the window [s UTC] (exclusive)."""
    verdict: WindowVerdict
    """Every gate's verdict; ``accepted`` and ``reason`` come from it."""
    samples: int
    """Samples read [-]."""
    good_samples: int
    """Samples of quality ok with finite u and y [-]."""
    T_fuel_C: float | None
    """Mean fuel temperature of the good samples [°C]; None when not recorded."""
    u_mean: float | None
    """Mean command of the good samples [V] (the operating point)."""
    y_mean: float | None
    """Mean flow of the good samples [L/min]."""
    model: ProcessModel | None = None
    """The fitted model (None when a pre-fit gate rejected the window or the fit failed)."""
    stderr: dict[str, float | None] = field(default_factory=dict)
    """Standard errors by MODEL_KEYS name [(L/min)/V, s]."""
    method: str = ""
    """"oe" or "pem"."""
    method_reason: str = ""
    """Why that estimator (the mode it was judged in, a pem fallback)."""
    fit_percent: float | None = None
    """Free-run fit of the model over the window [%]."""
    covariance: str = ""
    """How the covariance was made ("white", "hac", "noise-model")."""
    structure: dict[str, Any] | None = None
    """The order choice (``identify --json``'s ``structure``): the orders compared, the one kept
    and why, whether the intervals are conditional on it; None when nothing was fitted."""
    step_ls: dict[str, Any] | None = None
    """The article's step-ls model of the same samples: model, stderr, fit or the reason none."""
    plant_K: float | None = None
    """The plant model's K at the window's mean command and fuel temperature [(L/min)/V]."""
    health: LoopHealth | None = None
    """The loop's health over the window."""
    excitation: dict[str, Any] | None = None
    """What a test signal in the window cost, measured on its samples
    (:func:`~fuelid.online.excitation._cost.measured_cost`); None when no signal ran."""
    seconds: float = 0.0
    """Wall time of the analysis [s]."""
    warnings: list[str] = field(default_factory=list)
    """What the fit noticed."""
    estimator: OutputError | PredictionError | None = field(default=None, repr=False)
    """The fitted estimator (the next window's warm start); not stored."""

    @property
    def accepted(self) -> bool:
        """True when every gate passed."""
        return self.verdict.accepted

    @property
    def reason(self) -> str:
        """The verdict in one line."""
        return self.verdict.reason

    def ci95(self) -> dict[str, list[float] | None]:
        """95 % intervals as ``identify`` makes them (symmetric K, log-transformed times)."""
        if self.model is None:
            return {}
        values = self.model.to_json()
        out: dict[str, list[float] | None] = {}
        for key in MODEL_KEYS:
            ci = interval95(values[key], self.stderr.get(key), positive=key in POSITIVE_PARAMETERS)
            out[key] = None if ci is None else ci[0]
        return out

    def model_json(self) -> dict[str, Any] | None:
        """``model``, ``stderr``, ``ci95`` (as ``identify --json``), method, fit; None unfitted."""
        if self.model is None:
            return None
        values = self.model.to_json()
        out: dict[str, Any] = json_ready(
            {
                "model": {key: values[key] for key in MODEL_KEYS},
                "stderr": {key: self.stderr.get(key) for key in MODEL_KEYS},
                "ci95": self.ci95(),
                "method": self.method,
                "fit_percent": self.fit_percent,
            }
        )
        return out

    def to_json(self) -> dict[str, Any]:
        """JSON-ready record of the window (what the model history stores as its detail)."""
        out: dict[str, Any] = json_ready(
            {
                "start": self.t_from,
                "end": self.t_to,
                "accepted": self.accepted,
                "reason": self.reason,
                "mode": self.verdict.mode,
                "samples": self.samples,
                "good_samples": self.good_samples,
                "fuel_temperature": self.T_fuel_C,
                "operating_point": {"u_V": self.u_mean, "y_Lpm": self.y_mean},
                "method": self.method,
                "method_reason": self.method_reason,
                "covariance": self.covariance,
                "structure": self.structure,
                "fit_percent": self.fit_percent,
                "plant_K": self.plant_K,
                "gates": self.verdict.to_json(),
                "step_ls": self.step_ls,
                "health": None if self.health is None else self.health.to_json(),
                "excitation": self.excitation,
                "seconds": self.seconds,
                "warnings": self.warnings,
            }
        )
        fitted = self.model_json()
        if fitted is not None:
            out.update(fitted)
        return out


def _mean(values: np.ndarray[Any, Any]) -> float | None:
    finite = values[np.isfinite(values)]
    return float(np.mean(finite)) if finite.size else None


class WindowAnalyser:
    """Gates, fits and assesses windows, warm-starting each fit from the last accepted one.

    Parameters
    ----------
    settings : Online
        The site's ``[online]`` table (gate thresholds).
    priors : WindowPriors
        The plant file's meter, the limits, the control period.
    sample_time : float
        The sampling period [s] (``[sampling] period_s``).
    k_plant : callable, optional
        The plant model's K(u [V], T [°C]) [(L/min)/V] (:func:`~fuelid.online._tracking.
        plant_gain_function`); None without a plant file (no plant-ratio event).
    step_ls : bool
        Also fit the article's step-ls (reported, not gated).
    ti_s : float
        The PI's integral time [s], for the oscillation detector; updated by the service.
    fast : bool
        In AUTO, skip the pem fit when the noise screen shows its result would be discarded
        (:mod:`fuelid.online._pem_screen`), with the faster numerics
        (:data:`~fuelid.numerics_mode.WINDOW_NUMERICS`); False fits pem on every AUTO window
        with the numerics before issue 26 (:data:`~fuelid.numerics_mode.REFERENCE_NUMERICS`),
        kept for the benchmark's and the tests' comparison.

    Attributes
    ----------
    last_model_ : ProcessModel or None
        The last accepted window's model (the warm start).
    numerics : Numerics
        What ``fast`` chose: the numerics every fit and gate of a window runs with.
    """

    def __init__(
        self,
        settings: Online,
        priors: WindowPriors,
        sample_time: float,
        *,
        k_plant: PlantGain | None = None,
        step_ls: bool = True,
        ti_s: float = 1.0,
        fast: bool = True,
    ) -> None:
        self.settings = settings
        self.priors = priors
        self.sample_time = float(sample_time)
        self.k_plant = k_plant
        self.step_ls = step_ls
        self.ti_s = float(ti_s)
        self.fast = fast
        self.last_model_: ProcessModel | None = None
        self._last_noise: dict[str, Any] | None = None

    # --- warm start -----------------------------------------------------------------------

    def accept(self, result: WindowResult) -> None:
        """Warm-start the next fits from an accepted window's model."""
        if result.accepted and result.model is not None:
            self.last_model_ = result.model

    def resume(self, model: ProcessModel | None) -> None:
        """Warm-start from a model kept in the history (a restarted service)."""
        self.last_model_ = model

    # --- the window -----------------------------------------------------------------------

    @property
    def numerics(self) -> Numerics:
        """The window's numerics: :data:`~fuelid.numerics_mode.WINDOW_NUMERICS` when ``fast``.

        The searches stop where what is left to gain is under 0.02 standard errors
        (:data:`~fuelid.numerics_mode.STATISTICAL_TOLERANCES`); ``fast=False`` runs today's path
        for the benchmark (:data:`~fuelid.numerics_mode.REFERENCE_NUMERICS`): the same numbers,
        slower.
        """
        return WINDOW_NUMERICS if self.fast else REFERENCE_NUMERICS

    def _signal_cost(
        self, samples: SampleArrays, good: np.ndarray[Any, Any]
    ) -> dict[str, Any] | None:
        """The test signal's cost on this window's samples (None: no signal ran)."""
        last = getattr(self, "last_model_", None)
        tail = (
            last.settling_time(numerics=self.numerics)
            if last is not None
            else DEFAULT_SIGNAL_TAIL_S
        )
        return measured_cost(
            samples.time, samples.y, samples.setpoint, samples.excitation, good, tail
        )

    def analyse(self, samples: SampleArrays, t_from: float, t_to: float) -> WindowResult:
        """Gate, fit and assess one window's samples (``t_from ≤ time < t_to``).

        Never raises on data: a window that cannot be fitted is a rejected window with the
        reason. Every fit and gate runs with :attr:`numerics`.
        """
        started = time.perf_counter()
        good = (samples.quality == Quality.OK) & np.isfinite(samples.u) & np.isfinite(samples.y)
        temperature = samples.fuel_temperature[good]
        result = WindowResult(
            t_from=t_from,
            t_to=t_to,
            verdict=WindowVerdict.of([], {}),
            samples=len(samples),
            good_samples=int(np.count_nonzero(good)),
            T_fuel_C=_mean(temperature),
            u_mean=_mean(samples.u[good]),
            y_mean=_mean(samples.y[good]),
        )
        if result.good_samples < MIN_GOOD_SAMPLES:
            result.verdict = WindowVerdict.of(
                [f"too few good samples: {result.good_samples} < {MIN_GOOD_SAMPLES}"],
                {"good_samples": result.good_samples},
            )
            result.seconds = time.perf_counter() - started
            return result
        if self.k_plant is not None and result.u_mean is not None:
            T_C = DEFAULT_FUEL_TEMPERATURE_C if result.T_fuel_C is None else result.T_fuel_C
            try:
                result.plant_K = float(self.k_plant(result.u_mean, T_C))
            except FuelidError as error:  # outside the plant's range: no ratio event
                result.warnings.append(f"plant K not computed: {error}")
        result.health = self._health(samples, good)
        result.excitation = self._signal_cost(samples, good)
        prefit = prefit_samples(
            samples, self.settings, sample_time=self.sample_time, u_limits=self.priors.u_limits
        )
        result.verdict = prefit
        if not prefit.accepted:
            result.seconds = time.perf_counter() - started
            return result
        try:
            usable = _without_short_segments(samples, good, MIN_SEGMENT_SAMPLES)
            data = iodata_from_samples(usable, self.sample_time, source="window")
            self._fit(result, data, closed_loop=prefit.mode == "AUTO")
        except NotExcitingError as error:
            result.verdict = prefit.combine(excitation_refusal(error))
        except FuelidError as error:
            result.verdict = prefit.combine(
                WindowVerdict.of([f"fit failed: {' '.join(str(error).split())}"], {})
            )
        result.seconds = time.perf_counter() - started
        return result

    def _health(self, samples: SampleArrays, good: np.ndarray[Any, Any]) -> LoopHealth | None:
        delay = self.last_model_.delay if self.last_model_ is not None else 0.0
        try:
            return loop_health(
                samples.time,
                samples.u,
                samples.y,
                samples.setpoint,
                samples.mode,
                good,
                ti_s=self.ti_s,
                delay_s=max(delay, self.sample_time),
                y_span=self.priors.y_span,
                u_limits=self.priors.u_limits,
                numerics=self.numerics,
            )
        except FuelidError:  # too few samples for any measure: the window says so elsewhere
            return None

    def _estimator_settings(self) -> dict[str, Any]:
        # every window chooses its order by the rule of fuelid.identify._order (both orders
        # searched locally from the warm start): a second lag one window's noise suggested
        # must not stick to every later window
        return {"order": "auto", "delay": self.priors.delay, "T_f": self.priors.flowmeter_T}

    def _fit(self, result: WindowResult, data: IOData, *, closed_loop: bool) -> None:
        kwargs = self._estimator_settings()
        oe = OutputError(covariance="auto", numerics=self.numerics, **kwargs).fit(
            data, init=self.last_model_
        )
        chosen: OutputError | PredictionError = oe
        residuals = data.y - oe.y_hat_
        result.method, result.covariance = "oe", oe.covariance_
        result.method_reason = (
            "MAN (open loop): output error, consistent whatever the noise colour"
            if not closed_loop
            else ""
        )
        if closed_loop:
            chosen, residuals = self._fit_closed_loop(result, data, oe, kwargs)
        result.model = chosen.model_
        result.stderr = dict(chosen.stderr_)
        result.fit_percent = float(oe.fit_percent_ if chosen is oe else chosen.fit_percent_)
        result.estimator = chosen
        # the order is chosen by oe's fit (pem, warm-started from it, keeps that order)
        result.structure = oe.order_choice_.to_json()
        result.warnings.extend(chosen.warnings_)
        note = oe.order_choice_.conditional_note()
        if note:
            result.warnings.append(note)
        postfit = postfit_gates(
            chosen.model_,
            chosen.stderr_,
            result.fit_percent,
            residuals,
            data.sample_time,
            self.settings,
            segment_starts=data.segment_starts,
            plant_K=result.plant_K,
            u=data.u if chosen is oe else None,  # output errors: prewhitened by the noise's AR
            numerics=self.numerics,
        )
        result.verdict = result.verdict.combine(postfit)
        if self.step_ls:
            result.step_ls = self._step_ls(data, oe.model_)

    def _fit_closed_loop(
        self, result: WindowResult, data: IOData, oe: OutputError, kwargs: dict[str, Any]
    ) -> tuple[OutputError | PredictionError, np.ndarray[Any, Any]]:
        choice = closed_loop_choice(
            data, oe, kwargs, self._last_noise, screen=self.fast, numerics=self.numerics
        )
        if choice.noise is not None:
            self._last_noise = choice.noise
        result.method, result.covariance = choice.method, choice.covariance
        result.method_reason = choice.reason
        return choice.estimator, choice.residuals

    def _step_ls(self, data: IOData, oe_model: ProcessModel) -> dict[str, Any]:
        from fuelid.workflow import identify_step_ls

        options = IdentifyOptions(
            method="step-ls",
            flowmeter_T=self.priors.flowmeter_T or None,
            settling_time=self.priors.settling_time,
            control_period=self.priors.control_period,
        )
        try:
            fitted, _ = identify_step_ls(data, options, oe_model=oe_model, diagnose=not self.fast)
        except FuelidError as error:
            return {"model": None, "reason": " ".join(str(error).split())}
        values = fitted.model.to_json()
        out: dict[str, Any] = json_ready(
            {
                "model": {key: values[key] for key in MODEL_KEYS},
                "stderr": {key: fitted.stderr.get(key) for key in MODEL_KEYS},
                "fit_percent": fitted.fit_percent,
            }
        )
        return out


def _without_short_segments(
    samples: SampleArrays, good: np.ndarray[Any, Any], min_length: int
) -> SampleArrays:
    """The samples with good runs shorter than ``min_length`` flagged out of the fit.

    A run between two gaps that short carries no dynamics worth an initial state of its own
    (each segment gets one), and the estimators refuse segments under 20 samples.
    """
    index = np.flatnonzero(good)
    if index.size == 0:
        return samples
    seq = samples.seq[index]
    t = samples.time[index]
    with_seq = (seq[:-1] >= 0) & (seq[1:] >= 0)
    breaks = np.where(with_seq, np.diff(seq) != 1, np.diff(t) > 1.5 * np.median(np.diff(t)))
    edges = np.r_[0, np.flatnonzero(breaks) + 1, index.size]
    quality = samples.quality.copy()
    for a, b in itertools.pairwise(edges.tolist()):
        if b - a < min_length:
            quality[index[a:b]] = Quality.BAD_VALUE
    if np.array_equal(quality, samples.quality):
        return samples
    return replace(samples, quality=quality)


def window_priors(
    plant_path: str | None,
    *,
    control_period: float,
    u_limits: tuple[float, float] = U_LIMITS_V,
    y_span: float | None = None,
) -> tuple[WindowPriors, PlantGain | None]:
    """The priors and plant-gain function of a site (its plant file, when it names one).

    Parameters
    ----------
    plant_path : str or None
        The site file's ``[site] plant``.
    control_period : float
        ``[sampling] control_period_s`` [s].
    u_limits : (float, float)
        The command's limits [V] (the plant's VFD range when a plant file is given).
    y_span : float, optional
        The flow span [L/min]; default the plant's flowmeter range, else 120.

    Returns
    -------
    (WindowPriors, k_plant or None)

    Raises
    ------
    ConfigError
        The plant file cannot be read.
    """
    if plant_path is None:
        return (
            WindowPriors(u_limits=u_limits, y_span=y_span or 120.0, control_period=control_period),
            None,
        )
    from fuelid.online._tracking import plant_gain_function
    from fuelid.plant import load_plant_config
    from fuelid.workflow import plant_knowledge

    config = load_plant_config(plant_path)
    known = plant_knowledge(config)
    priors = WindowPriors(
        flowmeter_T=known.flowmeter_T,
        delay=known.flowmeter_delay,  # as `identify --config`: the meter's dead time, fixed
        settling_time=known.settling_time,
        u_limits=known.u_limits,
        y_span=y_span if y_span is not None else known.y_span,
        control_period=control_period,
        source=f"plant file {plant_path}",
    )
    return priors, plant_gain_function(config)


def check_site_plant(plant_path: str | None, window_s: float) -> float | None:
    """Check the site's plant file and that ``[online] window_s`` covers its settling time.

    Parameters
    ----------
    plant_path : str or None
        ``[site] plant`` (already taken from the site file's folder).
    window_s : float
        ``[online] window_s`` [s].

    Returns
    -------
    float or None
        The plant's 98 % settling time [s] at mid-range command and 20 °C (what ``fuelid plant
        info`` prints); None without a plant file.

    Raises
    ------
    ConfigError
        The plant file is missing or invalid (named with the key), or the window is shorter than
        the settling time (a window must hold settled responses).
    """
    if plant_path is None:
        return None
    from pathlib import Path

    from fuelid.errors import ConfigError
    from fuelid.plant import load_plant_config
    from fuelid.workflow import plant_knowledge

    if not Path(plant_path).is_file():
        raise ConfigError(f"[site] plant: no such plant file {plant_path}")
    try:
        config = load_plant_config(plant_path)
    except FuelidError as error:
        raise ConfigError(f"[site] plant {plant_path}: {' '.join(str(error).split())}") from None
    known = plant_knowledge(config)
    settling, middle = known.settling_time, known.middle
    if window_s < settling:
        raise ConfigError(
            f"[online] window_s = {window_s:g} s is shorter than the plant's settling time "
            f"{settling:.3g} s (plant {plant_path}, at {middle:g} V and "
            f"{DEFAULT_FUEL_TEMPERATURE_C:g} °C): a window must "
            "hold settled responses; make window_s at least that"
        )
    return settling


__all__ = [
    "MIN_GOOD_SAMPLES",
    "NEAR_INTEGRATING_POLE",
    "WindowAnalyser",
    "WindowPriors",
    "WindowResult",
    "check_site_plant",
    "window_priors",
]
