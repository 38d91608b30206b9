"""Nonlinear gray-box estimation: fit the parameters of an ODE model to records by output error.

The user (or :mod:`fuelid.calibration` for the fuel plant) writes the model; the estimator
integrates it with its forward sensitivities, fits one or several records at once, and says what
the data determine (:func:`identifiability`, :class:`IdentifiabilityReport`).

A model is an :class:`OdeModel` (or any :class:`GreyBoxModel`), its parameters
:class:`ParameterSpec`, its declared switches :class:`Switch` (located as solver events, the
sensitivities jumping there), its data one or several :class:`Record`. The estimator,
:class:`GreyBoxEstimator`, fits by single shooting (the least-squares driver and the
covariance; :class:`ConvergenceError` when it does not converge), retried from a segmented
start (multiple shooting) for long records and local minima, and judges identifiability at the
estimate, by profile likelihood where the model is not linear enough (:data:`LINEARITY_LIMIT`).
Its fit percentages are :func:`fuelid.model.nrmse_fit_columns`.

The public API
--------------
The names in ``__all__``, and at :mod:`fuelid.greybox.modelfile` the reading of a user's Python
model file (``fuelid greybox --model``): :func:`~fuelid.greybox.modelfile.load_model_file` (an
:class:`OdeModel`) and :func:`~fuelid.greybox.modelfile.read_model_file` (its
:class:`~fuelid.greybox.modelfile.ModelFile`, the model with what the file declared). A fitted
model saved as JSON is read by :mod:`fuelid.io.fitted_model` instead.
"""

from fuelid.greybox._estimator import VALIDATION_HEAD_SHARE, GreyBoxEstimator
from fuelid.greybox._fitting import ConvergenceError, noise_level
from fuelid.greybox._identifiability import (
    IdentifiabilityReport,
    NotIdentifiableError,
    correlation_warning,
    describe_identifiability,
    identifiability,
)
from fuelid.greybox._multiple_shooting import SUSPECT_NOISE_RATIO
from fuelid.greybox._odemodel import OdeModel
from fuelid.greybox._parameters import ParameterSpec, parameter_specs
from fuelid.greybox._profile import LINEARITY_LIMIT
from fuelid.greybox._solver_choice import check_request
from fuelid.greybox._switching import Switch
from fuelid.greybox._system import GreyBoxModel, OdeSystem, Record

__all__ = [
    "LINEARITY_LIMIT",
    "SUSPECT_NOISE_RATIO",
    "VALIDATION_HEAD_SHARE",
    "ConvergenceError",
    "GreyBoxEstimator",
    "GreyBoxModel",
    "IdentifiabilityReport",
    "NotIdentifiableError",
    "OdeModel",
    "OdeSystem",
    "ParameterSpec",
    "Record",
    "Switch",
    "check_request",
    "correlation_warning",
    "describe_identifiability",
    "identifiability",
    "noise_level",
    "parameter_specs",
]
