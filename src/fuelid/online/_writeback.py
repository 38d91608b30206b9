"""The online service's write-back: when a write may happen, the write, the revert, reconciling.

Writes (docs online.md §5): never in MAN, with the command at a limit, while the loop
oscillates or with the link down; the intent is committed to the history before the PLC is
written; the echo of the apply number must come back within ``echo_timeout_s``, otherwise the
last-known-good gains are written back and an event raised. An unfinished write (intent
recorded, no verdict: a service killed mid-write) is reconciled from the PLC's echo before
anything else is written. The PLC handshake itself (the block, the echo, the heartbeat) is
:class:`~fuelid.plc._gain_handshake.GainWriter`.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from fuelid.online._context import ServiceContext, stale_reason
from fuelid.online._gains import Gains
from fuelid.online._window import WindowResult
from fuelid.plc import GainWriter
from fuelid.plc.adapters import LinkError
from fuelid.tuning import BlockForm

AUTO = 1
"""The mode tag's value in AUTO."""
IAE_BASELINE_WINDOWS = 6
"""Windows before a write whose median IAE per unit step is the revert rule's baseline."""
LIMIT_MARGIN_V = 0.01
"""A command within this of a limit counts as at the limit [V]."""
GOOD_TUNED_FOR = "last_known_good_tuned_for"
"""The ``online_state`` key of the model the last-known-good gains were tuned for (None:
unknown, e.g. the commissioning gains): what a revert makes ``tuned_for`` again."""


