"""Simulate a record and its forward sensitivities in one integration.

With S = ∂x/∂φ (φ the optimiser's parameters: the free θ, in log space where positive, then the
estimated initial state) the forward sensitivity equations are

    dS/dt = ∂f/∂x · S + [∂f/∂θ · diag(∂θ/∂φ) | 0],     S(t0) = [∂x0/∂θ · diag(∂θ/∂φ) | I or 0]

integrated together with the state, so one simulation gives the output and its whole Jacobian
∂y/∂φ = ∂y/∂x · S + ∂y/∂φ|direct, instead of one simulation per parameter. The inputs are held
between samples, so the span is integrated piece by piece between input changes with the chosen
solver (:mod:`fuelid.greybox._solvers`; LSODA by default, which turns to BDF when fast modes make
the problem stiff); the implicit methods' Newton matrix is block-diagonal, ∂f/∂x for the state
and ∂f/∂x ⊗ I for the row-major S (the exact Jacobian of the sensitivity rows also has ∂²f/∂x²
terms, which only speed the corrector up and do not change the solution).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import FuelidError
from fuelid.greybox._solvers import RTOL, Newton, Rhs, SimulationError, Solver, integrate_piece
from fuelid.greybox._switching import UnlocatedSwitches, switched_integrator
from fuelid.greybox._system import OdeSystem, Record

__all__ = ["RTOL", "SimulationError", "Solver", "Trajectory", "input_changes", "simulate_record"]

FloatArray = NDArray[np.float64]
SENSITIVITY_ATOL_FACTOR = 1e3
"""Absolute tolerance of a sensitivity row over its state's (per unit of log θ or of θ)."""
SENSITIVITY_RTOL_FACTOR = 100.0
"""Relative tolerance of the sensitivity rows over the state's: 1e-4 at the default 1e-6. The
error control is there to keep them stable, not to make them exact: a standard error off by
1e-4 of itself, or a Gauss–Newton step by 1e-4 of its length, changes nothing the fit reports
(measured on the kinked benchmark model: standard errors within 3e-4 of a finite difference of
1e-10 simulations, as at the state's tolerance), and LSODA takes 40 % fewer steps."""
DEFAULT_SOLVER = Solver()


@dataclass(frozen=True)
class Trajectory:
    """States, outputs and their sensitivities at a record's output times."""

    states: FloatArray
    """x at t_k − output_delay (the first output's delay when outputs have their own), (N, n)."""
    outputs: FloatArray
    """Predicted y, shape (N, n_y)."""
    output_sensitivity: FloatArray | None
    """∂y/∂φ, shape (N, n_y, q); None when not asked for."""
    evaluations: int = 0
    """Right-hand-side evaluations the solver used."""


def input_changes(u: FloatArray) -> NDArray[np.intp]:
    """Indices where a held input starts: 0 and every sample whose input differs from the last."""
    changed = np.any(u[1:] != u[:-1], axis=1)
    return np.concatenate(([0], np.flatnonzero(changed) + 1))


