"""Closed-loop simulation: the PLC's discrete PI on the linear model or on the nonlinear plant.

The controller is the positional PI of Åström & Hägglund's PID code: at each period h it reads
the (delayed, lagged) flowmeter, outputs u = sat(Kc·e + I) within the 1–5 V signal range and then
updates the integral, I ← I + Kc·h/Ti·e + (h/Tt)·(u − v) (forward Euler plus back-calculation
anti-windup with tracking time Tt). Gain changes are bumpless: the integral absorbs the change of
the proportional term so the output does not jump.

Two simulators share the metrics:

- :func:`linear_closed_loop`: the process model, exact at every instant (the ZOH closed loop is a
  rational filter at the control instants; the output between them comes from the plant
  discretised on a finer grid). No limits: this is the fast path for sweeps.
- :func:`simulate_closed_loop`: the nonlinear plant (LSODA per control period, as
  :func:`fuelid.simulate.simulate`), the meter's delay applied exactly on a fine output grid,
  the limits and anti-windup active, setpoint steps and load disturbances (a step at the plant
  input, in V: a drive offset, pump wear).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import scipy.integrate
import scipy.optimize
import scipy.signal
from numpy.typing import NDArray

from fuelid import lti
from fuelid.errors import FuelidError
from fuelid.lti import discretise
from fuelid.model import ProcessModel
from fuelid.plant.config import PlantConfig
from fuelid.plant.system import (
    operating_point,
    plant_coefficients,
    plant_jacobian,
    plant_rhs,
    steady_state,
)
from fuelid.profiles import InputProfile
from fuelid.simulate import ATOL, RTOL
from fuelid.tuning.rules import PISettings
from fuelid.units import LPM_PER_M3S
from fuelid.units import T0 as KELVIN

FloatArray = NDArray[np.float64]
SETTLING_BAND = 0.02
CONTINUOUS_PERIOD = 0.02
"""Period [s] at which a continuous controller (control period 0) is simulated."""


class DiscretePI:
    """The PLC's PI: positional, forward-Euler integral, output limits, back-calculation.

    Parameters
    ----------
    settings : PISettings
        Kc [V per L/min], Ti [s], control period h [s] (0: simulated at 0.02 s).
    u_min, u_max : float
        Output limits [V] (the 1–5 V signal).
    u0 : float
        Output at start-up [V]; the integral starts there (bumpless start from manual).
    tracking_time : float, optional
        Anti-windup tracking time Tt [s] (back-calculation). With the default Tt = h the output
        computed for the current error is brought back to the limit within one period, so the
        integral cannot run away while saturated (it settles where Kc·e + integral sits at the
        limit, which may itself lie outside the limits while the error is large).

    Examples
    --------
    >>> pi = DiscretePI(PISettings("simc", Kc=0.1, Ti=2.0, control_period=1.0), 1.0, 5.0, u0=2.0)
    >>> pi.update(setpoint=30.0, measurement=25.0)  # 2 V + 0.1·5
    2.5
    >>> pi.update(setpoint=30.0, measurement=-1000.0)  # saturated at the top
    5.0
    """

    def __init__(
        self,
        settings: PISettings,
        u_min: float,
        u_max: float,
        u0: float,
        tracking_time: float | None = None,
    ) -> None:
        if not u_min < u_max:
            raise FuelidError(f"output limits must satisfy u_min < u_max, got {u_min}…{u_max}")
        self.h = settings.control_period if settings.control_period > 0.0 else CONTINUOUS_PERIOD
        self.Kc = settings.Kc
        self.Ti = settings.Ti
        self.u_min = u_min
        self.u_max = u_max
        self.tracking_time = self.h if tracking_time is None else tracking_time
        if not self.tracking_time > 0.0:
            raise FuelidError("the anti-windup tracking time must be positive")
        self.integral = float(np.clip(u0, u_min, u_max))
        self._last_error = 0.0

    def update(self, setpoint: float, measurement: float) -> float:
        """One control period: read, output the limited command [V], update the integral."""
        e = setpoint - measurement
        v = self.Kc * e + self.integral
        u = min(max(v, self.u_min), self.u_max)
        self.integral += self.Kc * self.h / self.Ti * e + self.h / self.tracking_time * (u - v)
        self._last_error = e
        return u

    def set_gains(self, Kc: float, Ti: float) -> None:
        """Change the gains bumplessly: the output for the last error stays the same."""
        if not (Kc > 0.0 and Ti > 0.0):
            raise FuelidError("controller gains must be positive")
        self.integral += (self.Kc - Kc) * self._last_error
        self.Kc, self.Ti = Kc, Ti


@dataclass(frozen=True)
class StepMetrics:
    """Quality of one setpoint step or one load disturbance."""

    kind: str
    """"setpoint" or "disturbance"."""
    start: float
    """When the step was applied [s]."""
    size: float
    """Setpoint change [L/min] or disturbance step [V]."""
    overshoot_percent: float
    """Setpoint: peak beyond the new setpoint in % of the step; disturbance: nan."""
    peak_deviation: float
    """Largest |setpoint − measurement| after a disturbance [L/min]; for a step, beyond it."""
    settling_time: float
    """Setpoint: time to stay within 2 % of the step; disturbance: within 2 % of the setpoint
    [s]; nan if not settled before the next event."""
    iae: float
    """Integral of |setpoint − measurement| over the event's window [(L/min)·s]."""

    def as_dict(self) -> dict[str, float | str]:
        """Plain dictionary for JSON."""
        return {
            "kind": self.kind,
            "start": self.start,
            "size": self.size,
            "overshoot_percent": self.overshoot_percent,
            "peak_deviation": self.peak_deviation,
            "settling_time": self.settling_time,
            "iae": self.iae,
        }


