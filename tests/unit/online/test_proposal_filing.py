"""Filing proposals in the history (fuelid.online._proposal_filing): what stays open, what is held.

A store in tmp_path and a stand-in for the service's context (the site's controller, the
``[online]`` settings, the log lines): :meth:`ProposalFiling.file` is given decisions directly,
so each test says which gains the evidence points at.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from fuelid.online import Gains, Online
from fuelid.online._context import ServiceStats
from fuelid.online._logs import log_line
from fuelid.online._proposal_filing import ProposalFiling
from fuelid.online._proposals import ProposalDecision
from fuelid.plc.site import Controller
from fuelid.store import OnlineHistory, SQLiteStore, tag_map_hash

T0 = 1_700_000_000.0  # plant time [s UTC]
COMMISSIONED = Gains(0.05, 2.0)  # the ideal form, engineering units: the block reads them as is


class _Context:
    """What :class:`ProposalFiling` reads of the service's context, and the log lines it says."""

    def __init__(self, history: OnlineHistory) -> None:
        self.history = history
        self.settings = Online()
        self.site = SimpleNamespace(controller=Controller(kc=0.05, ti=2.0))
        self.stats = ServiceStats()
        self.lines: list[str] = []

    def say(self, word: str, **fields: Any) -> None:
        self.lines.append(log_line(word, **fields))


@pytest.fixture
def context(tmp_path: Path) -> Iterator[_Context]:
    site = {"site_name": "tunnel 2 fuel loop", "tag_map_hash": tag_map_hash({"flow": "ir:20"})}
    with (
        SQLiteStore(tmp_path / "loop.db", period_s=0.02, **site) as store,
        OnlineHistory(store) as history,
    ):
        yield _Context(history)


def _decision(kc: float, ti: float = 2.0) -> ProposalDecision:
    """The rules' decision to move the commissioned gains to (kc, ti)."""
    return ProposalDecision(
        propose=True,
        reason=f"2 independent windows agree: Kc 0.05 → {kc}",
        old=COMMISSIONED,
        new=Gains(kc, ti),
        target=None,
        Ms={"newest": 1.4},
        model_ids=(),
        clipped=False,
        detail={},
    )


def _step(history: OnlineHistory, pid: int, status: str, who: str, why: str, t: float) -> None:
    history.set_proposal_status(pid, status, who=who, why=why, time=T0 + t)


def _written_then_reverted(context: _Context, kc: float) -> int:
    """A proposal of ``kc`` filed, approved by ana, written, then reverted by bob."""
    filing = ProposalFiling(context, tracker=None)  # type: ignore[arg-type]
    pid = filing.file(_decision(kc))
    history = context.history
    _step(history, pid, "approved", "ana", "looks right", 10.0)
    _step(history, pid, "writing", "service", "", 20.0)
    _step(history, pid, "applied", "service", "echo", 21.0)
    _step(history, pid, "reverted", "bob", "the loop hunts", 30.0)
    return pid


@pytest.mark.parametrize("approved", [False, True], ids=["pending", "approved"])
def test_evidence_pointing_at_reverted_gains_supersedes_the_open_proposal_that_says_otherwise(
    context: _Context, approved: bool
) -> None:
    # the trial's page: "New proposals: none filed: the newest evidence points at the gains of
    # #1 (reverted)" above "#2 waits for approval": #2 no longer is what the evidence says
    filing = ProposalFiling(context, tracker=None)  # type: ignore[arg-type]
    reverted = _written_then_reverted(context, 0.06)
    other = filing.file(_decision(0.08))  # 33 % from #1's gains: a proposal of its own
    assert other != reverted
    if approved:
        _step(context.history, other, "approved", "ana", "try it", 40.0)
    context.lines.clear()

    held = filing.file(_decision(0.0605))  # within the hysteresis of #1's gains: held back

    assert held == reverted
    assert context.history.proposals(["pending", "approved"]) == []
    last = context.history.proposal(other)["history"][-1]  # type: ignore[index]
    why = f"the newest evidence points at the gains of #{reverted} (reverted)"
    assert (last["status"], last["who"], last["why"]) == ("superseded", "service", why)
    assert context.history.state("held_proposal")["id"] == reverted
    (line,) = context.lines
    assert f'held="the gains of #{reverted} (reverted) are not proposed again"' in line
    assert f"superseded=#{other} " in line


def test_an_open_proposal_within_half_the_hysteresis_is_kept_and_nothing_is_held(
    context: _Context,
) -> None:
    filing = ProposalFiling(context, tracker=None)  # type: ignore[arg-type]
    reverted = _written_then_reverted(context, 0.06)
    # open before the evidence came back near #1's gains (filed by an older service, say)
    kept = context.history.add_proposal(
        model_id=None, old={"Kc": 0.05, "Ti": 2.0}, new={"Kc": 0.0612, "Ti": 2.0}, detail={}
    )
    # the open one says the same as the evidence (within half the hysteresis): kept with its
    # approval, even though #1's gains are as near
    assert filing.file(_decision(0.0615)) == kept != reverted
    assert [p["id"] for p in context.history.proposals(["pending"])] == [kept]
    assert context.history.state("held_proposal") is None


def test_holding_the_same_gains_again_says_nothing_new(context: _Context) -> None:
    filing = ProposalFiling(context, tracker=None)  # type: ignore[arg-type]
    reverted = _written_then_reverted(context, 0.06)
    context.lines.clear()
    assert filing.file(_decision(0.0605)) == reverted
    assert filing.file(_decision(0.0598)) == reverted
    assert len(context.lines) == 1  # logged once, when the hold began
    assert "superseded" not in context.lines[0]
