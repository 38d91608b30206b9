"""Whether the online service should propose new PI gains now, and which: a pure decision.

No I/O, no store, no PLC: :func:`propose` takes the accepted identification windows, the
current and the commissioning gains and the site's ``[online]`` table
(:class:`fuelid.online._settings.Online`) and returns a :class:`ProposalDecision` that says yes or
no, with one line of reason either way and every number behind it. The guards follow docs
online.md §5 (an adaptive tuner that trusts every window bursts):

1. **No proposal while the loop oscillates** (the caller's oscillation detector decides).
2. **Separate evidence.** ``agree_windows`` accepted windows must rest on *separate* excitation
   events: overlapping windows that contain the same step are one piece of evidence
   (:func:`independent_windows`, newest first).
3. **Agreement.** The rule (``rule``, default closed-loop time, the PLC's control period h)
   applied to each of those windows' models must give gains within ``hysteresis`` of each other:
   max/min − 1 ≤ ``hysteresis`` for Kc and for Ti.
4. **Target.** The rule applied to the inverse-variance weighted mean model of those windows
   (every parameter weighted by 1/se(K)²; equal weights when any se(K) is missing).
5. **Hard bounds.** A target outside ``gain_bounds`` × the commissioning gains is *clipped* to
   the bound (not refused): the evidence says "move that way", the bound says how far one may
   ever go; the decision says so (``clipped``, and in the reason).
6. **Dead band (hysteresis).** No proposal when the (clipped) target is within ``hysteresis`` of
   the current gains: |target/current − 1| ≤ ``hysteresis`` for both Kc and Ti. The dead band is
   on the distance to the target, not on the size of the partial step: a band on the step would
   leave the loop forever ``hysteresis``/``move_fraction`` away from its target.
7. **Partial move, geometric.** new = current·(target/current)^f with f = ``move_fraction``, for
   Kc and Ti separately (a straight line in log space: gains are scale quantities and the bounds
   are factors, so a rise and a fall by the same factor are treated alike). The result is
   clipped to the bounds again (it can only leave them when the current gains are outside).
8. **Robustness.** Ms of the new gains, sampled PI at h included, on the newest window's model,
   on the model the current gains were tuned for (when known) and on the newest model with K set
   to each end of ``K_range`` (the K(T) tracker's K_pred ± 2·se, when given): every Ms must be
   ≤ ``ms_target`` (an unstable loop counts as Ms = ∞). Otherwise Kc is reduced, Ti kept, to the
   largest factor that passes (bisection in log Kc) but not below the Kc lower bound; if even
   the bound fails there is no proposal. A detuned proposal that moves the gains less than the
   smallest undetuned step, (1 + ``hysteresis``)^f − 1, is not made, unless the current gains
   themselves fail the target (then any robust move is worth proposing).

Gains are in the ideal (ISA) form and engineering units throughout, Kc [V per L/min] and Ti [s]
(:class:`Gains`, a :class:`~fuelid.tuning._rules.PISettings`, from :mod:`fuelid.online._gains`);
:meth:`~fuelid.tuning._rules.PISettings.to_block` and
:meth:`~fuelid.tuning._rules.PISettings.from_block` convert to and from the form and units of
the PLC's block (:mod:`fuelid.tuning._block`, from the site's ``[controller]``). The windows'
evidence (:class:`WindowModel`, :func:`independent_windows`, :func:`weighted_mean_model`) lives
in :mod:`fuelid.online._evidence`; this module re-exports it and :class:`Gains`.

Units: time [s], K [(L/min)/V], Kc [V per L/min], Ti [s], Ms [-].

References
----------
K. J. Åström, B. Wittenmark, *Adaptive Control* (2nd ed., Addison-Wesley, 1995), §13 (practical
issues: parameter bounds, dead zones). B. D. O. Anderson, "Adaptive systems, lack of persistency
of excitation and bursting phenomena", Automatica 21 (1985) 247–258. J. E. Seem, "A new pattern
recognition adaptive controller with application to HVAC systems", Automatica 34 (1998)
969–982 (stepping the gains part of the way toward the optimum). S. Skogestad, "Simple analytic
rules for model reduction and PID controller tuning", J. Process Control 13 (2003) 291–309
(SIMC; Ms as the robustness measure).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from fuelid.errors import FuelidError
from fuelid.io.jsonsafe import json_ready
from fuelid.lti import check_control_period
from fuelid.model import ProcessModel
from fuelid.online._evidence import (
    EVENT_TOLERANCE_S,
    WindowModel,
    independent_windows,
    weighted_mean_model,
)
from fuelid.online._gains import Gains
from fuelid.online._settings import Online
from fuelid.tuning import PISettings, robustness, tune

DETUNE_TOLERANCE = 1e-3
"""The detuning search stops when its bracket of Kc factors is this narrow (relative) [-]."""


# --- the decision ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class ProposalDecision:
    """Whether to propose new PI gains, which, and why.

    Attributes
    ----------
    propose : bool
        True when new gains are proposed.
    reason : str
        One line, also when nothing is proposed ("only 1 independent window of 2",
        "change 4.0 % ≤ hysteresis 10 %", "loop oscillating", …).
    old : Gains
        The current gains [V per L/min, s].
    new : Gains or None
        The proposed gains (after the partial move, bounds and detuning); None when not
        proposing.
    target : Gains or None
        The rule's gains on the mean model, clipped to the bounds (what the move aims at); None
        when the decision stopped before a target.
    Ms : dict
        Check name (``newest``, ``tuned_for``, ``K_low``, ``K_high``) → Ms of the new gains (or
        of the last gains tried when the robustness check refused) [-]; ∞ for an unstable loop.
    model_ids : tuple of int
        The windows behind the decision (the independent windows, newest first).
    clipped : bool
        True when the target or the new gains were clipped to the hard bounds.
    detail : dict
        Everything else: settings, per-window gains, weights, the mean model, the unclipped
        target, the changes, every check's model and Ms before and after detuning, skipped
        checks, the detuning factor.
    """

    propose: bool
    reason: str
    old: Gains
    new: Gains | None
    target: Gains | None
    Ms: dict[str, float]
    model_ids: tuple[int, ...]
    clipped: bool
    detail: dict[str, Any]

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dictionary (non-finite numbers as None)."""
        out: dict[str, Any] = json_ready(
            {
                "propose": self.propose,
                "reason": self.reason,
                "old": self.old.to_json(),
                "new": None if self.new is None else self.new.to_json(),
                "target": None if self.target is None else self.target.to_json(),
                "Ms": dict(self.Ms),
                "model_ids": list(self.model_ids),
                "clipped": self.clipped,
                "detail": self.detail,
            }
        )
        return out


