"""Output-error estimation of a nonlinear gray-box ODE model from one or several records.

The estimate minimises Σ_records Σ_outputs Σ_k ((ŷ_k(φ) − y_k)/σ_c)² by trust-region
least squares (:func:`scipy.optimize.least_squares`, ``trf``, within the bounds), with the exact
Jacobian from the forward sensitivity equations (:mod:`fuelid.greybox.sensitivity`): one
simulation per record per iteration, however many parameters. σ_c, the noise level of each output,
starts at the first-difference estimate and is re-estimated from the residuals (a second pass
when it moved): that is maximum likelihood for Gaussian white output noise of unknown level per
output, and what weighs flow against pressure when both are logged.

The covariance is the inverse Fisher information (JᵀJ)⁻¹ with J the weighted sensitivities at the
estimate: the Cramér–Rao bound, attained asymptotically by this estimator when the output noise
is white. Positive parameters are estimated as log θ, so their 95 % interval exp(log θ̂ ± 1.96σ)
is asymmetric; :meth:`GreyBoxEstimator.profile_interval` gives the profile-likelihood interval
where the Gaussian one is not to be trusted.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.optimize
import scipy.stats
from numpy.typing import NDArray

from fuelid.errors import DataError, FuelidError, NotFittedError
from fuelid.greybox.identifiability import IdentifiabilityReport, identifiability
from fuelid.greybox.parameters import ParameterMap
from fuelid.greybox.sensitivity import SimulationError, Trajectory, simulate_record
from fuelid.greybox.system import GreyBoxModel, Record

FloatArray = NDArray[np.float64]
Z95 = float(scipy.stats.norm.ppf(0.975))
CHI2_95 = float(scipy.stats.chi2.ppf(0.95, 1))
VALIDATION_HEAD_SHARE = 0.1
"""A validation record's initial state is fitted to its first 10 % (at least 20 samples)."""
COST_TOLERANCE = 1e-4
"""The solver stops when an iteration lowers ½Σ(r/σ)² by less than this (see ``_solve``)."""
MAX_NOISE_PASSES = 4
"""Fits with re-estimated noise levels, at most (several outputs only)."""
NOISE_TOLERANCE = math.log(1.05)
"""The noise levels have settled when none moved by more than 5 % in a pass."""
XTOL = 1e-7
"""The solver stops when a step changes φ by less than this relative amount: 1e-7 of a
parameter is far inside any standard error the data give (log-space parameters: relative), and
the last iterations to 1e-10 only chase the integrator's rounding with rejected trial points."""
PROFILE_DOUBLINGS = 8
"""A profile steps out 2, 4, … 256 standard errors looking for the crossing."""
SEGMENT_MIN_SAMPLES = 50
"""A segment of the segmented start holds at least this many samples."""
SEGMENT_MAX_STATES = 240
"""At most this many segment initial states (n_states × segments) are estimated at once."""
SEGMENT_SHRINK = 4
"""Each stage of the segmented start has a quarter of the last stage's segments."""
ESTIMATE_CORRELATION_LIMIT = 0.999
"""Estimates correlated beyond this are named: the data determine mostly their combination."""
SUSPECT_NOISE_RATIO = 3.0
"""A fit whose residuals are this many times the first-difference noise level of an output is
suspected of a local minimum (or model error): ``segments="auto"`` then tries a segmented start."""


class ConvergenceError(FuelidError):
    """The fit did not converge: no numbers are given."""


class NotIdentifiableError(FuelidError):
    """The data cannot determine some parameters whatever their values; ``report`` names them."""

    def __init__(self, report: IdentifiabilityReport) -> None:
        super().__init__(report.message())
        self.report = report


@dataclass
class _Evaluation:
    residuals: FloatArray
    jacobian: FloatArray | None
    trajectories: list[Trajectory]