def simulate_record(
    system: OdeSystem,
    record: Record,
    x0: FloatArray,
    s0: FloatArray | None = None,
    theta_scale: FloatArray | None = None,
    max_evaluations: int | None = None,
    rtol: float | None = None,
    solver: Solver = DEFAULT_SOLVER,
) -> Trajectory:
    """Integrate ``system`` over ``record`` from ``x0`` (with sensitivities when ``s0`` is given).

    Parameters
    ----------
    system : OdeSystem
        The model bound to θ and this record.
    record : Record
        Times and held inputs (its outputs are not read).
    x0 : ndarray, shape (n,)
        State at the first sample time (and before it, for a delayed output).
    s0 : ndarray, shape (n, q), optional
        ∂x0/∂φ; its first p columns belong to θ (scaled by ``theta_scale``), the rest to the
        estimated initial state. None: no sensitivities.
    theta_scale : ndarray, shape (p,), optional
        ∂θ/∂φ for the free parameters (θ for those in log space, 1 otherwise).
    max_evaluations : int, optional
        Give up (SimulationError) after this many right-hand-side evaluations: a trial point
        where the solution chatters (a tank running dry under √x, say) costs no more than this.
    rtol : float, optional
        Relative tolerance on the state (the absolute one is ``system.atol``); default the
        solver's. The sensitivities have :data:`SENSITIVITY_RTOL_FACTOR` times it.
    solver : Solver
        The method (:mod:`fuelid.greybox._solvers`); LSODA by default.

    Returns
    -------
    Trajectory

    Raises
    ------
    SimulationError
        If the solver fails or the state becomes non-finite.
    """
    layout = _Layout.of(system.n_states, s0, theta_scale)
    t, u = record.t, record.u
    # each distinct output delay reads the state at its own times: integrate to all of them
    delays = np.atleast_1d(np.asarray(system.output_delay, dtype=float))
    distinct = np.unique(delays)
    eval_times, inverse = _output_times(t, distinct)
    z0 = np.concatenate([x0, (s0 if s0 is not None else np.zeros((layout.n, 0))).ravel()])
    atol, tolerance = _tolerances(system, layout, solver.rtol if rtol is None else rtol)
    if solver.method == "rk4" and hasattr(system, "jacobian_limit"):
        # RK4's stability limit on the real axis, h·|λ| ≤ 2.785: a steeper slope in ∂f/∂x is a
        # difference across a switch, not a mode of the model (the step was checked to resolve
        # those), and is taken from the other side
        # (the samples' median interval: a delayed output's extra times are not RK4 steps)
        interval = float(np.median(np.diff(t)))
        system.jacobian_limit = 2.785 * solver.substeps / interval
    pieces = _Pieces(
        solver,
        _right_hand_side(system, layout, float(t[0]), x0, u[0]),
        _newton_matrix(system, layout),
        tolerance,
        atol,
        max_evaluations,
        # a model with declared switches: solve_ivp from switch to switch, S jumping at each
        switched_integrator(system, layout.n, layout.q, layout.scale) or integrate_piece,
    )
    z_at, evaluations = pieces.integrate(z0, t, u, eval_times)
    parts = _outputs_by_delay(system, layout, t, u, eval_times, inverse, distinct, z_at)
    if len(parts) == 1:
        _, states, y, dy = parts[0]
        return Trajectory(states, y, dy, evaluations)
    # several delays: each output column from the states at its own delay
    per_output = np.broadcast_to(delays, (parts[0][2].shape[1],))
    states = next(states for delay, states, _, _ in parts if delay == per_output[0])
    y = np.empty_like(parts[0][2])
    dy = None if not layout.with_sens else np.empty_like(parts[0][3])
    for delay, _, y_k, dy_k in parts:
        columns = per_output == delay
        y[:, columns] = y_k[:, columns]
        if dy is not None and dy_k is not None:
            dy[:, columns] = dy_k[:, columns]
    return Trajectory(states, y, dy, evaluations)


@dataclass(frozen=True)
class _Layout:
    """z = [x, S raveled by rows]: n states, then q sensitivity columns per state.

    The first p = len(scale) columns of S belong to the free θ (∂θ/∂φ = ``scale``), the rest to
    the estimated initial state.
    """

    n: int
    q: int
    scale: FloatArray
    with_sens: bool

    @classmethod
    def of(cls, n: int, s0: FloatArray | None, theta_scale: FloatArray | None) -> _Layout:
        """The layout of a simulation from ∂x0/∂φ = ``s0`` (None: the state alone)."""
        q = 0 if s0 is None else s0.shape[1]
        scale = np.ones(0) if theta_scale is None else np.asarray(theta_scale, dtype=float)
        return cls(n, q, scale, s0 is not None)

    @property
    def p(self) -> int:
        """Columns of S that belong to θ."""
        return len(self.scale)

    @property
    def width(self) -> int:
        """Length of z."""
        return self.n * (1 + self.q)


def _output_times(t: FloatArray, distinct: FloatArray) -> tuple[FloatArray, NDArray[np.intp]]:
    """The times the state is read at, t − delay for every distinct delay, sorted and unique.

    Also the index of each (delay, sample) pair, delay-major, in them.
    """
    # (to the nanosecond: t − 0.2 and t − 0 for the next sample must be one output time, not
    # two 1e-14 s apart, which LSODA refuses as illegal input)
    eval_times, inverse = np.unique(
        np.round(np.concatenate([t - delay for delay in distinct]), 9), return_inverse=True
    )
    return eval_times, inverse


