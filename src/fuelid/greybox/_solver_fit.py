"""The estimator's side of the solver choice: auto's trial runs and the check at the estimate.

:mod:`fuelid.greybox._solver_choice` decides which solver from trial simulations;
:class:`SolverChecks` gives :class:`~fuelid.greybox._estimator.GreyBoxEstimator` those trial
simulations at the start values (a variable-step solver's trial is the fit's start evaluation
itself) and repeats the accuracy check at the estimate, refitting with a finer solver where the
estimate needs one.
"""

from __future__ import annotations

from collections.abc import Sequence

from fuelid.greybox._fitting import Evaluation, FloatArray, ShootingFit, ShootingResult
from fuelid.greybox._solver_choice import SolverChoice, verified
from fuelid.greybox._solvers import RTOL, SimulationError, Solver
from fuelid.greybox._system import Record


class SolverChecks(ShootingFit):
    """Trial simulations for the solver choice, and its check at the estimate."""

    solver: str
    substeps: int | None
    noise_floor_: FloatArray
    _start_evaluation: dict[Solver, Evaluation]

    def _recheck_solver(self, result: ShootingResult, records: Sequence[Record]) -> ShootingResult:
        """Check the solver's accuracy at the estimate; refit with a finer one where it fails.

        The solver was checked at the start values; at the estimate the model's modes may be
        faster (a shorter time constant, a steeper kink), and an error there biases the estimate.
        A solver the user gave outright (RK4 with its substeps) is used as given.
        """
        choice = self.solver_
        if choice.solver.method == "rk4" and self.substeps is not None:
            return result
        saved = self._budgets
        self._budgets = []  # a finer solver may take more evaluations than the start's budget

        def outputs(solver: Solver) -> list[FloatArray]:
            self.solver_ = SolverChoice(solver, choice.requested, "")
            try:
                return [t.outputs for t in self._simulate_all(result.phi, records)]
            finally:
                self.solver_ = choice

        try:
            solver, note = verified(
                outputs,
                choice.solver,
                self.noise_floor_,
                [t.outputs for t in result.evaluation.trajectories],
            )
        except SimulationError:
            solver, note = choice.solver, ""
        finally:
            self._budgets = saved
        if solver == choice.solver:
            return result
        reason = "; ".join(text for text in (choice.reason, f"at the estimate: {note}") if text)
        self.solver_ = SolverChoice(solver, choice.requested, reason)
        # the finer solver's work is bounded as the start's was (8× its evaluations, ≥ 2000),
        # and where it still fails the refit falls back as auto does at the start values
        evaluation = self._evaluate_or_fall_back(result.phi, records, result.sigma, "the estimate")
        refit = self._single_shooting(result.phi, records, result.sigma, evaluation)
        refit.iterations += result.iterations
        return refit

    def _start_outputs(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray, solver: Solver
    ) -> list[FloatArray]:
        """The records' outputs at φ with ``solver``: the trial runs of the solver choice.

        A variable-step solver's trial is the fit's start evaluation itself (with
        sensitivities), kept for the fit when that solver is chosen; RK4's doublings simulate
        the outputs alone.
        """
        if solver in self._start_evaluation:
            return [t.outputs for t in self._start_evaluation[solver].trajectories]
        saved = getattr(self, "solver_", None)
        self.solver_ = SolverChoice(solver, self.solver, "")
        try:
            if solver.method == "rk4" or solver.rtol != RTOL:
                # RK4's doublings and the accuracy check's finer tolerances: outputs alone
                trajectories = self._simulate_all(phi, records)
            else:
                evaluation = self._evaluate(phi, records, sigma, jacobian=True)
                self._start_evaluation[solver] = evaluation
                trajectories = evaluation.trajectories
        finally:
            if saved is not None:
                self.solver_ = saved
        return [trajectory.outputs for trajectory in trajectories]
