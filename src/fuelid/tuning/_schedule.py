"""A gain schedule over the fuel-temperature range (and flow, where the gain depends on it).

Each band is tuned by the rule on its most demanding case and detuned until every case in it
meets the Ms target; the margins are computed on the full linearised plant (five states and the
meter's delay), so the model-reduction error is part of what they see, or on the anchored models
when an identified model anchors the physics (:mod:`fuelid.tuning._cases`;
docs/explanation/tuning.md, section 8). Fuel temperatures are in kelvin (``T_fuel``, ``T_range``,
``T_low``…); the JSON of
:meth:`GainSchedule.to_json` gives them in °C.

The plant cases, the check of one fixed PI (:mod:`fuelid.tuning._cases`) and the uncertainty sweep
(:mod:`fuelid.tuning._sweep`) are re-exported here.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import FuelidError
from fuelid.plant import PlantConfig
from fuelid.tuning._block import BlockForm
from fuelid.tuning._cases import (
    DEFAULT_T_RANGE,
    Anchor,
    CaseCache,
    CaseEvaluation,
    FixedPIEvaluation,
    PlantCase,
    evaluate_fixed,
    plant_cases,
)
from fuelid.tuning._limits import MAX_BANDS, MAX_FLOW_BANDS
from fuelid.tuning._rules import PISettings, tune
from fuelid.tuning._sweep import SweepResult, uncertainty_sweep
from fuelid.units import kelvin_to_celsius

__all__ = [
    "DEFAULT_T_RANGE",
    "SINGLE_SET_TOLERANCE",
    "Anchor",
    "CaseEvaluation",
    "FixedPIEvaluation",
    "GainSchedule",
    "PlantCase",
    "ScheduleBand",
    "SweepResult",
    "band_edges",
    "evaluate_fixed",
    "gain_schedule",
    "plant_cases",
    "uncertainty_sweep",
]

FloatArray = NDArray[np.float64]

SINGLE_SET_TOLERANCE = 0.01
"""Relative spread of the bands' Kc and Ti within which one set of gains may serve them all."""


