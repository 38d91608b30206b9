"""One tuning, evaluated: the gains, their robustness on the model and the linear closed loop.

What ``fuelid tune``, ``fuelid report`` and the demo share, with the documented JSON object.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from fuelid.errors import FuelidError
from fuelid.model import ProcessModel
from fuelid.tuning.closedloop import LinearResponse, linear_closed_loop
from fuelid.tuning.frequency import Robustness, robustness
from fuelid.tuning.rules import PISettings, tune

UNITS = {
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
}


MS_WARNING = 2.0
"""Ms above which the gains are flagged: a gain margin that can be below 2 (Åström–Hägglund)."""


@dataclass(frozen=True)
class TuningResult:
    """PI settings with their margins and unit-step closed-loop metrics on the model."""

    model: ProcessModel
    pi: PISettings
    robustness: Robustness
    closed_loop: LinearResponse
    u_span: float
    y_span: float

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
            "model": self.model.as_dict(),
            "reduced_model": None
            if reduced is None
            else {"K": reduced.K, "T1": reduced.T1, "theta": reduced.theta},
            "plc": self.pi.plc_form(self.u_span, self.y_span),
            "gain_margin": self.robustness.gain_margin,
            "phase_margin_deg": self.robustness.phase_margin_deg,
            "Ms": self.robustness.Ms,
            "robustness": self.robustness.as_dict(),
            "closed_loop": {
                "model": "linear (the process model, exact ZOH)",
                "setpoint_step": self.closed_loop.setpoint.as_dict(),
                "load_step": self.closed_loop.disturbance.as_dict(),
            },
            "warnings": self.warnings,
        }


MAX_CONTROL_PERIOD = 10.0
"""Longest PLC control period [s] fuelid tunes for (a flow loop's PLC runs in 0.01…1 s)."""
MAX_TIME_SCALE = 1e5
"""Longest time constant or delay [s] of a model fuelid tunes (about a day)."""
MIN_TIME_CONSTANT = 1e-6
"""Shortest non-zero time constant [s]."""
GAIN_RANGE = (1e-6, 1e6)
"""Process gains [output unit per input unit] fuelid tunes."""
MAX_PERIODS = (1000, 10_000)
"""Largest delay and largest sum of time constants, in control periods, of a sampled loop."""


def check_control_period(control_period: float) -> None:
    """Refuse a control period that is negative, not finite or beyond 10 s."""
    if not (math.isfinite(control_period) and 0.0 <= control_period <= MAX_CONTROL_PERIOD):
        raise FuelidError(
            f"control period must be 0 (continuous) or up to {MAX_CONTROL_PERIOD:g} s, "
            f"got {control_period:g} s"
        )


def check_tunable(model: ProcessModel, control_period: float) -> None:
    """Refuse a model or control period far outside any flow loop, before any work is done.

    Such numbers come from a unit mix-up (ms for s) or a failed identification; tuning them
    would take minutes or overflow, and the gains would mean nothing.

    Raises
    ------
    FuelidError
        With the reason, e.g. a delay of more than 1,000 control periods.
    """
    check_control_period(control_period)
    lo, hi = GAIN_RANGE
    if model.K > 0.0 and not lo <= model.K <= hi:
        raise FuelidError(f"process gain K = {model.K:g} is outside {lo:g}…{hi:g}: check its units")
    for name in ("T", "T2", "T_f", "delay"):
        value = getattr(model, name)
        if value > MAX_TIME_SCALE:
            raise FuelidError(
                f"model {name} = {value:g} s exceeds {MAX_TIME_SCALE:g} s: check its units"
            )
        if name != "delay" and 0.0 < value < MIN_TIME_CONSTANT:
            raise FuelidError(
                f"model {name} = {value:g} s is below {MIN_TIME_CONSTANT:g} s: give 0 for no lag"
            )
    if control_period > 0.0:
        max_delay, max_lags = MAX_PERIODS
        if model.delay > max_delay * control_period:
            raise FuelidError(
                f"delay {model.delay:g} s is more than {max_delay} control periods of "
                f"{control_period:g} s: check the units or --control-period"
            )
        if sum(model.time_constants) > max_lags * control_period:
            raise FuelidError(
                f"time constants of {sum(model.time_constants):g} s span more than {max_lags} "
                f"control periods of {control_period:g} s: check the units or --control-period"
            )


def evaluate_tuning(
    model: ProcessModel,
    rule: str = "simc",
    control_period: float = 1.0,
    speed: float | None = None,
    u_span: float = 4.0,
    y_span: float = 100.0,
) -> TuningResult:
    """Tune ``model`` by ``rule`` and evaluate the gains on it (see :func:`~.rules.tune`).

    Examples
    --------
    >>> res = evaluate_tuning(ProcessModel(K=1.0, T=2.0, delay=1.0), "amigo", control_period=0.0)
    >>> round(res.pi.Kc, 3), round(res.robustness.Ms, 2)
    (0.406, 1.21)
    """
    check_tunable(model, control_period)
    pi = tune(model, rule, control_period, speed)
    return TuningResult(
        model=model,
        pi=pi,
        robustness=robustness(model, pi),
        closed_loop=linear_closed_loop(model, pi),
        u_span=u_span,
        y_span=y_span,
    )
