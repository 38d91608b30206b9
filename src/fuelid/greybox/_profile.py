"""What the data determine at a gray-box estimate: identifiability, correlations, profiles.

:class:`ProfileLikelihood` gives :class:`~fuelid.greybox._estimator.GreyBoxEstimator` its
identifiability report from the weighted sensitivities (:mod:`fuelid.greybox._identifiability`),
the refusal to fit parameters no data of this kind determine, the pairs of estimates correlated
near ±1, and the profile-likelihood interval of a parameter where the Gaussian one (from the
covariance, :mod:`fuelid.greybox._fitting`) is not to be trusted.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import scipy.optimize
import scipy.special

from fuelid.errors import FuelidError
from fuelid.greybox._fitting import Evaluation, FloatArray, ShootingFit, ShootingResult
from fuelid.greybox._identifiability import (
    ESTIMATE_CORRELATION_LIMIT,
    IdentifiabilityReport,
    NotIdentifiableError,
    UndeterminedCombination,
    identifiability,
    structural_report,
)
from fuelid.greybox._parameters import ParameterMap
from fuelid.greybox._solvers import SimulationError
from fuelid.greybox._system import Record

CHI2_95 = float(scipy.special.chdtri(1, 0.05))
"""χ²₁'s 95 % quantile."""
IDLE_STATE_LIMIT = 10.0
"""An estimated initial state in a combination of initial states whose standard deviation
exceeds ten times the states' size (or that no data of this kind determine) is held."""
LINEARITY_LIMIT = 0.2
"""A sensitivity that misses the simulated change over one standard error by more than this share
makes the parameter's Gaussian interval untrustworthy (:meth:`ProfileLikelihood._linearity`)."""
EVIDENCE_STEP = 0.1
"""A combination the sensitivities say no data determine is checked by simulating the model a
step of ±0.1 along it (relative units: 10 % of each parameter, or of each state's size)."""
PROFILE_DOUBLINGS = 8
"""A profile steps out 2, 4, … 256 standard errors looking for the crossing."""


