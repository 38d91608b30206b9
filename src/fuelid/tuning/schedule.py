"""The loop over the fuel-temperature range: plant models, one fixed PI, a gain schedule, a sweep.

The physics model (:mod:`fuelid.plant`) gives how the loop changes with fuel temperature and
operating point; an identified model, when given, anchors it: every physics model is scaled so that
at the identification's conditions it equals the identified one (K and T by ratio, the meter's
T_f and the delay taken from the identified model). Robustness is always evaluated on the full
linearised plant (five states and the meter's delay), not only on its reduction, so the reduction
error is part of what the margins see.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import FuelidError
from fuelid.model import ProcessModel, model_covariance
from fuelid.plant.config import PlantConfig
from fuelid.plant.linear import LinearPlant, linearise
from fuelid.tuning.closedloop import linear_closed_loop
from fuelid.tuning.frequency import Robustness, robustness
from fuelid.tuning.rules import PISettings, tune
from fuelid.units import LPM_PER_M3S
from fuelid.units import T0 as KELVIN

FloatArray = NDArray[np.float64]
DEFAULT_TEMPERATURES_DEGC = (-20.0, 50.0)


@dataclass(frozen=True)
class PlantCase:
    """The loop at one fuel temperature and command."""

    fuel_temperature: float
    """[°C]"""
    u: float
    """Command at the operating point [V]."""
    flow: float
    """Flow at the operating point [L/min]."""
    linear: LinearPlant
    """Full linearised plant (u [V] → meter reading [L/min])."""
    model: ProcessModel
    """Its reduction to the model family (anchored to an identified model when one is given)."""
    anchored: bool = False
    """True when ``model`` was scaled to an identified model."""

    @property
    def margin_plant(self) -> LinearPlant | ProcessModel:
        """What the margins are computed on: the full linearised plant, or the anchored model.

        An anchored model comes from data; the physics then only says how it moves with
        temperature and flow.
        """
        return self.model if self.anchored else self.linear


@dataclass(frozen=True)
class Anchor:
    """An identified model and the conditions it was identified at."""

    model: ProcessModel
    fuel_temperature: float
    """[°C]"""
    u: float
    """Command the data were centred on [V]."""


def plant_cases(
    config: PlantConfig,
    temperatures_degC: Sequence[float],
    commands_V: Sequence[float],
    anchor: Anchor | None = None,
    cache: dict[tuple[float, float], tuple[LinearPlant, ProcessModel]] | None = None,
) -> list[PlantCase]:
    """Linearised plants and their reduced models on a grid of fuel temperatures and commands.

    With an ``anchor`` the reduced models are rescaled: K·(K_id/K_phys,ref), T·(T_id/T_phys,ref)
    with T_f, T2 and delay from the identified model, and the margins are then computed on them.
    ``cache`` (keyed by temperature and command) saves repeated linearisations.
    """
    k_ratio = t_ratio = 1.0
    if anchor is not None:
        ref = linearise(config, anchor.u, anchor.fuel_temperature + KELVIN).equivalent_model()
        k_ratio = anchor.model.K / ref.model.K
        t_ratio = anchor.model.T / ref.model.T
    cases = []
    for t_degC in temperatures_degC:
        for u in commands_V:
            key = (round(float(t_degC), 9), round(float(u), 9))
            if cache is None or key not in cache:
                linear = linearise(config, u, t_degC + KELVIN)
                found = (linear, linear.equivalent_model().model)
                if cache is not None:
                    cache[key] = found
            linear, model = cache[key] if cache is not None else found
            if anchor is not None:
                model = replace(anchor.model, K=model.K * k_ratio, T=model.T * t_ratio)
            cases.append(
                PlantCase(
                    fuel_temperature=float(t_degC),
                    u=float(u),
                    flow=linear.operating_point.q * LPM_PER_M3S,
                    linear=linear,
                    model=model,
                    anchored=anchor is not None,
                )
            )
    return cases


@dataclass(frozen=True)
class CaseEvaluation:
    """One PI on one plant case."""

    case: PlantCase
    robustness: Robustness
    """Margins on the full linearised plant (or the anchored model)."""
    overshoot_percent: float
    """Setpoint-step overshoot on the reduced model (linear closed loop) [%]."""
    settling_time: float
    """2 % settling time of that step [s]."""


@dataclass(frozen=True)
class FixedPIEvaluation:
    """One fixed PI over every plant case: the worst case is what matters."""

    pi: PISettings
    cases: list[CaseEvaluation]

    @property
    def worst_Ms(self) -> float:
        """Largest Ms over the cases [-]."""
        return max(c.robustness.Ms for c in self.cases)

    @property
    def worst_overshoot(self) -> float:
        """Largest setpoint overshoot over the cases [%]."""
        return max(c.overshoot_percent for c in self.cases)

    @property
    def worst_gain_margin(self) -> float:
        """Smallest gain margin over the cases [-]."""
        return min(c.robustness.gain_margin for c in self.cases)

    @property
    def worst_phase_margin(self) -> float:
        """Smallest phase margin over the cases [°]."""
        return min(c.robustness.phase_margin_deg for c in self.cases)

    @property
    def all_stable(self) -> bool:
        """Every case closed-loop stable."""
        return all(c.robustness.stable for c in self.cases)

    def rows(self) -> list[dict[str, float | bool]]:
        """One row per case, for tables and JSON."""
        return [
            {
                "fuel_temperature": c.case.fuel_temperature,
                "u": c.case.u,
                "flow": c.case.flow,
                "K": c.case.model.K,
                "T": c.case.model.T,
                "Ms": c.robustness.Ms,
                "gain_margin": c.robustness.gain_margin,
                "phase_margin_deg": c.robustness.phase_margin_deg,
                "overshoot_percent": c.overshoot_percent,
                "settling_time": c.settling_time,
                "stable": c.robustness.stable,
            }
            for c in self.cases
        ]


def evaluate_fixed(pi: PISettings, cases: Sequence[PlantCase]) -> FixedPIEvaluation:
    """Margins (full linearised plant) and step metrics (reduced model) of one PI on every case."""
    evaluations = []
    for case in cases:
        step = linear_closed_loop(case.model, pi)
        evaluations.append(
            CaseEvaluation(
                case=case,
                robustness=robustness(case.margin_plant, pi),
                overshoot_percent=step.setpoint.overshoot_percent,
                settling_time=step.setpoint.settling_time,
            )
        )
    return FixedPIEvaluation(pi=pi, cases=evaluations)


@dataclass(frozen=True)
class ScheduleBand:
    """Gains for one fuel-temperature band (and flow band)."""

    t_low: float
    """[°C]"""
    t_high: float
    """[°C]"""
    u_low: float
    """[V]"""
    u_high: float
    """[V]"""
    flow_low: float
    """Flow at u_low at the band's middle temperature [L/min]."""
    flow_high: float
    """[L/min]"""
    pi: PISettings
    detune: float
    """Factor applied to the rule's Kc to meet the Ms target (1: none) [-]."""
    worst: FixedPIEvaluation
    """The band's gains on every case inside the band."""

    def as_dict(self) -> dict[str, Any]:
        """Plain dictionary for JSON."""
        return {
            "t_low": self.t_low,
            "t_high": self.t_high,
            "u_low": self.u_low,
            "u_high": self.u_high,
            "flow_low": self.flow_low,
            "flow_high": self.flow_high,
            "Kc": self.pi.Kc,
            "Ti": self.pi.Ti,
            "detune": self.detune,
            "Ms": self.worst.worst_Ms,
            "gain_margin": self.worst.worst_gain_margin,
            "phase_margin_deg": self.worst.worst_phase_margin,
            "overshoot_percent": self.worst.worst_overshoot,
        }


