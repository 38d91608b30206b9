"""Nonlinear gray-box estimation: fit the parameters of an ODE model to records by output error.

The user (or :mod:`fuelid.calibration` for the fuel plant) writes the model; the estimator
integrates it with its forward sensitivities, fits one or several records at once, and says what
the data determine (:mod:`fuelid.greybox._identifiability`).

The estimator (:mod:`fuelid.greybox._estimator`) is built from :mod:`~fuelid.greybox._fitting`
(single shooting, the least-squares driver, the covariance),
:mod:`~fuelid.greybox._multiple_shooting` (the segmented start) and
:mod:`~fuelid.greybox._profile` (identifiability at the estimate, profile likelihood). Its fit
percentages are :func:`fuelid.model.nrmse_fit_columns`.

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
    "check_request",
    "correlation_warning",
    "describe_identifiability",
    "identifiability",
    "noise_level",
    "parameter_specs",
]
