r"""PI tuning rules for K·e^(−θs)/((T·s+1)(T2·s+1)(T_f·s+1)), in a registry with a lister.

Every rule works on a first-order-plus-dead-time (FOPDT) reduction of the model:

- Skogestad's half rule: of the lags sorted by size, the largest T1 is kept, the second largest
  is split half to T1 and half to the dead time, every smaller one goes wholly to the dead time;
- a sampled controller with period h adds h/2 to the dead time (the zero-order hold delays the
  command by half a period on average), so ``control_period = 0`` means continuous control.

The controller is the ideal (standard, ISA) PI, C(s) = Kc·(1 + 1/(Ti·s)); for the fuel loop Kc is
in V per L/min and Ti in s. :meth:`PISettings.plc_form` converts it to percent of span and to the
discrete algorithm a PLC block runs; :meth:`PISettings.to_block` and
:meth:`PISettings.from_block` to and from the form and units of the site's PI block
(:mod:`fuelid.tuning._block`).

References
----------
S. Skogestad, "Simple analytic rules for model reduction and PID controller tuning",
J. Process Control 13 (2003) 291–309. C. Grimholt, S. Skogestad, "Optimal PI-control and
verification of the SIMC tuning rule", IFAC PID'12 (2012). K. J. Åström, T. Hägglund, "Revisiting
the Ziegler–Nichols step response method for PID control", J. Process Control 14 (2004) 635–650
(AMIGO). D. E. Rivera, M. Morari, S. Skogestad, "Internal model control. 4. PID controller
design", Ind. Eng. Chem. Process Des. Dev. 25 (1986) 252–265 (IMC/lambda).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Self

from fuelid.errors import FuelidError
from fuelid.lti import check_control_period
from fuelid.model import ProcessModel
from fuelid.tuning._block import BlockForm, from_block, to_block


@dataclass(frozen=True)
class ReducedModel:
    """The FOPDT model a rule is applied to: K·e^(−θs)/(T1·s+1)."""

    K: float
    """Static gain [output unit / input unit]."""
    T1: float
    """Time constant after the half rule (and the improved-SIMC shift) [s]."""
    theta: float
    """Effective dead time, h/2 of a sampled controller included [s]."""


def half_rule(model: ProcessModel, control_period: float = 0.0) -> ReducedModel:
    """Skogestad's half rule for a PI controller, plus h/2 for a sampled controller.

    Parameters
    ----------
    model : ProcessModel
        The process model.
    control_period : float
        Controller period h [s]; 0 for a continuous controller.

    Returns
    -------
    ReducedModel

    Examples
    --------
    >>> r = half_rule(ProcessModel(K=2.0, T=4.0, T2=1.0, T_f=0.2, delay=0.5), control_period=1.0)
    >>> r.K, r.T1, round(r.theta, 6)
    (2.0, 4.5, 1.7)
    """
    lags = sorted(model.time_constants, reverse=True)
    T1 = lags[0]
    theta = model.delay + 0.5 * control_period
    if len(lags) > 1:
        T1 += 0.5 * lags[1]
        theta += 0.5 * lags[1] + sum(lags[2:])
    return ReducedModel(K=model.K, T1=T1, theta=theta)


@dataclass(frozen=True)
class PISettings:
    """Ideal-form PI gains C(s) = Kc·(1 + 1/(Ti·s)) and how they were obtained."""

    rule: str
    """Registry name of the rule."""
    Kc: float
    """Proportional gain [input unit / output unit; V per L/min for the fuel loop]."""
    Ti: float
    """Integral (reset) time [s]."""
    control_period: float
    """Controller period h [s]; 0 for continuous control."""
    tuning_parameter: float | None = None
    """τc (SIMC) or λ (lambda) used [s], the closed-loop time constant (larger is slower); None
    for rules without one."""
    reduced: ReducedModel | None = None
    """The FOPDT reduction the rule was applied to."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.Kc) and self.Kc > 0.0):
            raise FuelidError(f"controller gain Kc must be positive, got {self.Kc:g}")
        if not (math.isfinite(self.Ti) and self.Ti > 0.0):
            raise FuelidError(f"integral time Ti must be positive, got {self.Ti:g} s")
        check_control_period(self.control_period)

    @property
    def Ki(self) -> float:
        """Integral gain of the parallel form Kp + Ki/s, Ki = Kc/Ti [input unit/(output unit·s)]."""
        return self.Kc / self.Ti

    def with_gain_factor(self, factor: float) -> PISettings:
        """The same settings with Kc multiplied by ``factor`` (detuning)."""
        return PISettings(
            rule=self.rule,
            Kc=self.Kc * factor,
            Ti=self.Ti,
            control_period=self.control_period,
            tuning_parameter=self.tuning_parameter,
            reduced=self.reduced,
        )

    def to_block(self, block: BlockForm) -> tuple[float, float]:
        """The (kc, ti) the PLC's block takes: :func:`fuelid.tuning.to_block`.

        Parameters
        ----------
        block : BlockForm
            The block's form and units (:meth:`BlockForm.of` of the site's ``[controller]``).

        Examples
        --------
        >>> pi = PISettings(rule="simc", Kc=0.05, Ti=30.0, control_period=1.0)
        >>> pi.to_block(BlockForm(form="parallel", gain_units="percent", integral_unit="min",
        ...                       u_span=4.0, y_span=100.0))
        (1.25, 2.5)
        """
        return to_block(self.Kc, self.Ti, block)

    @classmethod
    def from_block(
        cls, kc: float, ti: float, block: BlockForm, *, rule: str, control_period: float
    ) -> Self:
        """The settings a PLC block holds as (kc, ti): :func:`fuelid.tuning.from_block`.

        Parameters
        ----------
        kc, ti : float
            The block's two numbers, in its form and units.
        block : BlockForm
            The block's form and units.
        rule : str
            Where the gains came from (a rule's name, or e.g. ``"commissioning"``).
        control_period : float
            The PLC's PI period h [s]; 0 for continuous control.

        Examples
        --------
        >>> pi = PISettings.from_block(1.25, 2.5, BlockForm(form="parallel",
        ...     gain_units="percent", integral_unit="min", u_span=4.0, y_span=100.0),
        ...     rule="commissioning", control_period=1.0)
        >>> round(pi.Kc, 12), round(pi.Ti, 12)
        (0.05, 30.0)
        """
        Kc, Ti = from_block(kc, ti, block)
        return cls(rule=rule, Kc=Kc, Ti=Ti, control_period=control_period)

    def velocity_coefficients(self, h: float | None = None) -> tuple[float, float]:
        """(q0, q1) of the PLC's PI at period h: Δu[k] = q0·e[k] + q1·e[k−1].

        The one statement of the discrete PI every other part uses (PLC forms, the sampled
        loop's frequency response, the linear closed loop): the forward-Euler integral gives
        C(z) = Kc·(1 + (h/Ti)·z⁻¹/(1 − z⁻¹)) = (q0 + q1·z⁻¹)/(1 − z⁻¹), q0 = Kc,
        q1 = −Kc·(1 − h/Ti); q0 + q1 = Kc·h/Ti is the integral gain per sample.

        Parameters
        ----------
        h : float, optional
            Period [s], positive; default the controller's ``control_period``.

        Examples
        --------
        >>> PISettings(rule="x", Kc=0.05, Ti=2.0, control_period=1.0).velocity_coefficients()
        (0.05, -0.025)
        """
        period = self.control_period if h is None else h
        if not period > 0.0:
            raise FuelidError("the discrete PI needs a positive period")
        return self.Kc, -self.Kc * (1.0 - period / self.Ti)

    def plc_form(self, u_span: float | None = None, y_span: float | None = None) -> dict[str, Any]:
        """The gains as a PLC block takes them.

        Parameters
        ----------
        u_span : float, optional
            Span of the controller output [input unit], 4 V for a 1–5 V signal.
        y_span : float, optional
            Span of the measurement [output unit], the flowmeter's full scale in L/min. Without
            both spans ``percent_of_span`` is None: a %/% gain on spans nobody gave would be a
            wrong number to type into the block.

        Returns
        -------
        dict
            ``percent_of_span``: Kc in %/% (= Kc·y_span/u_span,
            :func:`~fuelid.tuning._block.percent_of_span`), Ti [s] and Ti in minutes (the ideal
            percent block of :func:`~fuelid.tuning.to_block`; None without the spans);
            ``parallel``: Kp, Ki;
            ``discrete``: for h > 0 the positional algorithm u[k] = Kc·e[k] + I[k] with the
            integral updated after the output, I[k+1] = I[k] + Kc·h/Ti·e[k] (forward Euler, as
            in Åström & Hägglund's PID code and :class:`~fuelid.tuning.closedloop.DiscretePI`),
            and its velocity (incremental) equivalent Δu[k] = q0·e[k] + q1·e[k−1] with
            q0 = Kc, q1 = −Kc·(1 − h/Ti); None for continuous control.

        Examples
        --------
        >>> pi = PISettings(rule="simc", Kc=0.05, Ti=2.0, control_period=1.0)
        >>> form = pi.plc_form(u_span=4.0, y_span=100.0)
        >>> form["percent_of_span"]["Kc"], form["discrete"]["q0"], form["discrete"]["q1"]
        (1.25, 0.05, -0.025)
        """
        if any(span is not None and not span > 0.0 for span in (u_span, y_span)):
            raise FuelidError("the output and measurement spans must be positive")
        h = self.control_period
        discrete = None
        if h > 0.0:
            q0, q1 = self.velocity_coefficients()
            discrete = {
                "algorithm": "positional u[k] = Kc*e[k] + I[k], I[k+1] = I[k] + Kc*h/Ti*e[k] "
                "(forward-Euler integral); velocity form du[k] = q0*e[k] + q1*e[k-1]",
                "h": h,
                "q0": q0,
                "q1": q1,
                "integral_gain_per_sample": q0 + q1,
            }
        percent: dict[str, float | None] | None = None
        if u_span is not None and y_span is not None:
            # the ideal block in %/% and minutes: the one conversion (fuelid.tuning._block)
            kc, ti_min = self.to_block(BlockForm("ideal", "percent", "min", u_span, y_span))
            percent = {
                "Kc": kc,
                "Ti": self.Ti,
                "Ti_min": ti_min,
                "u_span": u_span,
                "y_span": y_span,
            }
        return {
            "form": "ideal (standard, ISA): u = Kc*(e + (1/Ti)*integral(e dt)), e = setpoint - "
            "measurement",
            "Kc": self.Kc,
            "Ti": self.Ti,
            "percent_of_span": percent,
            "parallel": {"Kp": self.Kc, "Ki": self.Ki},
            "discrete": discrete,
        }


