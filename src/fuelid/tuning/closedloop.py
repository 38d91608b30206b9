"""Closed-loop simulation on the nonlinear plant: the PLC's discrete PI against the physics.

The controller is the positional PI of Åström & Hägglund's PID code: at each period h it reads
the (delayed, lagged, noisy, quantised) flowmeter, outputs u = sat(Kc·e + I) within the 1–5 V
signal range and then updates the integral, I ← I + Kc·h/Ti·e + (h/Tt)·(u − v) (forward Euler
plus back-calculation anti-windup with tracking time Tt). Gain changes are bumpless: the integral
absorbs the change of the proportional term so the output does not jump.

:func:`simulate_closed_loop` runs it against the nonlinear plant (one
:func:`fuelid.plant.simulate.integrate_held` per control period, the integration that
:func:`fuelid.plant.simulate.simulate` uses), the meter's delay applied exactly on a fine
output grid, the limits and anti-windup active, setpoint steps and load disturbances (a step at
the plant input, in V: a drive offset, pump wear). :func:`standard_runs` is the test
``fuelid tune --simulate`` and ``fuelid report`` show. The fast linear loop on the process model
lives in :mod:`fuelid.tuning._linearloop` and the step metrics in :mod:`fuelid.tuning._metrics`;
both are re-exported here. Fuel temperatures are in kelvin (``T_fuel``), flows in L/min, commands
in V (docs/explanation/tuning.md, section 6).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from fuelid.errors import FuelidError
from fuelid.plant import (
    PlantConfig,
    measure_flow,
    measured_state,
    operating_point,
    plant_coefficients,
    steady_state,
)
from fuelid.plant.simulate import integrate_held
from fuelid.profiles import InputProfile
from fuelid.tuning._controller import DiscretePI
from fuelid.tuning._linearloop import (
    CONTINUOUS_PERIOD,
    LinearResponse,
    closed_loop_poles,
    linear_closed_loop,
    linear_period,
)
from fuelid.tuning._metrics import (
    SETTLING_BAND,
    StepMetrics,
    disturbance_metrics,
    setpoint_step_metrics,
)
from fuelid.tuning._rules import PISettings
from fuelid.units import LPM_PER_M3S, kelvin_to_celsius

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "CONTINUOUS_PERIOD",
    "SETTLING_BAND",
    "ClosedLoopResult",
    "DiscretePI",
    "LinearResponse",
    "StepMetrics",
    "closed_loop_poles",
    "disturbance_metrics",
    "flow_at",
    "linear_closed_loop",
    "linear_period",
    "place_step",
    "reachable_flows",
    "setpoint_step_metrics",
    "simulate_closed_loop",
    "standard_runs",
    "standard_scenario",
    "steady_command",
]

FloatArray = NDArray[np.float64]


@dataclass
class ClosedLoopResult:
    """A closed-loop run on the nonlinear plant, on the fine output grid.

    Signals in engineering units (the PLC's), the fuel temperature in kelvin; :meth:`to_json`
    gives the documented JSON, the fuel temperature in °C.
    """

    time: FloatArray
    """[s]"""
    setpoint: FloatArray
    """[L/min]"""
    flow: FloatArray
    """Meter reading as the PLC logs it (lag, delay, noise, quantisation) [L/min]. At every
    control instant it is exactly what the controller read."""
    command: FloatArray
    """Controller output held [V]."""
    disturbance: FloatArray
    """Load disturbance added at the plant input [V]."""
    T_fuel: float
    """Fuel temperature [K]."""
    control_period: float
    """[s]"""
    events: list[StepMetrics] = field(default_factory=list)
    """Metrics of every setpoint step and disturbance, in time order."""
    time_at_limits: float = 0.0
    """Time the command spent at 1 V or 5 V [s]."""

    @property
    def start_flow(self) -> float:
        """Flow the run started at rest at [L/min]."""
        return float(self.setpoint[0])

    def summary(self) -> dict[str, float]:
        """Worst case over the run's events: overshoot, settling, IAE, time at the limits."""

        def worst(kind: str, name: str) -> float:
            values = [getattr(e, name) for e in self.events if e.kind == kind]
            if not values:
                return math.nan
            return math.nan if any(math.isnan(v) for v in values) else max(values)

        return {
            "overshoot_percent": worst("setpoint", "overshoot_percent"),
            "settling_time": worst("setpoint", "settling_time"),
            "iae": float(sum(e.iae for e in self.events)),
            "disturbance_peak": worst("disturbance", "peak_deviation"),
            "disturbance_settling_time": worst("disturbance", "settling_time"),
            "time_at_limits": self.time_at_limits,
        }

    def to_json(self, events: bool = True) -> dict[str, Any]:
        """The run as documented JSON: ``fuel_temperature`` [°C], ``start_flow``, ``summary``.

        With ``events`` also the metrics of every event (``events``), as ``fuelid tune --json``
        gives them; ``fuelid report --json`` leaves them out.
        """
        out: dict[str, Any] = {
            "fuel_temperature": kelvin_to_celsius(self.T_fuel),
            "start_flow": self.start_flow,
            "summary": self.summary(),
        }
        if events:
            out["events"] = [e.to_json() for e in self.events]
        return out

    def to_pandas(self) -> pd.DataFrame:
        """Columns ``t_s``, ``r_Lpm``, ``q_Lpm``, ``u_V``, ``d_V``."""
        import pandas as pd

        return pd.DataFrame(
            {
                "t_s": self.time,
                "r_Lpm": self.setpoint,
                "q_Lpm": self.flow,
                "u_V": self.command,
                "d_V": self.disturbance,
            }
        )


def steady_command(config: PlantConfig, flow_Lpm: float, T_fuel: float) -> float:
    """The command [V] that holds ``flow_Lpm`` at rest at fuel temperature ``T_fuel`` [K]."""
    c = plant_coefficients(config, T_fuel)

    def excess(u: float) -> float:
        return steady_state(u, c).q * LPM_PER_M3S - flow_Lpm

    lo, hi = excess(c.u_min), excess(c.u_max)
    if not lo <= 0.0 <= hi:
        raise FuelidError(
            f"flow {flow_Lpm:g} L/min is outside what the plant delivers at this fuel "
            f"temperature ({lo + flow_Lpm:.2f}…{hi + flow_Lpm:.2f} L/min)"
        )
    return float(scipy.optimize.brentq(excess, c.u_min, c.u_max, xtol=1e-12))


def _reading(
    times: FloatArray,
    grid: FloatArray,
    q_m: FloatArray,
    delay: float,
    noise: FloatArray | None,
    resolution: float,
) -> FloatArray:
    """What the PLC reads at ``times``: the meter state ``delay`` earlier, plus noise, quantised.

    ``grid`` and ``q_m`` hold the lagged meter state [L/min] up to the last of ``times`` at least
    (only ``times − delay`` is read); ``noise`` holds one draw per time of ``times``.
    """
    y = np.interp(times - delay, grid, q_m, left=q_m[0])
    if noise is not None:
        y = y + noise
    return measure_flow(y, resolution=resolution)


def simulate_closed_loop(
    config: PlantConfig,
    pi: PISettings,
    setpoint: InputProfile,
    *,
    T_fuel: float = 293.15,
    disturbance: InputProfile | None = None,
    sample_time: float = 0.02,
    noise_std: float = 0.0,
    resolution: float = 0.0,
    seed: int | None = None,
    gain_changes: dict[float, tuple[float, float]] | None = None,
) -> ClosedLoopResult:
    """Run the PLC's PI against the nonlinear plant.

    The plant starts at rest at the first setpoint (the controller's integral at the command that
    holds it). Events (setpoint and disturbance changes) take effect at the next control instant.
    The flow is logged on the output grid as the PLC reads it (the meter's lag and delay, white
    noise, then quantisation), and at every control instant the controller acts on exactly that
    logged reading: ``setpoint − flow`` there is the error it saw.

    Parameters
    ----------
    config : PlantConfig
        The plant; its drive's signal range gives the output limits.
    pi : PISettings
        The controller (control period 0: simulated at 0.02 s).
    setpoint : InputProfile
        Flow setpoint over time [L/min]; its duration is the run's.
    T_fuel : float
        Fuel temperature [K], constant over the run.
    disturbance : InputProfile, optional
        Load disturbance added to the command at the plant input [V] (clipped to the drive range).
    sample_time : float
        Output grid [s] (the meter's delay is applied on it by interpolation).
    noise_std : float
        Meter noise standard deviation [L/min], one draw per logged sample.
    resolution : float
        Quantisation step of the reading [L/min], after the noise (0: none).
    seed : int, optional
        Seed of the noise.
    gain_changes : dict, optional
        {time [s]: (Kc, Ti)}: bumpless gain changes (as a schedule would make them).

    Returns
    -------
    ClosedLoopResult

    Raises
    ------
    FuelidError
        On a negative noise level or resolution, a non-positive sample time, a run shorter than
        one control period, a start flow the plant cannot hold, or a failed ODE solve
        (:func:`fuelid.plant.simulate.integrate_held`).
    """
    h = pi.control_period if pi.control_period > 0.0 else CONTINUOUS_PERIOD
    if not (math.isfinite(sample_time) and sample_time > 0.0):
        raise FuelidError(f"sample time must be positive, got {sample_time:g} s")
    if not (math.isfinite(noise_std) and noise_std >= 0.0):
        raise FuelidError(f"noise standard deviation must not be negative, got {noise_std:g}")
    if not (math.isfinite(resolution) and resolution >= 0.0):
        raise FuelidError(f"resolution must not be negative, got {resolution:g} L/min")
    c = plant_coefficients(config, T_fuel)
    duration = setpoint.duration
    n_periods = math.floor(duration / h + 1e-9)
    if n_periods < 1:
        raise FuelidError(f"a closed-loop run needs at least one control period of {h:g} s")
    instants = np.round(np.arange(n_periods + 1) * h, 12)
    grid = np.unique(
        np.concatenate((np.round(np.arange(0.0, duration + 1e-9, sample_time), 12), instants))
    )
    at_instant = np.searchsorted(grid, instants)  # every instant is a grid point
    u0 = steady_command(config, float(setpoint.u[0]), T_fuel)
    x = steady_state(u0, c).state
    meter_state = measured_state(c)  # without a meter lag the reading is the flow q
    q_m = np.full(grid.size, x[meter_state] * LPM_PER_M3S)
    rng = np.random.default_rng(seed)
    noise = rng.normal(0.0, noise_std, grid.size) if noise_std > 0.0 else None
    flow = np.empty(grid.size)  # the logged reading, filled period by period
    flow[:1] = _reading(grid[:1], grid[:1], q_m[:1], c.delay, _part(noise, 0, 1), resolution)
    controller = DiscretePI(pi, c.u_min, c.u_max, u0)
    pending = dict(sorted((gain_changes or {}).items()))
    commands = np.empty(n_periods)
    d_held = np.zeros(n_periods)
    at_limits = 0
    for k in range(n_periods):
        t0 = float(instants[k])
        for when in [w for w in pending if w <= t0 + 1e-12]:
            controller.set_gains(*pending.pop(when))
        # the controller acts on the reading logged at this instant, nothing else
        u = controller.update(float(setpoint.at(t0)[()]), float(flow[at_instant[k]]))
        at_limits += u <= c.u_min or u >= c.u_max
        d = float(disturbance.at(t0)[()]) if disturbance is not None else 0.0
        commands[k], d_held[k] = u, d
        applied = min(max(u + d, c.u_min), c.u_max)
        first, last = at_instant[k] + 1, at_instant[k + 1] + 1  # grid points in (t0, t1]
        points = np.concatenate(([t0], grid[first:last]))
        states = integrate_held(x, points, applied, c)
        q_m[first:last] = states[1:, meter_state] * LPM_PER_M3S
        x = states[-1]
        # the readings up to t1 need the meter state up to t1 − delay only: all known now
        flow[first:last] = _reading(
            grid[first:last],
            grid[:last],
            q_m[:last],
            c.delay,
            _part(noise, first, last),
            resolution,
        )
    tail = at_instant[-1] + 1  # grid points after the last instant (a duration off the period)
    if tail < grid.size:
        x_tail = integrate_held(
            x,
            np.concatenate(([grid[tail - 1]], grid[tail:])),
            min(max(commands[-1] + d_held[-1], c.u_min), c.u_max),
            c,
        )
        q_m[tail:] = x_tail[1:, meter_state] * LPM_PER_M3S
        flow[tail:] = _reading(
            grid[tail:], grid, q_m, c.delay, _part(noise, tail, grid.size), resolution
        )
    k_of = np.minimum(np.searchsorted(instants, grid, side="right") - 1, n_periods - 1)
    r = np.asarray(setpoint.at(grid), dtype=float)
    result = ClosedLoopResult(
        time=grid,
        setpoint=r,
        flow=flow,
        command=commands[k_of],
        disturbance=d_held[k_of],
        T_fuel=T_fuel,
        control_period=pi.control_period,
        time_at_limits=at_limits * h,
    )
    result.events.extend(_event_metrics(result, setpoint, disturbance))
    return result


def _part(noise: FloatArray | None, start: int, stop: int) -> FloatArray | None:
    return None if noise is None else noise[start:stop]


def _event_metrics(
    run: ClosedLoopResult, setpoint: InputProfile, disturbance: InputProfile | None
) -> list[StepMetrics]:
    """Metrics of every setpoint change and disturbance change, each up to the next event."""
    events: list[tuple[float, str, float, float]] = []
    for i in range(1, setpoint.t.size):
        if setpoint.u[i] == setpoint.u[i - 1]:
            continue
        events.append((float(setpoint.t[i]), "setpoint", setpoint.u[i - 1], setpoint.u[i]))
    if disturbance is not None:
        for i in range(1, disturbance.t.size):
            if disturbance.u[i] == disturbance.u[i - 1]:
                continue
            events.append(
                (float(disturbance.t[i]), "disturbance", disturbance.u[i - 1], disturbance.u[i])
            )
    events.sort()
    out = []
    for j, (start, kind, before, after) in enumerate(events):
        stop = events[j + 1][0] if j + 1 < len(events) else run.time[-1] + 1.0
        window = (run.time >= start) & (run.time < stop)
        t, y = run.time[window], run.flow[window]
        if t.size < 3:
            continue
        if kind == "setpoint":
            out.append(setpoint_step_metrics(t, y, before, after, start))
        else:
            r = float(run.setpoint[window][0])
            out.append(disturbance_metrics(t, y, r, after - before, start))
    return out


def standard_scenario(
    flow: float,
    step: float,
    load: float = 0.2,
    t_step: float = 5.0,
    t_load: float = 45.0,
    duration: float = 90.0,
) -> tuple[InputProfile, InputProfile]:
    """The standard closed-loop test: a setpoint step, then a load step at the plant input.

    Parameters
    ----------
    flow : float
        Initial flow (the plant starts at rest there) [L/min].
    step : float
        Setpoint step at ``t_step`` [L/min].
    load : float
        Load disturbance step at the plant input at ``t_load`` [V].

    Returns
    -------
    (setpoint, disturbance) : InputProfile, InputProfile

    Examples
    --------
    >>> r, d = standard_scenario(30.0, 10.0)
    >>> r.u.tolist(), d.t.tolist(), d.u.tolist()
    ([30.0, 40.0], [0.0, 45.0], [0.0, 0.2])
    """
    setpoint = InputProfile(np.array([0.0, t_step]), np.array([flow, flow + step]), duration)
    disturbance = InputProfile(np.array([0.0, t_load]), np.array([0.0, load]), duration)
    return setpoint, disturbance


def reachable_flows(
    config: PlantConfig, T_fuels: Sequence[float], headroom: float = 0.05
) -> tuple[float, float]:
    """Flows [L/min] the drive holds at rest at every one of the fuel temperatures [K].

    The common range of the steady flows at the lowest and highest command, narrowed by
    ``headroom`` (a fraction of it) at each end so that a controller holding a flow there still
    has room to act on a load disturbance.
    """
    lows = [flow_at(config, config.vfd.u_min_V, T) for T in T_fuels]
    highs = [flow_at(config, config.vfd.u_max_V, T) for T in T_fuels]
    lo, hi = max(lows), min(highs)
    if not hi > lo:
        shown = ", ".join(f"{kelvin_to_celsius(T):g}" for T in T_fuels)
        raise FuelidError(
            f"no flow is reachable at every fuel temperature [{shown}] °C ({lo:.2f}…{hi:.2f} L/min)"
        )
    margin = headroom * (hi - lo)
    return lo + margin, hi - margin


def place_step(flow: float, step: float, lo: float, hi: float) -> tuple[float, float]:
    """A start flow and setpoint step [L/min] that stay within ``lo``…``hi``.

    The start is ``flow`` brought inside the range; the step keeps its size and, where the
    range allows, its direction, else it turns round; a step wider than the range shrinks to it.

    Examples
    --------
    >>> place_step(30.0, 10.0, 15.0, 60.0)  # fits as asked
    (30.0, 10.0)
    >>> place_step(55.0, 10.0, 15.0, 60.0)  # no room above: step down
    (55.0, -10.0)
    >>> place_step(70.0, 10.0, 15.0, 60.0)  # start beyond the drive: from its top, down
    (60.0, -10.0)
    >>> place_step(20.0, 10.0, 15.0, 22.0)  # range narrower than the step
    (15.0, 7.0)
    """
    start = min(max(flow, lo), hi)
    for signed in (step, -step):
        if lo <= start + signed <= hi:
            return start, signed
    size = min(abs(step), hi - lo)
    if step > 0:
        return min(start, hi - size), size
    return max(start, lo + size), -size


def standard_runs(
    config: PlantConfig,
    pi: PISettings,
    T_fuels: Sequence[float],
    flow: float,
    step: float,
) -> list[ClosedLoopResult]:
    """The standard test (:func:`standard_scenario`) on the nonlinear plant at each temperature.

    Every run starts at rest at the same flow, so the runs differ only by the fuel. The start
    and the step are placed within what the drive delivers at every one of the temperatures
    (:func:`reachable_flows`, :func:`place_step`): near the top of the range the step goes
    down; each run's ``setpoint`` says what was run.

    Parameters
    ----------
    config : PlantConfig
        The plant.
    pi : PISettings
        The controller.
    T_fuels : sequence of float
        Fuel temperatures [K], one run each.
    flow : float
        Flow the runs start at [L/min] (moved into the reachable range if outside it).
    step : float
        Setpoint step [L/min] (turned round or shrunk if it leaves the reachable range).
    """
    start, signed = place_step(flow, step, *reachable_flows(config, T_fuels))
    runs = []
    for T_fuel in T_fuels:
        setpoint, load = standard_scenario(start, signed)
        runs.append(simulate_closed_loop(config, pi, setpoint, T_fuel=T_fuel, disturbance=load))
    return runs


def flow_at(config: PlantConfig, u: float, T_fuel: float) -> float:
    """Steady flow [L/min] the command ``u`` [V] gives with fuel at ``T_fuel`` [K]."""
    return float(operating_point(config, u, T_fuel).q * LPM_PER_M3S)
