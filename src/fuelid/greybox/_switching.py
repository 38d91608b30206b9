"""Declared switches: modes located by solve_ivp events, the sensitivities' jump at each switch.

A model file may declare its switching functions, ``switches = [g1, g2, ...]`` (or a dict
name → function), each ``g(t, x, u, p)`` a number whose sign is the switch: the switch is *on*
where g > 0. ``f(t, x, u, p, on)`` then takes a fifth argument, ``on[name]`` (True or False),
and branches on it instead of on the state. Between switches f is smooth and every solver
integrates it; each switch is located as a terminal solve_ivp event on g and the integration
restarts on the other side, f evaluated in the mode the event selects.

The sensitivities S = ∂x/∂φ jump at a switch (Hiskens & Pai, "Trajectory sensitivity analysis
of hybrid systems", IEEE Trans. Circuits Syst. I 47(2), 2000, eq. (13)). The switching time τ(φ)
is where g(τ, x(τ), φ) = 0; differentiating that along the trajectory,

    g_x·(f⁻·τ_φ + S⁻) + g_φ + g_t·τ_φ = 0   ⇒   τ_φ = −(g_x·S⁻ + g_φ) / (g_x·f⁻ + g_t),

and with x continuous at τ (no reset) x⁺(τ) = x⁻(τ), so S⁺ = S⁻ + (f⁻ − f⁺)·τ_φ:

    S⁺ = S⁻ + (f⁺ − f⁻) · (g_x·S⁻ + g_φ) / (g_x·f⁻ + g_t).

Where f on the far side drives the state straight back (ġ⁻ = g_x·f⁻ + g_t > 0 below and
ġ⁺ < 0 above: a dump valve that empties faster than the pump fills), the state slides along
g = 0 (Filippov): f_s = f⁻ + α·(f⁺ − f⁻) with α = ġ⁻ / (ġ⁻ − ġ⁺), which keeps ġ = 0. The jump
into the sliding mode is the formula above with f⁺ = f_s, after which g_x·S + g_φ = 0 (the
perturbed trajectories slide too); the sliding mode ends where α reaches 0 or 1, where f is
continuous and S does not jump. The derivatives of g are central differences (g is called a few
times per switch, and in a sliding mode a few times per step).

A switch whose state sits on g = 0 when a piece starts (a new held input, or after another
switch) takes its mode from the directions of ġ⁻ and ġ⁺, not from the sign of a g that the
event left within rounding of zero.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.integrate
from numpy.typing import NDArray

from fuelid.greybox._solvers import BudgetSpent, Newton, Rhs, SimulationError, Solver, budgeted

FloatArray = NDArray[np.float64]
SwitchFunction = Callable[[float, Any, Any, Mapping[str, Any]], Any]
MAX_SWITCHES_PER_PIECE = 200
"""More switches than this within one held input is chattering the model does not describe: the
piece is refused (a SimulationError the fit steps back from), not ground through."""
_DIFFERENCE = 1e-6
"""Central-difference step of g's derivatives, relative to the variable's size."""
_BAND = 10.0
"""Each switch fires a band δ past zero, δ = this × the solver's relative tolerance × |g_x| ×
the state scale: past the rounding and the integration error of a g that rests on zero (a
level held at its rim, or settling onto a switch's level), which would otherwise fire at every
step. The switch is then located to δ/ġ in time, within what the tolerance allows anyway, and
the sensitivities are exact for a switch at ±δ (the jump is taken where it fires)."""
_METHODS = {"lsoda": "LSODA", "bdf": "BDF", "radau": "Radau", "rk45": "RK45"}


class UnlocatedSwitches(SimulationError):
    """A fixed-step method asked to integrate a model with declared switches (it cannot)."""


@dataclass(frozen=True)
class Switch:
    """A declared switch: on where ``function(t, x, u, p)`` > 0."""

    name: str
    function: SwitchFunction


class Modes:
    """Which switches are on, and the one the state slides along (None: none)."""

    def __init__(self, names: Sequence[str]) -> None:
        self.on: dict[str, bool] = dict.fromkeys(names, False)
        self.sliding: int | None = None


class ModedRhs:
    """f(t, x, u, p) of a switched model: the user's f(t, x, u, p, on) in the current mode.

    Without ``modes`` (loading checks, the steady-state guess) each call takes the modes from
    the signs of g at its own state, as an ``if`` would. In a sliding mode f is Filippov's
    combination of the two sides.
    """

    def __init__(
        self,
        f: Callable[..., Any],
        switches: Sequence[Switch],
        modes: Modes | None = None,
        state_scale: float = 1.0,
    ) -> None:
        self.f = f
        self.switches = tuple(switches)
        self.modes = modes
        self.state_scale = state_scale
        self.__name__ = getattr(f, "__name__", "f")

    def __call__(self, t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
        if self.modes is None:
            on = {s.name: _positive(s.function(t, x, u, p)) for s in self.switches}
            return self.f(t, x, u, p, on)
        if self.modes.sliding is None:
            return self.f(t, x, u, p, self.modes.on)
        return self.sliding(t, x, u, p, self.modes.sliding)

    def side(self, t: float, x: Any, u: Any, p: Mapping[str, Any], k: int, on: bool) -> FloatArray:
        """The user's f with switch k on or off (the others as they are)."""
        modes = dict(self.modes.on if self.modes is not None else {})
        modes[self.switches[k].name] = on
        return np.asarray(self.f(t, x, u, p, modes), dtype=float)

    def sliding(self, t: float, x: Any, u: Any, p: Mapping[str, Any], k: int) -> FloatArray:
        """Filippov's f_s = f⁻ + α·(f⁺ − f⁻), α = ġ⁻/(ġ⁻ − ġ⁺) (works on batches too)."""
        below = self.side(t, x, u, p, k, False)
        above = self.side(t, x, u, p, k, True)
        g = self.switches[k].function
        rise_below = rate_of_change(g, t, x, u, p, below, self.state_scale)
        rise_above = rate_of_change(g, t, x, u, p, above, self.state_scale)
        with np.errstate(all="ignore"):
            alpha = np.clip(rise_below / (rise_below - rise_above), 0.0, 1.0)
        alpha = np.where(np.isfinite(alpha), alpha, 0.0)
        return below + alpha * (above - below)


def _positive(value: Any) -> Any:
    """Whether g > 0: a bool (an array of them for a batch)."""
    out = np.asarray(value, dtype=float) > 0.0
    return bool(out) if out.ndim == 0 else out


def _power_of_two(size: Any) -> Any:
    """A step of about ``size`` rounded to a power of two: x ± step is then exact."""
    return np.exp2(np.round(np.log2(size)))


def state_gradient(
    g: SwitchFunction, t: float, x: FloatArray, u: Any, p: Mapping[str, Any], scale: float
) -> FloatArray:
    """∂g/∂x by central differences (x one state, not a batch)."""
    gradient = np.empty(len(x))
    for i in range(len(x)):
        step = float(_power_of_two(_DIFFERENCE * max(abs(x[i]), scale)))
        up, down = x.copy(), x.copy()
        up[i] += step
        down[i] -= step
        gradient[i] = (float(g(t, up, u, p)) - float(g(t, down, u, p))) / (2.0 * step)
    return gradient


def rate_of_change(
    g: SwitchFunction, t: float, x: Any, u: Any, p: Mapping[str, Any], f: Any, scale: float
) -> Any:
    """ġ = g_t + g_x·f by central differences in each state (x may be a batch, n × m)."""
    x = np.asarray(x, dtype=float)
    f = np.asarray(f, dtype=float)
    total = time_derivative(g, t, x, u, p)
    for i in range(x.shape[0]):
        step = _power_of_two(_DIFFERENCE * np.maximum(np.abs(x[i]), scale))
        up, down = x.copy(), x.copy()
        up[i] = up[i] + step
        down[i] = down[i] - step
        slope = (np.asarray(g(t, up, u, p), dtype=float) - np.asarray(g(t, down, u, p))) / (
            2.0 * step
        )
        total = total + slope * f[i]
    return total


def time_derivative(g: SwitchFunction, t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    """∂g/∂t by a central difference (0 for the usual g of the state alone; x may be a batch)."""
    step = float(_power_of_two(_DIFFERENCE * max(abs(t), 1.0)))
    return (np.asarray(g(t + step, x, u, p), dtype=float) - np.asarray(g(t - step, x, u, p))) / (
        2.0 * step
    )


# --- the model bound to parameters: modes carried along a record --------------------------------


def switched_system(
    model: Any,
    values: Mapping[str, float],
    free: Sequence[str],
    bound: Callable[[Any, Mapping[str, float], Sequence[str]], Any],
) -> Any:
    """The model at ``values`` with modes of its own, carried from piece to piece of a record.

    ``model`` is an ``OdeModel`` with switches and ``bound`` its ``FunctionSystem`` class,
    passed in (not imported: the model module imports this one); the bound system is returned.
    """
    assert model.moded_f is not None  # a model with switches keeps the user's f(t, x, u, p, on)
    modes = Modes([s.name for s in model.switches])
    view = copy.copy(model)
    moded = ModedRhs(model.moded_f, model.switches, modes, model.state_scale)
    # the fused sensitivities call the user's f without the model file's line-naming wrapper
    # (a failing call is repeated through it): the same modes around the bare function
    raw = getattr(model.moded_f, "__wrapped__", model.moded_f)
    moded.__wrapped__ = ModedRhs(raw, model.switches, modes, model.state_scale)  # type: ignore[attr-defined]
    view.f = moded
    system = bound(view, values, free)
    system.switched = _Switching(system, moded, modes)
    return system


class _Switching:
    """A bound system's switches: deciding modes, the jump of S, the events of a segment."""

    def __init__(self, system: Any, moded: ModedRhs, modes: Modes) -> None:
        # system: the bound FunctionSystem (greybox._odemodel, which imports this module)
        self.system = system
        self.moded = moded
        self.modes = modes
        self.switches = moded.switches
        self.scale = float(system.model.state_scale)
        self.rtol = 1e-6
        """The solver's relative tolerance on the state (sets the band, :data:`_BAND`)."""
        self.bands = np.zeros(len(self.switches))
        """δ of each switch, set where the modes are settled."""

    # modes -------------------------------------------------------------------------------------
    def _g(self, k: int, t: float, x: FloatArray, u: FloatArray) -> float:
        return float(self.switches[k].function(t, x, u, self.system.values))

    def _rises(self, k: int, t: float, x: FloatArray, u: FloatArray) -> tuple[float, float]:
        """ġ of switch k with it off (ġ⁻) and on (ġ⁺), the other switches as they are."""
        values = self.system.values
        g = self.switches[k].function
        below = self.moded.side(t, x, u, values, k, False)
        above = self.moded.side(t, x, u, values, k, True)
        return (
            float(rate_of_change(g, t, x, u, values, below, self.scale)),
            float(rate_of_change(g, t, x, u, values, above, self.scale)),
        )

    def _on_surface(self, k: int, t: float, x: FloatArray, u: FloatArray) -> bool:
        """Whether g_k is within its band of zero (and the band δ_k, set from g_x here)."""
        g = self.switches[k].function
        slope = state_gradient(g, t, x, u, self.system.values, self.scale)
        self.bands[k] = _BAND * self.rtol * max(float(np.max(np.abs(slope))) * self.scale, 1e-300)
        return bool(abs(self._g(k, t, x, u)) <= 2.0 * self.bands[k])

    def settle(self, t: float, x: FloatArray, u: FloatArray, at: int | None = None) -> None:
        """Each switch's mode at (t, x): by g's sign, or on g = 0 by the directions of ġ.

        ``at``: a switch known to be on its surface (its event just fired).
        """
        modes = self.modes
        modes.sliding = None
        surface: list[int] = []
        for k, switch in enumerate(self.switches):
            if self._on_surface(k, t, x, u) or k == at:
                surface.append(k)
            else:
                modes.on[switch.name] = self._g(k, t, x, u) > 0.0
        for k in surface:
            below, above = self._rises(k, t, x, u)
            name = self.switches[k].name
            if below > 0.0 and above < 0.0:
                if modes.sliding is not None:
                    other = self.switches[modes.sliding].name
                    raise SimulationError(
                        f"the state slides along two switches at once ({other} and {name}) at "
                        f"{t:g} s, which is not supported"
                    )
                modes.sliding = k
            elif below < 0.0 and above > 0.0:
                continue  # both sides lead away: the mode it came in stays
            elif below > 0.0 or above > 0.0:
                modes.on[name] = True
            elif below < 0.0 or above < 0.0:
                modes.on[name] = False
        self.system.forget()

    def f_now(self, t: float, x: FloatArray, u: FloatArray) -> FloatArray:
        """The model's f in the current mode (Filippov's in a sliding one)."""
        return np.asarray(self.moded(t, x, u, self.system.values), dtype=float).reshape(-1)

    # the jump ----------------------------------------------------------------------------------
    def jump(
        self,
        k: int,
        t: float,
        z: FloatArray,
        u: FloatArray,
        before: FloatArray,
        after: FloatArray,
        n: int,
        q: int,
        scale: FloatArray,
    ) -> FloatArray:
        """The state z with S⁺ = S⁻ + (f⁺ − f⁻)·(g_x·S⁻ + g_φ)/(g_x·f⁻ + g_t) (module docstring)."""
        if q == 0:
            return z
        x = z[:n]
        system = self.system
        g = self.switches[k].function
        slope = state_gradient(g, t, x, u, system.values, self.scale)
        rise = float(slope @ before) + float(time_derivative(g, t, x, u, system.values))
        if not math.isfinite(rise) or rise == 0.0:
            return z  # a grazing touch: the switching time does not move to first order
        g_phi = np.zeros(q)
        for j in range(len(scale)):
            name = system.free[j]
            step = _DIFFERENCE * max(abs(system.values[name]), 1.0)
            up, down = dict(system.values), dict(system.values)
            up[name] += step
            down[name] -= step
            g_phi[j] = (float(g(t, x, u, up)) - float(g(t, x, u, down))) / (2.0 * step) * scale[j]
        sens = z[n:].reshape(n, q)
        moved = (slope @ sens + g_phi) / rise
        out = z.copy()
        out[n:] = (sens + np.outer(after - before, moved)).ravel()
        return out

    # a piece -----------------------------------------------------------------------------------
    def events(self, u: FloatArray) -> list[Callable[[float, FloatArray], float]]:
        """The current mode's terminal events: each g leaving its side, or a slide's ends."""
        n = self.system.n_states
        values = self.system.values
        found: list[Callable[[float, FloatArray], float]] = []
        for k, switch in enumerate(self.switches):
            if k == self.modes.sliding:
                for on, direction in ((False, -1.0), (True, 1.0)):
                    found.append(self._slide_end(k, on, direction, u))
                continue
            g = switch.function
            on = self.modes.on[switch.name]
            # past the band: on → off where g falls through −δ, off → on where it rises through δ
            offset = self.bands[k] if on else -self.bands[k]

            def crossing(
                t: float, z: FloatArray, g: SwitchFunction = g, offset: float = offset
            ) -> float:
                return float(g(t, z[:n], u, values)) + offset

            crossing.terminal = True  # type: ignore[attr-defined]
            crossing.direction = -1.0 if on else 1.0  # type: ignore[attr-defined]
            crossing.switch = (k, None)  # type: ignore[attr-defined]
            found.append(crossing)
        return found

    def _slide_end(
        self, k: int, on: bool, direction: float, u: FloatArray
    ) -> Callable[[float, FloatArray], float]:
        n = self.system.n_states
        values = self.system.values
        g = self.switches[k].function

        def end(t: float, z: FloatArray) -> float:
            side = self.moded.side(t, z[:n], u, values, k, on)
            return float(rate_of_change(g, t, z[:n], u, values, side, self.scale))

        end.terminal = True  # type: ignore[attr-defined]
        end.direction = direction  # type: ignore[attr-defined]
        end.switch = (k, on)  # type: ignore[attr-defined]
        return end

    def cross(
        self, event: Any, t: float, z: FloatArray, u: FloatArray, n: int, q: int, scale: FloatArray
    ) -> FloatArray:
        """The new mode after ``event`` fired at (t, z), and z with S's jump applied."""
        k, leaves_to = event.switch
        if leaves_to is not None:  # a slide ends where f is continuous: S does not jump
            self.modes.sliding = None
            self.modes.on[self.switches[k].name] = leaves_to
            self.system.forget()
            return z
        before = self.f_now(t, z[:n], u)
        self.settle(t, z[:n], u, at=k)
        after = self.f_now(t, z[:n], u)
        return self.jump(k, t, z, u, before, after, n, q, scale)


def switched_integrator(
    system: Any, n: int, q: int, scale: FloatArray
) -> Callable[..., tuple[FloatArray, int]] | None:
    """A piece integrator (the signature of ``integrate_piece``) for a system with switches."""
    switching: _Switching | None = getattr(system, "switched", None)
    if switching is None:
        return None

    def integrate(
        solver: Solver,
        rhs: Rhs,
        newton: Newton | None,
        z: FloatArray,
        times: FloatArray,
        u: FloatArray,
        rtol: float | FloatArray,
        atol: FloatArray,
        budget: int | None = None,
    ) -> tuple[FloatArray, int]:
        return _piece(switching, solver, rhs, newton, z, times, u, rtol, atol, budget, n, q, scale)

    return integrate


def _piece(
    switching: _Switching,
    solver: Solver,
    rhs: Rhs,
    newton: Newton | None,
    z: FloatArray,
    times: FloatArray,
    u: FloatArray,
    rtol: float | FloatArray,
    atol: FloatArray,
    budget: int | None,
    n: int,
    q: int,
    scale: FloatArray,
) -> tuple[FloatArray, int]:
    """One held-input piece: solve_ivp from switch to switch, S jumping at each."""
    if solver.method not in _METHODS:
        raise UnlocatedSwitches(
            "rk4 cannot locate the model's declared switches (solve_ivp events): use lsoda, bdf, "
            "radau or rk45"
        )
    x = z[:n]
    switching.rtol = float(np.min(rtol))
    # a new piece: a held input that changed may move a g across zero at this instant (a
    # switch at a fixed time: S does not jump), and a state left on g = 0 takes its direction
    switching.settle(float(times[0]), x, u)
    limit = solver.steps_per_sample * max(10, len(times) - 1)
    if budget is not None:
        limit = max(1, min(limit, budget))
    fun, count = budgeted(rhs, u, limit)

    jac = None
    if newton is not None and solver.method in {"bdf", "radau", "lsoda"}:

        def jac(t: float, state: FloatArray) -> FloatArray:
            return np.array(newton(t, state, u), dtype=float)

    # LSODA and RK45 take the sensitivity rows' looser tolerance; the implicit ones take one
    tolerance: float | FloatArray = (
        rtol if solver.method in {"lsoda", "rk45"} else float(np.min(rtol))
    )
    out = np.empty((len(times) - 1, len(z)))
    filled = 0
    t_now, z_now = float(times[0]), np.array(z, dtype=float)
    t_end = float(times[-1])
    for _ in range(MAX_SWITCHES_PER_PIECE + 1):
        remaining = times[1 + filled :]
        events = switching.events(u)
        try:
            result = scipy.integrate.solve_ivp(
                fun,
                (t_now, t_end),
                z_now,
                method=_METHODS[solver.method],
                t_eval=remaining,
                events=events or None,
                rtol=tolerance,
                atol=atol,
                max_step=math.inf if solver.max_step is None else solver.max_step,
                **({"jac": jac} if jac is not None else {}),
            )
        except BudgetSpent:
            raise SimulationError(
                f"the ODE solver ({solver.method}) needed more than {limit} evaluations on "
                f"{times[0]:g}…{t_end:g} s between the model's switches"
            ) from None
        if result.status < 0:
            raise SimulationError(f"the ODE solver ({solver.method}) failed: {result.message}")
        # (no output time before the switch: solve_ivp leaves y an empty list)
        reached = np.asarray(result.y, dtype=float).reshape(len(z_now), -1)
        got = reached.shape[1]
        out[filled : filled + got] = reached.T
        filled += got
        if result.status != 1:
            break
        fired = min(
            (float(times_k[0]), i) for i, times_k in enumerate(result.t_events) if len(times_k)
        )
        index = fired[1]
        t_now = fired[0]
        z_now = switching.cross(
            events[index], t_now, np.array(result.y_events[index][0]), u, n, q, scale
        )
        if filled >= len(times) - 1:
            if t_now >= t_end:
                out[-1] = z_now  # a switch at the piece's last time: the next starts after it
            break
    else:
        raise SimulationError(
            f"more than {MAX_SWITCHES_PER_PIECE} switches on {times[0]:g}…{t_end:g} s (the "
            "model chatters between its modes)"
        )
    if filled != len(times) - 1:
        raise SimulationError(f"the ODE solver ({solver.method}) stopped short of {t_end:g} s")
    return out, count[0]
