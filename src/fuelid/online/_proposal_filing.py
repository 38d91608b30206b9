"""After each window: ask the proposal rules, and file a proposal in the history when they say so.

The decision itself is pure (:func:`~fuelid.online._proposals.propose`); this module gathers its
evidence from the history (the recent accepted windows, the K(T) tracker's band, the model the
current gains were tuned for) and keeps the history tidy: an open proposal that says the same is
kept (and its approval with it), gains a person rejected or that were reverted are not proposed
again until the evidence moves them by more than the hysteresis, older open proposals are
superseded: by a new proposal, and when the evidence points at turned-down gains (the open ones
no longer say what it says: "the newest evidence points at the gains of #1 (reverted)"). With
``write_back = "auto"`` a new proposal is approved at once.
"""

from __future__ import annotations

import math
from typing import Any

from fuelid.errors import NotFittedError
from fuelid.io.jsonsafe import json_ready
from fuelid.online._context import RECENT_WINDOWS_SPAN, ServiceContext, model_of
from fuelid.online._evidence import WindowModel
from fuelid.online._proposals import ProposalDecision, propose
from fuelid.online._tracking import KTracker, TrackingError
from fuelid.online._window import WindowResult
from fuelid.tuning import BlockForm
from fuelid.units import DEFAULT_FUEL_TEMPERATURE_C

TURNED_DOWN_MEMORY = 20
"""Rejected or reverted proposals whose gains are not proposed again (the newest this many)."""