class ProfileLikelihood(ShootingFit):
    """Identifiability and profile likelihood of :class:`GreyBoxEstimator`'s parameters."""

    state_scale_: float
    records_: list[Record]
    phi_: FloatArray
    sigma_: FloatArray
    cov_phi_: FloatArray
    correlation_: FloatArray
    cost_: float
    identifiability_: IdentifiabilityReport
    not_determined_: dict[str, str]
    stderr_: dict[str, float | None]
    hold_undetermined: bool
    _all_free: ParameterMap

    def _structural(
        self, phi: FloatArray, start: Evaluation
    ) -> tuple[IdentifiabilityReport, list[UndeterminedCombination]]:
        """The identifiability report at φ and its combinations no data of this kind determine."""
        assert start.jacobian is not None
        report = self._report(phi, start.jacobian)
        return report, [c for c in report.undetermined if not np.isfinite(c.uncertainty)]

    def _refuse_structural(
        self, phi: FloatArray, start: Evaluation, records: Sequence[Record], sigma: FloatArray
    ) -> None:
        """Refuse before fitting when the parameters cannot be determined whatever the values.

        A combination whose sensitivity vanishes at the start values to rounding (a scale the
        outputs cannot see, a parameter they do not depend on) is not determined by any data of
        this kind: fitting would only wander along it. The sensitivities' claim is checked by
        simulation (:meth:`_unconfirmed`): a combination along which the simulated fit does
        change is a point where the sensitivities miss a switch or a clip, not a property of the
        model, and is left for the fit's end point to judge.
        """
        report, structural = self._structural(phi, start)
        rises = self._simulated_rises(phi, records, sigma, start, structural)
        confirmed = [c for c in structural if rises[c.names] <= CHI2_95]
        if confirmed or report.zero_sensitivity:
            evidence = {c.names: rises[c.names] for c in confirmed}
            # a quantity without sensitivity that the simulation does depend on is hidden by a
            # switch: the refusal says so instead of blaming the records
            alone = [
                UndeterminedCombination((n,), (1.0,), math.inf) for n in report.zero_sensitivity
            ]
            moved = self._simulated_rises(phi, records, sigma, start, alone)
            hidden = {n[0]: rise for n, rise in moved.items() if not rise <= CHI2_95}
            raise NotIdentifiableError(
                structural_report(
                    report, confirmed, self.free_names_, "the start values", evidence, hidden
                )
            )

    def _simulated_rises(
        self,
        phi: FloatArray,
        records: Sequence[Record],
        sigma: FloatArray,
        evaluation: Evaluation,
        combinations: Sequence[UndeterminedCombination],
    ) -> dict[tuple[str, ...], float]:
        """Per combination, the largest rise of the simulated weighted cost a step along it makes.

        Each is stepped ±EVIDENCE_STEP along its direction (within the bounds) and simulated
        without sensitivities: where the cost rises by more than χ²₁'s 95 % quantile either way,
        the data do determine it, and the sensitivities that said otherwise are wrong here (a
        switch or a clip they do not follow). A step that cannot be simulated counts as a
        change (inf).
        """
        names, scale = self._report_columns(phi)
        lower, upper = self.map_.bounds()
        p = len(self.free_names_)
        cost = float(evaluation.residuals @ evaluation.residuals)
        out: dict[tuple[str, ...], float] = {}
        for combination in combinations:
            direction = np.zeros(len(phi))
            for name, weight in zip(combination.names, combination.weights, strict=True):
                j = names[name]
                direction[j] = EVIDENCE_STEP * weight * scale[j]
            rise = 0.0
            for sign in (1.0, -1.0):
                trial = phi + sign * direction
                if np.any(trial[:p] <= lower) or np.any(trial[:p] >= upper):
                    continue
                try:
                    moved = self._evaluate(trial, records, sigma, jacobian=False).residuals
                    rise = max(rise, float(moved @ moved) - cost)
                except (SimulationError, FloatingPointError, OverflowError):
                    rise = math.inf
            out[combination.names] = rise
        return out

    # --- parameters the outputs do not depend on (hold_undetermined) ----------------------------
    def _hold_unused(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray, start: Evaluation
    ) -> tuple[FloatArray, Evaluation]:
        """Hold the free parameters the outputs do not depend on at all, at their values.

        Such a parameter acts only where the records never go (beyond a limit, a kink or a
        switch): no value of it changes the fit, so it is reported as not determined and held,
        and the rest are fitted. Returns φ without those parameters and the evaluation there.
        """
        if not self.hold_undetermined:
            return phi, start
        report, structural = self._structural(phi, start)
        p = len(self.free_names_)
        alone = [c.names[0] for c in structural if len(c.names) == 1]
        unused = [
            name for name in self.free_names_ if name in report.zero_sensitivity or name in alone
        ]
        if not unused:
            return phi, start
        values = self.map_.values(phi[:p])
        for name in unused:
            self.not_determined_[name] = (
                "the outputs do not depend on it over these records at the start values (it acts "
                "only beyond a limit, kink or switch the simulation does not reach from there); "
                f"held at {values[name]:.6g}, not estimated"
            )
        keep = [j for j, name in enumerate(self.free_names_) if name not in unused]
        self._all_free = self.map_
        self._use_map(self._held_map(set(unused)))
        phi = np.concatenate([phi[:p][keep], phi[p:]])
        # the held states' indices move with the parameters before them
        self._held_states = [k - len(unused) for k in self._held_states]
        return phi, self._evaluate(phi, records, sigma, jacobian=True)

    def _hold_idle_states(self, phi: FloatArray, start: Evaluation) -> None:
        """Hold the estimated initial states the outputs do not depend on, where they start.

        An initial state no output depends on, or one that only trades against another (a fast
        mode's initial value, whose effect is gone before the first samples but for what it
        moved into a slow state), is a nuisance the data cannot fix: it is held at its start
        (the steady state at the first input) and listed in ``not_determined_``.
        """
        report, _ = self._structural(phi, start)
        p = len(self.free_names_)
        x0_names = self._x0_names()
        assert start.jacobian is not None
        norms = np.linalg.norm(start.jacobian[:, p:], axis=0)
        held: list[str] = [name for name in x0_names if name in report.zero_sensitivity]
        # an undetermined combination of initial states alone (a fast mode's initial value
        # trading against a slow state's, say): all but its best-seen member are nuisances
        for combination in report.undetermined:
            # what no data of this kind determine, or only to ten times the states' size
            if combination.uncertainty <= IDLE_STATE_LIMIT:
                continue
            if not all(name in x0_names for name in combination.names):
                continue
            # greedy: one direction at a time, keeping its best-seen member not yet held
            left = [name for name in combination.names if name not in held]
            ranked = sorted(left, key=lambda n: -norms[x0_names.index(n)])
            held.extend(ranked[1:] if len(combination.names) > 1 else ranked)
        for name in dict.fromkeys(held):
            k = x0_names.index(name)
            if p + k in self._held_states:
                continue
            self._held_states.append(p + k)
            self.not_determined_[name] = (
                "the outputs do not depend on this initial state apart from others (its mode "
                "settles before the first samples, or it is never seen): held at the value "
                f"the fit started from, {phi[p + k]:.6g}"
            )

    def _held_map(self, held: set[str]) -> ParameterMap:
        """The map of every free parameter with ``held`` ones fixed at their start values."""
        return ParameterMap(
            tuple(
                replace(spec, fixed=True) if spec.name in held else spec
                for spec in self._all_free.specs
            )
        )

    def _use_map(self, parameter_map: ParameterMap) -> None:
        self.map_ = parameter_map
        self.free_names_ = parameter_map.free_names

    def _release_held(self, result: ShootingResult, records: Sequence[Record]) -> ShootingResult:
        """Free again a held parameter that acts at the estimate, and refit from there.

        The outputs may not depend on a parameter at the start values yet depend on it at the
        estimate (a level that reaches its rim only with the fitted outflows, say): holding it
        would then bias the others without a word.
        """
        full = self._all_free
        held = [name for name in self.not_determined_ if name in full.free_names]
        p = len(self.free_names_)
        values = self.map_.values(result.phi[:p])
        phi_full = np.concatenate(
            [full.to_phi(np.array([values[name] for name in full.free_names])), result.phi[p:]]
        )
        current, held_states = self.map_, self._held_states
        self._use_map(full)
        shift = len(full.free_names) - p
        self._held_states = [k + shift for k in held_states]
        evaluation = self._evaluate_or_fall_back(phi_full, records, result.sigma, "the estimate")
        assert evaluation.jacobian is not None
        report = self._report(phi_full, evaluation.jacobian)
        alone = {
            c.names[0] for c in report.undetermined if len(c.names) == 1 and np.isinf(c.uncertainty)
        }
        idle = set(report.zero_sensitivity) | alone
        acting = [name for name in held if name not in idle]
        if not acting:
            self._use_map(current)
            self._held_states = held_states
            return result
        # this point is where the held fit ended, not where the fit will: a free parameter the
        # outputs stop depending on here (its limit left behind) is held for the refit, not
        # refused; what the data determine is judged at the refit's estimate (_finish)
        newly = [name for name in full.free_names if name in idle and name not in held]
        for name in newly:
            self.not_determined_[name] = (
                "the outputs do not depend on it where the fit ended with the others held (it "
                "acts only beyond a limit, kink or switch the simulation does not reach from "
                f"there); held at {values[name]:.6g}, not estimated"
            )
        still = {name for name in held if name not in acting} | set(newly)
        for name in acting:
            del self.not_determined_[name]
        self._use_map(self._held_map(still))
        self._held_states = [k - len(still) for k in self._held_states]
        keep = [j for j, name in enumerate(full.free_names) if name not in still]
        phi = np.concatenate(
            [phi_full[: len(full.free_names)][keep], phi_full[len(full.free_names) :]]
        )
        evaluation = self._evaluate_or_fall_back(phi, records, result.sigma, "the estimate")
        refit = self._single_shooting(phi, records, result.sigma, evaluation)
        refit.iterations += result.iterations
        return refit

    def _linearity(
        self,
        phi: FloatArray,
        records: Sequence[Record],
        evaluation: Evaluation,
        unknown: set[str],
    ) -> dict[str, float | None]:
        """Per free parameter: ‖Δr − J·Δφ‖/‖J·Δφ‖ for a step of one standard error in it.

        Δr is the change of the simulated residuals (one simulation without sensitivities),
        J·Δφ what the sensitivities predict. Where the model is smooth and the parameter well
        determined this is its curvature over one standard error, small when the Gaussian
        interval holds; where a switch (an ``if`` that makes the right-hand side jump) moves
        with the parameter, the sensitivity equations miss it and the covariance with them.
        The step goes up, or down where up would leave the bounds. None: not checked (no
        standard error, or a step of one standard error leaves the bounds both ways).
        """
        out: dict[str, float | None] = {}
        assert evaluation.jacobian is not None
        lower, upper = self.map_.bounds()
        sigma = self.sigma_ if "sigma_" in vars(self) else np.ones(1)
        for j, name in enumerate(self.free_names_):
            out[name] = None
            step = math.sqrt(max(float(self.cov_phi_[j, j]), 0.0))
            if name in unknown or step == 0.0:
                continue
            if phi[j] + step >= upper[j]:
                step = -step
            if not lower[j] < phi[j] + step < upper[j]:
                continue
            trial = phi.copy()
            trial[j] += step
            try:
                moved = self._evaluate(trial, records, sigma, jacobian=False).residuals
            except (SimulationError, FloatingPointError, OverflowError):
                out[name] = math.inf
                continue
            predicted = evaluation.jacobian[:, j] * step
            size = float(np.linalg.norm(predicted))
            if size > 0.0:
                actual = moved - evaluation.residuals
                out[name] = float(np.linalg.norm(actual - predicted)) / size
        return out

    def _report_columns(self, phi: FloatArray) -> tuple[dict[str, int], FloatArray]:
        """Each estimated quantity's index in φ, and the scale that makes its column relative."""
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
        return {name: j for j, name in enumerate(names)}, column_scale

    def _report(self, phi: FloatArray, jac: FloatArray) -> IdentifiabilityReport:
        index, column_scale = self._report_columns(phi)
        names = list(index)
        # held initial states are not estimated: not part of what the data must determine
        kept = [j for j in range(len(names)) if j not in set(self._held_states)]
        return identifiability(
            jac[:, kept],
            [names[j] for j in kept],
            column_scale[kept],
            report_only=self.free_names_,
        )

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
                    # no standard error: the report says why, a correlation would add nothing
                    and self.stderr_.get(names[i]) is not None
                    and self.stderr_.get(names[j]) is not None
                    and frozenset((names[i], names[j])) not in named
                ):
                    pairs.append((names[i], names[j], rho))
        return pairs

    def profile_interval(self, name: str, level: float = 0.95) -> tuple[float, float]:
        """Profile-likelihood interval of one free parameter.

        The parameter is held at trial values and the others (and initial states) re-fitted;
        the interval is where the weighted cost rises by the χ²₁ quantile over its minimum.
        Each side is bracketed by stepping out and then found by Brent's method.
        """
        self._check_fitted()
        if name in self.not_determined_:
            raise FuelidError(f"{name!r} was held as not determined: {self.not_determined_[name]}")
        if name not in self.free_names_:
            raise FuelidError(f"{name!r} is not a free parameter: {', '.join(self.free_names_)}")
        j = self.free_names_.index(name)
        threshold = float(scipy.special.chdtri(1, 1.0 - level))
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
