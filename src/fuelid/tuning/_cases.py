"""The loop over fuel temperature and command: plant cases and one fixed PI checked on them.

The physics model (:mod:`fuelid.plant`) gives how the loop changes with fuel temperature and
operating point; an identified model, when given, anchors it: every physics model is scaled so that
at the identification's conditions it equals the identified one (K and T by ratio, the meter's
T_f, T2 and the delay taken from the identified model). Data set the level, physics sets the
trend (docs/explanation/tuning.md, section 7). Fuel temperatures are in kelvin (``T_fuel``); the
JSON of :meth:`FixedPIEvaluation.to_json` gives them in °C.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

from fuelid.model import ProcessModel
from fuelid.plant import LinearPlant, PlantConfig, linearise
from fuelid.tuning._frequency import Robustness, robustness
from fuelid.tuning._linearloop import full_order_closed_loop, linear_closed_loop, step_duration
from fuelid.tuning._rules import PISettings
from fuelid.units import LPM_PER_M3S, celsius_to_kelvin, kelvin_to_celsius

DEFAULT_T_RANGE = (celsius_to_kelvin(-20.0), celsius_to_kelvin(50.0))
"""Fuel temperatures the gains are checked over by default [K]: −20…50 °C."""

CaseCache = dict[tuple[float, float], tuple[LinearPlant, ProcessModel]]
"""Linearisations by (T_fuel [K], command [V]), shared between calls of :func:`plant_cases`."""


@dataclass(frozen=True)
class PlantCase:
    """The loop at one fuel temperature and command."""

    T_fuel: float
    """Fuel temperature [K]."""
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
    T_fuel: float
    """Fuel temperature during the identification [K]."""
    u: float
    """Command the data were centred on [V]."""


def plant_cases(
    config: PlantConfig,
    T_fuels: Sequence[float],
    commands_V: Sequence[float],
    anchor: Anchor | None = None,
    cache: CaseCache | None = None,
) -> list[PlantCase]:
    """Linearised plants and their reduced models on a grid of fuel temperatures and commands.

    Parameters
    ----------
    config : PlantConfig
        The plant.
    T_fuels : sequence of float
        Fuel temperatures [K].
    commands_V : sequence of float
        Commands [V].
    anchor : Anchor, optional
        An identified model: the reduced models are rescaled to K·(K_id/K_phys,ref),
        T·(T_id/T_phys,ref) with T_f, T2 and delay from the identified model, and the margins
        are then computed on them.
    cache : dict, optional
        Saves repeated linearisations (keyed by temperature and command).

    Returns
    -------
    list of PlantCase
        Temperature by temperature, command by command.
    """
    k_ratio = t_ratio = 1.0
    if anchor is not None:
        _, ref = _linearised(config, anchor.T_fuel, anchor.u, cache)
        k_ratio = anchor.model.K / ref.K
        t_ratio = anchor.model.T / ref.T
    cases = []
    for T_fuel in T_fuels:
        for u in commands_V:
            linear, model = _linearised(config, T_fuel, u, cache)
            if anchor is not None:
                model = replace(anchor.model, K=model.K * k_ratio, T=model.T * t_ratio)
            cases.append(
                PlantCase(
                    T_fuel=float(T_fuel),
                    u=float(u),
                    flow=linear.operating_point.q * LPM_PER_M3S,
                    linear=linear,
                    model=model,
                    anchored=anchor is not None,
                )
            )
    return cases


def _linearised(
    config: PlantConfig, T_fuel: float, u: float, cache: CaseCache | None
) -> tuple[LinearPlant, ProcessModel]:
    """The plant linearised at ``T_fuel`` [K] and ``u`` [V] and its reduced model, cached."""
    key = (round(float(T_fuel), 9), round(float(u), 9))
    if cache is not None and key in cache:
        return cache[key]
    linear = linearise(config, u, T_fuel)
    found = (linear, linear.equivalent_model().model)
    if cache is not None:
        cache[key] = found
    return found


@dataclass(frozen=True)
class CaseEvaluation:
    """One PI on one plant case."""

    case: PlantCase
    robustness: Robustness
    """Margins on the full linearised plant (or the anchored model)."""
    overshoot_percent: float
    """Setpoint-step overshoot of the linear closed loop on the margins' plant [%]."""
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

    @property
    def T_range(self) -> tuple[float, float]:
        """Coldest and warmest fuel of the cases [K]."""
        temperatures = [c.case.T_fuel for c in self.cases]
        return min(temperatures), max(temperatures)

    def rows(self) -> list[dict[str, float | bool]]:
        """One row per case, for tables and JSON (fuel temperature in °C)."""
        return [
            {
                "fuel_temperature": kelvin_to_celsius(c.case.T_fuel),
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

    def to_json(self, cases: bool = True) -> dict[str, Any]:
        """The documented ``temperature_check`` JSON: the worst case, and with ``cases`` the rows.

        ``fuelid tune --json`` gives the rows (:meth:`rows`), ``fuelid report --json`` leaves them
        out.
        """
        out: dict[str, Any] = {
            "worst_Ms": self.worst_Ms,
            "worst_overshoot_percent": self.worst_overshoot,
            "worst_gain_margin": self.worst_gain_margin,
            "worst_phase_margin_deg": self.worst_phase_margin,
            "all_stable": self.all_stable,
        }
        if cases:
            out["cases"] = self.rows()
        return out


def evaluate_fixed(pi: PISettings, cases: Sequence[PlantCase]) -> FixedPIEvaluation:
    """Margins and step metrics of one PI on every case, both on :attr:`PlantCase.margin_plant`.

    On the full linearised plant when the cases come from physics alone (its lightly damped
    line modes are in the overshoot as in the Ms), on the anchored model when one anchors them.
    """
    evaluations = []
    for case in cases:
        step = (
            linear_closed_loop(case.model, pi)
            if case.anchored
            else full_order_closed_loop(case.linear, pi, step_duration(case.model, pi))
        )
        evaluations.append(
            CaseEvaluation(
                case=case,
                robustness=robustness(case.margin_plant, pi),
                overshoot_percent=step.setpoint.overshoot_percent,
                settling_time=step.setpoint.settling_time,
            )
        )
    return FixedPIEvaluation(pi=pi, cases=evaluations)
