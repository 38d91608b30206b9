"""One tuning, evaluated: the gains, their robustness on the model and the linear closed loop.

:class:`TuningResult` is what ``fuelid tune``, ``fuelid report`` and the demo share, with the
documented JSON object (:meth:`TuningResult.to_json`) and :data:`UNITS`, the units map of every
tuning JSON object. The limits and input guards live in :mod:`fuelid.tuning._limits`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from fuelid.model import ProcessModel
from fuelid.tuning._frequency import Robustness, robustness
from fuelid.tuning._limits import check_tunable
from fuelid.tuning._linearloop import LinearResponse, linear_closed_loop
from fuelid.tuning._rules import PISettings, tune

UNITS: dict[str, str] = {
    "Kc": "V/(L/min)",
    "Ti": "s",
    "Ki": "V/((L/min)*s)",
    "control_period": "s",
    "tuning_parameter": "s",
    "K": "(L/min)/V",
    "T": "s",
    "T2": "s",
    "T_f": "s",
    "delay": "s",
    "T1": "s",
    "theta": "s",
    "percent_of_span.Kc": "%/%",
    "Kc_percent_of_span": "%/%",
    "Kp": "V/(L/min)",
    "q0": "V/(L/min)",
    "q1": "V/(L/min)",
    "integral_gain_per_sample": "V/(L/min)",
    "h": "s",
    "u_span": "V",
    "y_span": "L/min",
    "gain_margin": "ratio",
    "phase_margin_deg": "deg",
    "Ms": "1",
    "Mt": "1",
    "crossover_frequency": "rad/s",
    "overshoot_percent": "% of the setpoint step",
    "settling_time": "s (2 % band)",
    "iae": "(L/min)*s per L/min of setpoint step, or per V of load step",
    "peak_deviation": "L/min per L/min of step, or per V of load step",
    "fuel_temperature": "degC",
    "flow": "L/min",
    "u": "V",
    "Ti_min": "min",
    "percent_of_span.Ti_min": "min",
    "design_fuel_temperature": "degC",
    "design_u": "V",
    "omega": "rad/s",
    "up_to": "rad/s",
    "u_range": "V",
    "u_low": "V",
    "u_high": "V",
    "t_low": "degC",
    "t_high": "degC",
    "flow_low": "L/min",
    "flow_high": "L/min",
    "Ms_of_chosen_gains": "1",
    "worst_Ms": "1",
    "worst_overshoot_percent": "%",
    "worst_gain_margin": "ratio",
    "worst_phase_margin_deg": "deg",
    "detune": "1",
    "value": "as its key (V for u_span, L/min for y_span, s for the control period)",
}
"""Units of the numbers in the JSON of ``fuelid tune`` and ``fuelid report`` (by key name)."""


MS_WARNING = 2.0
"""Ms above which the gains are flagged: a gain margin that can be below 2 (Åström–Hägglund)."""


@dataclass(frozen=True)
class TuningResult:
    """PI settings with their margins and unit-step closed-loop metrics on the model."""

    model: ProcessModel
    pi: PISettings
    robustness: Robustness
    closed_loop: LinearResponse
    u_span: float | None = None
    """Drive span of the percent-of-span gain [V]; None: not known, no %/% gain."""
    y_span: float | None = None
    """Meter span of the percent-of-span gain [L/min]; None: not known, no %/% gain."""

    def plc_form(self) -> dict[str, Any]:
        """The gains as PLC blocks take them; ``percent_of_span`` None without both spans."""
        return self.pi.plc_form(self.u_span, self.y_span)

    @property
    def warnings(self) -> list[str]:
        """What makes these gains unfit to type into the PLC as they are."""
        r = self.robustness
        out = []
        if not r.stable:
            out.append(
                "the loop is UNSTABLE on the model: check the model, or slow the loop down "
                "(a larger --tau-c or --lambda)"
            )
        elif r.Ms > MS_WARNING:
            out.append(
                f"Ms {r.Ms:.3g} > {MS_WARNING:g} (gain margin {r.gain_margin:.3g}): the loop is "
                "barely stable; a larger --tau-c or --lambda, or a shorter control period, "
                "gives it margin"
            )
        if math.isnan(self.closed_loop.setpoint.settling_time):
            out.append(
                "the setpoint step does not settle within the "
                f"{self.closed_loop.time[-1]:.3g} s simulated on the model"
            )
        return out

    def to_json(self) -> dict[str, Any]:
        """The documented JSON object of ``fuelid tune --json`` (without provenance)."""
        reduced = self.pi.reduced
        return {
            "rule": self.pi.rule,
            "Kc": self.pi.Kc,
            "Ti": self.pi.Ti,
            "Ki": self.pi.Ki,
            "control_period": self.pi.control_period,
            "tuning_parameter": self.pi.tuning_parameter,
            "model": self.model.to_json(),
            "reduced_model": None
            if reduced is None
            else {"K": reduced.K, "T1": reduced.T1, "theta": reduced.theta},
            "plc": self.plc_form(),
            "gain_margin": self.robustness.gain_margin,
            "phase_margin_deg": self.robustness.phase_margin_deg,
            "Ms": self.robustness.Ms,
            "robustness": self.robustness.to_json(),
            "closed_loop": {
                "model": "linear (the process model, exact ZOH)",
                "setpoint_step": self.closed_loop.setpoint.to_json(),
                "load_step": self.closed_loop.disturbance.to_json(),
            },
            "warnings": self.warnings,
        }


def evaluate_tuning(
    model: ProcessModel,
    rule: str = "simc",
    control_period: float = 1.0,
    closed_loop_time: float | None = None,
    u_span: float | None = None,
    y_span: float | None = None,
) -> TuningResult:
    """Tune ``model`` by ``rule`` and evaluate the gains on it.

    Parameters
    ----------
    model : ProcessModel
        The process model (K [(L/min)/V], times [s]); refused by
        :func:`~fuelid.tuning._limits.check_tunable` when far outside any flow loop.
    rule : str
        The rule's key in :data:`~fuelid.tuning.TUNING_RULES` (as for :func:`~fuelid.tuning.tune`).
    control_period : float
        The PLC's period h [s].
    closed_loop_time : float, optional
        τc or λ [s] (larger is slower; None for the rule's default).
    u_span, y_span : float, optional
        Drive span [V] and meter span [L/min] of the percent-of-span gain, from the user's
        facts; None: no %/% gain (no span is assumed).

    Examples
    --------
    >>> res = evaluate_tuning(ProcessModel(K=1.0, T=2.0, delay=1.0), "amigo", control_period=0.0)
    >>> round(res.pi.Kc, 3), round(res.robustness.Ms, 2)
    (0.406, 1.21)
    """
    check_tunable(model, control_period)
    pi = tune(model, rule, control_period, closed_loop_time)
    return TuningResult(
        model=model,
        pi=pi,
        robustness=robustness(model, pi),
        closed_loop=linear_closed_loop(model, pi),
        u_span=u_span,
        y_span=y_span,
    )
