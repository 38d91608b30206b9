"""Output-error estimation of a nonlinear gray-box ODE model from one or several records.

:class:`GreyBoxEstimator` follows the conventions of fuelid's other estimators (see
:mod:`fuelid.identify`): settings in ``__init__`` only, ``fit(records)`` returns the estimator,
and the fitted attributes (ending in ``_``) exist only after ``fit``: reading one before raises
:class:`~fuelid.errors.NotFittedError`. Its parts live along their seams:

- :mod:`fuelid.greybox._fitting`: single shooting, the least-squares driver, the noise levels and
  the covariance (the Cramér–Rao bound (JᵀJ)⁻¹; positive parameters are estimated as log θ, so
  their 95 % interval is asymmetric);
- :mod:`fuelid.greybox._multiple_shooting`: the segmented start for long records and local minima;
- :mod:`fuelid.greybox._start_search`: a start off the flat spot, where the outputs do not depend
  on a parameter at the start values;
- :mod:`fuelid.greybox._profile`: what the data determine at the estimate, and the
  profile-likelihood interval (:meth:`GreyBoxEstimator.profile_interval`) where the Gaussian
  one is not to be trusted.

The names those modules define are importable from here too, as before the split.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.optimize

from fuelid.errors import ConfigError, DataError, FuelidError, NotFittedError
from fuelid.greybox._fitting import (
    COST_TOLERANCE,
    MAX_NOISE_PASSES,
    NOISE_TOLERANCE,
    XTOL,
    Z95,
    ConvergenceError,
    Evaluation,
    FloatArray,
    first_outputs,
    noise_level,
    parameter_uncertainty,
)
from fuelid.greybox._identifiability import (
    ESTIMATE_CORRELATION_LIMIT,
    IdentifiabilityReport,
    NotIdentifiableError,
    correlation_warning,
)
from fuelid.greybox._multiple_shooting import (
    SEGMENT_MAX_STATES,
    SEGMENT_MIN_SAMPLES,
    SEGMENT_SHRINK,
    SUSPECT_NOISE_RATIO,
    SegmentedStart,
)
from fuelid.greybox._parameters import ParameterMap
from fuelid.greybox._profile import CHI2_95, PROFILE_DOUBLINGS, ProfileLikelihood
from fuelid.greybox._sensitivity import Trajectory, simulate_record
from fuelid.greybox._solver_choice import SolverChoice, check_request, choose_solver, fall_back
from fuelid.greybox._solver_fit import SolverChecks
from fuelid.greybox._solvers import SimulationError, Solver
from fuelid.greybox._start_search import StartSearch
from fuelid.greybox._system import GreyBoxModel, OdeSystem, Record
from fuelid.model import nrmse_fit_columns
from fuelid.params import Params

__all__ = [
    "CHI2_95",
    "COST_TOLERANCE",
    "ESTIMATE_CORRELATION_LIMIT",
    "MAX_NOISE_PASSES",
    "NOISE_TOLERANCE",
    "PROFILE_DOUBLINGS",
    "SEGMENT_MAX_STATES",
    "SEGMENT_MIN_SAMPLES",
    "SEGMENT_SHRINK",
    "SUSPECT_NOISE_RATIO",
    "VALIDATION_HEAD_SHARE",
    "XTOL",
    "Z95",
    "ConvergenceError",
    "GreyBoxEstimator",
    "IdentifiabilityReport",
    "NotIdentifiableError",
    "correlation_warning",
    "first_outputs",
    "noise_level",
]

VALIDATION_HEAD_SHARE = 0.1
"""A validation record's initial state is fitted to its first 10 % (at least 20 samples)."""
RELEASE_ROUNDS = 3
"""Times held parameters are re-examined at the estimate and the fit redone, at most."""