@dataclass(frozen=True)
class GainSchedule:
    """Gains per fuel-temperature band (and flow band) that keep Ms within a target everywhere."""

    rule: str
    control_period: float
    ms_target: float
    bands: list[ScheduleBand] = field(default_factory=list)

    @property
    def worst_Ms(self) -> float:
        """Largest Ms over every band's cases [-]."""
        return max(b.worst.worst_Ms for b in self.bands)

    def lookup(self, fuel_temperature: float, u: float | None = None) -> ScheduleBand:
        """The band for a fuel temperature [°C] (and command [V]); the ends extend outwards."""
        candidates = [b for b in self.bands if u is None or b.u_low <= u <= b.u_high] or self.bands
        for band in candidates:
            if band.t_low <= fuel_temperature <= band.t_high:
                return band
        return min(
            candidates,
            key=lambda b: min(abs(fuel_temperature - b.t_low), abs(fuel_temperature - b.t_high)),
        )

    def as_dict(self) -> dict[str, Any]:
        """Plain dictionary for JSON."""
        return {
            "rule": self.rule,
            "control_period": self.control_period,
            "ms_target": self.ms_target,
            "worst_Ms": self.worst_Ms,
            "bands": [b.as_dict() for b in self.bands],
        }


MAX_BANDS = 50
"""Most temperature bands of a schedule (each band is a tuning)."""
MAX_FLOW_BANDS = 10
"""Most flow (command) bands per temperature band."""


