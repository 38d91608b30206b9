"""Single-shooting output-error fit of a gray-box model: the least-squares driver and covariance.

The estimate minimises Σ_records Σ_outputs Σ_k ((ŷ_k(φ) − y_k)/σ_c)² by trust-region
least squares (:func:`scipy.optimize.least_squares`, ``trf``, within the bounds), with the exact
Jacobian from the forward sensitivity equations (:mod:`fuelid.greybox._sensitivity`): one
simulation per record per iteration, however many parameters. σ_c, the noise level of each output,
starts at the first-difference estimate and is re-estimated from the residuals (a second pass
when it moved): that is maximum likelihood for Gaussian white output noise of unknown level per
output, and what weighs flow against pressure when both are logged.

The covariance is the inverse Fisher information (JᵀJ)⁻¹ with J the weighted sensitivities at the
estimate (:func:`parameter_uncertainty`): the Cramér–Rao bound, attained asymptotically by this
estimator when the output noise is white. Positive parameters are estimated as log θ, so their
95 % interval exp(log θ̂ ± 1.96σ) is asymmetric.

:class:`ShootingFit` holds the machinery :class:`~fuelid.greybox._estimator.GreyBoxEstimator`
fits with; the segmented start (:mod:`fuelid.greybox._multiple_shooting`) and the profile
likelihood (:mod:`fuelid.greybox._profile`) build on it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.optimize
import scipy.special
from numpy.typing import NDArray

from fuelid.errors import FuelidError, NotFittedError
from fuelid.greybox._parameters import ParameterMap
from fuelid.greybox._sensitivity import Trajectory, simulate_record
from fuelid.greybox._solver_choice import SolverChoice, choose_solver
from fuelid.greybox._solvers import SimulationError, Solver
from fuelid.greybox._stopping import (
    GAUSS_NEWTON_LAST_STEP_SE,
    Step,
    converged,
    gauss_newton_step,
    last_step,
)
from fuelid.greybox._system import GreyBoxModel, Record

FloatArray = NDArray[np.float64]
Z95 = float(scipy.special.ndtri(0.975))
"""The standard normal's 97.5 % quantile (scipy.stats costs 0.3 s to import: not here)."""
COST_TOLERANCE = 1e-4
"""The solver stops when an iteration lowers ½Σ(r/σ)² by less than this (see ``_cost_ftol``)."""
MAX_RESTARTS = 3
"""Times a fit goes on from an extrapolated point (:mod:`fuelid.greybox._stopping`) before it
stops at one."""
MAX_NOISE_PASSES = 4
"""Fits with re-estimated noise levels, at most (several outputs only)."""
NOISE_TOLERANCE = math.log(1.05)
"""The noise levels have settled when none moved by more than 5 % in a pass."""
XTOL = 1e-7
"""The solver stops when a step changes φ by less than this relative amount: 1e-7 of a
parameter is far inside any standard error the data give (log-space parameters: relative), and
the last iterations to 1e-10 only chase the integrator's rounding with rejected trial points."""


class ConvergenceError(FuelidError):
    """The fit did not converge: no numbers are given."""


class OutOfBudget(Exception):
    """A fit stage spent its allowance of right-hand-side evaluations (the segmented start)."""


class _Converged(Exception):
    """Raised from the Jacobian callback where the fit ends (:mod:`fuelid.greybox._stopping`)."""

    def __init__(self, phi: FloatArray, jacobians: int) -> None:
        super().__init__("converged")
        self.phi = np.array(phi, dtype=float)
        self.jacobians = jacobians


class _Restart(Exception):
    """Raised from the Jacobian callback to go on from an extrapolated point."""

    def __init__(self, phi: FloatArray, rate: float) -> None:
        super().__init__("restart")
        self.phi = np.array(phi, dtype=float)
        self.rate = rate


@dataclass
class Evaluation:
    """Weighted residuals (and their Jacobian) of every record at one φ, with the trajectories."""

    residuals: FloatArray
    jacobian: FloatArray | None
    trajectories: list[Trajectory]