@dataclass(frozen=True)
class _Check:
    name: str
    model: ProcessModel
    model_id: int | None


def _rel_change(new: Gains, old: Gains) -> dict[str, float]:
    return {"Kc": abs(new.Kc / old.Kc - 1.0), "Ti": abs(new.Ti / old.Ti - 1.0)}


def _spread(values: Sequence[float]) -> float:
    return max(values) / min(values) - 1.0


def _clip(value: float, low: float, high: float) -> float:
    return min(max(value, low), high)


def _clip_gains(gains: Gains, bounds: Mapping[str, tuple[float, float]]) -> Gains:
    return Gains(
        Kc=_clip(gains.Kc, *bounds["Kc"]),
        Ti=_clip(gains.Ti, *bounds["Ti"]),
    )


def _move(current: Gains, target: Gains, fraction: float) -> Gains:
    """Geometric partial move: current·(target/current)^fraction, per gain."""
    return Gains(
        Kc=current.Kc * (target.Kc / current.Kc) ** fraction,
        Ti=current.Ti * (target.Ti / current.Ti) ** fraction,
    )


def _pct(x: float) -> str:
    return f"{100.0 * x:.1f} %"


def propose(
    windows: Sequence[WindowModel],
    current: Gains,
    commissioning: Gains,
    settings: Online,
    *,
    control_period: float,
    tuned_for: ProcessModel | None = None,
    K_range: tuple[float, float] | None = None,
    oscillating: bool = False,
) -> ProposalDecision:
    """Decide whether to propose new PI gains now, and which (module docstring: the rules).

    Parameters
    ----------
    windows : sequence of WindowModel
        The accepted windows available (any order); the newest independent
        ``settings.agree_windows`` of them are used.
    current : Gains
        The gains the PLC runs now [V per L/min, s].
    commissioning : Gains
        The commissioning gains, the reference of ``settings.gain_bounds``.
    settings : Online
        The site's ``[online]`` table: ``rule``, ``ms_target``, ``gain_bounds``,
        ``agree_windows``, ``hysteresis``, ``move_fraction``.
    control_period : float
        The PLC's PI period h [s] (tuning and Ms include it); 0 for continuous control.
    tuned_for : ProcessModel, optional
        The model the current gains were tuned for; its Ms check is skipped when None.
    K_range : tuple of float, optional
        (K_low, K_high) [(L/min)/V], the ends of the K uncertainty at the current operating
        point, typically K_pred ∓ 2·se from :meth:`fuelid.online._tracking.KTracker.predict`; the
        newest model with K set to each is checked. None skips both checks; K_low ≤ 0 skips
        that end.
    oscillating : bool
        True when the loop oscillates now: no proposal.

    Returns
    -------
    ProposalDecision

    Raises
    ------
    FuelidError
        On a negative control period or a K_range with K_low > K_high or a non-finite end.
    """
    check_control_period(control_period)
    _check_K_range(K_range)
    n = settings.agree_windows
    bounds = _gain_bounds(commissioning, settings.gain_bounds)
    draft = _Draft(current, _settings_detail(settings, control_period, commissioning, bounds))
    draft.detail["windows_available"] = len(windows)
    if oscillating:
        return draft.refuse("loop oscillating: no proposal while it oscillates")

    # gates 2 and 3: separate evidence that agrees
    chosen = independent_windows(windows, n)
    draft.ids = tuple(w.model_id for w in chosen)
    if len(chosen) < n:
        plural = "" if len(chosen) == 1 else "s"
        return draft.refuse(
            f"only {len(chosen)} independent window{plural} of {n} "
            f"({len(windows)} accepted; windows sharing an excitation event count once)"
        )
    disagreement = _disagreement(chosen, settings, control_period, draft.detail)
    if disagreement is not None:
        return draft.refuse(disagreement)

    # gates 4 to 6: the target, within the bounds, outside the dead band
    draft.target, draft.clipped = _target(chosen, settings, control_period, bounds, draft.detail)
    change = _rel_change(draft.target, current)
    draft.detail["change_to_target"] = change
    largest = max(change.values())
    if largest <= settings.hysteresis:
        return draft.refuse(
            f"change {_pct(largest)} ≤ hysteresis {100.0 * settings.hysteresis:g} %"
        )

    # gate 7: part of the way there
    moved = _move(current, draft.target, settings.move_fraction)
    new = _clip_gains(moved, bounds)
    draft.clipped = draft.clipped or new != moved
    draft.detail["undetuned"] = new.to_json()

    # gate 8: robust on every model the evidence allows
    checks, skipped = _robustness_checks(chosen[0], tuned_for, K_range)
    draft.detail["skipped"] = skipped
    robust = _Robustness(tuple(checks), settings, control_period)
    return _robust_decision(draft, new, bounds["Kc"][0], robust, len(chosen))