@dataclass
class _Fit:
    """A single-shooting fit of the whole records."""

    phi: FloatArray
    solution: Any
    """scipy's least-squares result of the last noise pass."""
    evaluation: _Evaluation
    sigma: FloatArray
    """Noise level per output from the residuals."""
    iterations: int


def fit_percent(y: FloatArray, y_hat: FloatArray) -> FloatArray:
    """NRMSE fit 100·(1 − ‖y − ŷ‖/‖y − ȳ‖) per output column, over the finite samples."""
    out = []
    for column in range(y.shape[1]):
        keep = np.isfinite(y[:, column])
        error = np.linalg.norm(y[keep, column] - y_hat[keep, column])
        spread = np.linalg.norm(y[keep, column] - np.mean(y[keep, column]))
        out.append(100.0 * (1.0 - error / spread) if spread > 0.0 else math.nan)
    return np.array(out)


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


def correlation_warning(first: str, second: str, rho: float) -> str:
    """The warning for two estimates that correlate near ±1."""
    return (
        f"{first} and {second} are estimated with correlation {rho:+.4f}: the data determine "
        "mostly a combination of them, and their intervals hold only if everything held fixed "
        "(and the model itself) is right"
    )


def _stages(count: int) -> list[int]:
    """Segments per record of each stage of a segmented start: count, count/4, … above 1.

    >>> _stages(60)
    [60, 15, 3]
    """
    stages = []
    while count > 1:
        stages.append(count)
        count //= SEGMENT_SHRINK
    return stages