@dataclass(frozen=True)
class ScheduleBand:
    """Gains for one fuel-temperature band (and flow band)."""

    T_low: float
    """Coldest fuel of the band [K]."""
    T_high: float
    """Warmest fuel of the band [K]."""
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
    design_T: float = math.nan
    """Fuel temperature of the case the band's gains were designed on [K]."""
    design_u: float = math.nan
    """Command of that case [V]."""
    operating: bool = False
    """The band holds the operating point of the anchoring model: its gains are designed on that
    model, as the headline gains are (equal to them unless ``detune`` < 1)."""

    def to_json(self) -> dict[str, Any]:
        """The band as documented JSON (``t_low``, ``t_high`` in °C)."""
        return {
            "t_low": kelvin_to_celsius(self.T_low),
            "t_high": kelvin_to_celsius(self.T_high),
            "design_fuel_temperature": kelvin_to_celsius(self.design_T),
            "design_u": self.design_u,
            "operating": self.operating,
            "u_low": self.u_low,
            "u_high": self.u_high,
            "flow_low": self.flow_low,
            "flow_high": self.flow_high,
            "Kc": self.pi.Kc,
            "Ti": self.pi.Ti,
            "Ti_min": self.pi.to_block(BlockForm(integral_unit="min"))[1],
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
    u_span: float | None = None
    """Drive span (the controller output's signal range) of the percent-of-span gains [V];
    None: not known, no %/% gains."""
    y_span: float | None = None
    """Measurement span of the percent-of-span gains [L/min]; None: not known."""
    single_set: FixedPIEvaluation | None = None
    """One PI for every band, on every band's cases, when the bands' Kc and Ti agree within
    :data:`SINGLE_SET_TOLERANCE` and that PI meets the Ms target everywhere; else None."""

    @property
    def single_set_suffices(self) -> bool:
        """Whether one set of gains meets the Ms target over the whole range (no schedule)."""
        return self.single_set is not None

    def percent_of_span(self, pi: PISettings) -> float | None:
        """Kc of ``pi`` in %/% of span (Kc·y_span/u_span, as :meth:`PISettings.plc_form`).

        None when the spans are not known.
        """
        span = pi.plc_form(self.u_span, self.y_span)["percent_of_span"]
        return None if span is None else float(span["Kc"])

    @property
    def worst_Ms(self) -> float:
        """Largest Ms over every band's cases [-]."""
        return max(b.worst.worst_Ms for b in self.bands)

    def lookup(self, T_fuel: float, u: float | None = None) -> ScheduleBand:
        """The band for a fuel temperature [K] (and command [V]); the ends extend outwards."""
        candidates = [b for b in self.bands if u is None or b.u_low <= u <= b.u_high] or self.bands
        for band in candidates:
            if band.T_low <= T_fuel <= band.T_high:
                return band
        return min(
            candidates,
            key=lambda b: min(abs(T_fuel - b.T_low), abs(T_fuel - b.T_high)),
        )

    def to_json(self) -> dict[str, Any]:
        """The schedule as documented JSON (``fuelid tune --schedule --json``)."""
        single = self.single_set
        return {
            "rule": self.rule,
            "control_period": self.control_period,
            "ms_target": self.ms_target,
            "worst_Ms": self.worst_Ms,
            "u_span": self.u_span,
            "y_span": self.y_span,
            "bands": [
                b.to_json() | {"Kc_percent_of_span": self.percent_of_span(b.pi)} for b in self.bands
            ],
            "single_set_suffices": self.single_set_suffices,
            "single_set": None
            if single is None
            else {
                "Kc": single.pi.Kc,
                "Ti": single.pi.Ti,
                "Kc_percent_of_span": self.percent_of_span(single.pi),
                "Ms": single.worst_Ms,
                "gain_margin": single.worst_gain_margin,
                "phase_margin_deg": single.worst_phase_margin,
                "overshoot_percent": single.worst_overshoot,
            },
        }


def band_edges(T_low: float, T_high: float, width: float) -> FloatArray:
    """Fuel-temperature edges from ``T_low`` to ``T_high`` [K] in steps of about ``width`` [K].

    The bands are equal; at most :data:`~fuelid.tuning._limits.MAX_BANDS` of them.

    Examples
    --------
    >>> [round(float(T) - 273.15, 9) for T in band_edges(253.15, 323.15, 10.0)]
    [-20.0, -10.0, 0.0, 10.0, 20.0, 30.0, 40.0, 50.0]
    """
    if not (math.isfinite(T_low) and math.isfinite(T_high) and T_high > T_low):
        raise FuelidError(
            f"a temperature range needs low < high, got {kelvin_to_celsius(T_low):g}…"
            f"{kelvin_to_celsius(T_high):g} °C"
        )
    if not (math.isfinite(width) and width > 0.0):
        raise FuelidError(f"a band width must be positive, got {width:g} K")
    n = max(1, round((T_high - T_low) / width))
    if n > MAX_BANDS:
        raise FuelidError(
            f"a band width of {width:g} K makes {n} bands of {kelvin_to_celsius(T_low):g}…"
            f"{kelvin_to_celsius(T_high):g} °C; at most {MAX_BANDS}"
        )
    return np.linspace(T_low, T_high, n + 1)


def gain_schedule(
    config: PlantConfig,
    rule: str = "simc",
    control_period: float = 1.0,
    closed_loop_time: float | None = None,
    *,
    T_range: tuple[float, float] = DEFAULT_T_RANGE,
    band_width: float = 10.0,
    ms_target: float = 1.7,
    flow_bands: int = 3,
    flow_split: float = 0.10,
    anchor: Anchor | None = None,
    y_span: float | None = None,
    u_span: float | None = None,
    cache: CaseCache | None = None,
    operating: Anchor | None = None,
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
    rule : str
        The rule's key in :data:`~fuelid.tuning.TUNING_RULES` (as for :func:`~fuelid.tuning.tune`).
    control_period : float
        The PLC's period h [s].
    closed_loop_time : float, optional
        τc or λ [s] (larger is slower; None for the rule's default).
    T_range : (float, float)
        Coldest and warmest fuel [K].
    band_width : float
        Width of a temperature band [K].
    ms_target : float
        Largest acceptable maximum sensitivity [-].
    flow_bands : int
        Number of flow bands where the gain depends on the flow (1: never split).
    flow_split : float
        Relative spread of K across the commands above which bands are split [-].
    anchor : Anchor, optional
        An identified model that anchors the physics (:func:`~fuelid.tuning._cases.plant_cases`).
        The band holding its operating point (``anchor.T_fuel``, ``anchor.u``) is designed on
        the model itself, as the headline gains are: its gains equal theirs unless the band's
        other cases need them detuned (``detune``), and it is marked ``operating``.
    operating : Anchor, optional
        The model and point the headline gains were designed on, when it does not anchor the
        physics (a plant file's own reduction: the cases are then its full linearisation);
        default ``anchor``.
    y_span, u_span : float, optional
        Measurement span [L/min] and drive span [V] of the percent-of-span gains (default: the
        plant's meter span and the command's signal range).
    cache : dict, optional
        Linearised plant cases by (T_fuel, u), shared with a temperature check of the same call
        so that no case is linearised twice.

    Notes
    -----
    When every band's Kc and Ti agree within :data:`SINGLE_SET_TOLERANCE`, the most cautious of
    them (the lowest Kc, with its Ti) is checked on every band's cases; if it meets the target
    everywhere, it is the schedule's ``single_set``: one set of gains suffices.
    """
    if not (math.isfinite(ms_target) and ms_target > 1.0):
        raise FuelidError(f"the Ms target must be greater than 1, got {ms_target:g}")
    if not 1 <= flow_bands <= MAX_FLOW_BANDS:
        raise FuelidError(
            f"the number of flow bands must be 1 to {MAX_FLOW_BANDS}, got {flow_bands}"
        )
    operating = anchor if operating is None else operating
    edges = band_edges(T_range[0], T_range[1], band_width)
    u_lo, u_hi = config.vfd.u_min_V, config.vfd.u_max_V
    bands: list[ScheduleBand] = []
    every_case: dict[tuple[float, float], PlantCase] = {}
    cache = {} if cache is None else cache  # shared with the temperature check when given
    for T_low, T_high in itertools.pairwise(edges):
        temps = (float(T_low), 0.5 * float(T_low + T_high), float(T_high))
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
            every_case.update(((c.T_fuel, c.u), c) for c in cases)
            holds = (
                operating is not None
                and not any(band.operating for band in bands)
                and T_low <= operating.T_fuel <= T_high
                and a <= operating.u <= b
            )
            bands.append(
                _tune_band(
                    cases,
                    rule,
                    control_period,
                    closed_loop_time,
                    ms_target,
                    temps,
                    (a, b),
                    operating if holds else None,
                )
            )
    return GainSchedule(
        rule=rule,
        control_period=control_period,
        ms_target=ms_target,
        bands=bands,
        u_span=u_hi - u_lo if u_span is None else u_span,
        y_span=config.flowmeter.span_Lpm if y_span is None else y_span,
        single_set=_single_set(bands, list(every_case.values()), ms_target),
    )


def _spread(values: list[float]) -> float:
    """Relative spread (max − min)/max of positive values [-]."""
    return (max(values) - min(values)) / max(abs(v) for v in values)


def _single_set(
    bands: list[ScheduleBand], cases: list[PlantCase], ms_target: float
) -> FixedPIEvaluation | None:
    """One PI for all bands, checked on all their cases, when the bands' gains agree; else None."""
    Kc, Ti = [b.pi.Kc for b in bands], [b.pi.Ti for b in bands]
    if _spread(Kc) > SINGLE_SET_TOLERANCE or _spread(Ti) > SINGLE_SET_TOLERANCE:
        return None
    cautious = min(bands, key=lambda b: b.pi.Kc).pi
    evaluation = evaluate_fixed(cautious, cases)
    if evaluation.worst_Ms > ms_target or not evaluation.all_stable:
        return None
    return evaluation


def _tune_band(
    cases: list[PlantCase],
    rule: str,
    control_period: float,
    closed_loop_time: float | None,
    ms_target: float,
    temps: tuple[float, float, float],
    commands: tuple[float, float],
    operating: Anchor | None = None,
) -> ScheduleBand:
    """One band: tuned on its most demanding case (largest K/T), detuned to meet the target.

    The band holding the operating point (``operating``) is tuned on the anchoring model
    itself, as the headline gains are.
    """
    design = max(cases, key=lambda c: c.model.K / c.model.T)
    design_model, design_T, design_u = design.model, design.T_fuel, design.u
    if operating is not None:
        design_model, design_T, design_u = operating.model, operating.T_fuel, operating.u
    pi = tune(design_model, rule, control_period, closed_loop_time)
    factor = 1.0
    evaluation = evaluate_fixed(pi, cases)
    while evaluation.worst_Ms > ms_target or not evaluation.all_stable:
        factor *= 0.95
        if factor < 0.05:
            raise FuelidError(
                f"no {rule} gains reach Ms ≤ {ms_target:g} for {kelvin_to_celsius(temps[0]):g}…"
                f"{kelvin_to_celsius(temps[2]):g} °C"
            )
        evaluation = evaluate_fixed(pi.with_gain_factor(factor), cases)
    middle = [c for c in cases if c.T_fuel == temps[1]] or cases
    flows = sorted((c.u, c.flow) for c in middle)
    return ScheduleBand(
        T_low=temps[0],
        T_high=temps[2],
        u_low=float(commands[0]),
        u_high=float(commands[1]),
        flow_low=flows[0][1],
        flow_high=flows[-1][1],
        pi=evaluation.pi,
        detune=factor,
        worst=evaluation,
        design_T=design_T,
        design_u=design_u,
        operating=operating is not None,
    )