def simc(
    model: ProcessModel, control_period: float = 0.0, tau_c: float | None = None
) -> PISettings:
    """SIMC PI (Skogestad 2003): Kc = T1/(K(τc+θ)), Ti = min(T1, 4(τc+θ)); τc = θ by default.

    τc [s] is the desired closed-loop time constant: larger is slower and more robust.

    Examples
    --------
    The worked example K = 1, T = 2 s, θ = 1 s, continuous, τc = θ:

    >>> pi = simc(ProcessModel(K=1.0, T=2.0, delay=1.0))
    >>> round(pi.Kc, 6), round(pi.Ti, 6)
    (1.0, 2.0)
    """
    return _simc(model, control_period, tau_c, improved=False)


def improved_simc(
    model: ProcessModel, control_period: float = 0.0, tau_c: float | None = None
) -> PISettings:
    """Improved SIMC (Grimholt & Skogestad 2012): SIMC with T1 → T1 + θ/3.

    Examples
    --------
    >>> pi = improved_simc(ProcessModel(K=1.0, T=2.0, delay=1.0))
    >>> round(pi.Kc, 6), round(pi.Ti, 6)
    (1.166667, 2.333333)
    """
    return _simc(model, control_period, tau_c, improved=True)


def _simc(
    model: ProcessModel, control_period: float, tau_c: float | None, improved: bool
) -> PISettings:
    r = half_rule(model, control_period)
    if r.theta <= 0.0 and tau_c is None:
        raise FuelidError("SIMC needs a dead time (or a control period) or an explicit tau_c")
    tc = r.theta if tau_c is None else _positive(tau_c, "tau_c")
    T1 = r.T1 + r.theta / 3.0 if improved else r.T1
    reduced = ReducedModel(K=r.K, T1=T1, theta=r.theta)
    return PISettings(
        rule="isimc" if improved else "simc",
        Kc=T1 / (r.K * (tc + r.theta)),
        Ti=min(T1, 4.0 * (tc + r.theta)),
        control_period=control_period,
        tuning_parameter=tc,
        reduced=reduced,
    )