def _tolerances(
    system: OdeSystem, layout: _Layout, state_rtol: float
) -> tuple[FloatArray, float | FloatArray]:
    """Absolute and relative tolerances of z: the state's, the sensitivity rows' looser.

    The sensitivities are error-controlled, loosely: without any control LSODA's Adams mode
    takes the huge steps a state at rest allows and the sensitivity rows (which share the
    state's fast modes) go unstable, which the state's error test never sees.
    """
    n = layout.n
    state_atol = np.broadcast_to(np.asarray(system.atol, dtype=float), (n,))
    atol = np.concatenate([state_atol, np.tile(SENSITIVITY_ATOL_FACTOR * state_atol, layout.q)])
    tolerance: float | FloatArray = state_rtol
    if layout.with_sens:
        tolerance = np.full(layout.width, SENSITIVITY_RTOL_FACTOR * state_rtol)
        tolerance[:n] = state_rtol
    return atol, tolerance


def _right_hand_side(
    system: OdeSystem, layout: _Layout, t0: float, x0: FloatArray, u0: FloatArray
) -> Rhs:
    """dz/dt: the system's fused one where it has one, else built from its derivatives."""
    n, q, p, scale = layout.n, layout.q, layout.p, layout.scale
    # the system's own right-hand side of the state with its sensitivities, where it has one
    fused_for = getattr(system, "sensitivity_rhs", None) if layout.with_sens else None
    fused: Rhs | None = None if fused_for is None else fused_for(q, scale, t0, x0, u0)
    if fused is not None:
        return fused
    if layout.with_sens:
        dz = np.empty(layout.width)
        dsens = dz[n:].reshape(n, q)

        def rhs(t_now: float, z_now: FloatArray, u_now: FloatArray) -> FloatArray:
            dx, jac_x, jac_theta = system.derivatives(t_now, z_now[:n], u_now)
            dz[:n] = dx
            np.matmul(jac_x, z_now[n:].reshape(n, q), out=dsens)
            if p:
                dsens[:, :p] += jac_theta * scale
            return dz

        return rhs
    # the state alone: f, without the Jacobians the sensitivities need
    plain: Rhs | None = getattr(system, "rhs", None)
    if plain is not None:
        return plain

    def state_rhs(t_now: float, z_now: FloatArray, u_now: FloatArray) -> FloatArray:
        return system.derivatives(t_now, z_now, u_now)[0]

    return state_rhs


def _newton_matrix(system: OdeSystem, layout: _Layout) -> Newton:
    """The implicit methods' Newton matrix of z: ∂f/∂x for x, ∂f/∂x ⊗ I_q for the rows of S."""
    n, with_sens = layout.n, layout.with_sens
    newton_matrix = np.zeros((layout.width, layout.width))
    identity_q = np.eye(layout.q)

    def newton(t_now: float, z_now: FloatArray, u_now: FloatArray) -> FloatArray:
        jac_x = system.state_jacobian(t_now, z_now[:n], u_now)
        if not with_sens:
            return jac_x
        # z = [x, S raveled by rows]: d vec(S)/dt = (∂f/∂x ⊗ I_q)·vec(S) + …
        newton_matrix[:n, :n] = jac_x
        newton_matrix[n:, n:] = np.kron(jac_x, identity_q)
        return newton_matrix

    return newton