def band_edges(low: float, high: float, width: float) -> FloatArray:
    """Edges from ``low`` to ``high`` in steps of about ``width`` (equal bands).

    Examples
    --------
    >>> band_edges(-20.0, 50.0, 10.0).tolist()
    [-20.0, -10.0, 0.0, 10.0, 20.0, 30.0, 40.0, 50.0]
    """
    if not (math.isfinite(low) and math.isfinite(high) and high > low):
        raise FuelidError(f"a range needs low < high, got {low:g}…{high:g}")
    if not (math.isfinite(width) and width > 0.0):
        raise FuelidError(f"a band width must be positive, got {width:g}")
    n = max(1, round((high - low) / width))
    if n > MAX_BANDS:
        raise FuelidError(
            f"a band width of {width:g} makes {n} bands of {low:g}…{high:g}; at most {MAX_BANDS}"
        )
    return np.linspace(low, high, n + 1)


def gain_schedule(
    config: PlantConfig,
    rule: str = "simc",
    control_period: float = 1.0,
    speed: float | None = None,
    *,
    t_range: tuple[float, float] = DEFAULT_TEMPERATURES_DEGC,
    band_width: float = 10.0,
    ms_target: float = 1.7,
    flow_bands: int = 3,
    flow_split: float = 0.10,
    anchor: Anchor | None = None,
) -> GainSchedule:
    """Gains per fuel-temperature band, split by flow where the gain depends on the flow.

    For each temperature band the loop is evaluated at its two edges and its middle, at the
    drive's two ends and its middle command. Where K varies by more than ``flow_split`` across
    the commands, the band is split into ``flow_bands`` command (flow) bands. Each band is tuned
    by the rule on its highest-gain case (the one that needs the lowest Kc) and, if any case of
    the band still has Ms above ``ms_target``, Kc is reduced until none has.

    Parameters
    ----------
    config : PlantConfig
        The plant whose physics gives the dependence on temperature and flow.
    rule, control_period, speed
        As for :func:`~fuelid.tuning.rules.tune`.
    t_range : (float, float)
        Fuel temperatures [°C].
    band_width : float
        Width of a temperature band [°C].
    ms_target : float
        Largest acceptable maximum sensitivity [-].
    flow_bands : int
        Number of flow bands where the gain depends on the flow (1: never split).
    flow_split : float
        Relative spread of K across the commands above which bands are split [-].
    anchor : Anchor, optional
        An identified model that anchors the physics (see the module docstring).
    """
    if not (math.isfinite(ms_target) and ms_target > 1.0):
        raise FuelidError(f"the Ms target must be greater than 1, got {ms_target:g}")
    if not 1 <= flow_bands <= MAX_FLOW_BANDS:
        raise FuelidError(
            f"the number of flow bands must be 1 to {MAX_FLOW_BANDS}, got {flow_bands}"
        )
    edges = band_edges(t_range[0], t_range[1], band_width)
    u_lo, u_hi = config.vfd.u_min_V, config.vfd.u_max_V
    schedule = GainSchedule(rule=rule, control_period=control_period, ms_target=ms_target)
    cache: dict[tuple[float, float], tuple[LinearPlant, ProcessModel]] = {}
    for t_low, t_high in itertools.pairwise(edges):
        temps = (float(t_low), 0.5 * float(t_low + t_high), float(t_high))
        probe = plant_cases(config, temps, (u_lo, 0.5 * (u_lo + u_hi), u_hi), anchor, cache)
        gains = [c.model.K for c in probe]
        split = (max(gains) - min(gains)) / max(gains) > flow_split and flow_bands > 1
        u_edges = np.linspace(u_lo, u_hi, flow_bands + 1) if split else np.array([u_lo, u_hi])
        for a, b in itertools.pairwise(u_edges):
            commands = (float(a), 0.5 * float(a + b), float(b))
            cases = (
                [c for c in probe if a <= c.u <= b]
                if not split
                else plant_cases(config, temps, commands, anchor, cache)
            )
            schedule.bands.append(
                _tune_band(cases, rule, control_period, speed, ms_target, temps, (a, b))
            )
    return schedule


def _tune_band(
    cases: list[PlantCase],
    rule: str,
    control_period: float,
    speed: float | None,
    ms_target: float,
    temps: tuple[float, float, float],
    commands: tuple[float, float],
) -> ScheduleBand:
    design = max(cases, key=lambda c: c.model.K / c.model.T)
    pi = tune(design.model, rule, control_period, speed)
    factor = 1.0
    evaluation = evaluate_fixed(pi, cases)
    while evaluation.worst_Ms > ms_target or not evaluation.all_stable:
        factor *= 0.95
        if factor < 0.05:
            raise FuelidError(
                f"no {rule} gains reach Ms ≤ {ms_target:g} for {temps[0]:g}…{temps[2]:g} °C"
            )
        evaluation = evaluate_fixed(pi.with_gain_factor(factor), cases)
    middle = [c for c in cases if c.fuel_temperature == temps[1]] or cases
    flows = sorted((c.u, c.flow) for c in middle)
    return ScheduleBand(
        t_low=temps[0],
        t_high=temps[2],
        u_low=float(commands[0]),
        u_high=float(commands[1]),
        flow_low=flows[0][1],
        flow_high=flows[-1][1],
        pi=evaluation.pi,
        detune=factor,
        worst=evaluation,
    )


