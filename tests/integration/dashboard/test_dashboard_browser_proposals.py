"""A proposal that changes under an engineer's hand is said on its card; nothing is sent (issue 39).

The held-out trial: a proposal went out of date while the engineer was in the approve
confirmation, and the reason typed for the approval was left next to the remaining reject
button. Here, on the session's ``dashboard_store`` (a short virtual run, copied; no service
running) with a fresh pending proposal of our own, in headless Chromium:

1. a reason typed and the approve question open, then a window judged after the proposal's
   window ages it out of date (a sample and a window stored, as the service would): the
   question closes, the reason is cleared, the card says "the proposal changed (now: out of
   date, not written): nothing was sent", and no request was filed;
2. a reason typed for reject, then the proposal rejected elsewhere (the CLI, another page): the
   card, now a decided one, says so the same way, and who rejected it and why.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("fastapi")

from fuelid.dashboard import UsersFile
from fuelid.dashboard._views import STATE_LABELS
from fuelid.online import RECENT_WINDOWS_SPAN
from fuelid.store import OnlineHistory, Sample, SQLiteStore
from support.browser import browser_page, dashboard, wait_ready, wait_until

pytestmark = pytest.mark.xdist_group("dashboard")

WINDOW_S = 120.0  # the dashboard store's [online] window_s (tests/conftest.py)


def _pending_proposal(store: Path) -> int:
    """A fresh pending proposal on the newest accepted model; its id."""
    with SQLiteStore(store) as reader, OnlineHistory(reader) as history:
        model_id = history.accepted_models(limit=1)[0]["id"]
        for old in history.proposals(["pending", "approved"]):  # one open card: ours
            history.set_proposal_status(old["id"], "superseded", who="service", why="test")
        return history.add_proposal(
            model_id=model_id, old={"Kc": 0.10, "Ti": 2.0}, new={"Kc": 0.12, "Ti": 2.2},
            detail={"reason": "2 independent windows agree"}, who="online",
        )  # fmt: skip


def _age_out(store: Path) -> None:
    """A sample and a window past the proposal's age limit, as the recorder and service store."""
    with SQLiteStore(store) as reader:
        info = reader.info()
        newest = reader.last_time()
    assert newest is not None
    later = newest + RECENT_WINDOWS_SPAN * WINDOW_S + 60.0
    with SQLiteStore(store, site_name=info.site_name, tag_map_hash=info.tag_map_hash) as writer:
        writer.append(samples=[Sample(time=later, seq=None, u=2.5, y=10.0, mode=1)])
        with OnlineHistory(writer) as history:
            history.add_window(
                t_from=later - WINDOW_S, t_to=later, accepted=False, reason="no excitation",
                T_fuel=math.nan, u_mean=2.5, detail={}, time=later,
            )  # fmt: skip


def _reject_elsewhere(store: Path, proposal: int) -> None:
    with SQLiteStore(store) as reader, OnlineHistory(reader) as history:
        history.set_proposal_status(proposal, "rejected", who="ana", why="decided at the panel")


def _selector(proposal: int) -> str:
    return f'#proposals-part div.proposal[data-proposal="{proposal}"]'


_CARD_JS = """((selector) => {
  const card = document.querySelector(selector);
  if (!card) return null;
  const form = card.querySelector('form.action');
  const confirm = form && form.querySelector('.confirm');
  const kinds = form ? Array.from(form.querySelectorAll('button[data-kind]')) : [];
  return {
    state: card.dataset.state,
    text: card.querySelector('.state-text').textContent,
    changed: Array.from(card.querySelectorAll('p.changed')).map((p) => p.textContent),
    why: form ? form.querySelector('input[name=why]').value : null,
    confirming: confirm ? !confirm.hidden : false,
    buttons: kinds.map((b) => b.dataset.kind),
  };
})"""


def _card(page: Any, proposal: int) -> dict[str, Any]:
    """What the card of ``proposal`` shows (None when it has none)."""
    return page.evaluate(_CARD_JS, _selector(proposal))  # type: ignore[no-any-return]


def _state_is(proposal: int, state: str) -> str:
    card = f"document.querySelector('{_selector(proposal)}')"
    return f"({card} || {{dataset: {{}}}}).dataset.state === '{state}'"


def test_a_proposal_changing_under_a_typed_reason_or_a_question_is_said_and_nothing_sent(
    dashboard_store: Path, tmp_path: Path
) -> None:
    store = Path(shutil.copy(dashboard_store, tmp_path / "loop.db"))
    proposal = _pending_proposal(store)
    users = UsersFile(tmp_path / "users.json")
    token = users.add("eve", "engineer")
    form = f"form.action[data-proposal='{proposal}']"
    with (
        dashboard(tmp_path, "--store", str(store), "--users", str(users.path)) as (_, base),
        browser_page() as (page, errors),
    ):
        (row,) = page.context.request.get(f"{base}/api/loops").json()["loops"]
        path = f"/loops/{row['loop_id']}"
        page.goto(f"{base}/login?next={path}")
        page.fill("input[name=name]", "eve")
        page.fill("input[name=token]", token)
        page.click("button[type=submit]")
        page.wait_for_url(f"{base}{path}")
        wait_ready(page)
        wait_until(page, _state_is(proposal, "waiting"), timeout=15)
        # 1. the approve question open over a typed reason; the proposal ages out of date
        page.fill(f"{form} input[name=why]", "the windows agree")
        page.click(f"{form} button[data-kind=approve]")
        assert _card(page, proposal)["confirming"]
        _age_out(store)
        wait_until(page, _state_is(proposal, "out_of_date"), timeout=15)
        aged = _card(page, proposal)
        # 2. a reason typed for reject; the proposal is rejected elsewhere
        page.fill(f"{form} input[name=why]", "not now")
        _reject_elsewhere(store, proposal)
        wait_until(page, _state_is(proposal, "rejected"), timeout=15)
        rejected = _card(page, proposal)
        requests = page.context.request.get(f"{base}/api{path}/requests").json()
    assert errors == []
    label = STATE_LABELS["out_of_date"]
    assert aged["buttons"] == ["reject"]
    assert (aged["confirming"], aged["why"]) == (False, "")
    assert aged["changed"] == [f"the proposal changed (now: {label}): nothing was sent"]
    assert rejected["buttons"] == []  # a decided card: nothing to do
    assert rejected["changed"] == ["the proposal changed (now: rejected): nothing was sent"]
    assert "by ana: decided at the panel" in rejected["text"]
    assert requests["requests"] == []
