"""Gray-box models with kinks and switches, their references, and records simulated from them.

Written as a user writes them (``max``, ``min``, ``if`` on scalars). The references are exact
where the model allows it (a linear tank behind a clipped input: the zero-order-hold solution)
and otherwise a tight error-controlled DOP853 integration, which finds each kink by step
rejection; the sliding switch's reference is a very fine explicit Euler (its error is first
order in the step, like any method's at a sliding switch).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from fuelid.greybox import OdeModel, ParameterSpec, Record

FloatArray = NDArray[np.float64]
Rhs = Callable[[float, Any, Any, Mapping[str, Any]], Any]
H_RIM = 2.0
"""The overflow tank's rim [m]."""


def overflow_f(t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    """A tank with an overflow pipe above its rim: Torricelli outflow plus c·(level − rim)."""
    level = max(x[0], 0.0)
    return [p["a"] * u[0] - p["b"] * math.sqrt(level) - p["c"] * max(x[0] - H_RIM, 0.0)]


def valve_f(t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    """A valve at its stop (opening clipped to 0…u_max) feeding a linear tank."""
    opening = min(max(u[0], 0.0), p["u_max"])
    return [(p["K"] * opening - x[0]) / p["T"]]


def pump_f(t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    """A pump that cannot run backwards: no flow once the tank's head exceeds what it gives."""
    flow = max(p["k"] * u[0] - p["r"] * x[0], 0.0)
    return [flow - x[0] / p["T"]]


def drain_f(t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    """A switch that slides: a drain taking a fixed 0.05 m/s whenever the level is above the rim.

    Below the rim the level rises, above it falls: it chatters on the rim, where an
    error-controlled solver shrinks its step without end.
    """
    rate = p["a"] * u[0] - p["b"] * math.sqrt(max(x[0], 0.0))
    if x[0] > H_RIM:
        rate -= 0.05
    return [rate]


def stiff_drain_f(t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    """The sliding drain behind an actuator 10⁴ times faster than the 1 s samples."""
    return [1e4 * (u[0] - x[0]), drain_f(t, x[1:], x[:1], p)[0]]


TRUTH: dict[str, dict[str, float]] = {
    "overflow": {"a": 0.2, "b": 0.1, "c": 0.3},
    "valve": {"K": 2.0, "T": 8.0, "u_max": 0.8},
    "pump": {"k": 1.0, "r": 0.5, "T": 10.0},
    "drain": {"a": 0.2, "b": 0.1},
}
FUNCTIONS: dict[str, Rhs] = {
    "overflow": overflow_f,
    "valve": valve_f,
    "pump": pump_f,
    "drain": drain_f,
}
INPUT_RANGE = {
    "overflow": (0.5, 1.1),  # the level crosses the rim (steady level (a·u/b)² is 1…4.8 m)
    "valve": (0.0, 1.2),  # the opening reaches its stop, 0.8
    "pump": (0.0, 1.0),  # falling inputs leave the head above what the pump gives
    "drain": (0.4, 0.95),
}


def held_steps(rng: np.random.Generator, n: int, low: float, high: float) -> FloatArray:
    """Random levels, each held 30 to 90 samples, from the upper and lower half of the range.

    The halves alternate: every record crosses its model's kinks both ways (the rim reached and
    left, the check valve opened and closed), so what acts only beyond them is determined.
    """
    u = np.empty(n)
    middle = 0.5 * (low + high)
    k, upper = 0, bool(rng.integers(0, 2))
    while k < n:
        hold = int(rng.integers(30, 91))
        u[k : k + hold] = rng.uniform(middle, high) if upper else rng.uniform(low, middle)
        k += hold
        upper = not upper
    return u


def valve_exact(
    u: FloatArray, p: Mapping[str, float], x0: float = 0.0, dt: float = 1.0
) -> FloatArray:
    """The valve tank's level at each sample: the zero-order-hold solution, exact."""
    a = math.exp(-dt / p["T"])
    x = np.empty(len(u))
    level = x0
    for k, u_k in enumerate(u):
        x[k] = level
        level = a * level + (1.0 - a) * p["K"] * min(max(u_k, 0.0), p["u_max"])
    return x


def fine_reference(
    f: Rhs, u: FloatArray, p: Mapping[str, float], x0: float, dt: float = 1.0
) -> FloatArray:
    """The state at each sample by DOP853 at rtol 1e-11 (kinks found by step rejection)."""
    x = np.array([x0], dtype=float)
    out = np.empty(len(u))
    for k, u_k in enumerate(u):
        out[k] = x[0]
        step = solve_ivp(
            lambda t, z, level=u_k: f(t, z, [level], p),
            (0.0, dt),
            x,
            method="DOP853",
            rtol=1e-11,
            atol=1e-12,
        )
        x = step.y[:, -1]
    return out


def sliding_reference(u: FloatArray, p: Mapping[str, float], x0: float) -> FloatArray:
    """The drain's level at each sample by explicit Euler with 2,000 steps per sample."""
    steps = 2000
    h = 1.0 / steps
    x = x0
    out = np.empty(len(u))
    for k, u_k in enumerate(u):
        out[k] = x
        for _ in range(steps):
            x += h * drain_f(0.0, [x], [u_k], p)[0]
    return out


def reference(name: str, u: FloatArray, p: Mapping[str, float], x0: float) -> FloatArray:
    """The named model's reference level at each sample."""
    if name == "valve":
        return valve_exact(u, p, x0)
    if name == "drain":
        return sliding_reference(u, p, x0)
    return fine_reference(FUNCTIONS[name], u, p, x0)


X0 = {"overflow": 1.0, "valve": 0.0, "pump": 0.0, "drain": 1.0}


def kinked_model(name: str, start: Mapping[str, float]) -> OdeModel:
    """The named model, every parameter free from ``start`` (lower bound 0), x0 known."""
    level = X0[name]
    return OdeModel(
        FUNCTIONS[name],
        [ParameterSpec(key, value, 0.0) for key, value in start.items()],
        ["level"],
        x0=lambda p, u0, y0: [level],
    )


def kinked_record(
    name: str,
    seed: int,
    n: int = 400,
    noise: float = 0.01,
    input_range: tuple[float, float] | None = None,
    truth: Mapping[str, float] | None = None,
) -> tuple[Record, FloatArray]:
    """A record of the named model (1 s samples, held random steps) and its noise-free level."""
    rng = np.random.default_rng(seed)
    low, high = input_range or INPUT_RANGE[name]
    u = held_steps(rng, n, low, high)
    clean = reference(name, u, truth or TRUTH[name], X0[name])
    y = clean + noise * rng.standard_normal(n)
    return Record.from_arrays(np.arange(n, dtype=float), u, y, name=name), clean