def lambda_tuning(
    model: ProcessModel, control_period: float = 0.0, lam: float | None = None
) -> PISettings:
    """Lambda / IMC-PI: Kc = T1/(K(λ+θ)), Ti = T1; λ = T1 (the open-loop time) by default.

    λ [s] is the desired closed-loop time constant: larger is slower and more robust.

    Examples
    --------
    >>> pi = lambda_tuning(ProcessModel(K=1.0, T=2.0, delay=1.0), lam=3.0)
    >>> round(pi.Kc, 6), pi.Ti
    (0.5, 2.0)
    """
    r = half_rule(model, control_period)
    lam_used = r.T1 if lam is None else _positive(lam, "lambda")
    return PISettings(
        rule="lambda",
        Kc=r.T1 / (r.K * (lam_used + r.theta)),
        Ti=r.T1,
        control_period=control_period,
        tuning_parameter=lam_used,
        reduced=r,
    )


def amigo(
    model: ProcessModel, control_period: float = 0.0, closed_loop_time: float | None = None
) -> PISettings:
    """AMIGO PI (Åström & Hägglund 2004), designed for Ms ≤ 1.4, with L = θ, T = T1.

    Kp = 0.15/K + (0.35 − LT/(L+T)²)·T/(K·L), Ti = 0.35L + 13LT²/(T² + 12LT + 7L²). The rule
    has no closed-loop time to choose: ``closed_loop_time`` must be None.

    Examples
    --------
    The worked example K = 1, T = 2 s, L = 1 s, continuous:

    >>> pi = amigo(ProcessModel(K=1.0, T=2.0, delay=1.0))
    >>> round(pi.Kc, 4), round(pi.Ti, 4)
    (0.4056, 1.8357)
    """
    if closed_loop_time is not None:
        raise FuelidError("the AMIGO rule has no tuning parameter (drop --tau-c/--lambda)")
    r = half_rule(model, control_period)
    L, T, K = r.theta, r.T1, r.K
    if L <= 0.0:
        raise FuelidError("AMIGO needs a dead time (or a control period) greater than zero")
    Kc = 0.15 / K + (0.35 - L * T / (L + T) ** 2) * T / (K * L)
    Ti = 0.35 * L + 13.0 * L * T**2 / (T**2 + 12.0 * L * T + 7.0 * L**2)
    return PISettings(rule="amigo", Kc=Kc, Ti=Ti, control_period=control_period, reduced=r)