class GreyBoxEstimator:
    """Fit a :class:`~fuelid.greybox.system.GreyBoxModel` to records by output error.

    Parameters
    ----------
    model : GreyBoxModel
        The model (e.g. :class:`~fuelid.greybox.odemodel.OdeModel`); its parameter list says
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
        ≥ 50 samples) only when that fit did not converge or its residuals exceed 3× the noise
        level the records show; the better fit is kept. None: single shooting only.

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
    """

    def __init__(
        self,
        model: GreyBoxModel,
        initial_state: str = "auto",
        max_iterations: int = 60,
        segments: int | str | None = "auto",
    ) -> None:
        self.model = model
        self.initial_state = initial_state
        self.max_iterations = max_iterations
        self.segments = segments

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

    def _x0_names(self) -> list[str]:
        if not self.estimate_x0_:
            return []
        many = len(self.records_) > 1
        return [
            f"x0[{state}]" + (f"@{record.name or i + 1}" if many else "")
            for i, record in enumerate(self.records_)
            for state in self.model.state_names
        ]

    def _start(self) -> FloatArray:
        phi = self.map_.start()
        if not self.estimate_x0_:
            return phi
        values = self.map_.values(phi)
        guesses = [self.model.steady_state_guess(values, record) for record in self.records_]
        return np.concatenate([phi, *guesses])

    # --- one evaluation -------------------------------------------------------------------------
    def _evaluate(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray, jacobian: bool
    ) -> _Evaluation:
        """Simulate every record at φ: weighted residuals (and their Jacobian)."""
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
                )
            )
        self._work[0] += len(trajectories)
        self._work[1] += sum(trajectory.evaluations for trajectory in trajectories)
        return self._assemble(trajectories, records, sigma, jacobian)

    def _assemble(
        self,
        trajectories: list[Trajectory],
        records: Sequence[Record],
        sigma: FloatArray,
        jacobian: bool,
    ) -> _Evaluation:
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
        return _Evaluation(r, np.vstack(rows) if jacobian else None, trajectories)

    def _solve(
        self,
        phi0: FloatArray,
        records: Sequence[Record],
        sigma: FloatArray,
        hold: int | Sequence[int] | None = None,
        seed: _Evaluation | None = None,
    ) -> tuple[FloatArray, Any, _Evaluation]:
        """Least squares from phi0; ``hold`` keeps φ components fixed (profiles, initial states).

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
        clip_low, clip_high = lower[active], upper[active]
        start = np.clip(phi0[active], clip_low + 1e-12, clip_high - 1e-12)
        # evaluations by φ: the latest (for its Jacobian) and the best (the solver's answer)
        latest: dict[bytes, _Evaluation] = {}
        best: list[tuple[float, bytes, _Evaluation]] = []
        if seed is not None and np.array_equal(start, phi0[active]):
            latest[start.tobytes()] = seed

        def full(phi_active: FloatArray) -> FloatArray:
            phi = phi0.copy()
            phi[active] = phi_active
            return phi

        def remember(key: bytes, evaluation: _Evaluation) -> None:
            latest.clear()
            latest[key] = evaluation
            cost = float(evaluation.residuals @ evaluation.residuals)
            if not best or cost <= best[0][0]:
                best[:] = [(cost, key, evaluation)]

        def fun(phi_active: FloatArray) -> FloatArray:
            key = phi_active.tobytes()
            evaluation = latest.get(key)
            if evaluation is None:
                try:
                    evaluation = self._evaluate(full(phi_active), records, sigma, jacobian=True)
                except (SimulationError, FloatingPointError, OverflowError):
                    # a trial point where the ODE cannot be solved counts as a very poor fit,
                    # so the trust region shrinks back towards the last good point
                    if not best:
                        raise
                    return 1e3 * (np.abs(best[0][2].residuals) + 1.0)
            remember(key, evaluation)
            return evaluation.residuals

        def jac(phi_active: FloatArray) -> FloatArray:
            evaluation = latest.get(phi_active.tobytes())
            if evaluation is None:
                evaluation = self._evaluate(full(phi_active), records, sigma, jacobian=True)
            if evaluation.jacobian is None:
                raise FuelidError("internal: an evaluation without its Jacobian")
            return evaluation.jacobian[:, active]

        # Stop when an iteration lowers the weighted cost ½Σr² by less than COST_TOLERANCE
        # (at the optimum ½Σr² ≈ m/2): the step then moves φ by ~0.01 standard errors, and
        # further iterations would chase the integrator's rounding rather than the data.
        n_residuals = (
            len(seed.residuals)
            if seed is not None
            else sum(int(np.isfinite(record.y).sum()) for record in records)
        )
        ftol = min(1e-6, max(1e-12, COST_TOLERANCE / (0.5 * max(n_residuals, 1))))
        solution = scipy.optimize.least_squares(
            fun,
            start,
            jac=jac,
            bounds=(clip_low, clip_high),
            method="trf",
            x_scale="jac",
            xtol=XTOL,
            ftol=ftol,
            gtol=1e-10,
            max_nfev=self.max_iterations,
        )
        key = np.asarray(solution.x, dtype=float).tobytes()
        found = latest.get(key)
        if found is None and best and best[0][1] == key:
            found = best[0][2]
        if found is None:
            found = self._evaluate(full(solution.x), records, sigma, jacobian=True)
        return full(solution.x), solution, found

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
        try:
            evaluation = self._evaluate(phi, records, sigma, jacobian=True)
        except (SimulationError, FloatingPointError, OverflowError) as exc:
            raise ConvergenceError(
                f"the model cannot be simulated at the start values ({exc})"
            ) from None
        # a trial point may cost 20× the start's work (chattering at a bound), not more
        self._budgets = [max(20 * t.evaluations, 50_000) for t in evaluation.trajectories]
        if self.estimate_x0_:
            phi, evaluation = self._settle_initial_states(phi, records, sigma, evaluation)
        self._refuse_structural(phi, evaluation)
        start_phi, start_sigma, start_evaluation = phi, sigma, evaluation
        self.start_ = "single shooting"
        if self.segments not in (None, "auto"):
            phi = self._segmented_start(phi, records, sigma, evaluation, int(self.segments))
            evaluation = self._evaluate(phi, records, sigma, jacobian=True)
        failure: ConvergenceError | None = None
        try:
            result = self._single_shooting(phi, records, sigma, evaluation)
        except ConvergenceError as exc:
            if self.segments != "auto":
                raise
            failure, result = exc, None
        if self.segments == "auto" and (result is None or self._suspect(result, self.noise_floor_)):
            retried = self._retry_segmented(
                start_phi, records, start_sigma, start_evaluation, result
            )
            if retried is not None:
                result = retried
        if result is None:
            assert failure is not None
            raise failure
        self.phi_ = result.phi
        self.sigma_ = result.sigma
        self._finish(result.phi, records, result.solution, result.evaluation)
        self.n_iterations_ = result.iterations
        return self

    def _settle_initial_states(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray, start: _Evaluation
    ) -> tuple[FloatArray, _Evaluation]:
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

    def _single_shooting(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray, evaluation: _Evaluation
    ) -> _Fit:
        """Fit the whole records from φ, re-estimating the noise levels between passes.

        Returns φ̂, the solver's result, the evaluation at φ̂, the noise levels and the iterations.
        """
        iterations = 0
        try:
            for _ in range(MAX_NOISE_PASSES):
                phi, solution, evaluation = self._solve(phi, records, sigma, seed=evaluation)
                iterations += int(solution.njev if solution.njev is not None else solution.nfev)
                residual_sigma = self._residual_sigma(evaluation, records, len(phi))
                moved = np.abs(np.log(residual_sigma / sigma))
                sigma = residual_sigma
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
        return _Fit(phi, solution, evaluation, sigma, iterations)

    @staticmethod
    def _suspect(result: _Fit, floor: FloatArray) -> bool:
        """Residuals far above the noise the records show: a local minimum, or a wrong model."""
        return bool(np.any(result.sigma > SUSPECT_NOISE_RATIO * floor))

    def _retry_segmented(
        self,
        phi: FloatArray,
        records: Sequence[Record],
        sigma: FloatArray,
        evaluation: _Evaluation,
        first: _Fit | None,
    ) -> _Fit | None:
        """Fit again from a segmented start; the better of the two fits (None: no better one)."""
        count = self._segment_count(records)
        if count < 2:
            return None
        try:
            phi = self._segmented_start(phi, records, sigma, evaluation, count)
            evaluation = self._evaluate(phi, records, sigma, jacobian=True)
            second = self._single_shooting(phi, records, sigma, evaluation)
        except (ConvergenceError, SimulationError, FloatingPointError, OverflowError):
            if first is not None:
                self.start_ = "single shooting (a segmented start did not converge)"
            return None
        # compare the fits by their likelihood: Σ log σ_c² over the outputs' samples
        if first is not None and self._log_likelihood_cost(
            first, records
        ) <= self._log_likelihood_cost(second, records):
            self.start_ = "single shooting (a segmented start found no better fit)"
            return None
        return second

    @staticmethod
    def _log_likelihood_cost(result: _Fit, records: Sequence[Record]) -> float:
        counts = np.sum([np.isfinite(record.y).sum(axis=0) for record in records], axis=0)
        return float(np.sum(counts * np.log(result.sigma**2)))

    def _segment_count(self, records: Sequence[Record]) -> int:
        """Segments per record of the first stage: ≥ SEGMENT_MIN_SAMPLES samples each."""
        shortest = min(len(record.t) for record in records)
        by_states = SEGMENT_MAX_STATES // max(self.n_states_ * len(records), 1)
        return int(min(shortest // SEGMENT_MIN_SAMPLES, by_states))

    def _segmented_start(
        self,
        phi: FloatArray,
        records: Sequence[Record],
        sigma: FloatArray,
        evaluation: _Evaluation,
        count: int,
    ) -> FloatArray:
        """Start values from the records cut into segments, each with its own initial state.

        Multiple shooting without the continuity constraints: over a short segment a wrong
        parameter cannot drift the prediction far (an oscillator's phase, say), so the fit is
        nearly convex; each stage has a quarter of the last one's segments (their initial states
        taken from the last stage's trajectories), down to one. The whole records are then fitted
        from the result by :meth:`_single_shooting`, which alone gives the estimate.
        """
        p = len(self.free_names_)
        n = self.n_states_
        theta_phi = phi[:p]
        states = [trajectory.states.copy() for trajectory in evaluation.trajectories]
        saved = (self.estimate_x0_, self._budgets)
        self.estimate_x0_ = True
        self.start_ = (
            "segmented start ("
            + ", ".join(str(c) for c in _stages(count))
            + " segments per record)"
        )
        try:
            for stage in _stages(count):
                pieces, spans, guesses = [], [], []
                for i, record in enumerate(records):
                    edges = np.linspace(0, len(record.t), stage + 1).round().astype(int)
                    for a, b in itertools.pairwise(edges):
                        if np.isfinite(record.y[a:b]).sum() <= n:
                            continue  # nothing to fit there: its states stay as they were
                        pieces.append(
                            Record(record.t[a:b], record.u[a:b], record.y[a:b], "", record.context)
                        )
                        spans.append((i, a, b))
                        guesses.append(states[i][a])
                if not pieces:
                    break
                self._budgets = [
                    max(saved[1][i] * (b - a) // len(records[i].t), 50_000) for i, a, b in spans
                ]
                phi_stage = np.concatenate([theta_phi, *guesses])
                try:
                    phi_stage, _, found = self._solve(phi_stage, pieces, sigma)
                except (SimulationError, FloatingPointError, OverflowError):
                    break  # keep the last stage's values
                theta_phi = phi_stage[:p]
                for (i, a, b), trajectory in zip(spans, found.trajectories, strict=True):
                    states[i][a:b] = trajectory.states
        finally:
            self.estimate_x0_, self._budgets = saved
        if not self.estimate_x0_:
            return theta_phi
        return np.concatenate([theta_phi, *[s[0] for s in states]])

    def _structural(
        self, phi: FloatArray, start: _Evaluation
    ) -> tuple[IdentifiabilityReport, list[Any]]:
        """The identifiability report at φ and its combinations no data of this kind determine."""
        assert start.jacobian is not None
        report = self._report(phi, start.jacobian)
        return report, [c for c in report.undetermined if not np.isfinite(c.uncertainty)]

    def _refuse_structural(self, phi: FloatArray, start: _Evaluation) -> None:
        """Refuse before fitting when the parameters cannot be determined whatever the values.

        A combination whose sensitivity vanishes at the start values to rounding (a scale the
        outputs cannot see, a parameter they do not depend on) is not determined by any data of
        this kind: fitting would only wander along it.
        """
        report, structural = self._structural(phi, start)
        if structural or report.zero_sensitivity:
            advice = []
            for combination in structural:
                parameters = [n for n in combination.names if n in self.free_names_]
                if parameters:
                    advice.append(
                        f"no data of this kind determine {', '.join(parameters)} together: fix "
                        f"one of them (e.g. {parameters[0]}) at a known value"
                    )
            if report.zero_sensitivity:
                advice.append(f"fix {', '.join(report.zero_sensitivity)} or drop it from the model")
            structural_report = IdentifiabilityReport(
                report.names,
                report.singular_values,
                report.rank,
                report.condition_number,
                report.collinearity_index,
                tuple(structural),
                (),
                report.zero_sensitivity,
            )
            raise NotIdentifiableError(structural_report.with_advice(advice))

    def _report(self, phi: FloatArray, jac: FloatArray) -> IdentifiabilityReport:
        p = len(self.free_names_)
        names = [*self.free_names_, *self._x0_names()]
        theta = self.map_.to_theta(phi[:p])
        column_scale = np.concatenate(
            [
                # a parameter at 0 (an offset, say) has no size of its own: unit scale
                np.where(self.map_.log_mask, 1.0, np.where(theta != 0.0, np.abs(theta), 1.0)),
                np.maximum(np.abs(phi[p:]), self.state_scale_),
            ]
        )
        return identifiability(jac, names, column_scale, report_only=self.free_names_)

    @staticmethod
    def _residual_sigma(
        evaluation: _Evaluation, records: Sequence[Record], n_estimated: int
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

    def _finish(
        self, phi: FloatArray, records: Sequence[Record], solution: Any, evaluation: _Evaluation
    ) -> None:
        p = len(self.free_names_)
        jac = evaluation.jacobian
        if jac is None:
            raise FuelidError("internal: the final evaluation has no Jacobian")
        self.sensitivities_ = jac
        self.identifiability_: IdentifiabilityReport = self._report(phi, jac)
        information = jac.T @ jac
        cov_phi = np.linalg.pinv(information, rcond=1e-12, hermitian=True)
        self.cov_phi_ = cov_phi
        theta = self.map_.to_theta(phi[:p])
        scale = self.map_.dtheta_dphi(phi[:p])
        cov = cov_phi[:p, :p] * np.outer(scale, scale)
        self.cov_ = cov
        stderr_phi = np.sqrt(np.clip(np.diag(cov_phi[:p, :p]), 0.0, None))
        with np.errstate(invalid="ignore", divide="ignore"):
            sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
            self.correlation_ = cov / np.outer(sd, sd)
        # no interval for a parameter in an undetermined combination; a confounded pair keeps
        # its (wide) intervals and is warned about
        unknown = {
            name for combination in self.identifiability_.undetermined for name in combination.names
        } | set(self.identifiability_.zero_sensitivity)
        self.params_ = self.map_.values(phi[:p])
        self.stderr_: dict[str, float | None] = {spec.name: None for spec in self.map_.specs}
        self.ci95_: dict[str, tuple[float, float] | None] = {
            spec.name: None for spec in self.map_.specs
        }
        log_mask = self.map_.log_mask
        for j, name in enumerate(self.free_names_):
            if name in unknown:
                continue
            self.stderr_[name] = float(sd[j])
            if log_mask[j]:
                self.ci95_[name] = (
                    float(theta[j] * math.exp(-Z95 * stderr_phi[j])),
                    float(theta[j] * math.exp(Z95 * stderr_phi[j])),
                )
            else:
                # clipped to the parameter's bounds: the estimate cannot lie beyond them
                spec = self.map_.free[j]
                low = float(theta[j] - Z95 * sd[j])
                high = float(theta[j] + Z95 * sd[j])
                self.ci95_[name] = (
                    low if spec.lower is None else max(low, spec.lower),
                    high if spec.upper is None else min(high, spec.upper),
                )
        n = self.n_states_
        if self.estimate_x0_:
            self.x0_ = [phi[p + i * n : p + (i + 1) * n].copy() for i in range(len(records))]
        else:
            self.x0_ = [t.states[0].copy() for t in evaluation.trajectories]
        self.trajectories_ = evaluation.trajectories
        self.fit_percent_ = [
            fit_percent(record.y, t.outputs)
            for record, t in zip(records, evaluation.trajectories, strict=True)
        ]
        self.cost_ = float(np.sum(evaluation.residuals**2))
        self.n_residuals_ = len(evaluation.residuals)
        self.n_simulations_ = self._work[0]
        self.n_evaluations_ = self._work[1]

    def _check_fitted(self) -> None:
        if not hasattr(self, "params_"):
            raise NotFittedError("fit the estimator first")

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
        return simulate_record(system, record, np.asarray(x0, dtype=float))

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
                try:
                    last[key] = simulate_record(system, head, x0, identity)
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

    def correlated_pairs(
        self, limit: float = ESTIMATE_CORRELATION_LIMIT
    ) -> list[tuple[str, str, float]]:
        """Pairs of free parameters whose estimates correlate beyond ``limit`` (name, name, ρ).

        Pairs the identifiability report already names as confounded are left out. Three or more
        parameters can trade against each other with no pair of sensitivities
        alike (the identifiability report's confounded pairs); their estimates then still
        correlate near ±1, and each interval holds only if the model is exactly right.
        """
        self._check_fitted()
        named = {frozenset(pair[:2]) for pair in self.identifiability_.confounded_pairs}
        names = self.free_names_
        pairs = []
        for i in range(len(names)):
            for j in range(i + 1, len(names)):
                rho = float(self.correlation_[i, j])
                if (
                    math.isfinite(rho)
                    and abs(rho) > limit
                    and frozenset((names[i], names[j])) not in named
                ):
                    pairs.append((names[i], names[j], rho))
        return pairs

    def score(self, record: Record) -> FloatArray:
        """NRMSE fit % per output on a record (see :meth:`predict`)."""
        return fit_percent(record.y, self.predict(record))

    def profile_interval(self, name: str, level: float = 0.95) -> tuple[float, float]:
        """Profile-likelihood interval of one free parameter.

        The parameter is held at trial values and the others (and initial states) re-fitted;
        the interval is where the weighted cost rises by the χ²₁ quantile over its minimum.
        Each side is bracketed by stepping out and then found by Brent's method.
        """
        self._check_fitted()
        if name not in self.free_names_:
            raise FuelidError(f"{name!r} is not a free parameter: {', '.join(self.free_names_)}")
        j = self.free_names_.index(name)
        threshold = float(scipy.stats.chi2.ppf(level, 1))
        lower, upper = self.map_.bounds()
        sd = math.sqrt(max(float(self.cov_phi_[j, j]), 1e-30))
        best = self.cost_
        # refits by offset: each new one starts from the nearest (a warm start), and Brent's
        # method re-asks for the bracket's ends at no cost
        refits: dict[float, tuple[float, FloatArray]] = {0.0: (-threshold, self.phi_)}

        def excess(offset: float) -> float:
            if offset in refits:
                return refits[offset][0]
            nearest = min(refits, key=lambda known: abs(known - offset))
            phi = refits[nearest][1].copy()
            phi[j] = self.phi_[j] + offset
            try:
                refit_phi, _, refit = self._solve(phi, self.records_, self.sigma_, hold=j)
                value = float(refit.residuals @ refit.residuals) - best - threshold
            except (SimulationError, FloatingPointError, OverflowError):
                return math.inf
            refits[offset] = (value, refit_phi)
            return value

        ends = []
        for direction in (-1.0, 1.0):
            bound = lower[j] if direction < 0 else upper[j]
            # the farthest offset inside the bound (a hair inside, where the model is defined)
            room = direction * (bound - self.phi_[j]) if math.isfinite(bound) else math.inf
            step = 2.0 * sd
            inner = 0.0
            end = math.nan
            for _ in range(PROFILE_DOUBLINGS):
                at_bound = step >= room * (1.0 - 1e-9)
                offset = direction * (room * (1.0 - 1e-9) if at_bound else step)
                if offset == inner:
                    end = bound
                    break
                if excess(offset) > 0.0:
                    root = scipy.optimize.brentq(
                        lambda o: min(excess(o), 1e6), inner, offset, xtol=0.02 * sd
                    )
                    end = self.phi_[j] + root
                    break
                if at_bound:
                    end = bound  # the cost never rises enough before the bound
                    break
                inner = offset
                step *= 2.0
            else:
                end = -math.inf if direction < 0 else math.inf
            ends.append(end)
        if self.map_.log_mask[j]:
            # exp(−inf) = 0: a side without a crossing reaches the positivity bound
            return math.exp(ends[0]), math.exp(ends[1])
        return ends[0], ends[1]
