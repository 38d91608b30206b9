"""Gates on one identification window: the verdict, each failed gate with its reason.

The online service identifies the loop on a rolling window every few minutes; a window it
should not trust is skipped, and why is recorded (docs online.md §5: adaptive tuning that trusts
every window bursts). Two sets of gates, both judged against the site's ``[online]`` table
(:class:`fuelid.online.Online`), both returning a :class:`WindowVerdict`:

- :func:`prefit_gates`, on the window's samples before any fit: the share of lost or flagged
  samples, the share of the command at an output limit, and excitation (command steps in MAN,
  setpoint moves in AUTO), with the times of the excitation events;
- :func:`postfit_gates`, on a fitted model: the relative standard errors of K and T, the
  validation fit, the size of the residual autocorrelation (of output errors prewhitened by
  the noise's own model, :func:`prewhiten`); and the plant-ratio *event*,
  which flags but never rejects. :func:`gate_estimator` and :func:`gate_result` feed it from a
  fitted estimator or an ``identify`` result; :func:`excitation_refusal` turns the estimator's own
  :class:`~fuelid.errors.NotExcitingError` into a rejection.

:meth:`WindowVerdict.combine` joins the two; every failed gate is listed, not only the first.
(The verdict and the two sets live in ``_verdict.py``, ``_prefit.py`` and ``_postfit.py``.)

Units: time [s], command u [V], flow y and setpoint [L/min], K [(L/min)/V], T [s].

References
----------
L. Ljung, *System Identification: Theory for the User* (2nd ed., Prentice Hall, 1999), §13.4
(closed-loop identifiability) and §16.6 (residual analysis). B. D. O. Anderson, "Adaptive
systems, lack of persistency of excitation and bursting phenomena", Automatica 21 (1985)
247–258. G. E. P. Box, G. M. Jenkins, *Time Series Analysis* (1976), §8.2.
"""

from __future__ import annotations

from fuelid.online._residual_acf import Prewhitened, acf_lags, largest_residual_acf, prewhiten
from fuelid.online.gates._postfit import (
    excitation_refusal,
    gate_estimator,
    gate_result,
    postfit_gates,
)
from fuelid.online.gates._prefit import (
    GAP_PERIODS,
    MAN,
    MIN_COMMAND_STEP_V,
    NOISE_LEVELS,
    STEP_HOLD_S,
    bad_share,
    command_steps,
    judged_mode,
    lost_samples,
    prefit_gates,
    prefit_samples,
    setpoint_moves,
)
from fuelid.online.gates._verdict import WindowVerdict

__all__ = [
    "GAP_PERIODS",
    "MAN",
    "MIN_COMMAND_STEP_V",
    "NOISE_LEVELS",
    "STEP_HOLD_S",
    "Prewhitened",
    "WindowVerdict",
    "acf_lags",
    "bad_share",
    "command_steps",
    "excitation_refusal",
    "gate_estimator",
    "gate_result",
    "judged_mode",
    "largest_residual_acf",
    "lost_samples",
    "postfit_gates",
    "prefit_gates",
    "prefit_samples",
    "prewhiten",
    "setpoint_moves",
]