@dataclass(frozen=True)
class _Pieces:
    """The integration of z piece by piece, one piece per held input, with the solver's settings."""

    solver: Solver
    rhs: Rhs
    newton: Newton
    tolerance: float | FloatArray
    atol: FloatArray
    max_evaluations: int | None
    integrator: Callable[..., tuple[FloatArray, int]] = integrate_piece

    def integrate(
        self, z: FloatArray, t: FloatArray, u: FloatArray, eval_times: FloatArray
    ) -> tuple[FloatArray, int]:
        """Integrate from z(t[0]) = ``z``: z at ``eval_times`` and the evaluations used."""
        n_samples = len(t)
        z_at = np.empty((len(eval_times), len(z)))
        # samples read before the first time see the initial state (the plant was at rest there)
        before = eval_times <= t[0]
        z_at[before] = z
        starts = input_changes(u)
        ends = np.append(starts[1:], n_samples)
        evaluations = 0
        with np.errstate(all="ignore"):
            for start, end in zip(starts.tolist(), ends.tolist(), strict=True):
                if self.max_evaluations is not None and evaluations > self.max_evaluations:
                    raise SimulationError(
                        f"the ODE needed more than {self.max_evaluations} evaluations by "
                        f"{t[start]:g} s (the solution chatters or is very stiff at these "
                        "parameters)"
                    )
                t_start = t[start]
                t_end = t[end] if end < n_samples else t[-1] + (t[-1] - t[-2])
                inside = np.flatnonzero((eval_times > t_start) & (eval_times <= t_end))
                if not len(inside) and end >= n_samples:
                    break
                times = np.concatenate(([t_start], eval_times[inside]))
                if times[-1] < t_end and end < n_samples:
                    times = np.append(times, t_end)
                solution, used = self._piece(z, times, u[start], evaluations, float(t_end))
                evaluations += used
                z_at[inside] = solution[: len(inside)]
                z = solution[-1]
        return z_at, evaluations

    def _piece(
        self, z: FloatArray, times: FloatArray, u: FloatArray, spent: int, t_end: float
    ) -> tuple[FloatArray, int]:
        """One piece from ``z`` at times[0] with ``u`` held; any failure a SimulationError."""
        t_start = times[0]
        try:
            solution, used = self.integrator(
                self.solver,
                self.rhs,
                self.newton,
                z,
                times,
                u,
                self.tolerance,
                self.atol,
                None if self.max_evaluations is None else self.max_evaluations - spent,
            )
        except UnlocatedSwitches:
            raise  # the method, not this piece: the solver choice says so as it is
        except SimulationError as exc:
            reason = _reason(exc, self.rhs, float(t_start), z, u)
            raise SimulationError(f"on {t_start:g}…{t_end:g} s {reason}") from None
        except FuelidError:
            raise
        except (ArithmeticError, ValueError) as exc:
            # the model's own arithmetic failed (math.sqrt of a negative state, say): a
            # point where it cannot be simulated, like a solver failure
            raise SimulationError(
                f"the model raised {type(exc).__name__} ({exc}) on {t_start:g}…{t_end:g} s"
            ) from exc
        if not np.all(np.isfinite(solution)):
            raise SimulationError(f"on {t_start:g}…{t_end:g} s {_NOT_FINITE}")
        return solution, used


def _outputs_by_delay(
    system: OdeSystem,
    layout: _Layout,
    t: FloatArray,
    u: FloatArray,
    eval_times: FloatArray,
    inverse: NDArray[np.intp],
    distinct: FloatArray,
    z_at: FloatArray,
) -> list[tuple[float, FloatArray, FloatArray, FloatArray | None]]:
    """Per distinct delay: (delay, states, outputs, ∂y/∂φ or None) at the samples."""
    n, q, p, scale = layout.n, layout.q, layout.p, layout.scale
    n_samples = len(t)
    # the input in effect at each (delayed) output time
    held_at = np.clip(np.searchsorted(t, eval_times, side="right") - 1, 0, n_samples - 1)
    parts = []
    for k, delay in enumerate(distinct):
        rows = inverse[k * n_samples : (k + 1) * n_samples]
        z_k = z_at[rows]
        with np.errstate(all="ignore"):
            y_k, dy_dx, dy_dtheta = system.outputs(z_k[:, :n], u[held_at[rows]])
        dy_k = None
        if layout.with_sens:
            sens = z_k[:, n:].reshape(n_samples, n, q)
            dy_k = np.einsum("kyn,knq->kyq", dy_dx, sens)
            if p:
                dy_k[:, :, :p] += dy_dtheta * scale
        parts.append((delay, z_k[:, :n], y_k, dy_k))
    return parts


_NOT_FINITE = (
    "the model's derivatives are NaN or infinite there (a square root of a negative value, a "
    "division by zero?)"
)


def _reason(exc: SimulationError, rhs: Rhs, t: float, z: FloatArray, u: FloatArray) -> str:
    """Why a piece failed: non-finite derivatives at its start, or the solver's own message.

    numpy arithmetic (√ of a negative, a division by zero) gives NaN or inf, not an exception:
    the solver then fails; the derivatives at the piece's start say which.
    """
    try:
        derivative = np.asarray(rhs(t, z, u), dtype=float)
    except (ArithmeticError, ValueError, FuelidError):
        return str(exc)
    if not np.all(np.isfinite(derivative)) or not np.all(np.isfinite(z)):
        return _NOT_FINITE
    return str(exc)