class GreyBoxEstimator(Params, SolverChecks, SegmentedStart, StartSearch, ProfileLikelihood):
    """Fit a :class:`~fuelid.greybox._system.GreyBoxModel` to records by output error.

    Parameters
    ----------
    model : GreyBoxModel
        The model (e.g. :class:`~fuelid.greybox._odemodel.OdeModel`); its parameter list says
        which are free, their start values and bounds.
    initial_state : {"auto", "model", "estimate"}
        "model": the model's own x0(θ, u0, y0); "estimate": one initial state per record is
        estimated with the parameters; "auto": the model's when it has one.
    max_iterations : int
        Most function evaluations (simulations of every record) of the trust-region solver in
        one pass; a fit that needs more raises :class:`ConvergenceError`.
    segments : {"auto"} or int or None
        A robust start for long records (multiple shooting without continuity): the records are
        cut into this many segments each, every segment with its own initial state, and fitted
        in stages of a quarter as many segments; the whole records are then fitted from that
        start. "auto" (default): a single-shooting fit first, and a segmented start (segments of
        ≥ 50 samples) only when that fit did not converge, or its residuals exceed 3× the noise
        level the records show and the segments say the parameters, not the model, are wrong
        (:mod:`fuelid.greybox._segment_trigger`: with each segment's state reset, the
        parameters would remove at least half of the misfit above the noise); the better fit is
        kept, and the segmented start may use no more right-hand-side evaluations than the fit
        it retries did. None: single shooting only.
    solver : {"auto", "lsoda", "bdf", "radau", "rk45", "rk4"}
        The ODE solver (:mod:`fuelid.greybox._solvers`). "auto" (default): LSODA, or where it
        cannot simulate the start values BDF with a bounded step, then RK4 with its steps per
        sample doubled until they agree (:mod:`fuelid.greybox._solver_choice`).
    max_step : float, optional
        Longest step [s] of a variable-step solver (and of auto's choices).
    substeps : int, optional
        RK4 steps per sample interval (1…64); without it RK4 chooses them by doubling.
    hold_undetermined : bool
        A free parameter the outputs do not depend on at all (one acting only beyond a limit
        or kink the records never reach) is held at its value and reported in
        ``not_determined_`` instead of refusing the fit; it is freed again if it acts at the
        estimate. Default False: such a fit is refused, naming the parameter. Either way a start
        where it acts is searched for first (``start_search_``): held or refused is only what
        no start in the bounds cures.
    start_search : bool
        Where the outputs do not depend on some free parameter at the start values, search the
        bounds for a start where they do (default True; :mod:`fuelid.greybox._start_search`).
        False: refuse (or hold) at once, as from the start values.

    Attributes
    ----------
    params_ : dict
        Every parameter's value (fixed ones at theirs).
    stderr_ : dict
        Standard error per parameter; None for fixed ones and ones the data do not determine.
    ci95_ : dict
        95 % interval per parameter (None as for ``stderr_``).
    cov_ : ndarray
        Covariance of the free parameters, natural units, in ``free_names_`` order.
    correlation_ : ndarray
        Their correlation matrix.
    x0_ : list of ndarray
        The initial state of each record.
    fit_percent_ : list of ndarray
        NRMSE fit per record and output.
    sigma_ : ndarray
        Noise level per output from the residuals.
    identifiability_ : IdentifiabilityReport
    n_iterations_ : int
        Jacobian evaluations of the solver (its iterations), over every noise pass.
    n_simulations_ : int
        Record simulations the fit used (each with its sensitivities).
    n_evaluations_ : int
        Right-hand-side evaluations over all those simulations.
    noise_floor_ : ndarray
        Each output's sample-to-sample (first-difference) noise level in the records: residuals
        well above it mean a model error, slow disturbances or a local minimum.
    start_ : str
        How the fit was started ("single shooting" or the segmented start's stages).
    solver_ : SolverChoice
        The solver the fit ran with, what was asked for and why.
    linearity_ : dict
        Per free parameter, how far its sensitivity is from the simulation over one standard
        error (relative; None where not checked): above
        :data:`~fuelid.greybox._profile.LINEARITY_LIMIT` its interval is not to be trusted (a
        switch the sensitivities do not follow, or strong nonlinearity).
    not_determined_ : dict
        What was held because the outputs do not depend on it, name → reason: estimated initial
        states always (``x0[state]``: a mode that settles before the first sample, say), and
        parameters with ``hold_undetermined``; empty otherwise.
    start_search_ : StartSearchReport or None
        Where the outputs did not depend on some free parameter at the start values, the search
        for a start where they do (:mod:`fuelid.greybox._start_search`): which start was used
        and why, or the evidence that none was; None when the start values were not flat.
    """

    _SETTINGS = (
        "model",
        "initial_state",
        "max_iterations",
        "segments",
        "solver",
        "max_step",
        "substeps",
        "hold_undetermined",
        "start_search",
    )
    """The constructor's parameters: what ``get_params`` returns and a refit keeps."""

    def __init__(
        self,
        model: GreyBoxModel,
        initial_state: str = "auto",
        max_iterations: int = 60,
        segments: int | str | None = "auto",
        solver: str = "auto",
        max_step: float | None = None,
        substeps: int | None = None,
        hold_undetermined: bool = False,
        start_search: bool = True,
    ) -> None:
        self.model = model
        self.initial_state = initial_state
        self.max_iterations = max_iterations
        self.segments = segments
        self.solver = solver
        self.max_step = max_step
        self.substeps = substeps
        self.hold_undetermined = hold_undetermined
        self.start_search = start_search

    if not TYPE_CHECKING:  # hidden from mypy, which would otherwise accept any attribute name

        def __getattr__(self, name: str) -> Any:
            # called only when normal lookup fails: a fitted attribute before fit
            if name.endswith("_") and not name.startswith("__"):
                raise NotFittedError(
                    f"{type(self).__name__} is not fitted: {name} exists only after fit(records)"
                )
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def _unfit(self) -> None:
        """Forget a previous fit: only the settings remain."""
        for name in [n for n in vars(self) if n not in self._SETTINGS]:
            delattr(self, name)

    # --- set-up ---------------------------------------------------------------------------------
    def _prepare(self, records: Sequence[Record]) -> None:
        if self.initial_state not in {"auto", "model", "estimate"}:
            raise FuelidError(
                f"initial_state must be auto, model or estimate, not {self.initial_state!r}"
            )
        if self.segments not in (None, "auto") and (
            isinstance(self.segments, bool)
            or not isinstance(self.segments, int)
            or self.segments < 2
        ):
            raise FuelidError(
                f"segments must be 'auto', None or an integer ≥ 2, not {self.segments!r}"
            )
        try:
            check_request(self.solver, self.max_step, self.substeps)
        except ConfigError as exc:
            raise FuelidError(str(exc)) from None
        if not records:
            raise DataError("no record to fit")
        n_outputs = len(self.model.output_names)
        for record in records:
            if not isinstance(record, Record):
                raise DataError(f"expected a Record, got {type(record).__name__}")
            record.validate()
            if record.u.shape[1] != records[0].u.shape[1]:
                raise DataError(
                    f"record {record.name or '?'} has {record.u.shape[1]} input column(s), the "
                    f"first record {records[0].u.shape[1]}"
                )
            if record.y.shape[1] != n_outputs:
                raise DataError(
                    f"record {record.name or '?'} has {record.y.shape[1]} output column(s); the "
                    f"model has {n_outputs} ({', '.join(self.model.output_names)})"
                )
        for column, name in enumerate(self.model.output_names):
            if not any(np.isfinite(record.y[:, column]).any() for record in records):
                raise DataError(f"output {name} has no finite sample in any record")
        self.records_ = list(records)
        self.map_ = ParameterMap(tuple(self.model.parameters))
        self.free_names_ = self.map_.free_names
        values = self.map_.values(self.map_.start())
        probe = self.model.bind(values, self.free_names_, records[0])
        has_model_x0 = probe.initial_state(records[0].u[0], first_outputs(records[0].y)) is not None
        if self.initial_state == "model" and not has_model_x0:
            raise FuelidError("initial_state='model' but the model defines no x0")
        self.estimate_x0_ = self.initial_state == "estimate" or not has_model_x0
        self.n_states_ = len(self.model.state_names)
        self.state_scale_ = float(getattr(self.model, "state_scale", 1.0))

    def _start(self) -> FloatArray:
        phi = self.map_.start()
        if not self.estimate_x0_:
            return phi
        values = self.map_.values(phi)
        guesses = [self.model.steady_state_guess(values, record) for record in self.records_]
        return np.concatenate([phi, *guesses])

    # --- fit ------------------------------------------------------------------------------------
    def fit(self, records: Record | Sequence[Record]) -> GreyBoxEstimator:
        """Estimate the free parameters (and initial states) from the records.

        Raises
        ------
        DataError
            For records that cannot be fitted (see :meth:`Record.validate`), or fewer finite
            output samples than estimated quantities.
        NotIdentifiableError
            When the data cannot determine some parameters whatever their values.
        ConvergenceError
            If the solver stops without converging or the model cannot be simulated at the
            start values.
        """
        records = [records] if isinstance(records, Record) else list(records)
        self._unfit()
        try:
            self._fit(records)
        except BaseException:
            self._unfit()  # no half-set fitted attributes
            raise
        return self

    def _fit(self, records: list[Record]) -> None:
        self._prepare(records)
        sigma = np.max([noise_level(record.y) for record in records], axis=0)
        self.noise_floor_ = sigma
        phi = self._start()
        n_finite = sum(int(np.isfinite(record.y).sum()) for record in records)
        if n_finite <= len(phi):
            raise DataError(
                f"{n_finite} finite output samples for {len(phi)} estimated quantities: "
                "give a longer record"
            )
        self._budgets: list[int] = []
        self._work = [0, 0]
        self._work_limit: int | None = None
        self._start_evaluation: dict[Solver, Evaluation] = {}
        self._held_states: list[int] = []
        self.not_determined_: dict[str, str] = {}
        try:
            self.solver_ = choose_solver(
                self.solver,
                self.max_step,
                self.substeps,
                lambda solver: self._start_outputs(phi, records, sigma, solver),
                records,
                sigma,
            )
            evaluation = self._start_evaluation.pop(self.solver_.solver, None) or self._evaluate(
                phi, records, sigma, jacobian=True
            )
            self._start_evaluation.clear()
        except (SimulationError, FloatingPointError, OverflowError) as exc:
            raise ConvergenceError(
                f"the model cannot be simulated at the start values ({exc})"
            ) from None
        # a trial point may cost 8× the start's work (chattering at a switch), not more: one
        # that needs more is a point the fit steps back from, like one that cannot be simulated
        self._budgets = [max(8 * t.evaluations, 2_000) for t in evaluation.trajectories]
        if self.estimate_x0_:
            self._hold_idle_states(phi, evaluation)
            phi, evaluation = self._settle_initial_states(phi, records, sigma, evaluation)
        phi, evaluation = self._search_start(phi, records, sigma, evaluation)
        phi, evaluation = self._hold_unused(phi, records, sigma, evaluation)
        try:
            self._refuse_structural(phi, evaluation, records, sigma)
        except NotIdentifiableError as refusal:
            raise self._with_search_evidence(refusal) from None
        start_phi, start_sigma, start_evaluation = phi, sigma, evaluation
        self.start_ = "single shooting"
        if self.segments not in (None, "auto"):
            phi = self._segmented_start(phi, records, sigma, evaluation, int(self.segments))
            # a point the fit reached: a solver failing there falls back, it does not end the fit
            evaluation = self._evaluate_or_fall_back(
                phi, records, sigma, "the segmented start's end"
            )
        failure: ConvergenceError | None = None
        plain_work = self._work[1]
        try:
            result = self._single_shooting(phi, records, sigma, evaluation)
        except ConvergenceError as exc:
            if self.segments != "auto":
                raise
            failure, result = exc, None
        if self.segments == "auto" and (
            result is None
            or (
                self._suspect(result, self.noise_floor_)
                and self._segmented_start_pays(result, records)
            )
        ):
            # the segmented start may spend what the fit it retries spent, no more
            retried = self._retry_segmented(
                start_phi,
                records,
                start_sigma,
                start_evaluation,
                result,
                # a fit that failed is rescued without a limit, as before the allowance
                allowance=None if result is None else max(self._work[1] - plain_work, 1),
            )
            if retried is not None:
                result = retried
        if result is None:
            assert failure is not None
            raise failure
        # parameters were held: do they act at the estimate? (a release may idle another)
        for _ in range(RELEASE_ROUNDS if "_all_free" in vars(self) else 0):
            held = set(self.not_determined_)
            result = self._release_held(result, records)
            if set(self.not_determined_) == held:
                break
        result = self._recheck_solver(result, records)
        self.phi_ = result.phi
        self.sigma_ = result.sigma
        self._finish(result.phi, records, result.solution, result.evaluation)
        self.n_iterations_ = result.iterations

    def _settle_initial_states(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray, start: Evaluation
    ) -> tuple[FloatArray, Evaluation]:
        """Fit the estimated initial states alone when the start shows a structural gap.

        The initial-state guess is the steady state at the first input; a record that starts
        away from it (a free decay with the input at zero, say) has, from that guess, no
        sensitivity to any parameter, which would refuse a fit the data support. The initial
        states are fitted with the parameters held; the fit starts there when that closes the
        gap, and a gap that stays is reported as seen from the start.
        """
        report, structural = self._structural(phi, start)
        if not structural and not report.zero_sensitivity:
            return phi, start
        held = list(range(len(self.free_names_)))
        try:
            settled, _, evaluation = self._solve(phi, records, sigma, hold=held, seed=start)
        except (SimulationError, FloatingPointError, OverflowError):
            return phi, start
        settled_report, settled_structural = self._structural(settled, evaluation)
        if not settled_structural and not settled_report.zero_sensitivity:
            return settled, evaluation
        # a true gap: reported as seen from the start, unless the start showed no sensitivity
        # where the settled state shows the parameters trading against each other (the better
        # description of, say, a free decay whose scale is not determined)
        if len(settled_report.zero_sensitivity) < len(report.zero_sensitivity):
            return settled, evaluation
        return phi, start

    def _finish(
        self, phi: FloatArray, records: Sequence[Record], solution: Any, evaluation: Evaluation
    ) -> None:
        p = len(self.free_names_)
        jac = evaluation.jacobian
        if jac is None:
            raise FuelidError("internal: the final evaluation has no Jacobian")
        self.sensitivities_ = jac
        self.identifiability_ = self._judged_at_estimate(phi, records, evaluation)
        # no interval for a parameter in an undetermined combination; a confounded pair keeps
        # its (wide) intervals and is warned about
        unknown = {
            name for combination in self.identifiability_.undetermined for name in combination.names
        } | set(self.identifiability_.zero_sensitivity)
        # where the sensitivities are contradicted by the simulation, their covariance is too
        unknown |= {name for names, _ in self.identifiability_.unconfirmed for name in names}
        estimated = jac.copy()
        estimated[:, self._held_states] = 0.0  # held initial states carry no uncertainty
        uncertainty = parameter_uncertainty(self.map_, phi, estimated, unknown)
        self.cov_phi_ = uncertainty.cov_phi
        self.cov_ = uncertainty.cov
        self.correlation_ = uncertainty.correlation
        self.params_ = self.map_.values(phi[:p])
        self.stderr_ = uncertainty.stderr
        self.ci95_ = uncertainty.ci95
        self.linearity_ = self._linearity(phi, records, evaluation, unknown)
        if self.hold_undetermined:
            for name in self.identifiability_.zero_sensitivity:
                if name in self.free_names_:
                    self.not_determined_[name] = (
                        "at the estimate the outputs do not depend on it (the fit moved it "
                        "beyond what the records reach): its value is where the fit left it, not "
                        "an estimate"
                    )
        n = self.n_states_
        if self.estimate_x0_:
            self.x0_ = [phi[p + i * n : p + (i + 1) * n].copy() for i in range(len(records))]
        else:
            self.x0_ = [t.states[0].copy() for t in evaluation.trajectories]
        self.trajectories_ = evaluation.trajectories
        self.fit_percent_ = [
            nrmse_fit_columns(record.y, t.outputs)
            for record, t in zip(records, evaluation.trajectories, strict=True)
        ]
        self.cost_ = float(np.sum(evaluation.residuals**2))
        self.n_residuals_ = len(evaluation.residuals)
        self.n_simulations_ = self._work[0]
        self.n_evaluations_ = self._work[1]

    def _judged_at_estimate(
        self, phi: FloatArray, records: Sequence[Record], evaluation: Evaluation
    ) -> IdentifiabilityReport:
        """The identifiability report at the estimate, its claims checked by simulation.

        A combination the sensitivities say no data determine, along which the simulated fit
        does change (:meth:`_simulated_rises`), is where the sensitivities miss a switch or a
        clip: it is reported as such (``unconfirmed``), not as the model's.
        """
        assert evaluation.jacobian is not None
        report = self._report(phi, evaluation.jacobian)
        _, structural = self._structural(phi, evaluation)
        rises = self._simulated_rises(phi, records, self.sigma_, evaluation, structural)
        return report.contradicted(
            {names: rise for names, rise in rises.items() if not rise <= CHI2_95}
        )

    # --- use ------------------------------------------------------------------------------------
    def simulate(self, record: Record, x0: FloatArray | None = None) -> Trajectory:
        """Simulate the fitted model over a record's inputs from ``x0``.

        Without ``x0`` the model's x0(θ, u0, y0) is used, or, when initial states are estimated,
        the steady-state guess at the first input.
        """
        self._check_fitted()
        system = self.model.bind(self.params_, self.free_names_, record)
        if x0 is None:
            init = system.initial_state(record.u[0], first_outputs(record.y))
            x0 = (
                init[0] if init is not None else self.model.steady_state_guess(self.params_, record)
            )
        where = f"record {record.name}" if record.name else "a record it did not fit"
        return self._simulate_or_fall_back(system, record, np.asarray(x0, dtype=float), None, where)

    def _simulate_or_fall_back(
        self,
        system: OdeSystem,
        record: Record,
        x0: FloatArray,
        s0: FloatArray | None,
        where: str,
    ) -> Trajectory:
        """A record the fit did not see, with the fit's solver or, where it fails, auto's next.

        LSODA's "Excess work" at an undeclared switch on a validation record ends nothing:
        auto's chain, with bounded work, and the solver's reason says so (a solver the user
        chose is not replaced: its failure is raised).
        """
        try:
            return simulate_record(system, record, x0, s0, solver=self.solver_.solver)
        except SimulationError as exc:
            choice = fall_back(
                self.solver_,
                exc,
                lambda solver: [simulate_record(system, record, x0, solver=solver).outputs],
                [record],
                self.sigma_,
                self.max_step,
                where,
            )
        if choice.reason not in self.solver_.reason:
            self.solver_ = SolverChoice(
                self.solver_.solver,
                self.solver_.requested,
                "; ".join(text for text in (self.solver_.reason, choice.reason) if text),
            )
        return simulate_record(system, record, x0, s0, solver=choice.solver)

    def predict(self, record: Record) -> FloatArray:
        """Predicted outputs for a record (N × n_y).

        With a model x0 it is used; otherwise the initial state is fitted, parameters held, to
        the first 10 % of the record (at least 20 samples), and the whole record simulated from
        it: the fit on the rest is a fair validation.
        """
        return self.simulate(record, self.validation_initial_state(record)).outputs

    def validation_initial_state(self, record: Record) -> FloatArray | None:
        """The initial state :meth:`predict` uses (None: the model's own x0)."""
        self._check_fitted()
        if not self.estimate_x0_:
            return None
        head = record.head(max(20, int(VALIDATION_HEAD_SHARE * record.n_samples)))
        system = self.model.bind(self.params_, self.free_names_, head)
        keep = np.isfinite(head.y)
        n = self.n_states_
        identity = np.eye(n)
        last: dict[bytes, Trajectory] = {}

        def simulate(x0: FloatArray) -> Trajectory | None:
            key = x0.tobytes()
            if key not in last:
                last.clear()
                where = f"the head of record {record.name}" if record.name else "a record's head"
                try:
                    last[key] = self._simulate_or_fall_back(system, head, x0, identity, where)
                except SimulationError:
                    return None
            return last[key]

        def residual(x0: FloatArray) -> FloatArray:
            out = simulate(x0)
            if out is None:
                return np.full(int(keep.sum()), 1e6)
            weighted: FloatArray = (out.outputs - head.y) / self.sigma_
            return weighted[keep]

        def jacobian(x0: FloatArray) -> FloatArray:
            out = simulate(x0)
            if out is None or out.output_sensitivity is None:
                return np.zeros((int(keep.sum()), n))
            sens: FloatArray = out.output_sensitivity / self.sigma_[None, :, None]
            return sens[keep]

        # the initial state enters linearly for a linear model: a few sensitivity steps
        start = self.model.steady_state_guess(self.params_, record)
        solution = scipy.optimize.least_squares(
            residual, start, jac=jacobian, method="trf", x_scale="jac", max_nfev=200
        )
        return np.asarray(solution.x, dtype=float)

    def score(self, record: Record) -> FloatArray:
        """NRMSE fit % per output on a record (see :meth:`predict`)."""
        return nrmse_fit_columns(record.y, self.predict(record))