@dataclass
class ShootingResult:
    """A single-shooting fit of the whole records."""

    phi: FloatArray
    solution: Any
    """scipy's least-squares result of the last noise pass."""
    evaluation: Evaluation
    sigma: FloatArray
    """Noise level per output from the residuals."""
    iterations: int


def first_outputs(y: FloatArray) -> FloatArray:
    """Each output's first finite sample (NaN for a column without one): the y0 of x0(θ, u0, y0).

    >>> first_outputs(np.array([[np.nan, 2.0], [1.0, 3.0]]))
    array([1., 2.])
    """
    out = np.full(y.shape[1], np.nan)
    for column in range(y.shape[1]):
        finite = np.flatnonzero(np.isfinite(y[:, column]))
        if len(finite):
            out[column] = y[finite[0], column]
    return out


def noise_level(y: FloatArray) -> FloatArray:
    """First-difference noise estimate per output, floored above zero.

    1.4826·MAD(Δy)/√2: the differences of white noise have √2 its standard deviation, and the
    median absolute deviation ignores the few large differences where the signal itself steps,
    so the first pass of the fit starts with nearly the weights it ends with.
    """
    levels = []
    for column in range(y.shape[1]):
        values = y[np.isfinite(y[:, column]), column]
        diff = np.diff(values)
        level = 0.0
        if len(diff) > 1:
            mad = float(np.median(np.abs(diff - np.median(diff))))
            level = 1.4826 * mad / math.sqrt(2.0) if mad > 0.0 else float(np.std(diff))
        spread = float(np.std(values)) if len(values) > 1 else 0.0
        levels.append(max(level, 1e-6 * spread, 1e-12))
    return np.array(levels)


def residual_sigma(
    evaluation: Evaluation, records: Sequence[Record], n_estimated: int
) -> FloatArray:
    """Noise level per output from the residuals (degrees of freedom shared by outputs)."""
    errors = [t.outputs - r.y for t, r in zip(evaluation.trajectories, records, strict=True)]
    stacked = np.vstack(errors)
    out = []
    for column in range(stacked.shape[1]):
        finite = stacked[np.isfinite(stacked[:, column]), column]
        dof = max(len(finite) - n_estimated / stacked.shape[1], 1.0)
        out.append(max(float(np.sqrt(np.sum(finite**2) / dof)), 1e-12))
    return np.array(out)


@dataclass(frozen=True)
class ParameterUncertainty:
    """The covariance of the free parameters at the estimate and what follows from it."""

    cov_phi: FloatArray
    """Covariance of everything estimated (free parameters, then initial states), in φ."""
    cov: FloatArray
    """Covariance of the free parameters in natural units."""
    correlation: FloatArray
    stderr: dict[str, float | None]
    """Standard error per parameter (None: fixed, or not determined by the data)."""
    ci95: dict[str, tuple[float, float] | None]
    """95 % interval per parameter (None as for ``stderr``)."""


