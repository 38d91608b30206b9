"""Where the single-shooting fit stops: the Gauss–Newton step left, read at each Jacobian.

The fit (:meth:`fuelid.greybox._fitting.ShootingFit._solve`) runs scipy's trust region, which
knows neither the standard errors nor that its residuals come from an ODE solver with an error
of its own. At every Jacobian the Gauss–Newton step δ = −J⁺r is computed; its length ‖J·δ‖ (J
weighted by σ, so JᵀJ is the Fisher information) is the most any estimate would move, in its
own standard errors. :func:`last_step` reads it with the previous one:

- under :data:`GAUSS_NEWTON_STEP_SE` the fit has converged where it is;
- under :data:`GAUSS_NEWTON_LAST_STEP_SE`, shrinking fast (quadratically, as near an optimum
  of a small-residual fit), the step is taken without the trust region's test and is the last;
- shrinking by a steady ratio ρ along one direction (a large residual turning the Jacobian, or
  a model nonlinear at the scale of the standard errors: linear convergence), the rest of the
  geometric series is summed: the last step is δ/(1 − ρ) (Aitken's extrapolation), where
  scipy would take a step per term;
- not shrinking, and made of the residuals' departure from the last linear model rather than
  of the Jacobian turning, it is the simulation's own error moving with φ
  (:func:`on_error_floor`): the step is the last.

The caller evaluates the point returned and keeps the better of it and the current one; from
an extrapolated point whose own step left is not short it iterates on (a ratio still drifting,
far from the optimum, sums the series short).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

GAUSS_NEWTON_STEP_SE = 0.005
"""The fit stops when the Gauss–Newton step left is shorter than this many standard errors:
no estimate would move by more than 0.005 of its standard error, and two fits from different
starts agree to 0.01."""
GAUSS_NEWTON_LAST_STEP_SE = 0.05
"""A Gauss–Newton step shorter than this, less than half the previous one, is taken without the
trust region's test, and the fit stops there: the cost it would gain (½·0.05² of χ²) is below
what the integrator's tolerance resolves, so scipy's trust region, which cannot know it, would
reject ever shorter trial steps, one simulation each; shrinking that fast the iteration
converges quadratically and the step lands within GAUSS_NEWTON_STEP_SE."""
GAUSS_NEWTON_FLOOR_SE = 0.15
"""Below this many standard errors a step that shrinks by less than half is read for linear
convergence (extrapolated) or the simulation's error (taken and the last)."""
SLOW = 0.5
"""A step more than this fraction of the previous one shrinks slowly (not quadratically)."""
COLLINEAR = 0.95
"""|cos| between two successive steps (in the Fisher metric) above which they are one
direction converging linearly."""
MAX_RATE = 0.95
"""The steadiest linear rate extrapolated: beyond it 1/(1 − ρ) amplifies the ratio's error."""


@dataclass(frozen=True)
class Step:
    """A Gauss–Newton step from an accepted point (with the point, its Jacobian, its length)."""

    phi: FloatArray
    jacobian: FloatArray
    step: FloatArray
    length: float


def gauss_newton_step(
    jacobian: FloatArray, residuals: FloatArray, phi: FloatArray, low: FloatArray, high: FloatArray
) -> tuple[FloatArray, float] | None:
    """The Gauss–Newton step from φ and its length in standard errors (None: not usable).

    None for a step that leaves the bounds (at a bound the trust region decides) or a Jacobian
    that is not finite.
    """
    if not np.all(np.isfinite(jacobian)):
        return None
    solution, *_ = np.linalg.lstsq(jacobian, -residuals, rcond=None)
    step: FloatArray = np.asarray(solution, dtype=float)
    if not np.all((phi + step > low) & (phi + step < high)):
        return None
    predicted = jacobian @ step
    return step, float(np.sqrt(predicted @ predicted))


def _length(vector: FloatArray) -> float:
    return float(np.sqrt(vector @ vector))


def _taken_whole(previous: Step, current: Step) -> bool:
    """Whether the trust region took the previous Gauss–Newton step whole (to 10 % of it)."""
    shortfall = previous.jacobian @ (current.phi - previous.phi - previous.step)
    return _length(shortfall) <= 0.1 * previous.length