def setpoint_step_metrics(
    t: FloatArray, y: FloatArray, r0: float, r1: float, start: float = 0.0
) -> StepMetrics:
    """Overshoot, 2 % settling time and IAE of a response y(t) to a setpoint step r0 → r1.

    Examples
    --------
    A first-order response with T = 1 s: no overshoot, settles at ln 50 = 3.91 s, IAE = T.

    >>> t = np.linspace(0.0, 20.0, 200_001)
    >>> m = setpoint_step_metrics(t, 1 - np.exp(-t), 0.0, 1.0)
    >>> m.overshoot_percent, round(m.settling_time, 3), round(m.iae, 4)
    (0.0, 3.912, 1.0)
    """
    step = r1 - r0
    if step == 0.0:
        raise FuelidError("a setpoint step needs a non-zero size")
    rel = (y - r0) / step
    overshoot = max(0.0, float(np.max(rel)) - 1.0) * 100.0
    settle = lti.settling_time(t - start, rel, 1.0, SETTLING_BAND)
    return StepMetrics(
        kind="setpoint",
        start=start,
        size=step,
        overshoot_percent=overshoot,
        peak_deviation=overshoot / 100.0 * abs(step),
        settling_time=settle,
        iae=float(scipy.integrate.trapezoid(np.abs(r1 - y), t)),
    )


def disturbance_metrics(
    t: FloatArray,
    y: FloatArray,
    r: float,
    size: float,
    start: float = 0.0,
    band: float | None = None,
) -> StepMetrics:
    """Peak deviation, recovery time and IAE after a load step.

    Recovery is back within ``band`` of the setpoint for good; by default 2 % of the setpoint.
    A deviation model (setpoint 0) needs an absolute ``band`` [output unit].
    """
    e = r - y
    if band is None:
        band = SETTLING_BAND * max(abs(r), 1e-12)
    outside = np.flatnonzero(np.abs(e) > band)
    if outside.size == 0:
        settle = 0.0
    elif outside[-1] == t.size - 1:
        settle = math.nan
    else:
        settle = float(t[outside[-1] + 1] - start)
    return StepMetrics(
        kind="disturbance",
        start=start,
        size=size,
        overshoot_percent=math.nan,
        peak_deviation=float(np.max(np.abs(e))),
        settling_time=settle,
        iae=float(scipy.integrate.trapezoid(np.abs(e), t)),
    )