def parameter_uncertainty(
    parameter_map: ParameterMap, phi: FloatArray, jac: FloatArray, unknown: set[str]
) -> ParameterUncertainty:
    """Covariance (JᵀJ)⁻¹, standard errors and 95 % intervals at the estimate φ.

    ``jac`` is the weighted Jacobian at φ; ``unknown`` names the parameters in a combination the
    data do not determine: they get no standard error and no interval.
    """
    p = len(parameter_map.free_names)
    information = jac.T @ jac
    cov_phi = np.asarray(np.linalg.pinv(information, rcond=1e-12, hermitian=True), dtype=float)
    theta = parameter_map.to_theta(phi[:p])
    scale = parameter_map.dtheta_dphi(phi[:p])
    cov = cov_phi[:p, :p] * np.outer(scale, scale)
    stderr_phi = np.sqrt(np.clip(np.diag(cov_phi[:p, :p]), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        correlation = cov / np.outer(sd, sd)
    stderr: dict[str, float | None] = {spec.name: None for spec in parameter_map.specs}
    ci95: dict[str, tuple[float, float] | None] = {spec.name: None for spec in parameter_map.specs}
    log_mask = parameter_map.log_mask
    for j, name in enumerate(parameter_map.free_names):
        if name in unknown:
            continue
        stderr[name] = float(sd[j])
        if log_mask[j]:
            ci95[name] = (
                float(theta[j] * math.exp(-Z95 * stderr_phi[j])),
                float(theta[j] * math.exp(Z95 * stderr_phi[j])),
            )
        else:
            # clipped to the parameter's bounds: the estimate cannot lie beyond them
            spec = parameter_map.free[j]
            low = float(theta[j] - Z95 * sd[j])
            high = float(theta[j] + Z95 * sd[j])
            ci95[name] = (
                low if spec.lower is None else max(low, spec.lower),
                high if spec.upper is None else min(high, spec.upper),
            )
    return ParameterUncertainty(cov_phi, cov, correlation, stderr, ci95)


class ShootingFit:
    """Simulate the records at φ and fit φ by least squares (the estimator's machinery).

    The attributes are set by :meth:`GreyBoxEstimator.fit
    <fuelid.greybox._estimator.GreyBoxEstimator.fit>` before any of these methods runs.
    """

    model: GreyBoxModel
    max_iterations: int
    map_: ParameterMap
    free_names_: tuple[str, ...]
    n_states_: int
    estimate_x0_: bool
    _budgets: list[int]
    """Right-hand-side evaluations a simulation of each record may use (empty: no limit)."""
    _work: list[int]
    """Record simulations and right-hand-side evaluations so far."""
    _held_states: list[int]
    """Indices in φ of estimated initial states the outputs do not depend on: held (see
    :meth:`fuelid.greybox._profile.ProfileLikelihood._hold_unused`)."""
    _work_limit: int | None
    """Right-hand-side evaluations after which :meth:`_evaluate` raises OutOfBudget (the
    segmented start's allowance); None: no limit."""
    solver_: SolverChoice
    records_: list[Record]
    max_step: float | None
    substeps: int | None

    def _check_fitted(self) -> None:
        if "params_" not in vars(self):
            raise NotFittedError(f"{type(self).__name__} is not fitted: call fit(records) first")

    def _x0_names(self) -> list[str]:
        if not self.estimate_x0_:
            return []
        many = len(self.records_) > 1
        names = [record.name or str(i + 1) for i, record in enumerate(self.records_)]
        if len(set(names)) < len(names):  # two logs of one name: number them instead
            names = [str(i + 1) for i in range(len(names))]
        return [
            f"x0[{state}]" + (f"@{name}" if many else "")
            for name in names
            for state in self.model.state_names
        ]

    def _evaluate(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray, jacobian: bool
    ) -> Evaluation:
        """Simulate every record at φ: weighted residuals (and their Jacobian)."""
        if self._work_limit is not None and self._work[1] >= self._work_limit:
            raise OutOfBudget(f"{self._work[1]} right-hand-side evaluations spent")
        trajectories = self._simulate_all(phi, records, jacobian)
        return self._assemble(trajectories, records, sigma, jacobian)

    def _evaluate_or_fall_back(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray, where: str
    ) -> Evaluation:
        """The evaluation (with sensitivities) at φ; where the solver fails, the next one.

        A point the fit itself reaches (a released parameter's refit, the solver check's
        refit) is not a trial point the trust region can step back from: an ODE solver that
        fails there (LSODA's "Excess work" at a switch) must not end the fit. With ``auto`` the
        solver is chosen again at φ as at the start values (LSODA, BDF, RK4 by doubling, each
        with bounded work) and the fit's solver line says why; a solver the user asked for, or
        a point no solver simulates, is a ConvergenceError that gives the reasons.
        """
        try:
            return self._evaluate(phi, records, sigma, jacobian=True)
        except (SimulationError, FloatingPointError, OverflowError) as exc:
            failure = f"{self.solver_.solver.method} failed at {where}: {exc}"
        choice = self.solver_
        if choice.requested != "auto":
            raise ConvergenceError(
                f"the fit did not converge: {failure} (--solver auto falls back to another solver)"
            )

        def outputs(solver: Solver) -> list[FloatArray]:
            if solver.method == choice.solver.method:
                # it just failed here with sensitivities: the trial without them proves nothing
                raise SimulationError(failure)
            self.solver_ = SolverChoice(solver, choice.requested, "")
            try:
                return [t.outputs for t in self._simulate_all(phi, records)]
            finally:
                self.solver_ = choice

        substeps = self.substeps if choice.solver.method == "rk4" else None
        try:
            fallback = choose_solver("auto", self.max_step, substeps, outputs, records, sigma)
            # its reason repeats the failure: the solver it chose is what is new
            to = fallback.solver.describe()
            reason = "; ".join(
                text for text in (choice.reason, failure, f"fell back to {to}") if text
            )
            self.solver_ = SolverChoice(fallback.solver, "auto", reason)
            return self._evaluate(phi, records, sigma, jacobian=True)
        except (SimulationError, FloatingPointError, OverflowError) as exc:
            raise ConvergenceError(
                f"the fit did not converge: {failure}; no fallback solver simulates it ({exc})"
            ) from None

    def _simulate_all(
        self, phi: FloatArray, records: Sequence[Record], jacobian: bool = False
    ) -> list[Trajectory]:
        """Simulate every record at φ with the fit's solver (with sensitivities if asked)."""
        p = len(self.free_names_)
        n = self.n_states_
        values = self.map_.values(phi[:p])
        scale = self.map_.dtheta_dphi(phi[:p])
        trajectories = []
        for i, record in enumerate(records):
            system = self.model.bind(values, self.free_names_, record)
            if self.estimate_x0_:
                x0 = phi[p + i * n : p + (i + 1) * n]
                s0 = np.hstack([np.zeros((n, p)), np.eye(n)])
            else:
                init = system.initial_state(record.u[0], first_outputs(record.y))
                if init is None:
                    raise FuelidError("the model stopped defining x0 after the first call")
                x0, dx0 = init
                s0 = np.asarray(dx0, dtype=float).reshape(n, p) * scale
            budget = self._budgets[i] if i < len(self._budgets) else None
            trajectories.append(
                simulate_record(
                    system,
                    record,
                    np.asarray(x0, dtype=float),
                    s0 if jacobian else None,
                    scale if jacobian else None,
                    budget,
                    solver=self.solver_.solver,
                )
            )
        self._work[0] += len(trajectories)
        self._work[1] += sum(trajectory.evaluations for trajectory in trajectories)
        return trajectories

    def _assemble(
        self,
        trajectories: list[Trajectory],
        records: Sequence[Record],
        sigma: FloatArray,
        jacobian: bool,
    ) -> Evaluation:
        """Weighted residuals (and Jacobian) from simulated trajectories: no new simulation."""
        p = len(self.free_names_)
        n = self.n_states_
        n_x0 = n * len(records) if self.estimate_x0_ else 0
        residuals: list[FloatArray] = []
        rows: list[FloatArray] = []
        for i, (record, trajectory) in enumerate(zip(records, trajectories, strict=True)):
            keep = np.isfinite(record.y)
            weighted = (trajectory.outputs - record.y) / sigma
            residuals.append(weighted[keep])
            if jacobian:
                sens = trajectory.output_sensitivity
                if sens is None:
                    raise FuelidError("internal: a trajectory without sensitivities")
                sens = sens / sigma[None, :, None]
                block = np.zeros((int(keep.sum()), p + n_x0))
                block[:, :p] = sens[:, :, :p][keep]
                if self.estimate_x0_:
                    block[:, p + i * n : p + (i + 1) * n] = sens[:, :, p:][keep]
                rows.append(block)
        r = np.concatenate(residuals)
        if not np.all(np.isfinite(r)):
            raise SimulationError("the model's outputs are not finite at these parameters")
        return Evaluation(r, np.vstack(rows) if jacobian else None, trajectories)

    def _solve(
        self,
        phi0: FloatArray,
        records: Sequence[Record],
        sigma: FloatArray,
        hold: int | Sequence[int] | None = None,
        seed: Evaluation | None = None,
        jacobian_scaled: bool = False,
    ) -> tuple[FloatArray, Any, Evaluation]:
        """Least squares from phi0; ``hold`` keeps φ components fixed (profiles, initial states).

        ``jacobian_scaled``: scipy's ``x_scale="jac"`` trust region (the segmented start's
        stages, whose many initial states differ in scale) instead of the relative one.
        ``seed`` is the evaluation at phi0 with this σ, if already at hand. Returns φ̂, the
        solver's result and the evaluation at φ̂ (the solver's last accepted point, so the caller
        need not simulate it again).
        """
        p = len(self.free_names_)
        lower, upper = self.map_.bounds()
        n_extra = len(phi0) - p
        lower = np.concatenate([lower, np.full(n_extra, -np.inf)])
        upper = np.concatenate([upper, np.full(n_extra, np.inf)])
        active = np.ones(len(phi0), dtype=bool)
        if hold is not None:
            active[np.atleast_1d(np.asarray(hold, dtype=int))] = False
        if self._held_states:  # initial states the outputs do not depend on
            active[self._held_states] = False
        run = _LeastSquaresRun(self, phi0, records, sigma, active, (lower[active], upper[active]))
        start = np.clip(phi0[active], run.clip_low + 1e-12, run.clip_high - 1e-12)
        if seed is not None and np.array_equal(start, phi0[active]):
            run.latest[start.tobytes()] = seed
        n_residuals = (
            len(seed.residuals)
            if seed is not None
            else sum(int(np.isfinite(record.y).sum()) for record in records)
        )
        x_scale = "jac" if jacobian_scaled else self._relative_scale(phi0)[active]
        solution = run.minimise(start, x_scale, _cost_ftol(n_residuals))
        return run.full(solution.x), solution, run.evaluation_at(solution.x)

    def _relative_scale(self, phi0: FloatArray) -> FloatArray:
        """The trust region's scale of each φ component: relative to its size.

        Log-space parameters already are relative; the others and the initial states are
        scaled by their size (not scipy's 'jac', which lets the least determined directions take
        the longest steps: a parameter near 0 runs off to 0).
        """
        p = len(self.free_names_)
        theta_size = np.where(
            self.map_.log_mask, 1.0, np.maximum(np.abs(self.map_.to_theta(phi0[:p])), 1e-3)
        )
        state_size = np.maximum(np.abs(phi0[p:]), getattr(self, "state_scale_", 1.0))
        return np.concatenate([theta_size, state_size])

    def _single_shooting(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray, evaluation: Evaluation
    ) -> ShootingResult:
        """Fit the whole records from φ, re-estimating the noise levels between passes.

        Returns φ̂, the solver's result, the evaluation at φ̂, the noise levels and the iterations.
        """
        iterations = 0
        try:
            for _ in range(MAX_NOISE_PASSES):
                phi, solution, evaluation = self._solve(phi, records, sigma, seed=evaluation)
                iterations += int(solution.njev if solution.njev is not None else solution.nfev)
                from_residuals = residual_sigma(evaluation, records, len(phi))
                moved = np.abs(np.log(from_residuals / sigma))
                sigma = from_residuals
                evaluation = self._assemble(evaluation.trajectories, records, sigma, True)
                if len(sigma) == 1 or np.all(moved < NOISE_TOLERANCE):
                    break
        except (SimulationError, FloatingPointError, OverflowError) as exc:
            raise ConvergenceError(
                f"the fit did not converge: the model cannot be simulated ({exc})"
            ) from None
        if solution.status <= 0:
            raise ConvergenceError(
                f"the fit did not converge in {self.max_iterations} iterations "
                f"({solution.message.rstrip('.')}); no estimate is given: try other start "
                "values, fix a parameter, or give a longer or more exciting record"
            )
        return ShootingResult(phi, solution, evaluation, sigma, iterations)


def _cost_ftol(n_residuals: int) -> float:
    """The ``ftol`` that stops scipy when an iteration lowers ½Σr² by less than COST_TOLERANCE.

    At the optimum ½Σr² ≈ m/2 for m weighted residuals: a smaller gain moves φ by ~0.01 standard
    errors, and further iterations would chase the integrator's rounding rather than the data.
    """
    return min(1e-6, max(1e-12, COST_TOLERANCE / (0.5 * max(n_residuals, 1))))


class _LeastSquaresRun:
    """One trust-region least-squares run of :meth:`ShootingFit._solve` over the active φ.

    scipy calls :meth:`residuals` and :meth:`jacobian`; both share the evaluations by φ (the
    latest, whose Jacobian the next call wants, and the best, the answer when a stage's budget
    runs out). :meth:`jacobian` also applies the Gauss–Newton stopping rule
    (:mod:`fuelid.greybox._stopping`), ending the run by raising :class:`_Converged` or going on
    from an extrapolated point by raising :class:`_Restart`; :meth:`minimise` turns either into
    scipy's result.
    """

    def __init__(
        self,
        fit: ShootingFit,
        phi0: FloatArray,
        records: Sequence[Record],
        sigma: FloatArray,
        active: NDArray[np.bool_],
        bounds: tuple[FloatArray, FloatArray],
    ) -> None:
        self.fit = fit
        self.phi0 = phi0
        self.records = records
        self.sigma = sigma
        self.active = active
        self.clip_low, self.clip_high = bounds
        self.latest: dict[bytes, Evaluation] = {}
        self.best: tuple[float, bytes, Evaluation] | None = None
        """(cost, φ's bytes, evaluation) of the lowest cost so far."""
        self.jac_calls = 0
        self.previous: Step | None = None
        """The Gauss–Newton step of the last Jacobian."""
        self.restarts = 0
        self.restart_rate: float | None = None
        """The rate the current restart was extrapolated with (None: not a restart)."""

    def full(self, phi_active: FloatArray) -> FloatArray:
        """φ with the active components from ``phi_active`` and the held ones from phi0."""
        phi = self.phi0.copy()
        phi[self.active] = phi_active
        return phi

    def _evaluate(self, phi_active: FloatArray) -> Evaluation:
        return self.fit._evaluate(self.full(phi_active), self.records, self.sigma, jacobian=True)

    def _remember(self, key: bytes, evaluation: Evaluation) -> None:
        self.latest.clear()
        self.latest[key] = evaluation
        cost = float(evaluation.residuals @ evaluation.residuals)
        if self.best is None or cost <= self.best[0]:
            self.best = (cost, key, evaluation)

    def residuals(self, phi_active: FloatArray) -> FloatArray:
        """The weighted residuals at φ (scipy's ``fun``)."""
        key = phi_active.tobytes()
        evaluation = self.latest.get(key)
        if evaluation is None:
            try:
                evaluation = self._evaluate(phi_active)
            except (SimulationError, FloatingPointError, OverflowError):
                # a trial point where the ODE cannot be solved counts as a very poor fit,
                # so the trust region shrinks back towards the last good point
                if self.best is None:
                    raise
                return 1e3 * (np.abs(self.best[2].residuals) + 1.0)
        self._remember(key, evaluation)
        return evaluation.residuals

    def jacobian(self, phi_active: FloatArray) -> FloatArray:
        """The Jacobian at φ (scipy's ``jac``): the stopping rule sees each Gauss–Newton step."""
        evaluation = self.latest.get(phi_active.tobytes())
        if evaluation is None:
            evaluation = self._evaluate(phi_active)
        if evaluation.jacobian is None:
            raise FuelidError("internal: an evaluation without its Jacobian")
        jacobian = evaluation.jacobian[:, self.active]
        self.jac_calls += 1
        residuals = evaluation.residuals
        bounds = (self.clip_low, self.clip_high)
        found = gauss_newton_step(jacobian, residuals, phi_active, *bounds)
        if found is None:
            self.previous = None
            return jacobian
        current = Step(phi_active, jacobian, *found)
        if converged(self.previous, current, self.restart_rate):
            raise _Converged(phi_active, self.jac_calls)
        ending = last_step(self.previous, current, residuals, bounds, self.restart_rate)
        self.restart_rate = None
        self.previous = current
        if ending is None:
            return jacobian
        self._take_last_step(phi_active, residuals, ending.phi, ending.rate, ending.guarded)
        return jacobian

    def _take_last_step(
        self,
        phi_active: FloatArray,
        residuals: FloatArray,
        last: FloatArray,
        rate: float | None,
        guarded: bool,
    ) -> None:
        """Try the last step to ``last``: end there, restart from it, or let scipy go on.

        ``rate`` is the convergence rate the step was extrapolated with (None: the solver-error
        floor's step); ``guarded``: the step ends only where it lowers the cost. Returns when the
        trust region is to go on; raises :class:`_Converged` or :class:`_Restart` otherwise.
        """
        try:
            step_to = self._evaluate(last)
        except (SimulationError, FloatingPointError, OverflowError):
            if rate is not None:
                return  # an extrapolation too far: the trust region goes on
            raise _Converged(phi_active, self.jac_calls) from None
        if guarded and step_to.residuals @ step_to.residuals > residuals @ residuals:
            if rate is not None:
                return  # the series did not hold: the trust region goes on
            raise _Converged(phi_active, self.jac_calls)  # the floor: the better of the two
        self._remember(last.tobytes(), step_to)
        if rate is not None and self.restarts < MAX_RESTARTS and step_to.jacobian is not None:
            left = gauss_newton_step(
                step_to.jacobian[:, self.active],
                step_to.residuals,
                last,
                self.clip_low,
                self.clip_high,
            )
            # still converging at that rate, what is left is the step over 1 − ρ (half
            # the last-step threshold: the rate measured so far may still be drifting)
            left_se = math.inf if left is None else left[1] / (1.0 - rate)
            if left_se >= 0.5 * GAUSS_NEWTON_LAST_STEP_SE:
                raise _Restart(last, rate)  # not there: iterate on from the nearer point
        raise _Converged(last, self.jac_calls)

    def minimise(self, start: FloatArray, x_scale: str | FloatArray, ftol: float) -> Any:
        """Run scipy's trust region from ``start``, restarts included: its result, or one like it.

        The run ends where scipy stops, where the stopping rule ends it (status 5), or where a
        stage's allowance of evaluations is spent (status 0, at the best point so far).
        """
        evaluations_before = self.fit._work[0]
        try:
            while True:
                try:
                    solution = scipy.optimize.least_squares(
                        self.residuals,
                        start,
                        jac=self.jacobian,
                        bounds=(self.clip_low, self.clip_high),
                        method="trf",
                        x_scale=x_scale,
                        xtol=XTOL,
                        ftol=ftol,
                        gtol=1e-10,
                        # the allowance is the whole fit's, restarts included
                        max_nfev=max(1, self.fit.max_iterations - self.jac_calls),
                    )
                    # scipy counts its own call only: the fit's, restarts included
                    solution.nfev = self.fit._work[0] - evaluations_before
                    solution.njev = self.jac_calls
                    return solution
                except _Restart as again:  # from an extrapolated point (its evaluation kept)
                    start, self.previous, self.restart_rate = again.phi, None, again.rate
                    self.restarts += 1
        except OutOfBudget:
            if self.best is None:
                raise
            # the stage's best point so far: a start for what follows, not an estimate
            return scipy.optimize.OptimizeResult(
                x=np.frombuffer(self.best[1], dtype=float).copy(),
                status=0,
                success=False,
                message="stopped: the stage's allowance of evaluations was spent",
                nfev=self.fit._work[0] - evaluations_before,
                njev=self.jac_calls,
            )
        except _Converged as done:
            return scipy.optimize.OptimizeResult(
                x=done.phi,
                status=5,
                success=True,
                message="the Gauss-Newton step left less than the tolerance to gain",
                nfev=self.fit._work[0] - evaluations_before,
                njev=done.jacobians,
            )

    def evaluation_at(self, phi_active: FloatArray) -> Evaluation:
        """The evaluation at the run's answer: remembered (latest or best), or simulated."""
        key = np.asarray(phi_active, dtype=float).tobytes()
        found = self.latest.get(key)
        if found is None and self.best is not None and self.best[1] == key:
            found = self.best[2]
        if found is None:
            found = self._evaluate(phi_active)
        return found
