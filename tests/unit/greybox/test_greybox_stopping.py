"""Where the single-shooting fit stops: at the optimum, and at the integrator's error floor.

The fit's residuals come from an ODE solver whose error moves with φ: a few hundredths of a
standard error at its tolerance, in the directions the sensitivities span (it is a smooth error
in time, like them). Gauss–Newton steps then stop shrinking quadratically; the fit must stop
within that floor instead of iterating on it. A linear least-squares problem with such an error
added stands in for the solver: its exact solution is known, so how far the fit stops from it is
a number theory fixes.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid.greybox import ParameterSpec, Record
from fuelid.greybox import _stopping as stopping
from fuelid.greybox._fitting import Evaluation, ShootingFit
from fuelid.greybox._parameters import ParameterMap

FloatArray = NDArray[np.float64]


class LinearWithSolverError(ShootingFit):
    """Residuals A·(φ + e(φ)) − b with Jacobian A: e is the solver's error, in se along u.

    u is a direction of 1 standard error (‖A·u‖ = 1) and s = (A·u)ᵀ·A·φ the position along
    it in standard errors; e(φ) = ε·sin(ω·s)·u. Its slope ε·ω is what the sensitivities miss:
    Gauss–Newton then converges linearly at that rate near the optimum, never quadratically.
    """

    def __init__(self, a: FloatArray, b: FloatArray, error_se: float, rate: float) -> None:
        p = a.shape[1]
        self.map_ = ParameterMap(tuple(ParameterSpec(f"c{j}", 0.0) for j in range(p)))
        self.free_names_ = self.map_.free_names
        self.max_iterations = 200
        self._held_states = []
        self._work = [0, 0]
        self._work_limit = None
        self._budgets = []
        self.a, self.b = a, b
        self.u = np.linalg.solve(a.T @ a, np.ones(p))
        self.u /= np.linalg.norm(a @ self.u)
        self.error_se, self.frequency = error_se, rate / error_se if error_se else 0.0

    def _evaluate(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray, jacobian: bool
    ) -> Evaluation:
        self._work[0] += 1
        position = float((self.a @ self.u) @ (self.a @ phi))
        error = self.error_se * math.sin(self.frequency * position) * self.u
        residuals = self.a @ (phi + error) - self.b
        return Evaluation(residuals, self.a.copy() if jacobian else None, [])


def problem(
    error_se: float, rate: float = 0.0, seed: int = 0
) -> tuple[LinearWithSolverError, FloatArray]:
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(400, 3)) @ np.diag([1.0, 10.0, 100.0])  # unequal scales, as θ's are
    truth = np.array([0.3, -0.2, 0.05])
    b = a @ truth + rng.normal(size=400)
    return LinearWithSolverError(a, b, error_se, rate), np.linalg.lstsq(a, b, rcond=None)[0]


def distance_se(fit: LinearWithSolverError, phi: FloatArray, exact: FloatArray) -> float:
    return float(np.linalg.norm(fit.a @ (phi - exact)))


def test_without_solver_error_the_fit_stops_at_the_least_squares_solution() -> None:
    fit, exact = problem(0.0)
    phi, solution, _ = fit._solve(np.zeros(3), [], np.ones(1))
    assert solution.success
    # the Gauss–Newton stop: within GAUSS_NEWTON_STEP_SE = 0.005 se
    assert distance_se(fit, phi, exact) < 0.005


def test_on_the_solver_error_floor_the_fit_stops_within_it(monkeypatch: Any) -> None:
    """An error of ε = 0.12 se whose slope the Jacobian misses by 0.8 (either sign).

    The optimum of the residuals as simulated lies within ε of the exact one; the fit must stop
    within ε plus half a step on the floor (GAUSS_NEWTON_FLOOR_SE / 2): 0.2 se. And it must
    stop sooner than without the floor rule, where the steps shrink by 0.8 at best until the
    last-step threshold (0.05 se): fewer simulations over the same twenty problems, never more
    for any one.
    """
    rule = stopping.GAUSS_NEWTON_FLOOR_SE
    counts: dict[float, list[int]] = {}
    for floor in (rule, 0.0):
        monkeypatch.setattr(stopping, "GAUSS_NEWTON_FLOOR_SE", floor)
        counts[floor] = []
        for seed in range(20):
            fit, exact = problem(0.12, 0.8 if seed % 2 else -0.8, seed)
            phi, solution, _ = fit._solve(np.full(3, 5.0), [], np.ones(1))
            assert solution.success, seed
            assert distance_se(fit, phi, exact) < 0.2, (floor, seed)
            counts[floor].append(fit._work[0])
    with_rule, without = np.array(counts[rule]), np.array(counts[0.0])
    assert np.all(with_rule <= without), (with_rule, without)
    assert with_rule.sum() < without.sum(), (with_rule, without)


class LargeResidual(LinearWithSolverError):
    """r(φ) = 20·(φ + 1, λφ² + φ − 1), exact Jacobian: Gauss–Newton converges at the rate λ.

    The textbook large-residual problem (no solver error): the steps shrink by λ each, steadily,
    because the Jacobian turns under a large residual, not because the residuals are noisy.
    """

    def __init__(self, rate: float) -> None:
        super().__init__(np.ones((2, 1)), np.zeros(2), 0.0, 0.0)
        self.rate = rate

    def _evaluate(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray, jacobian: bool
    ) -> Evaluation:
        self._work[0] += 1
        x, rate = float(phi[0]), self.rate
        residuals = 20.0 * np.array([x + 1.0, rate * x * x + x - 1.0])
        slope = 20.0 * np.array([[1.0], [2.0 * rate * x + 1.0]])
        return Evaluation(residuals, slope if jacobian else None, [])


def test_a_slowly_converging_large_residual_fit_ends_at_its_optimum(monkeypatch: Any) -> None:
    """Steps shrinking by 0.8–0.95 each are the data's: summed, not stopped short.

    Without the extrapolation (GAUSS_NEWTON_FLOOR_SE 0, which turns the slow-step rules off)
    the fit stops wherever the trust region's tolerances leave it; with it, the last step is
    the rest of the geometric series, δ/(1 − ρ), and lands at the optimum within
    GAUSS_NEWTON_LAST_STEP_SE (0.05 se: the ratio's change over the last steps is second
    order). Distances in standard errors: |x − x*|·‖J(x*)‖.
    """
    rule = stopping.GAUSS_NEWTON_FLOOR_SE
    for rate, start in itertools.product((0.8, 0.9, 0.95), (1.0, 3.0)):
        # the optimum: (x + 1) + (λx² + x − 1)(2λx + 1) = 0, the real root nearest 0
        roots = np.roots([2 * rate**2, 3 * rate, 2 - rate, 0.0])
        exact = float(min(roots[np.isreal(roots)].real, key=abs))
        unit = 20.0 * math.hypot(1.0, 2.0 * rate * exact + 1.0)
        with_rule = LargeResidual(rate)
        phi, solution, _ = with_rule._solve(np.array([start]), [], np.ones(1))
        assert solution.success
        assert abs(phi[0] - exact) * unit < stopping.GAUSS_NEWTON_LAST_STEP_SE, (rate, start)
        monkeypatch.setattr(stopping, "GAUSS_NEWTON_FLOOR_SE", 0.0)
        without = LargeResidual(rate)
        without._solve(np.array([start]), [], np.ones(1))
        monkeypatch.setattr(stopping, "GAUSS_NEWTON_FLOOR_SE", rule)
        assert with_rule._work[0] <= without._work[0], (rate, with_rule._work, without._work)


class BoundedLargeResidual(LinearWithSolverError):
    """The large-residual pair in y = a + b, and 20·(a + 2b): b has an upper bound it nears.

    Along the slow direction b moves towards its bound while y converges: an extrapolated step
    would cross it (a reviewer's case).
    """

    def __init__(self, rate: float, upper: float) -> None:
        super().__init__(np.eye(3)[:, :2], np.zeros(3), 0.0, 0.0)
        specs = (ParameterSpec("a", 2.0), ParameterSpec("b", -1.0, lower=-10.0, upper=upper))
        self.map_ = ParameterMap(specs)
        self.free_names_ = self.map_.free_names
        self.rate = rate

    def _evaluate(
        self, phi: FloatArray, records: Sequence[Record], sigma: FloatArray, jacobian: bool
    ) -> Evaluation:
        self._work[0] += 1
        a, b = float(phi[0]), float(phi[1])
        y, rate = a + b, self.rate
        residuals = np.array(
            [20.0 * (y + 1.0), 20.0 * (rate * y * y + y - 1.0), 20.0 * (a + 2 * b)]
        )
        slope = np.array([[20.0, 20.0], [20.0 * (2 * rate * y + 1.0)] * 2, [20.0, 40.0]])
        return Evaluation(residuals, slope if jacobian else None, [])


def test_an_extrapolation_never_leaves_the_bounds() -> None:
    """The fit ends inside the bounds (a step beyond one is the trust region's to shorten)."""
    for rate, upper in ((0.9, -0.02), (0.9, -0.01), (0.95, -0.03)):
        fit = BoundedLargeResidual(rate, upper)
        phi, solution, _ = fit._solve(np.array([2.0, -1.0]), [], np.ones(1))
        assert solution.success, (rate, upper)
        assert phi[1] < upper, (rate, upper, phi)