# --- the gates ------------------------------------------------------------------------------------


@dataclass
class _Draft:
    """The decision as it is being made: what any outcome reports, filled in gate by gate."""

    current: Gains
    detail: dict[str, Any]
    ids: tuple[int, ...] = ()
    """The independent windows behind the decision, once chosen."""
    target: Gains | None = None
    """The rule's gains on the mean model (clipped), once computed."""
    clipped: bool = False

    def refuse(self, reason: str, Ms: Mapping[str, float] | None = None) -> ProposalDecision:
        """No proposal, for ``reason``, with what the gates found so far."""
        return ProposalDecision(
            propose=False,
            reason=reason,
            old=self.current,
            new=None,
            target=self.target,
            Ms=dict(Ms or {}),
            model_ids=self.ids,
            clipped=self.clipped,
            detail=self.detail,
        )

    def accept(self, reason: str, new: Gains, Ms: dict[str, float]) -> ProposalDecision:
        """The proposal of ``new``, which every gate passed."""
        return ProposalDecision(
            propose=True,
            reason=reason,
            old=self.current,
            new=new,
            target=self.target,
            Ms=Ms,
            model_ids=self.ids,
            clipped=self.clipped,
            detail=self.detail,
        )


def _check_K_range(K_range: tuple[float, float] | None) -> None:
    if K_range is None:
        return
    k_lo, k_hi = K_range
    if not (math.isfinite(k_lo) and math.isfinite(k_hi) and k_lo <= k_hi and k_hi > 0.0):
        raise FuelidError(f"K_range must be finite with K_low <= K_high, K_high > 0: {K_range}")