def _positive(value: float, name: str) -> float:
    if not (math.isfinite(value) and value > 0.0):
        raise FuelidError(f"{name} must be a positive number of seconds, got {value:g}")
    return float(value)


RuleFunction = Callable[[ProcessModel, float, float | None], PISettings]
"""A rule: (model, control period h [s], closed-loop time [s] or None) → PI settings."""


@dataclass(frozen=True)
class TuningRule:
    """A registered rule: the function, what its tuning parameter means, and its source."""

    name: str
    function: RuleFunction
    parameter: str | None
    """Meaning of the rule's closed-loop time (τc or λ) [s] (None: the rule has none)."""
    summary: str
    source: str


TUNING_RULES: dict[str, TuningRule] = {
    "simc": TuningRule(
        "simc",
        simc,
        "tau_c: closed-loop time constant (default θ, tight control)",
        "Kc = T1/(K(τc+θ)), Ti = min(T1, 4(τc+θ))",
        "Skogestad 2003",
    ),
    "isimc": TuningRule(
        "isimc",
        improved_simc,
        "tau_c: closed-loop time constant (default θ)",
        "SIMC with T1 → T1 + θ/3 (better for delay-dominant loops)",
        "Grimholt & Skogestad 2012",
    ),
    "lambda": TuningRule(
        "lambda",
        lambda_tuning,
        "lambda: closed-loop time constant (default T1, typically 1–3·T1)",
        "Kc = T1/(K(λ+θ)), Ti = T1",
        "Rivera, Morari & Skogestad 1986 (IMC-PI)",
    ),
    "amigo": TuningRule(
        "amigo",
        amigo,
        None,
        "Kp = 0.15/K + (0.35 − LT/(L+T)²)T/(KL), Ti = 0.35L + 13LT²/(T²+12LT+7L²), Ms ≈ 1.4",
        "Åström & Hägglund 2004",
    ),
}


def list_rules() -> list[TuningRule]:
    """Every registered rule, in registry order.

    Examples
    --------
    >>> [rule.name for rule in list_rules()]
    ['simc', 'isimc', 'lambda', 'amigo']
    """
    return list(TUNING_RULES.values())


def tune(
    model: ProcessModel,
    rule: str = "simc",
    control_period: float = 1.0,
    closed_loop_time: float | None = None,
) -> PISettings:
    """PI settings for ``model`` by the named rule.

    Parameters
    ----------
    model : ProcessModel
        Process model (K in output per input unit, times in s).
    rule : str
        A key of :data:`TUNING_RULES`.
    control_period : float
        Controller period h [s] (1 s for the article's PLC); 0 for continuous control.
    closed_loop_time : float, optional
        The rule's tuning parameter [s], the desired closed-loop time constant: τc for SIMC and
        improved SIMC, λ for lambda; None for the rule's default (θ, T1). Larger is slower and
        more robust: a lower Kc. AMIGO has none.

    Raises
    ------
    FuelidError
        On an unknown rule, a negative control period or a non-positive tuning parameter.
    """
    if rule not in TUNING_RULES:
        raise FuelidError(f"unknown tuning rule {rule!r}; choose from {', '.join(TUNING_RULES)}")
    check_control_period(control_period)
    if model.K <= 0.0:
        raise FuelidError(
            f"the process gain K must be positive for these rules, got {model.K:g} "
            "(swap the action of the controller for a reverse-acting loop)"
        )
    return TUNING_RULES[rule].function(model, control_period, closed_loop_time)
