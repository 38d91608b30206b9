"""Identification of the equivalent model from logged input/output data.

- :class:`StepResponseLS`: the source article's method (truncated step-response least squares,
  then K and T by Newton iteration with the flowmeter's T_f and τ known);
- :class:`OutputError`: output-error (maximum-likelihood under white noise) fit of the
  continuous-time gray-box model on the raw samples, with exact ZOH discretisation and a
  fractional dead time; :func:`cramer_rao_bound` its parameters' bound;
- :class:`PredictionError`: the prediction-error fit with a noise model (its orders chosen
  among :data:`NOISE_ORDERS` by :func:`information_criterion`);
- the diagnostics: :func:`residual_whiteness`, :func:`input_residual_correlation`,
  :func:`feedback_suspected`, :func:`steady_state_errors`, :func:`sample_time_advice`,
  :func:`lead_check` (the output moving before its input), :class:`MisfitBound`;
- :func:`gain_bands`: the static gain per command band (does K change with the operating
  point?);
- :func:`identify`: what ``fuelid identify`` runs, with its settings
  (:class:`IdentifyOptions`) and its result (:class:`IdentificationResult`, its 95 % intervals
  through :func:`interval95`);
- :mod:`~fuelid.identify.preprocess`: the data made ready for a fit: a time window
  (:func:`~fuelid.identify.preprocess.select`), zero-phase low-pass filtering
  (:func:`~fuelid.identify.preprocess.lowpass`), decimation with its anti-alias filter
  (:func:`~fuelid.identify.preprocess.decimate`), records joined as segments
  (:func:`~fuelid.identify.preprocess.join_segments`). ``fuelid.preprocess`` before 0.2.0.

Underneath: the output-error model as a regression for given time constants, shared by oe, pem
and the noise model (``identify/_variable_projection.py``), and step-ls's second stage,
:func:`step_shape`.

The methods, their assumptions and references: docs/explanation/identification.md.

The estimator convention
------------------------
Every estimator (:class:`StepResponseLS`, :class:`OutputError`, :class:`PredictionError`, and
the gray-box :class:`~fuelid.greybox.GreyBoxEstimator`) follows
scikit-learn's conventions, through a common base (``Estimator``, in ``identify/_base.py``):

- ``__init__`` only stores its keyword settings, unchanged and unchecked; ``get_params()``
  returns them (``type(est)(**est.get_params())`` is an unfitted copy), ``set_params(**kw)``
  changes them;
- ``fit(data, ...)`` checks the settings and the :class:`~fuelid.io.timeseries.IOData`,
  estimates, and returns the estimator itself. A refit replaces every fitted attribute; a fit
  that fails leaves the estimator unfitted;
- what ``fit`` estimates is stored in attributes whose names end in an underscore and that exist
  only after ``fit``: every estimator has ``model_`` (the fitted
  :class:`~fuelid.model.ProcessModel`), ``K_``, ``T_``, ``T2_``, ``delay_``, ``T_f_``,
  ``stderr_`` (standard error by model parameter, None for a fixed one), ``fixed_``,
  ``fit_percent_``, ``n_samples_``, ``sample_time_`` and ``warnings_``. Before ``fit``, reading
  one or calling ``simulate``, ``predict`` or ``score`` raises
  :class:`~fuelid.errors.NotFittedError` (also an ``AttributeError``, so ``hasattr`` is False);
- ``simulate(data, initial="fitted" | "rest" | "estimate")`` is the free-run response of the
  fitted model to ``data.u``: from the initial conditions estimated by ``fit`` (only on the
  fitting record or one that continues it, as a validation split does; refused on any other),
  from rest at u[0] with the fitted output offset, or with the offset and the free response of
  the initial state re-estimated by least squares on ``data`` (held-out records that do not
  start at rest). ``fit_percent_``, ``fuelid identify``'s fit and validation-split fit score
  ``simulate(..., initial="fitted")``; a separate validation record is scored from ``"rest"``;
- ``predict(data, horizon=1, initial="rest")`` is the k-step-ahead prediction ŷ(t | t − k). For
  the estimators here the noise model is H = 1, and the predictor is the simulation for every
  k (Ljung 1999, §3.2); an estimator with a noise model uses past outputs and differs;
- ``score(data, initial="fitted")`` is the NRMSE fit [%] of ``simulate(data, initial)``;
- ``to_control()`` gives the delay-free part as a python-control transfer function (imported
  only then: importing :mod:`fuelid.identify` loads neither python-control nor matplotlib).

A record with gaps (``IOData.segment_starts``) is fitted as toolboxes merge experiments: one
model for all segments, each segment simulated on its own with its own initial state, nothing
simulated, filtered or correlated across a gap (:data:`MIN_SEGMENT_SAMPLES`,
:func:`drop_short_segments`).

Methods are named in one registry, :data:`METHODS`.

The public API
--------------
The names in ``__all__`` (the estimators, :func:`identify` and its result, the diagnostics), and
:func:`~fuelid.identify.preprocess.select`, :func:`~fuelid.identify.preprocess.lowpass`,
:func:`~fuelid.identify.preprocess.decimate`, :func:`~fuelid.identify.preprocess.join_segments`
at :mod:`fuelid.identify.preprocess` (its old path ``fuelid.preprocess`` was removed in 0.3.0).
"""