def _gain_bounds(commissioning: Gains, factors: Sequence[float]) -> dict[str, tuple[float, float]]:
    """The hard bounds of Kc and Ti: ``gain_bounds`` × the commissioning gains."""
    low, high = factors
    return {
        "Kc": (low * commissioning.Kc, high * commissioning.Kc),
        "Ti": (low * commissioning.Ti, high * commissioning.Ti),
    }


def _settings_detail(
    settings: Online,
    control_period: float,
    commissioning: Gains,
    bounds: Mapping[str, tuple[float, float]],
) -> dict[str, Any]:
    """The decision's detail as it starts: the settings every gate works with."""
    return {
        "rule": settings.rule,
        "control_period_s": control_period,
        "ms_target": settings.ms_target,
        "hysteresis": settings.hysteresis,
        "move_fraction": settings.move_fraction,
        "move": "geometric: new = current * (target / current) ** move_fraction",
        "commissioning": commissioning.to_json(),
        "bounds": {k: list(v) for k, v in bounds.items()},
    }


def _disagreement(
    chosen: Sequence[WindowModel], settings: Online, control_period: float, detail: dict[str, Any]
) -> str | None:
    """Why the rule's gains on the windows' models disagree (gate 3), or None when they agree.

    The per-window gains and their spread go into ``detail``.
    """
    try:
        per_window = [tune(w.model, settings.rule, control_period) for w in chosen]
    except FuelidError as error:
        return f"rule {settings.rule} refused a window's model: {error}"
    detail["window_gains"] = [
        {"model_id": w.model_id, "Kc": pi.Kc, "Ti": pi.Ti, "events_s": list(w.events)}
        for w, pi in zip(chosen, per_window, strict=True)
    ]
    spread = {
        "Kc": _spread([pi.Kc for pi in per_window]),
        "Ti": _spread([pi.Ti for pi in per_window]),
    }
    detail["spread"] = spread
    disagree = [
        f"{name} {min(values):.3g}–{max(values):.3g}{unit}"
        for name, values, unit in (
            ("Kc", [pi.Kc for pi in per_window], ""),
            ("Ti", [pi.Ti for pi in per_window], " s"),
        )
        if spread[name] > settings.hysteresis
    ]
    if not disagree:
        return None
    return (
        f"windows disagree: {', '.join(disagree)} "
        f"(spread above hysteresis {100.0 * settings.hysteresis:g} %)"
    )


def _target(
    chosen: Sequence[WindowModel],
    settings: Online,
    control_period: float,
    bounds: Mapping[str, tuple[float, float]],
    detail: dict[str, Any],
) -> tuple[Gains, bool]:
    """The rule's gains on the weighted mean model, clipped to the bounds (gates 4 and 5).

    Returns the target and whether it was clipped; the weights, the mean model and the
    unclipped target go into ``detail``.
    """
    mean, weights = weighted_mean_model(chosen)
    detail["weights"] = weights
    detail["mean_model"] = mean.to_json()
    raw_pi = tune(mean, settings.rule, control_period)
    raw = Gains(Kc=raw_pi.Kc, Ti=raw_pi.Ti)
    target = _clip_gains(raw, bounds)
    detail["target_unclipped"] = raw.to_json()
    return target, target != raw


def _robustness_checks(
    newest: WindowModel, tuned_for: ProcessModel | None, K_range: tuple[float, float] | None
) -> tuple[list[_Check], dict[str, str]]:
    """The models the new gains' Ms is checked on (gate 8), and the checks skipped and why."""
    checks = [_Check("newest", newest.model, newest.model_id)]
    skipped: dict[str, str] = {}
    if tuned_for is None:
        skipped["tuned_for"] = "the model the current gains were tuned for is not known"
    else:
        checks.append(_Check("tuned_for", tuned_for, None))
    if K_range is None:
        skipped["K_low"] = skipped["K_high"] = "no K uncertainty given"
        return checks, skipped
    for name, k in (("K_low", K_range[0]), ("K_high", K_range[1])):
        if k > 0.0:
            checks.append(_Check(name, replace(newest.model, K=k), newest.model_id))
        else:
            skipped[name] = f"K {k:g} ≤ 0"
    return checks, skipped


@dataclass(frozen=True)
class _Robustness:
    """Gate 8's measure: the Ms of PI gains on every check model, and whether all pass."""

    checks: tuple[_Check, ...]
    settings: Online
    control_period: float

    def ms_of(self, gains: Gains) -> dict[str, float]:
        """Check name → Ms of ``gains`` (sampled PI at h), ∞ for an unstable loop."""
        pi = PISettings(
            rule=self.settings.rule, Kc=gains.Kc, Ti=gains.Ti, control_period=self.control_period
        )
        out = {}
        for check in self.checks:
            r = robustness(check.model, pi)
            out[check.name] = r.Ms if r.stable else math.inf
        return out

    def passes(self, ms: Mapping[str, float]) -> bool:
        """Whether every Ms is within the target."""
        return all(v <= self.settings.ms_target for v in ms.values())