@dataclass(frozen=True)
class LinearResponse:
    """Unit setpoint step and unit input-disturbance step of the linear closed loop."""

    time: FloatArray
    """Times [s] (a fine grid, between the control instants too)."""
    setpoint_response: FloatArray
    """Output after a unit setpoint step at t = 0 [output unit]."""
    setpoint_command: FloatArray
    """Controller output (held) for the setpoint step [input unit]."""
    disturbance_response: FloatArray
    """Output deviation after a unit step at the plant input at t = 0."""
    setpoint: StepMetrics
    disturbance: StepMetrics


MAX_LINEAR_STEPS = 50_000
"""Most control periods the linear closed loop is simulated for."""


def _loop_time_scale(model: ProcessModel, pi: PISettings) -> float:
    """Ti, or the closed loop's time constant Ti/(K·Kc) when the loop is detuned below that."""
    return max(pi.Ti, pi.Ti / (abs(model.K) * pi.Kc))


def linear_period(model: ProcessModel, pi: PISettings) -> float:
    """Step [s] of the linear closed loop.

    The control period; for a continuous controller 0.02 s, coarser for a slow loop so that its
    delay and lags span at most about 500 steps.
    """
    if pi.control_period > 0.0:
        return pi.control_period
    scale = model.delay + sum(model.time_constants) + _loop_time_scale(model, pi)
    return max(CONTINUOUS_PERIOD, scale / 500.0)