class ProposalFiling:
    """Decides on and files proposals after each window.

    Parameters
    ----------
    context : ServiceContext
        The service's shared state.
    tracker : KTracker
        The K(T) tracker (its prediction band bounds the proposal's K).
    """

    def __init__(self, context: ServiceContext, tracker: KTracker) -> None:
        self.context = context
        self.history = context.history
        self.settings = context.settings
        self.tracker = tracker

    def windows_for_proposal(self) -> list[WindowModel]:
        """The recent accepted windows: evidence older than the recency span does not vote."""
        rows = self.history.accepted_models(limit=50)
        if not rows:
            return []
        span = RECENT_WINDOWS_SPAN * max(
            self.settings.window_s, self.settings.identify_every_s * self.settings.agree_windows
        )
        newest = max(float(row["t_to"]) for row in rows)
        out = []
        for row in rows:
            if float(row["t_to"]) < newest - span:
                continue
            m = row["model"]
            model = model_of(m)
            if model is None:
                continue
            out.append(
                WindowModel(
                    model_id=int(row["id"]),
                    t_from=float(row["t_from"]),
                    t_to=float(row["t_to"]),
                    model=model,
                    stderr=dict(m.get("stderr") or {}),
                    T_fuel_C=m.get("T_fuel"),
                    u_mean=float(m.get("u_mean") or math.nan),
                    events=tuple(float(e) for e in m.get("events") or ()),
                )
            )
        return out

    def k_range(self, result: WindowResult) -> tuple[float, float] | None:
        """The tracker's K ± 2 standard errors at the window's conditions; None without one."""
        if result.model is None or len(self.tracker.observations) < 2:
            return None
        T_C = result.T_fuel_C if result.T_fuel_C is not None else DEFAULT_FUEL_TEMPERATURE_C
        try:
            K, se = self.tracker.predict(T_C, result.u_mean, K_plant=result.plant_K)
        except (TrackingError, NotFittedError):  # the last refit was refused
            return None
        if not (math.isfinite(K) and math.isfinite(se)):
            return None
        return max(K - 2.0 * se, 1e-9), K + 2.0 * se

    def consider(self, result: WindowResult) -> int | None:
        """Ask the rules after ``result``; the id of the proposal filed or kept, else None."""
        context = self.context
        gains = context.current_gains()
        if gains is None or context.commissioning is None:
            return None
        oscillating = bool(result.health is not None and result.health.oscillation.oscillating)
        tuned_for = model_of(self.history.state("tuned_for"))
        decision = propose(
            self.windows_for_proposal(),
            gains,
            context.commissioning,
            self.settings,
            control_period=context.site.sampling.control_period_s,
            tuned_for=tuned_for,
            K_range=self.k_range(result),
            oscillating=oscillating,
        )
        if not decision.propose or decision.new is None:
            return None
        return self.file(decision)

    def file(self, decision: ProposalDecision) -> int:
        """File ``decision`` (or keep the open or turned-down proposal that says the same)."""
        c = self.context.site.controller
        assert c is not None
        assert decision.new is not None
        block = BlockForm.of(c)
        old_kc, old_ti = decision.old.to_block(block)
        new_kc, new_ti = decision.new.to_block(block)
        open_ones = self.history.proposals(["pending", "approved"])
        for old in open_ones:
            if same_gains(old, new_kc, new_ti, 0.5 * self.settings.hysteresis):
                return int(old["id"])  # the open proposal says the same: keep it (and approval)
        turned_down = self.history.proposals(["rejected", "reverted"])[-TURNED_DOWN_MEMORY:]
        for old in reversed(turned_down):
            if same_gains(old, new_kc, new_ti, self.settings.hysteresis):
                # a person rejected these gains, or they were reverted: do not ask again until
                # the evidence moves them by more than the hysteresis
                return self._hold(old, open_ones, new_kc, new_ti)
        self._supersede(open_ones, "a newer proposal")
        self.history.set_state("held_proposal", None)  # a new proposal: nothing held any more
        detail = json_ready(
            {
                **decision.to_json(),
                "Ms": decision.Ms,
                "reason": decision.reason,
                "ideal": {"old": decision.old.to_json(), "new": decision.new.to_json()},
                "target_model": self._target_model(decision),
            }
        )
        pid = self.history.add_proposal(
            model_id=decision.model_ids[0] if decision.model_ids else None,
            old={"Kc": old_kc, "Ti": old_ti},
            new={"Kc": new_kc, "Ti": new_ti},
            detail=detail,
        )
        self.context.stats.proposals += 1
        self.context.say("proposal", id=pid, Kc=new_kc, Ti=new_ti, reason=decision.reason)
        if self.settings.write_back == "auto":
            self.history.set_proposal_status(
                pid, "approved", who="service (write_back = auto)", why="passed every rule"
            )
        return pid

    def _hold(
        self, turned_down: dict[str, Any], open_ones: list[dict[str, Any]], kc: float, ti: float
    ) -> int:
        """File nothing: the evidence points at ``turned_down``'s gains; its id.

        The open proposals left here differ from the evidence by more than half the hysteresis
        (one that says the same was kept before): the newest evidence no longer says what they
        say, so they are superseded, as a new proposal would supersede them, and the pages
        never say "none filed" above a proposal that waits. The hold is kept for the status
        (the pages say why no proposal comes) until a new proposal is filed, and logged once,
        when it begins or closes an open proposal.
        """
        what = f"#{turned_down['id']} ({turned_down['status']})"
        superseded = self._supersede(
            open_ones, f"the newest evidence points at the gains of {what}"
        )
        held = self.history.state("held_proposal") or {}
        if superseded or not isinstance(held, dict) or held.get("id") != turned_down["id"]:
            self.history.set_state(
                "held_proposal",
                {"id": turned_down["id"], "status": turned_down["status"], "Kc": kc, "Ti": ti},
            )
            closed = {"superseded": ", ".join(f"#{pid}" for pid in superseded)}
            self.context.say(
                "proposal",
                held=f"the gains of {what} are not proposed again",
                **(closed if superseded else {}),
                Kc=kc,
                Ti=ti,
            )
        return int(turned_down["id"])

    def _supersede(self, open_ones: list[dict[str, Any]], why: str) -> list[int]:
        """Supersede the open proposals (pending, approved), saying why; their ids."""
        for old in open_ones:
            self.history.set_proposal_status(old["id"], "superseded", who="service", why=why)
        return [int(old["id"]) for old in open_ones]

    def _target_model(self, decision: ProposalDecision) -> dict[str, Any] | None:
        if not decision.model_ids:
            return None
        row = self.history.model(decision.model_ids[0])
        return None if row is None else row["model"].get("model")


def same_gains(proposal: dict[str, Any], kc: float, ti: float, tolerance: float) -> bool:
    """True when ``proposal``'s new gains are within ``tolerance`` (relative) of kc, ti.

    Examples
    --------
    >>> same_gains({"new": {"Kc": 1.0, "Ti": 2.0}}, 1.04, 2.0, 0.05)
    True
    >>> same_gains({"new": {}}, 1.0, 2.0, 0.05)
    False
    """
    new = proposal.get("new") or {}
    try:
        return all(
            abs(float(new[key]) / value - 1.0) <= tolerance
            for key, value in (("Kc", kc), ("Ti", ti))
        )
    except (KeyError, TypeError, ValueError, ZeroDivisionError):
        return False


__all__ = ["TURNED_DOWN_MEMORY", "ProposalFiling", "same_gains"]