from __future__ import annotations

from fuelid.identify._causality import lead_check
from fuelid.identify._covariance import MAX_AR_ORDER, ResidualAR, residual_ar
from fuelid.identify._diagnostics import (
    CorrelationTest,
    StepError,
    feedback_suspected,
    input_residual_correlation,
    residual_whiteness,
    sample_time_advice,
    settled_stretches,
    settled_whiteness,
    steady_state_errors,
)
from fuelid.identify._long_record import long_record_note
from fuelid.identify._misfit import MisfitBound
from fuelid.identify._noise import (
    NOISE_ORDERS,
    SELECTION_WARMUP,
    NoiseOrder,
    NoiseShape,
    filter_segments,
    hannan_rissanen,
    information_criterion,
    noise_coefficients,
    used_samples,
)
from fuelid.identify._nonlinearity import GainBand, NonlinearityCheck, gain_bands
from fuelid.identify._oe import OutputError
from fuelid.identify._pem import PredictionError
from fuelid.identify._procedure import identify
from fuelid.identify._progress import (
    DIAGNOSING,
    FITTING,
    StageCallback,
    StepDisplay,
    advance,
    steps_only,
)
from fuelid.identify._result import (
    METHODS,
    POSITIVE_PARAMETERS,
    IdentificationResult,
    IdentifyOptions,
    interval95,
)
from fuelid.identify._segments import MIN_SEGMENT_SAMPLES, drop_short_segments
from fuelid.identify._step_ls import StepResponseLS
from fuelid.identify._step_shape_fit import step_shape
from fuelid.identify._variable_projection import cramer_rao_bound

__all__ = [
    "DIAGNOSING",
    "FITTING",
    "MAX_AR_ORDER",
    "METHODS",
    "MIN_SEGMENT_SAMPLES",
    "NOISE_ORDERS",
    "POSITIVE_PARAMETERS",
    "SELECTION_WARMUP",
    "CorrelationTest",
    "GainBand",
    "IdentificationResult",
    "IdentifyOptions",
    "MisfitBound",
    "NoiseOrder",
    "NoiseShape",
    "NonlinearityCheck",
    "OutputError",
    "PredictionError",
    "ResidualAR",
    "StageCallback",
    "StepDisplay",
    "StepError",
    "StepResponseLS",
    "advance",
    "cramer_rao_bound",
    "drop_short_segments",
    "feedback_suspected",
    "filter_segments",
    "gain_bands",
    "hannan_rissanen",
    "identify",
    "information_criterion",
    "input_residual_correlation",
    "interval95",
    "lead_check",
    "long_record_note",
    "noise_coefficients",
    "residual_ar",
    "residual_whiteness",
    "sample_time_advice",
    "settled_stretches",
    "settled_whiteness",
    "steady_state_errors",
    "step_shape",
    "steps_only",
    "used_samples",
]