def _closed_loop_polynomials(
    model: ProcessModel, pi: PISettings, h: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """(r→u numerator, d→u numerator, characteristic polynomial, plant b, plant a) in z⁻¹."""
    d = discretise(model.time_constants, model.delay, h)
    gn = np.concatenate((np.zeros(d.shift), model.K * d.b))
    gd = d.a
    cn = pi.Kc * np.array([1.0, h / pi.Ti - 1.0])
    cd = np.array([1.0, -1.0])
    n = max(gn.size, gd.size) + 1
    char = np.zeros(n)
    a1 = np.convolve(cd, gd)
    a2 = np.convolve(cn, gn)
    char[: a1.size] += a1
    char[: a2.size] += a2
    # u = C·S·r and, for a load d at the plant input, u = −C·G·S·d
    r_to_u = np.convolve(cn, gd)
    d_to_u = -np.convolve(cn, gn)
    return r_to_u, d_to_u, char, d.b, d.a


def linear_closed_loop(
    model: ProcessModel, pi: PISettings, duration: float | None = None, oversample: int = 10
) -> LinearResponse:
    """Setpoint and load-disturbance step responses of PI ``pi`` on the process ``model``.

    The controller output follows from the closed loop at the control instants (exact ZOH,
    fractional delay included); the plant output is then computed on a grid ``oversample`` times
    finer with the same held command, so overshoot between samples is not missed. A continuous
    controller is simulated at 0.02 s (coarser for a slow loop, :func:`linear_period`).

    Examples
    --------
    >>> from fuelid.tuning.rules import simc
    >>> model = ProcessModel(K=1.0, T=2.0, delay=1.0)
    >>> res = linear_closed_loop(model, simc(model, control_period=1.0))
    >>> 0.0 <= res.setpoint.overshoot_percent < 20.0 and res.setpoint.settling_time < 15.0
    True
    """
    h = linear_period(model, pi)
    if duration is None:
        duration = 10.0 * (_loop_time_scale(model, pi) + model.delay + sum(model.time_constants))
        duration += 20.0 * h
    n = min(max(math.ceil(duration / h), 4), MAX_LINEAR_STEPS)
    r_to_u, d_to_u, char, _, _ = _closed_loop_polynomials(model, pi, h)
    ones = np.ones(n)
    u_r = scipy.signal.lfilter(r_to_u, char, ones)
    u_d = scipy.signal.lfilter(d_to_u, char, ones)
    m = oversample if pi.control_period > 0.0 else 1
    fine = discretise(model.time_constants, model.delay, h / m)
    t = np.arange(n * m, dtype=np.float64) * (h / m)
    y_r = model.K * fine.response(np.repeat(u_r, m))
    y_d = model.K * fine.response(np.repeat(u_d, m) + 1.0)
    return LinearResponse(
        time=t,
        setpoint_response=y_r,
        setpoint_command=np.repeat(u_r, m),
        disturbance_response=y_d,
        setpoint=setpoint_step_metrics(t, y_r, 0.0, 1.0),
        # recovered: within 2 % of what the unit load would do to the output without control
        disturbance=disturbance_metrics(t, y_d, 0.0, 1.0, band=SETTLING_BAND * abs(model.K)),
    )


def closed_loop_poles(model: ProcessModel, pi: PISettings) -> FloatArray:
    """Magnitudes of the closed-loop poles at the control instants (all < 1 when stable)."""
    h = linear_period(model, pi)
    char = _closed_loop_polynomials(model, pi, h)[2]
    return np.asarray(np.abs(np.roots(np.trim_zeros(char, "b"))), dtype=np.float64)


@dataclass
class ClosedLoopResult:
    """A closed-loop run on the nonlinear plant, on the fine output grid (engineering units)."""

    time: FloatArray
    """[s]"""
    setpoint: FloatArray
    """[L/min]"""
    flow: FloatArray
    """Meter reading as the PLC sees it (lag, delay, noise) [L/min]."""
    command: FloatArray
    """Controller output held [V]."""
    disturbance: FloatArray
    """Load disturbance added at the plant input [V]."""
    fuel_temperature: float
    """[°C]"""
    control_period: float
    """[s]"""
    events: list[StepMetrics] = field(default_factory=list)
    """Metrics of every setpoint step and disturbance, in time order."""
    time_at_limits: float = 0.0
    """Time the command spent at 1 V or 5 V [s]."""

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

    def to_pandas(self) -> pd.DataFrame:
        """Columns ``t_s``, ``r_Lpm``, ``q_Lpm``, ``u_V``, ``d_V``."""
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


def simulate_closed_loop(
    config: PlantConfig,
    pi: PISettings,
    setpoint: InputProfile,
    *,
    fuel_temperature: float = 293.15,
    disturbance: InputProfile | None = None,
    sample_time: float = 0.02,
    noise_std: float = 0.0,
    seed: int | None = None,
    gain_changes: dict[float, tuple[float, float]] | None = None,
) -> ClosedLoopResult:
    """Run the PLC's PI against the nonlinear plant.

    The plant starts at rest at the first setpoint (the controller's integral at the command that
    holds it). Events (setpoint and disturbance changes) take effect at the next control instant.

    Parameters
    ----------
    config : PlantConfig
        The plant; its drive's signal range gives the output limits.
    pi : PISettings
        The controller (control period 0: simulated at 0.02 s).
    setpoint : InputProfile
        Flow setpoint over time [L/min]; its duration is the run's.
    fuel_temperature : float
        [K], constant over the run.
    disturbance : InputProfile, optional
        Load disturbance added to the command at the plant input [V] (clipped to the drive range).
    sample_time : float
        Output grid [s] (the meter's delay is applied on it by interpolation).
    noise_std : float
        Meter noise [L/min] seen by the controller and logged.
    seed : int, optional
        Seed of the noise.
    gain_changes : dict, optional
        {time [s]: (Kc, Ti)}: bumpless gain changes (as a schedule would make them).

    Returns
    -------
    ClosedLoopResult
    """
    h = pi.control_period if pi.control_period > 0.0 else CONTINUOUS_PERIOD
    if not (math.isfinite(sample_time) and sample_time > 0.0):
        raise FuelidError(f"sample time must be positive, got {sample_time:g} s")
    c = plant_coefficients(config, fuel_temperature)
    duration = setpoint.duration
    n_periods = math.floor(duration / h + 1e-9)
    instants = np.round(np.arange(n_periods + 1) * h, 12)
    grid = np.unique(
        np.concatenate((np.round(np.arange(0.0, duration + 1e-9, sample_time), 12), instants))
    )
    u0 = steady_command(config, float(setpoint.u[0]), fuel_temperature)
    x = steady_state(u0, c).state
    meter_state = 4 if c.T_f > 0.0 else 3
    q_m = np.full(grid.size, x[meter_state] * LPM_PER_M3S)
    rng = np.random.default_rng(seed)
    controller = DiscretePI(pi, c.u_min, c.u_max, u0)
    pending = dict(sorted((gain_changes or {}).items()))
    commands = np.empty(n_periods)
    d_held = np.zeros(n_periods)
    at_limits = 0
    for k in range(n_periods):
        t0, t1 = float(instants[k]), float(instants[k + 1])
        done = grid <= t0 + 1e-12
        y = float(np.interp(t0 - c.delay, grid[done], q_m[done], left=q_m[0]))
        if noise_std > 0.0:
            y += float(rng.normal(0.0, noise_std))
        for when in [w for w in pending if w <= t0 + 1e-12]:
            controller.set_gains(*pending.pop(when))
        u = controller.update(float(setpoint.at(t0)[()]), y)
        at_limits += u <= c.u_min or u >= c.u_max
        d = float(disturbance.at(t0)[()]) if disturbance is not None else 0.0
        commands[k], d_held[k] = u, d
        applied = min(max(u + d, c.u_min), c.u_max)
        inside = (grid > t0 + 1e-12) & (grid <= t1 + 1e-12)
        points = np.concatenate(([t0], grid[inside]))
        if points[-1] < t1 - 1e-12:
            points = np.append(points, t1)
        states = scipy.integrate.odeint(
            plant_rhs,
            x,
            points,
            args=(applied, c),
            Dfun=plant_jacobian,
            tfirst=True,
            rtol=RTOL,
            atol=ATOL,
            mxstep=100_000,
        )
        q_m[inside] = states[1 : 1 + int(inside.sum()), meter_state] * LPM_PER_M3S
        x = states[-1]
    k_of = np.minimum(np.searchsorted(instants, grid, side="right") - 1, n_periods - 1)
    measured = np.interp(grid - c.delay, grid, q_m, left=q_m[0])
    if noise_std > 0.0:
        measured = measured + rng.normal(0.0, noise_std, grid.size)
    r = np.asarray(setpoint.at(grid), dtype=float)
    result = ClosedLoopResult(
        time=grid,
        setpoint=r,
        flow=measured,
        command=commands[k_of],
        disturbance=d_held[k_of],
        fuel_temperature=fuel_temperature - KELVIN,
        control_period=pi.control_period,
        time_at_limits=at_limits * h,
    )
    result.events.extend(_event_metrics(result, setpoint, disturbance))
    return result


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
    config: PlantConfig, temperatures_degC: tuple[float, ...], headroom: float = 0.05
) -> tuple[float, float]:
    """Flows [L/min] the drive holds at rest at every one of the fuel temperatures [°C].

    The common range of the steady flows at the lowest and highest command, narrowed by
    ``headroom`` (a fraction of it) at each end so that a controller holding a flow there still
    has room to act on a load disturbance.
    """
    lows = [flow_at(config, config.vfd.u_min_V, t) for t in temperatures_degC]
    highs = [flow_at(config, config.vfd.u_max_V, t) for t in temperatures_degC]
    lo, hi = max(lows), min(highs)
    if not hi > lo:
        raise FuelidError(
            f"no flow is reachable at every fuel temperature {list(temperatures_degC)} °C "
            f"({lo:.2f}…{hi:.2f} L/min)"
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
    temperatures_degC: tuple[float, ...],
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
    temperatures_degC : tuple of float
        Fuel temperatures [°C], one run each.
    flow : float
        Flow the runs start at [L/min] (moved into the reachable range if outside it).
    step : float
        Setpoint step [L/min] (turned round or shrunk if it leaves the reachable range).
    """
    start, signed = place_step(flow, step, *reachable_flows(config, temperatures_degC))
    runs = []
    for t_degC in temperatures_degC:
        setpoint, load = standard_scenario(start, signed)
        runs.append(
            simulate_closed_loop(
                config, pi, setpoint, fuel_temperature=t_degC + KELVIN, disturbance=load
            )
        )
    return runs


def flow_at(config: PlantConfig, u: float, t_degC: float) -> float:
    """Steady flow [L/min] the command ``u`` [V] gives with fuel at ``t_degC`` [°C]."""
    return float(operating_point(config, u, t_degC + KELVIN).q * LPM_PER_M3S)