@dataclass(frozen=True)
class SweepResult:
    """One PI over many plant variants (temperature and identification uncertainty)."""

    fuel_temperature: FloatArray
    """[°C] per variant."""
    K: FloatArray
    T: FloatArray
    delay: FloatArray
    Ms: FloatArray
    gain_margin: FloatArray
    phase_margin_deg: FloatArray
    overshoot_percent: FloatArray
    stable: NDArray[np.bool_]

    def summary(self) -> dict[str, float]:
        """Worst case and 95th percentile of Ms and overshoot, the smallest margins."""
        return {
            "n": self.Ms.size,
            "worst_Ms": float(np.max(self.Ms)),
            "Ms_p95": float(np.percentile(self.Ms, 95)),
            "worst_overshoot_percent": float(np.max(self.overshoot_percent)),
            "overshoot_p95": float(np.percentile(self.overshoot_percent, 95)),
            "min_gain_margin": float(np.min(self.gain_margin)),
            "min_phase_margin_deg": float(np.min(self.phase_margin_deg)),
            "unstable_fraction": float(np.mean(~self.stable)),
        }


def uncertainty_sweep(
    pi: PISettings,
    anchor: Anchor,
    cov_names: Sequence[str],
    cov: FloatArray,
    config: PlantConfig,
    *,
    n: int = 1000,
    t_range: tuple[float, float] = DEFAULT_TEMPERATURES_DEGC,
    seed: int | None = 0,
) -> SweepResult:
    """Evaluate one PI on ``n`` variants of the identified model.

    Each variant draws a fuel temperature uniformly over ``t_range`` and the estimated
    parameters from N(estimate, cov) (the identification's covariance, its model-parameter block:
    :func:`model_covariance`); the physics model then
    moves K and T from the identification's temperature to the drawn one (by ratio, interpolated
    on a 2 °C grid). Draws with T ≤ 0 are redrawn; a negative delay is set to 0. Margins and the
    step overshoot come from the linear models (exact ZOH, exact delay).
    """
    rng = np.random.default_rng(seed)
    names, cov = model_covariance(cov_names, cov)
    mean = np.array([getattr(anchor.model, name) for name in names], dtype=float)
    grid = np.arange(t_range[0], t_range[1] + 1e-9, 2.0)
    if grid[-1] < t_range[1]:
        grid = np.append(grid, t_range[1])
    ref = linearise(config, anchor.u, anchor.fuel_temperature + KELVIN).equivalent_model().model
    phys = [linearise(config, anchor.u, t + KELVIN).equivalent_model().model for t in grid]
    k_ratio = np.array([m.K / ref.K for m in phys])
    t_ratio = np.array([m.T / ref.T for m in phys])
    temps = rng.uniform(t_range[0], t_range[1], n)
    draws = np.empty((n, len(names)))
    filled = 0
    t_index = names.index("T") if "T" in names else None
    while filled < n:
        batch = rng.multivariate_normal(mean, cov, size=n - filled) if names else np.empty((n, 0))
        if t_index is not None:
            batch = batch[batch[:, t_index] > 0.0]
        draws[filled : filled + batch.shape[0]] = batch
        filled += batch.shape[0]
    out: dict[str, list[float]] = {key: [] for key in ("K", "T", "delay", "Ms", "gm", "pm", "os")}
    stable = np.empty(n, dtype=bool)
    for i in range(n):
        params = dict(zip(names, draws[i], strict=True))
        params["delay"] = max(params.get("delay", anchor.model.delay), 0.0)
        for name in ("T2", "T_f"):
            if name in params:
                params[name] = max(params[name], 0.0)
        base = replace(anchor.model, **params)
        model = replace(
            base,
            K=base.K * float(np.interp(temps[i], grid, k_ratio)),
            T=base.T * float(np.interp(temps[i], grid, t_ratio)),
        )
        r = robustness(model, pi, n=600)
        step = linear_closed_loop(model, pi)
        out["K"].append(model.K)
        out["T"].append(model.T)
        out["delay"].append(model.delay)
        out["Ms"].append(r.Ms)
        out["gm"].append(r.gain_margin)
        out["pm"].append(r.phase_margin_deg)
        out["os"].append(step.setpoint.overshoot_percent if r.stable else math.inf)
        stable[i] = r.stable
    return SweepResult(
        fuel_temperature=temps,
        K=np.array(out["K"]),
        T=np.array(out["T"]),
        delay=np.array(out["delay"]),
        Ms=np.array(out["Ms"]),
        gain_margin=np.array(out["gm"]),
        phase_margin_deg=np.array(out["pm"]),
        overshoot_percent=np.array(out["os"]),
        stable=stable,
    )