def on_error_floor(previous: Step, current: Step, residuals: FloatArray) -> bool:
    """Whether a slowly shrinking step is the simulation's error rather than the data's pull.

    After a whole Gauss–Newton step the residuals' projection on the last Jacobian's columns is
    what the linear model there did not predict: second order in the step for a smooth model,
    so small beside the new step when the Jacobian's turning (a large residual) made it. When
    that projection is at least half the new step, the residuals moved by something that does
    not shrink with the step: the integrator's error as φ moves (a few hundredths of a standard
    error at the checked tolerance, :func:`~fuelid.greybox._solver_choice.verified`), on which
    iterating only wanders.
    """
    departure, *_ = np.linalg.lstsq(previous.jacobian, -residuals, rcond=None)
    return _length(previous.jacobian @ departure) >= 0.5 * current.length


def linear_rate(previous: Step, current: Step) -> float | None:
    """ρ with δ_k ≈ ρ·δ_(k−1), when the two steps are one direction (None: they are not)."""
    now = current.jacobian @ current.step
    before = current.jacobian @ previous.step
    size = _length(now) * _length(before)
    if size == 0.0 or abs(float(now @ before)) < COLLINEAR * size:
        return None
    rate = float(now @ before) / float(before @ before)
    return rate if abs(rate) <= MAX_RATE else None


@dataclass(frozen=True)
class Ending:
    """Where the fit ends from a point: ``phi``, and how it was found."""

    phi: FloatArray
    rate: float | None = None
    """The linear rate the step was extrapolated with (None: a Gauss–Newton step)."""
    guarded: bool = False
    """Keep the current point if this one's cost is higher: a step that is not a small one in
    the quadratic regime (there a cost gain below the integrator's resolution means nothing)."""


def current_rate(previous: Step | None, current: Step, rate: float | None = None) -> float | None:
    """The linear rate the steps converge at, if they do so slowly (None: not measured).

    ``rate``: the one a fit going on from an extrapolated point was extrapolated with (it has
    no previous step of its own yet).
    """
    if previous is None:
        return rate
    if current.length <= SLOW * previous.length or not _taken_whole(previous, current):
        return None
    return linear_rate(previous, current)


def converged(previous: Step | None, current: Step, rate: float | None = None) -> bool:
    """Whether what is left is under GAUSS_NEWTON_STEP_SE: the step, or the series it starts."""
    measured = current_rate(previous, current, rate)
    left = current.length / (1.0 - measured) if measured is not None else current.length
    return left < GAUSS_NEWTON_STEP_SE


def last_step(
    previous: Step | None,
    current: Step,
    residuals: FloatArray,
    bounds: tuple[FloatArray, FloatArray],
    rate: float | None = None,
) -> Ending | None:
    """The point to end the fit at from ``current`` (None: iterate on; see the module).

    An extrapolated point (a rate, not None) is where the series would end if its ratio held;
    the caller checks what is left there, the step left over 1 − ρ, and goes on from it if
    that is not short. ``current.length`` is at least GAUSS_NEWTON_STEP_SE (below it the
    caller stops). ``bounds``: an extrapolated point must lie strictly inside them (else the
    trust region goes on). ``rate``: the one a fit going on from an extrapolated point was
    extrapolated with; that fit takes a step of its own first.
    """
    length = current.length
    if previous is None and rate is not None:
        return None  # one step to measure the rate afresh: what is left was not the series
    slow = (
        previous is not None and length > SLOW * previous.length and _taken_whole(previous, current)
    )
    if not slow:
        return Ending(current.phi + current.step) if length < GAUSS_NEWTON_LAST_STEP_SE else None
    assert previous is not None
    if length >= GAUSS_NEWTON_FLOOR_SE:
        return None
    if on_error_floor(previous, current, residuals):
        return Ending(current.phi + current.step, guarded=True)
    measured = linear_rate(previous, current)
    if measured is None:
        return None
    extrapolated = current.phi + current.step / (1.0 - measured)
    low, high = bounds
    if not np.all((extrapolated > low) & (extrapolated < high)):
        return None  # beyond a bound: the trust region's business
    return Ending(extrapolated, measured, guarded=True)