def _robust_decision(
    draft: _Draft, new: Gains, kc_floor: float, robust: _Robustness, n_windows: int
) -> ProposalDecision:
    """Gate 8: propose ``new`` if robust, else Kc detuned until it is, or nothing.

    ``kc_floor`` is the Kc lower bound the detuning stops at; ``n_windows`` the independent
    windows that agreed (for the reason).
    """
    current, detail, settings = draft.current, draft.detail, robust.settings
    ms_current = robust.ms_of(current)
    ms_undetuned = robust.ms_of(new)
    detail["Ms_current"] = ms_current
    detail["Ms_undetuned"] = ms_undetuned
    detail["checks"] = {
        c.name: {"model_id": c.model_id, "model": c.model.to_json()} for c in robust.checks
    }
    factor, ms_final = _detune(
        new,
        kc_floor,
        lambda f: robust.ms_of(Gains(new.Kc * f, new.Ti)),
        robust.passes,
        ms_undetuned,
    )
    detail["detune_factor"] = factor
    clip_note = " (target clipped to the bounds)" if draft.clipped else ""
    if factor is None:
        worst = max(ms_final, key=lambda k: ms_final[k])
        return draft.refuse(
            f"Ms {ms_final[worst]:.2f} > {settings.ms_target:g} ({worst}) even at the Kc lower "
            f"bound {kc_floor:.3g}{clip_note}",
            Ms=ms_final,
        )
    detuned = factor < 1.0
    final = Gains(new.Kc * factor, new.Ti) if detuned else new
    step = max(_rel_change(final, current).values())
    detail["change_proposed"] = _rel_change(final, current)
    min_step = (1.0 + settings.hysteresis) ** settings.move_fraction - 1.0
    if detuned and step < min_step and robust.passes(ms_current):
        # a detuned move this small is not worth making while the current gains are robust
        return draft.refuse(
            f"detuned to Ms ≤ {settings.ms_target:g}, the change {_pct(step)} is below the "
            f"smallest step {_pct(min_step)}{clip_note}",
            Ms=ms_final,
        )
    ms_worst = max(ms_final.values())
    how = f"Kc detuned ×{factor:.3f} for Ms" if detuned else "Ms"
    reason = (
        f"{n_windows} independent windows agree: Kc {current.Kc:.4g} → {final.Kc:.4g}, "
        f"Ti {current.Ti:.4g} → {final.Ti:.4g} s ({100.0 * settings.move_fraction:g} % of the "
        f"way, geometric){clip_note}; {how} {ms_worst:.3f} ≤ {settings.ms_target:g}"
    )
    return draft.accept(reason, final, ms_final)


def _detune(
    gains: Gains,
    kc_floor: float,
    ms_at: Callable[[float], dict[str, float]],
    passes: Callable[[Mapping[str, float]], bool],
    ms_at_one: dict[str, float],
) -> tuple[float | None, dict[str, float]]:
    """Largest Kc factor f ≤ 1 (not below the floor) whose Ms passes, by bisection in log f.

    Returns (f, Ms at f), or (None, Ms at the floor) when even the floor fails. The bracket's
    lower end always passes, so the returned gains pass even where Ms is not monotonic in Kc.
    """
    if passes(ms_at_one):
        return 1.0, ms_at_one
    f_low = min(1.0, kc_floor / gains.Kc)
    ms_low = ms_at(f_low)
    if f_low >= 1.0 or not passes(ms_low):
        return None, ms_low
    lo, hi = math.log(f_low), 0.0
    while hi - lo > DETUNE_TOLERANCE:
        mid = 0.5 * (lo + hi)
        ms_mid = ms_at(math.exp(mid))
        if passes(ms_mid):
            lo, ms_low = mid, ms_mid
        else:
            hi = mid
    return math.exp(lo), ms_low


__all__ = [
    "DETUNE_TOLERANCE",
    "EVENT_TOLERANCE_S",
    "Gains",
    "ProposalDecision",
    "WindowModel",
    "independent_windows",
    "propose",
    "weighted_mean_model",
]
