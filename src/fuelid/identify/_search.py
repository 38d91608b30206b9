"""The online windows' nonlinear search: Levenberg–Marquardt on one to three parameters.

The output-error search runs over log T, (log T2) and (θ) only (variable projection), with an
analytic Jacobian (:func:`~fuelid.identify._variable_projection.sensitivities`). scipy's
``least_squares(method="trf")`` spends a fifth of such a search on its own bookkeeping with the
30,000 × p Jacobian (an SVD of it per iteration, scalings, copies); here every iteration works
with JᵀJ and Jᵀr (p × p and p) once they are formed.

The method (Moré 1978): the step solves (JᵀJ + λ·diag JᵀJ)·δ = −Jᵀr, clipped to the bounds;
a step that lowers Σr² is kept and λ shrinks (to 0, Gauss–Newton, near the optimum), one that
does not is retried with λ grown. It stops by ``least_squares``'s ftol and xtol rules, with the
same tolerances (the fit's :class:`~fuelid.numerics_mode.Numerics`): a kept step that lowered
Σr² by under ``ftol`` of it, or a step under ``xtol``·(``xtol`` + ‖z‖); and when the gradient
Jᵀr is under ``gtol``·Σr² in every component (scipy's gtol is on the scaled gradient without
Σr²). So what is left to gain at the stop is what the tolerances bound
(:data:`~fuelid.numerics_mode.STATISTICAL_TOLERANCES` says how many standard errors).

Which search runs is the fit's ``numerics``: this one when it asks for analytic Jacobians (the
online windows', :data:`~fuelid.numerics_mode.WINDOW_NUMERICS`), else scipy's ``trf`` with
finite differences of the residual (``fuelid identify``'s, and the path before issue 26).

Reference: J. J. Moré, "The Levenberg–Marquardt algorithm: implementation and theory",
*Numerical Analysis*, Lecture Notes in Mathematics 630 (1978) 105–116.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import partial

import numpy as np
from numpy.typing import NDArray

from fuelid.identify._long_record import LongRecordSearch, is_long, polish, search_copy
from fuelid.identify._variable_projection import (
    LinearFit,
    Structure,
    grid_starts,
    projected_jacobian,
    regressors,
    sensitivities,
    solve_linear,
    start_from_model,
)
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel
from fuelid.numerics_mode import DEFAULT_NUMERICS, Numerics

FloatArray = NDArray[np.float64]
#: the damping's growth after a step that did not lower Σr², and its shrinkage after one that did
GROW, SHRINK = 4.0, 0.25


def levenberg_marquardt(
    residual: Callable[[FloatArray], FloatArray],
    jacobian: Callable[[FloatArray], FloatArray],
    z0: FloatArray,
    bounds: tuple[Sequence[float], Sequence[float]],
    *,
    xtol: float,
    ftol: float,
    gtol: float,
    max_nfev: int = 100,
) -> FloatArray:
    """The minimiser of ‖residual(z)‖² within ``bounds``, from ``z0``.

    Parameters
    ----------
    residual : callable
        z ↦ r (length N).
    jacobian : callable
        z ↦ ∂r/∂z (N × p), asked for only at points whose residual was just evaluated.
    z0 : array
        Start, inside the bounds.
    bounds : (lower, upper)
        Box constraints on z.
    xtol, ftol, gtol : float
        Stopping tolerances (module docstring).
    max_nfev : int
        Most residual evaluations.

    Returns
    -------
    ndarray
        The last point kept.

    Examples
    --------
    >>> t = np.linspace(0.0, 4.0, 50)
    >>> y = np.exp(-t / 1.5)
    >>> z = levenberg_marquardt(
    ...     lambda z: np.exp(-t / np.exp(z[0])) - y,
    ...     lambda z: (np.exp(-t / np.exp(z[0])) * t / np.exp(z[0]))[:, None],
    ...     np.array([0.0]), ([-5.0], [5.0]), xtol=1e-12, ftol=1e-14, gtol=1e-14)
    >>> round(float(np.exp(z[0])), 6)
    1.5
    """
    lo, hi = np.asarray(bounds[0], dtype=float), np.asarray(bounds[1], dtype=float)
    z: FloatArray = np.clip(np.asarray(z0, dtype=float), lo, hi)
    r = residual(z)
    cost = float(r @ r)
    nfev = 1
    damping = 0.0  # Gauss–Newton first: a warm start is close to the optimum
    while nfev < max_nfev:
        J = jacobian(z)
        A = J.T @ J
        g = J.T @ r
        if np.max(np.abs(g)) <= gtol * cost:
            break
        diag = np.maximum(np.diag(A), 1e-300)
        kept = False
        while nfev < max_nfev:
            try:
                step = np.linalg.solve(A + damping * np.diag(diag), -g)
            except np.linalg.LinAlgError:
                step = np.linalg.lstsq(A + damping * np.diag(diag), -g, rcond=None)[0]
            trial: FloatArray = np.clip(z + step, lo, hi)
            step = trial - z
            small = math.sqrt(float(step @ step)) < xtol * (xtol + math.sqrt(float(z @ z)))
            r_trial = residual(trial)
            nfev += 1
            trial_cost = float(r_trial @ r_trial)
            if trial_cost < cost:
                gained = cost - trial_cost
                z, r, cost, kept = trial, r_trial, trial_cost, True
                damping *= SHRINK
                if damping < 1e-12:
                    damping = 0.0
                if gained < ftol * (cost + gained) or small:
                    return z
                break
            if small:  # no lower point within the step the tolerance resolves
                return z
            damping = max(GROW * damping, 1e-3)
        if not kept:
            break
    return z


class ProjectedSearch:
    """The variable-projection residual and its Jacobian, sharing one evaluation per point.

    ``evaluate(z)`` is the linear fit at the search vector z = [log T, (log T2), (θ)];
    ``sensitivities(z, fit)`` is ∂(Φβ)/∂(T, T2, θ) at fixed β there. The Jacobian of the
    residual is Kaufman's −P⊥·∂(Φβ)/∂z (:func:`~fuelid.identify._variable_projection.
    projected_jacobian`); ``last_sensitivities`` keeps the latest (fit, ∂(Φβ)/∂(T, T2, θ)) for
    the stored fit's covariance.
    """

    def __init__(
        self,
        evaluate: Callable[[FloatArray], LinearFit],
        sensitivities: Callable[[FloatArray, LinearFit], FloatArray],
        n_log: int,
    ) -> None:
        self._evaluate = evaluate
        self._sensitivities = sensitivities
        self._n_log = n_log
        self._last: tuple[FloatArray, LinearFit] | None = None
        self.last_sensitivities: tuple[LinearFit, FloatArray] | None = None

    def at(self, z: FloatArray) -> LinearFit:
        """The linear fit at ``z`` (the last one evaluated when it was there)."""
        if self._last is not None and np.array_equal(self._last[0], z):
            return self._last[1]
        fit = self._evaluate(z)
        self._last = (np.array(z, dtype=float), fit)
        return fit

    def residual(self, z: FloatArray) -> FloatArray:
        """r(z) = y − Φ(z)·β̂(z)."""
        return self.at(z).residual

    def jacobian(self, z: FloatArray) -> FloatArray:
        """∂r/∂z (Kaufman's form)."""
        fit = self.at(z)
        sens = self._sensitivities(z, fit)
        self.last_sensitivities = (fit, sens)
        # the lags are searched in logs: ∂/∂log T = T·∂/∂T
        per_log = np.ones(sens.shape[1])
        per_log[: self._n_log] = np.exp(z[: self._n_log])
        return projected_jacobian(fit.Phi, sens * per_log)


StepCallback = Callable[[str], None]
"""Told what a long search does next (a phase's description)."""


@dataclass(frozen=True)
class StructureSearch:
    """One structure's search: where it ended, and how."""

    z: FloatArray
    """The search vector [log T, (log T2), (θ)]."""
    fit: LinearFit
    """The linear fit at ``z``."""
    sensitivities: tuple[LinearFit, FloatArray] | None
    """The search's last (fit, ∂(Φβ)/∂(T, T2, θ)), or None: the stored fit's Jacobian when it
    is at that fit."""
    long_record: LongRecordSearch | None = None
    """For a long record: the copy it searched and the polish on the whole (None otherwise)."""


def search_structure(
    data: IOData,
    st: Structure,
    init: ProcessModel | None,
    delay_bound: float,
    step: StepCallback | None = None,
    *,
    numerics: Numerics = DEFAULT_NUMERICS,
) -> StructureSearch:
    """The output-error fit's nonlinear search for one structure (oe's and pem's start).

    From ``init`` (a warm start: one local search) or from the best points of a coarse grid;
    the delay, when free, searched within [0, ``delay_bound``] s. A long record
    (:func:`~fuelid.identify._long_record.is_long`) is searched on a copy of spread-out
    stretches and the optimum polished on the whole record (:mod:`fuelid.identify._long_record`,
    which says why the result is the whole record's optimum); ``step(what)``, when given, is
    told as each of those phases starts. ``numerics``: which local search, its tolerances, and
    how the model is discretised (module docstring).

    Returns
    -------
    StructureSearch
    """
    h = data.sample_time
    record = data.n_samples * h
    lo = [math.log(h / 20.0)] * st.order
    hi = [math.log(20.0 * record)] * st.order
    if st.delay is None:
        lo.append(0.0)
        hi.append(max(delay_bound, 1e-9))
    if not is_long(data):
        return StructureSearch(*_search(data, st, init, (lo, hi), numerics))
    copy = search_copy(data)
    if step is not None:
        step(f"searching on {copy.n_samples:,} samples in {copy.n_segments} stretches")
    # the copy's optimum is only a start: the online windows' numerics find it to a few
    # hundredths of its own standard error, and every stretch starts where it finds itself
    z0, _, _ = _search(copy, replace(st, later="estimate"), init, (lo, hi), numerics.statistical())
    if step is not None:
        step(f"polishing on all {data.n_samples:,} samples")
    u_ref = st.u_before if st.u_before is not None else float(data.u[0])
    problem = _problem(data, st, numerics)
    polished = polish(
        data, st, problem.at, z0, (np.array(lo), np.array(hi)), u_ref, numerics=numerics
    )
    done = LongRecordSearch(
        data.n_samples, copy.n_samples, copy.n_segments, polished.steps, polished.converged
    )
    if polished.converged and polished.sensitivities is not None:
        return StructureSearch(
            polished.z, polished.fit, (polished.fit, polished.sensitivities), done
        )
    # outside the basin after all: the whole record's own local search from the copy's optimum
    return StructureSearch(*_local_searches(problem, [polished.z], (lo, hi), numerics), done)


def evaluate_structure(
    data: IOData, st: Structure, z: FloatArray, numerics: Numerics = DEFAULT_NUMERICS
) -> LinearFit:
    """The linear fit of ``st`` on ``data`` at the search vector ``z`` (a found optimum)."""
    u_ref = st.u_before if st.u_before is not None else float(data.u[0])
    return _evaluate(st, u_ref, numerics, z, data)


def _evaluate(
    st: Structure, u_ref: float, numerics: Numerics, z: FloatArray, record: IOData
) -> LinearFit:
    T, T2, delay = st.unpack(z)
    Phi = regressors(
        st,
        T,
        T2,
        delay,
        record.u,
        record.sample_time,
        u_ref,
        record.segment_bounds(),
        numerics=numerics,
    )
    return solve_linear(Phi, record.y)


def _problem(data: IOData, st: Structure, numerics: Numerics) -> ProjectedSearch:
    """The projected residual and Jacobian of ``st`` on ``data``."""
    h = data.sample_time
    u_ref = st.u_before if st.u_before is not None else float(data.u[0])
    bounds = data.segment_bounds()
    return ProjectedSearch(
        lambda z: _evaluate(st, u_ref, numerics, z, data),
        lambda z, fit: sensitivities(
            st, *st.unpack(z), fit.beta, data.u, h, u_ref, bounds, fit.Phi, numerics=numerics
        ),
        st.order,
    )


def _search(
    data: IOData,
    st: Structure,
    init: ProcessModel | None,
    bounds: tuple[list[float], list[float]],
    numerics: Numerics,
) -> tuple[FloatArray, LinearFit, tuple[LinearFit, FloatArray] | None]:
    """The grid (or the warm start) and the local searches from its best points, on ``data``."""
    u_ref = st.u_before if st.u_before is not None else float(data.u[0])
    starts = (
        [start_from_model(init, st)]
        if init is not None
        else grid_starts(data, st, partial(_evaluate, st, u_ref, numerics), bounds[1][-1])
    )
    return _local_searches(_problem(data, st, numerics), starts, bounds, numerics)


def _local_searches(
    problem: ProjectedSearch,
    starts: list[FloatArray],
    bounds: tuple[list[float], list[float]],
    numerics: Numerics,
) -> tuple[FloatArray, LinearFit, tuple[LinearFit, FloatArray] | None]:
    """The best of the local searches from ``starts``."""
    from scipy.optimize import least_squares  # slow to import: only when fitting

    lo, hi = bounds
    # analytic Jacobians (the online windows' numerics): Levenberg–Marquardt with them; else
    # (and before issue 26's second pass) scipy's trf with finite differences of the residual
    best: tuple[FloatArray, LinearFit] | None = None
    for z0 in starts:
        z0 = np.clip(z0, np.array(lo) + 1e-9, np.array(hi) - 1e-9)
        if numerics.analytic_jacobians:
            x = levenberg_marquardt(
                problem.residual,
                problem.jacobian,
                z0,
                (lo, hi),
                xtol=numerics.tolerances.xtol,
                ftol=numerics.tolerances.ftol,
                gtol=numerics.tolerances.gtol,
            )
        else:
            x = least_squares(
                problem.residual,
                z0,
                bounds=(lo, hi),
                method="trf",
                x_scale=1.0,
                max_nfev=100,
                **numerics.tolerances.as_kwargs(),
            ).x
        ev = problem.at(x)  # the search's own evaluation when it ended there
        if best is None or ev.sse < best[1].sse:
            best = (x, ev)
    assert best is not None
    return (*best, problem.last_sensitivities)


__all__ = [
    "ProjectedSearch",
    "StepCallback",
    "StructureSearch",
    "evaluate_structure",
    "levenberg_marquardt",
    "search_structure",
]