class WriteBack:
    """Writes approved proposals and reverts, under the rules of the module docstring.

    Parameters
    ----------
    context : ServiceContext
        The service's shared state.

    Attributes
    ----------
    gain_writer : GainWriter or None
        The PLC handshake; None while the site cannot write (or before the run starts).
    """

    def __init__(self, context: ServiceContext) -> None:
        self.context = context
        self.history = context.history
        self.settings = context.settings
        self.gain_writer: GainWriter | None = None

    # --- when -------------------------------------------------------------------------------

    def write_refusal(self) -> str | None:
        """Why a write may not happen now; None when it may."""
        recorder = self.context.recorder
        if recorder is None or not recorder.connected:
            return "the link is down"
        latest = recorder.latest
        age = time.time() - recorder.last_reading
        if not (age < max(5.0, 10 * self.context.site.sampling.period_s)):
            return "no fresh reading from the PLC"
        mode = latest.get("mode")
        if mode is None or round(mode) != AUTO:
            return "the loop is not in AUTO"
        u = latest.get("command", math.nan)
        low, high = self.context.priors.u_limits
        if not math.isfinite(u) or u <= low + LIMIT_MARGIN_V or u >= high - LIMIT_MARGIN_V:
            return "the command is at an output limit"
        last = self.history.last_window()
        if last is not None:
            health = last["detail"].get("health") or {}
            if (health.get("oscillation") or {}).get("oscillating"):
                return "the loop oscillates"
        return None

    def settling(self) -> bool:
        """True until a whole window under the gains of the last write has been seen."""
        last = self.history.state("last_write")
        return bool(last) and not last.get("seen_after", False)

    async def writes_due(self) -> None:
        """Settle unfinished writes, then a requested revert or the approved proposals."""
        if self.gain_writer is None:
            return
        if self.history.unfinished_writes():  # a write left half done: settle it first
            try:
                await self.reconcile()
            except LinkError:
                return
        revert = self.history.state("revert_requested")
        if revert:
            refusal = self.write_refusal()
            if refusal is None or refusal == "the loop oscillates":
                self.history.set_state("revert_requested", None)
                why = str(revert.get("why") or "requested")
                await self.revert(who=str(revert.get("who", "user")), why=why)
            return
        for proposal in self.history.proposals("approved"):
            stale = self._stale(proposal)
            if stale is not None:
                self.history.set_proposal_status(proposal["id"], "superseded", who="service",
                                                 why=stale)  # fmt: skip
                self.context.say("write", proposal=proposal["id"], held=stale)
                continue
            refusal = self.write_refusal()
            if refusal is not None:
                if self.history.state("write_held") != refusal:
                    self.history.set_state("write_held", refusal)
                    self.context.say("write", proposal=proposal["id"], held=refusal)
                return
            self.history.set_state("write_held", None)
            await self._write_proposal(proposal)

    def _stale(self, proposal: dict[str, Any]) -> str | None:
        """Why an approved proposal is too old to write; None when fresh.

        Its evidence predates the recent windows (e.g. across a restart and a change of fuel
        temperature): new windows will propose afresh.
        """
        model_id = proposal.get("model_id")
        row = None if model_id is None else self.history.model(int(model_id))
        window_end = None if row is None else float(row["t_to"])
        return stale_reason(window_end, self.context.store.last_time(), self.settings.window_s)

    # --- writing ----------------------------------------------------------------------------

    async def _next_apply(self) -> int:
        assert self.gain_writer is not None
        echo = await self.gain_writer.echo()
        last = self.history.last_apply_seq() or 0
        return max(last, echo or 0) + 1

    async def _write_proposal(self, proposal: dict[str, Any]) -> None:
        assert self.gain_writer is not None
        kc, ti = float(proposal["new"]["Kc"]), float(proposal["new"]["Ti"])
        apply_seq = await self._next_apply()
        history = proposal.get("history") or []
        who = history[-1]["who"] if history else "service"
        write_id = self.history.begin_write(
            kind="proposal",
            kc=kc,
            ti=ti,
            apply_seq=apply_seq,
            who=who,
            why=f"proposal {proposal['id']}: {proposal['detail'].get('reason', '')}",
            proposal_id=proposal["id"],
        )
        self.history.set_proposal_status(proposal["id"], "writing", who="service", why="")
        echoed = await self.gain_writer.write_block(kc, ti, apply_seq)
        self.context.stats.writes += 1
        if echoed:
            self.history.finish_write(write_id, "verified", {"echo": apply_seq})
            self.history.set_proposal_status(proposal["id"], "applied", who="service", why="echo")
            self._applied(proposal)
            self.context.say(
                "write", proposal=proposal["id"], apply=apply_seq, Kc=kc, Ti=ti, ok=True
            )
            return
        self.history.finish_write(write_id, "failed", {"reason": "no echo"})
        self.history.set_proposal_status(
            proposal["id"], "failed", who="service", why="no echo within the timeout"
        )
        self.context.event(
            "write_failed", f"proposal {proposal['id']}: no echo of apply {apply_seq}"
        )
        await self.revert(who="service", why="no echo of the last write", force=True)

    def _applied(self, proposal: dict[str, Any]) -> None:
        detail = proposal["detail"]
        ideal = detail.get("ideal") or {}
        old = ideal.get("old")
        if old is not None:
            self.history.set_state(GOOD_TUNED_FOR, self._tuned_for_gains(old))
            self.history.set_state("last_known_good", old)
        self.history.set_state("current_gains", ideal.get("new"))
        self.history.set_state("tuned_for", detail.get("target_model"))
        self.history.set_state(
            "last_write",
            {
                "proposal": proposal["id"],
                "time": time.time(),
                "data_time": self.context.store.last_time(),
                "iae_before": self._iae_before(),
                "judged": False,
            },
        )

    def _tuned_for_gains(self, gains: dict[str, Any]) -> Any:
        """The model ``gains`` [ideal form] were tuned for, if they are the current ones.

        ``tuned_for`` belongs to ``current_gains`` (both set by the last write); gains other
        than those (the commissioning gains, gains changed at the panel) have no known model.
        """
        current = self.history.state("current_gains")
        same = isinstance(current, dict) and all(
            isinstance(current.get(k), int | float)
            and isinstance(gains.get(k), int | float)
            and math.isclose(float(current[k]), float(gains[k]), rel_tol=1e-6)
            for k in ("Kc", "Ti")
        )
        return self.history.state("tuned_for") if same else None

    def _iae_before(self) -> float | None:
        """Median IAE per unit setpoint step of the last windows before a write [s]."""
        values = []
        for window in self.history.windows(limit=IAE_BASELINE_WINDOWS):
            iae = (window["detail"].get("health") or {}).get("iae_per_unit_step_s")
            if isinstance(iae, int | float) and math.isfinite(iae):
                values.append(float(iae))
        return float(np.median(values)) if values else None

    async def revert(self, *, who: str, why: str, force: bool = False) -> bool:
        """Write the last-known-good gains back (the commissioning gains when none is kept).

        Not written when the PLC already reads those gains, unless ``force`` (after a write
        whose echo was lost the PLC's state is not known for sure: the block is written).
        Either way ``tuned_for`` becomes the model the gains back in force were tuned for
        (:data:`GOOD_TUNED_FOR`, kept when they became the last-known-good; None for the
        commissioning gains or when unknown), so the drift is judged against their model.
        """
        controller = self.context.site.controller
        if self.gain_writer is None or controller is None:
            return False
        good = self.history.state("last_known_good")
        # the model the gains written back were tuned for: the drift chip compares K with it
        tuned_for = self.history.state(GOOD_TUNED_FOR) if good else None
        gains = (
            Gains(
                float(good["Kc"]),
                float(good["Ti"]),
                control_period=self.context.site.sampling.control_period_s,
            )
            if good
            else self.context.commissioning
        )
        if gains is None:
            self.context.event("revert_failed", "no last-known-good or commissioning gains")
            return False
        now = None if force else self.context.current_gains()
        if now is not None and all(
            math.isclose(a, b, rel_tol=1e-6) for a, b in ((now.Kc, gains.Kc), (now.Ti, gains.Ti))
        ):
            self.context.event(
                "revert", f"nothing to write: the PLC holds those gains ({why}, by {who})"
            )
            self.history.set_state("tuned_for", tuned_for)
            return True
        kc, ti = gains.to_block(BlockForm.of(controller))
        apply_seq = await self._next_apply()
        write_id = self.history.begin_write(
            kind="revert", kc=kc, ti=ti, apply_seq=apply_seq, who=who, why=why
        )
        echoed = await self.gain_writer.write_block(kc, ti, apply_seq)
        self.history.finish_write(write_id, "verified" if echoed else "failed", {})
        self.context.stats.reverts += 1
        self.context.say("write", kind="revert", apply=apply_seq, Kc=kc, Ti=ti, ok=echoed, why=why)
        if echoed:
            for applied in self.history.proposals("applied")[-1:]:
                self.history.set_proposal_status(applied["id"], "reverted", who=who, why=why)
            self.history.set_state("current_gains", gains.to_json())
            self.history.set_state("tuned_for", tuned_for)
            self.history.set_state("last_write", None)
        self.context.event("revert" if echoed else "revert_failed", f"{why} (by {who})")
        return echoed

    async def check_revert(self, result: WindowResult) -> None:
        """Revert automatically after one of our writes when the loop misbehaves.

        Judged on windows wholly under the new gains (``t_from`` after the write's data time):
        any such window in which the loop oscillates reverts; the first such window with
        setpoint changes reverts when its IAE per unit step exceeds ``revert_iae_factor``
        times the median of the windows before the write (one noisy window before is not the
        baseline).
        """
        last = self.history.state("last_write")
        if not last or self.gain_writer is None or result.health is None:
            return
        written_at = last.get("data_time")
        if written_at is None or result.t_from < float(written_at):
            return  # the window still holds samples under the old gains
        if not last.get("seen_after"):
            last = {**last, "seen_after": True}
            self.history.set_state("last_write", last)
        refusal = self.write_refusal()
        if refusal not in (None, "the loop oscillates"):
            return  # a revert is a write too: not in MAN, at a limit or with the link down
        if result.health.oscillation.oscillating:
            await self.revert(who="service", why="the loop oscillates after a write")
            return
        before = last.get("iae_before")
        now = result.health.iae_per_unit_step
        if last.get("judged") or not (before and math.isfinite(now)):
            return
        if now > self.settings.revert_iae_factor * before:
            await self.revert(
                who="service",
                why=f"IAE per setpoint change {now:.3g} s > {self.settings.revert_iae_factor:g}"
                f" × {before:.3g} s before the write",
            )
            return
        self.history.set_state("last_write", {**last, "judged": True, "iae_after": now})

    async def reconcile(self) -> None:
        """Settle writes a stopped service left half done, from the PLC's echo."""
        assert self.gain_writer is not None
        for write in self.history.unfinished_writes():
            echo = await self.gain_writer.echo()
            if echo is None:
                raise LinkError("cannot read the echo to reconcile an unfinished write")
            applied = echo == int(write["apply_seq"])
            self.history.finish_write(
                write["id"], "verified" if applied else "not_applied", {"echo": echo}
            )
            pid = write.get("proposal_id")
            if pid is not None:
                proposal = self.history.proposal(pid)
                if proposal is not None and proposal["status"] == "writing":
                    if applied:
                        self.history.set_proposal_status(
                            pid, "applied", who="service", why="reconciled from the echo"
                        )
                        self._applied(proposal)
                    else:
                        self.history.set_proposal_status(
                            pid, "failed", who="service", why="not applied (service stopped)"
                        )
            self.context.event(
                "write_reconciled",
                f"write {write['id']} (apply {write['apply_seq']}): "
                + ("applied" if applied else "not applied"),
            )


__all__ = ["AUTO", "GOOD_TUNED_FOR", "IAE_BASELINE_WINDOWS", "LIMIT_MARGIN_V", "WriteBack"]
