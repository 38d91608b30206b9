"""A gray-box model from plain functions ``f(t, x, u, p)``, ``h(x, u, p)``, ``x0(p, u0, y0)``.

The Jacobians the sensitivity equations need are finite differences of ``f`` and ``h`` (cheap
function calls, not simulations). When ``f`` is written with numpy operations it is called once per
step on a batch of perturbed states and parameters (each column one perturbation); a function that
only takes scalars (``math.sqrt``, ``max``, an ``if`` on a state) is detected at the first call and
evaluated column by column instead.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from fuelid.errors import ConfigError
from fuelid.greybox._parameters import ParameterSpec
from fuelid.greybox._switching import ModedRhs, Switch, switched_system
from fuelid.greybox._system import Record

FloatArray = NDArray[np.float64]
RhsFunction = Callable[[float, Any, Any, Mapping[str, Any]], Any]
OutputFunction = Callable[[Any, Any, Mapping[str, Any]], Any]
InitialStateFunction = Callable[[Mapping[str, Any], Any, Any], Any]
_STEP = 1.5e-8  # ≈ √ε: the forward-difference step relative to the variable's size


def _steps(values: FloatArray, floor: FloatArray | float) -> FloatArray:
    return _STEP * np.maximum(np.abs(values), floor)


def _call_batch(
    function: Callable[..., Any], columns: int, n_out: int, *args: Any
) -> FloatArray | None:
    """Call a user function on a batch; None when it does not broadcast over columns.

    A list with one entry per output may mix arrays and constants (``[x[1], 0.0]``): each entry
    is broadcast over the columns.
    """
    out: FloatArray
    try:
        raw = function(*args)  # (the simulation runs under np.errstate(all="ignore"))
        if isinstance(raw, list | tuple) and len(raw) == n_out:
            out = np.empty((n_out, columns))
            for i, row in enumerate(raw):
                out[i] = row
        else:
            out = np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError, IndexError):
        return None
    if out.shape == (n_out, columns):
        return out
    if n_out == 1 and out.shape == (columns,):
        return out.reshape(1, columns)
    return None


@dataclass
class _BatchMode:
    f_vectorised: bool | None = None
    h_vectorised: bool | None = None


class FunctionSystem:
    """An :class:`~fuelid.greybox._system.OdeSystem` of user functions, Jacobians by differences."""

    def __init__(self, model: OdeModel, values: Mapping[str, float], free: Sequence[str]) -> None:
        self.model = model
        self.values = dict(values)
        self.free = tuple(free)
        self.n_states = len(model.state_names)
        self.n_outputs = len(model.output_names)
        self.atol = np.full(self.n_states, model.atol)
        self.output_delay: float | FloatArray = 0.0
        theta = np.array([self.values[name] for name in self.free], dtype=float)
        self._theta_steps = _steps(theta, 1.0) if len(theta) else np.zeros(0)
        self._mode = model._mode
        # the batch layout is the same at every call: build it once
        n, p = self.n_states, len(self.free)
        self._columns = 1 + n + p
        self._batch_values = self._batch_parameters(1 + n)
        self._batch_states = np.empty((n, self._columns))
        self._state_columns = 1 + np.arange(n)
        self._rows = np.arange(n)
        self._all_steps = np.empty(n + p)
        self._all_steps[n:] = self._theta_steps
        self._state_scale = float(model.state_scale)
        self._last: tuple[float, bytes, FloatArray] | None = None
        self._fused_at: tuple[float, bytes] | None = None
        """Where :meth:`sensitivity_rhs`'s function last ran (its differences are kept)."""
        self._fused: tuple[FloatArray, FloatArray] = (np.zeros((0, 0)), np.zeros((0, 1)))
        self.jacobian_limit = np.inf
        """|∂f/∂x| beyond which a column is taken as a difference straddling a switch (set by
        fixed-step RK4 to its stability limit: see :meth:`_one_sided`)."""
        # the parameters with one free parameter stepped, for the scalar differences
        self._perturbed = []
        for j, name in enumerate(self.free):
            stepped = dict(self.values)
            stepped[name] += float(self._theta_steps[j])
            self._perturbed.append(stepped)

    # --- batches of perturbed parameters --------------------------------------------------------
    def _batch_parameters(self, leading: int) -> dict[str, Any]:
        """Parameters for [leading unperturbed columns, then one column per free parameter]."""
        columns = leading + len(self.free)
        batch: dict[str, Any] = {}
        for name, value in self.values.items():
            if name in self.free:
                column = np.full(columns, value)
                j = self.free.index(name)
                column[leading + j] += self._theta_steps[j]
                batch[name] = column
            else:
                batch[name] = value
        return batch

    def _perturbed_values(self, j: int) -> dict[str, float]:
        return self._perturbed[j]

    def forget(self) -> None:
        """Drop the Jacobians kept for the Newton matrix (a declared switch changed f's mode)."""
        self._last = None
        self._fused_at = None

    def _f(self, t: float, x: FloatArray, u: FloatArray, values: Mapping[str, Any]) -> FloatArray:
        # no np.errstate here: it costs a microsecond a call, and every caller (the simulation,
        # the steady-state guess) runs under one already
        return np.array(self.model.f(t, x, u, values), dtype=float).reshape(self.n_states)

    def rhs(self, t: float, x: FloatArray, u: FloatArray) -> FloatArray:
        """f(t, x, u) alone: a simulation without sensitivities needs no Jacobian."""
        return np.array(self.model.f(t, x, u, self.values), dtype=float).reshape(self.n_states)

    # --- OdeSystem ------------------------------------------------------------------------------
    def derivatives(
        self, t: float, x: FloatArray, u: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """f, ∂f/∂x and ∂f/∂θ by forward differences (one batched call when f broadcasts)."""
        n, p = self.n_states, len(self.free)
        dx_steps = _STEP * np.maximum(np.abs(x), self._state_scale)
        if self._mode.f_vectorised is not False:
            states = self._batch_states
            states[...] = x[:, None]
            states[self._rows, self._state_columns] += dx_steps
            out = _call_batch(self.model.f, self._columns, n, t, states, u, self._batch_values)
            if self._mode.f_vectorised is None:
                self._mode.f_vectorised = out is not None and self._agrees(t, x, u, out, dx_steps)
            if self._mode.f_vectorised and out is not None:
                base = out[:, 0].copy()
                steps = self._all_steps
                steps[:n] = dx_steps
                jac = (out[:, 1:] - base[:, None]) / steps
                jac_x = self._one_sided(t, x, u, base, jac[:, :n], dx_steps)
                self._last = (t, x.tobytes(), jac_x)
                return base, jac_x, jac[:, n:]
        # a function of scalars: one call per column, the results stacked once (the calls
        # themselves are most of the cost of a simulation with sensitivities)
        f = self.model.f
        values = self.values
        shifted = x[:, None] + np.diag(dx_steps)
        rows = [f(t, x, u, values)]
        rows.extend(f(t, shifted[:, i], u, values) for i in range(n))
        rows.extend(f(t, x, u, stepped) for stepped in self._perturbed)
        try:
            table = np.array(rows, dtype=float).reshape(1 + n + p, n)
        except ValueError as exc:  # a ragged return (a list and an array mixed)
            raise ConfigError(f"f did not return {n} numbers ({exc})") from None
        base = table[0]
        steps = self._all_steps
        steps[:n] = dx_steps
        jac = ((table[1:] - base) / steps[:, None]).T
        jac_x = self._one_sided(t, x, u, base, jac[:, :n], dx_steps)
        self._last = (t, x.tobytes(), jac_x)
        return base, jac_x, jac[:, n:]

    def sensitivity_rhs(
        self, q: int, theta_scale: FloatArray, t0: float, x0: FloatArray, u0: FloatArray
    ) -> Callable[[float, FloatArray, FloatArray], FloatArray] | None:
        """d[x, S]/dt in one function for an ``f`` of scalars (None: use :meth:`derivatives`).

        The state and its sensitivities S (n × q, row-major after x in z) move together:
        dS/dt = ∂f/∂x·S + [∂f/∂θ·diag(∂θ/∂φ) | 0] = D·W with D = [∂f/∂x | ∂f/∂θ·diag(∂θ/∂φ)]
        from the forward differences of f and W = [S; I_p 0] (p = len(theta_scale): all the
        free parameters, or none when only the initial state's sensitivities are asked for);
        one product instead of the general
        path's Jacobians, copies and sums around the same 1 + n + p calls of ``f`` (those calls
        then are most of a simulation's cost). The first call at (t0, x0, u0) settles whether f
        takes batches (then one batched call: :meth:`_batched_sensitivity_rhs`); RK4's
        one-sided differences at a switch keep the general path.
        """
        if self._mode.f_vectorised is None:
            try:
                with np.errstate(all="ignore"):
                    self.derivatives(t0, np.asarray(x0, dtype=float), u0)
            except (ArithmeticError, ValueError):
                return None  # the simulation says where the model fails
        n, p = self.n_states, len(theta_scale)
        if np.isfinite(self.jacobian_limit) or p not in (0, len(self.free)):
            return None
        if self._mode.f_vectorised:
            return self._batched_sensitivity_rhs(q, theta_scale)
        # the user's function itself: the model file's wrapper that names the failing line in
        # an error costs a fifth of a call; a failing evaluation is repeated through it
        f = getattr(self.model.f, "__wrapped__", self.model.f)
        # (no θ columns asked for: the initial state's sensitivities alone, f at stepped x only)
        values, perturbed = self.values, self._perturbed[:p]
        state_floor = self._state_scale
        stepped = np.empty((n, n))  # row i: the state with its i-th entry stepped
        changes, inverse_steps, finish = self._fused_product(q, theta_scale, n + p)
        derivatives = self.derivatives

        def rhs(t: float, z: FloatArray, u: FloatArray) -> FloatArray:
            x = z[:n]
            try:
                rows = [f(t, x, u, values)]
                stepped[:] = x
                for i, value in enumerate(x.tolist()):
                    step = _STEP * max(abs(value), state_floor)
                    inverse_steps[i, 0] = 1.0 / step
                    stepped[i, i] = value + step
                    rows.append(f(t, stepped[i], u, values))
                rows.extend([f(t, x, u, changed) for changed in perturbed])
                table = np.array(rows, dtype=float).reshape(1 + n + p, n)
            except Exception:
                derivatives(t, x, u)  # the general path raises the model file's located error
                raise
            np.subtract(table[1:], table[0], out=changes)
            return finish(t, z, table[0])

        return rhs

    def _fused_product(
        self, q: int, theta_scale: FloatArray, rows: int
    ) -> tuple[FloatArray, FloatArray, Callable[[float, FloatArray, Any], FloatArray]]:
        """The buffers of a fused right-hand side and its last step, dS/dt = changesᵀ·weights.

        ``changes`` (rows × n): row k is f with variable k stepped minus f (the n states, then
        the parameters); ``inverse_steps`` (n × 1): 1 / each state's step, filled by the caller
        before ``finish(t, z, f(x))``, which returns d[x, S]/dt. weights = [S / steps;
        diag(∂θ/∂φ / θ steps) 0], so ∂f/∂x·S + ∂f/∂θ·diag(∂θ/∂φ)·[I 0] is one product. The
        buffers are kept for the Newton matrix (:meth:`state_jacobian`).
        """
        n, p = self.n_states, len(theta_scale)
        changes = np.empty((rows, n))
        inverse_steps = np.empty((n, 1))
        weights = np.zeros((rows, q))
        weights[n : n + p, :p] = np.diag(
            np.asarray(theta_scale, dtype=float) / self._theta_steps[:p]
        )
        dz = np.empty(n * (1 + q))
        dsens = dz[n:].reshape(n, q)
        self._fused = (changes, inverse_steps)
        self._fused_at = None  # the buffers are new: nothing cached in them yet
        # the rows the product uses: the states' and the parameters asked for (a batch computes
        # every parameter's column; one not asked for may be NaN there, and 0·NaN is NaN)
        used_changes, used_weights = changes[: n + p], weights[: n + p]

        def finish(t: float, z: FloatArray, base: Any) -> FloatArray:
            dz[:n] = base
            np.multiply(z[n:].reshape(n, q), inverse_steps, out=weights[:n])
            np.matmul(used_changes.T, used_weights, out=dsens)
            self._last = None
            self._fused_at = (t, z[:n].tobytes())
            return dz

        return changes, inverse_steps, finish

    def _batched_sensitivity_rhs(
        self, q: int, theta_scale: FloatArray
    ) -> Callable[[float, FloatArray, FloatArray], FloatArray]:
        """:meth:`sensitivity_rhs` for an f that takes a batch: one call on every perturbation.

        The batch holds every free parameter's column; with none asked for (p = 0) their
        weights are zero. Where f stops broadcasting (a branch on a state at this point) the
        general path's differences stand in.
        """
        n, p_all = self.n_states, len(self.free)
        f, columns, batch_values = self.model.f, self._columns, self._batch_values
        state_floor = self._state_scale
        states = self._batch_states  # column 0: x; column 1 + i: x with entry i stepped
        diagonal = np.arange(n)
        changes, inverse_steps, finish = self._fused_product(q, theta_scale, n + p_all)
        theta_steps = self._theta_steps[:, None]
        derivatives = self.derivatives

        def rhs(t: float, z: FloatArray, u: FloatArray) -> FloatArray:
            x = z[:n]
            steps = _STEP * np.maximum(np.abs(x), state_floor)
            states[...] = x[:, None]
            states[diagonal, diagonal + 1] += steps
            out = _call_batch(f, columns, n, t, states, u, batch_values)
            if out is None:
                base, jac_x, jac_theta = derivatives(t, x, u)
                changes[:n] = jac_x.T * steps[:, None]
                changes[n:] = jac_theta.T * theta_steps
            else:
                base = out[:, 0]
                np.subtract(out[:, 1:].T, base, out=changes)
            inverse_steps[:, 0] = 1.0 / steps
            return finish(t, z, base)

        return rhs

    def _one_sided(
        self,
        t: float,
        x: FloatArray,
        u: FloatArray,
        base: FloatArray,
        jac_x: FloatArray,
        dx_steps: FloatArray,
    ) -> FloatArray:
        """∂f/∂x with each column beyond ``jacobian_limit`` taken from the other side.

        A forward difference whose step crosses a switch of the model (an ``if`` that makes f
        jump) is the jump over the step, ~1e8 times the real slope: a "mode" a fixed step
        cannot integrate, which would blow the sensitivities up. Such a column is recomputed
        backwards, and the smaller of the two kept: the slope on the side the state is on.
        """
        if not np.isfinite(self.jacobian_limit):
            return jac_x
        large = np.flatnonzero(np.max(np.abs(jac_x), axis=0) > self.jacobian_limit)
        if not len(large):
            return jac_x
        jac_x = jac_x.copy()
        for i in large:
            shifted = x.copy()
            shifted[i] -= dx_steps[i]
            backward = (base - self._f(t, shifted, u, self.values)) / dx_steps[i]
            if np.max(np.abs(backward)) < np.max(np.abs(jac_x[:, i])):
                jac_x[:, i] = backward
        return jac_x

    def _agrees(
        self, t: float, x: FloatArray, u: FloatArray, out: FloatArray, dx_steps: FloatArray
    ) -> bool:
        """Check a batched call against scalar calls once (a function may broadcast wrongly)."""
        base = self._f(t, x, u, self.values)
        shifted = x.copy()
        shifted[0] += dx_steps[0]
        first = self._f(t, shifted, u, self.values)
        return bool(
            np.allclose(out[:, 0], base, rtol=1e-12, atol=0.0, equal_nan=True)
            and np.allclose(out[:, 1], first, rtol=1e-12, atol=0.0, equal_nan=True)
        )

    def state_jacobian(self, t: float, x: FloatArray, u: FloatArray) -> FloatArray:
        """∂f/∂x (the one the last :meth:`derivatives` call at this point computed)."""
        if self._last is not None and self._last[0] == t and self._last[1] == x.tobytes():
            return self._last[2]
        if self._fused_at is not None and self._fused_at == (t, x.tobytes()):
            # the differences the last fused right-hand side computed at this point
            changes, inverse_steps = self._fused
            jac: FloatArray = changes[: self.n_states].T * inverse_steps[:, 0]
            return jac
        # the stiff solver's Newton matrix alone: the state columns, not the parameters'
        n = self.n_states
        dx_steps = _STEP * np.maximum(np.abs(x), self._state_scale)
        base = self._f(t, x, u, self.values)
        jac_x = np.empty((n, n))
        for i in range(n):
            shifted = x.copy()
            shifted[i] += dx_steps[i]
            jac_x[:, i] = (self._f(t, shifted, u, self.values) - base) / dx_steps[i]
        jac_x = self._one_sided(t, x, u, base, jac_x, dx_steps)
        self._last = (t, x.tobytes(), jac_x)
        return jac_x

    def _h(self, x: FloatArray, u: FloatArray, values: Mapping[str, Any]) -> FloatArray:
        """Outputs for states x (N × n), inputs u (N × n_u): shape (N, n_y)."""
        n_samples = len(x)
        if self._mode.h_vectorised is not False:
            out = _call_batch(self.model.h, n_samples, self.n_outputs, x.T, u.T, values)
            if self._mode.h_vectorised is None and out is not None:
                scalar = self._h_loop(x[:2], u[:2], values)
                self._mode.h_vectorised = bool(
                    np.allclose(out[:, :2].T, scalar, rtol=1e-12, atol=0.0, equal_nan=True)
                )
            elif out is None:
                self._mode.h_vectorised = False
            if self._mode.h_vectorised and out is not None:
                return out.T
        return self._h_loop(x, u, values)

    def _h_loop(self, x: FloatArray, u: FloatArray, values: Mapping[str, Any]) -> FloatArray:
        with np.errstate(all="ignore"):  # (called outside a simulation too)
            rows = [
                np.asarray(self.model.h(x_k, u_k, values), dtype=float).reshape(self.n_outputs)
                for x_k, u_k in zip(x, u, strict=True)
            ]
        return np.array(rows).reshape(len(x), self.n_outputs)

    def outputs(self, x: FloatArray, u: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """y, ∂y/∂x and ∂y/∂θ at every sample (differences over whole columns of samples)."""
        n_samples, n, p = len(x), self.n_states, len(self.free)
        y = self._h(x, u, self.values)
        dy_dx = np.empty((n_samples, self.n_outputs, n))
        steps = _steps(x, self.model.state_scale)
        for i in range(n):
            shifted = x.copy()
            shifted[:, i] += steps[:, i]
            dy_dx[:, :, i] = (self._h(shifted, u, self.values) - y) / steps[:, i, None]
        dy_dtheta = np.empty((n_samples, self.n_outputs, p))
        for j in range(p):
            changed = self._h(x, u, self._perturbed_values(j))
            dy_dtheta[:, :, j] = (changed - y) / self._theta_steps[j]
        return y, dy_dx, dy_dtheta

    def initial_state(self, u0: FloatArray, y0: FloatArray) -> tuple[FloatArray, FloatArray] | None:
        """x0(p, u0, y0) and its θ-derivative when the model defines x0."""
        x0_function = self.model.x0
        if x0_function is None:
            return None

        def evaluate(values: Mapping[str, float]) -> FloatArray:
            out: FloatArray = np.asarray(x0_function(values, u0, y0), dtype=np.float64).reshape(-1)
            if out.shape != (self.n_states,):
                raise ConfigError(
                    f"x0 returned {out.size} values for {self.n_states} states "
                    f"({', '.join(self.model.state_names)})"
                )
            return out

        base = evaluate(self.values)
        jac = np.empty((self.n_states, len(self.free)))
        for j in range(len(self.free)):
            jac[:, j] = (evaluate(self._perturbed_values(j)) - base) / self._theta_steps[j]
        return base, jac


def _identity_output(x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    return x[0]


class OdeModel:
    """A continuous-time gray-box model written as plain functions.

    Parameters
    ----------
    f : callable
        ``f(t, x, u, p)`` → dx/dt; ``x`` and ``u`` arrays, ``p`` a mapping name → value.
    parameters : sequence of ParameterSpec
        The parameters, with start values, bounds and fixed flags.
    state_names : sequence of str
        One name per state.
    h : callable, optional
        ``h(x, u, p)`` → the measured output(s); default: the first state.
    x0 : callable, optional
        ``x0(p, u0, y0)`` → the initial state from the parameters and the first input and output;
        without it the initial state of every record is estimated.
    output_names : sequence of str, optional
        One per output (default ``y1, y2, …``; ``y`` for one).
    state_scale : float
        Typical size of a state (finite-difference steps and tolerances scale with it).
    switches : sequence of Switch, optional
        Declared switches (:mod:`fuelid.greybox._switching`): ``f`` then takes a fifth argument,
        ``on`` (switch name → True where its function is positive), and each switch is located
        as a solver event, the sensitivities jumping there.

    Examples
    --------
    >>> model = OdeModel(
    ...     f=lambda t, x, u, p: [-x[0] / p["tau"] + p["k"] * u[0] / p["tau"]],
    ...     parameters=[ParameterSpec("k", 1.0, 0.0), ParameterSpec("tau", 2.0, 0.0)],
    ...     state_names=["y"],
    ... )
    >>> model.output_names
    ('y',)
    """

    def __init__(
        self,
        f: RhsFunction,
        parameters: Sequence[ParameterSpec],
        state_names: Sequence[str],
        h: OutputFunction | None = None,
        x0: InitialStateFunction | None = None,
        output_names: Sequence[str] | None = None,
        n_outputs: int = 1,
        state_scale: float = 1.0,
        switches: Sequence[Switch] = (),
    ) -> None:
        self.switches = tuple(switches)
        self.moded_f: Callable[..., Any] | None = None
        if self.switches:
            # f(t, x, u, p, on): unbound (loading checks, steady state) it takes the modes from
            # the signs of the switches at its own state; bound, from the events (bind)
            self.moded_f = f
            f = ModedRhs(f, self.switches, None, float(state_scale))
        self.f = f
        self.h = h if h is not None else _identity_output
        self.x0 = x0
        self.parameters = tuple(parameters)
        self.state_names = tuple(state_names)
        if output_names is None:
            output_names = ["y"] if n_outputs == 1 else [f"y{i + 1}" for i in range(n_outputs)]
        self.output_names = tuple(output_names)
        self.state_scale = float(state_scale)
        self.atol = 1e-9 * self.state_scale
        self._mode = _BatchMode()
        names = [spec.name for spec in self.parameters]
        if len(set(names)) != len(names):
            raise ConfigError(f"parameter names repeat: {', '.join(names)}")
        if not self.state_names:
            raise ConfigError("the model has no states")

    def bind(
        self, values: Mapping[str, float], free: Sequence[str], record: Record
    ) -> FunctionSystem:
        """The model at ``values`` (θ = the ``free`` ones) for ``record``."""
        if self.switches:
            return switched_system(self, values, free, FunctionSystem)  # type: ignore[no-any-return]
        return FunctionSystem(self, values, free)

    def steady_state_guess(self, values: Mapping[str, float], record: Record) -> FloatArray:
        """The state where f(x, u0) = 0 nearest the state scale (least squares); else all ones."""
        u0 = record.u[0]
        n = len(self.state_names)
        start = np.full(n, self.state_scale)

        def residual(x: FloatArray) -> FloatArray:
            with np.errstate(all="ignore"):
                out = np.asarray(self.f(record.t[0], x, u0, values), dtype=float).reshape(n)
            return np.where(np.isfinite(out), out, 1e6)

        try:
            solution = scipy.optimize.least_squares(residual, start, method="lm", max_nfev=2000)
        except (ValueError, TypeError, ArithmeticError):
            return start
        guess = np.asarray(solution.x, dtype=float)
        return guess if np.all(np.isfinite(guess)) else start
