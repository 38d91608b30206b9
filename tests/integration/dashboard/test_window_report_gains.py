"""The window report's gains beside the online proposal from the same window (issue 37, item 4).

The dashboard's report of one window shows "PI gains to enter in the PLC" from its own analysis
of the window's samples. When the online service filed a proposal from that window, the page's
notices must name it with its gains in the same (ideal) form and say why the two differ when
they do by more than 1 %: each step from the page's gains to the proposal's that moves them
(another rule or period, the service's own fit of the window, the weighted mean of the agreeing
windows' models, the bounds, the partial move, the detuning).

The end-to-end case reads the store a virtual run wrote (the session fixture
``dashboard_store``: windows and a pending proposal); the others give
:func:`~fuelid.dashboard._window_report.proposal_notice` what a proposal records.
"""

from __future__ import annotations

import html
import re
import shutil
from pathlib import Path
from typing import Any

import pytest

from fuelid.dashboard import SQLiteLoop
from fuelid.dashboard._window_report import SAME_GAINS, proposal_notice, window_report_html
from fuelid.model import ProcessModel
from fuelid.online import decision_json
from fuelid.tuning import PISettings

PAGE = PISettings(rule="simc", Kc=0.04, Ti=1.0, control_period=1.0)
WINDOW = {
    "id": 12,
    "model_id": 7,
    "detail": {"method": "oe", "model": {"K": 13.0, "T": 1.0, "delay": 0.5}},
}


def _proposal(**decision: Any) -> dict[str, Any]:
    """A proposal from model 7 whose every step keeps the page's gains, but for ``decision``."""
    same = {"Kc": PAGE.Kc, "Ti": PAGE.Ti}
    ideal = {
        "old": same,
        "target": same,
        "target_unclipped": same,
        "undetuned": same,
        "new": same,
        **decision.pop("ideal", {}),
    }
    base = {
        "rule": "simc",
        "control_period_s": 1.0,
        "move_fraction": 0.5,
        "hysteresis": 0.1,
        "ms_target": 1.7,
        "clipped": False,
        "detune_factor": 1.0,
        "bounds": {"Kc": [0.02, 0.08], "Ti": [0.5, 2.0]},
        "model_ids": [7, 5],
        "window_gains": [{"model_id": 7, **same}, {"model_id": 5, **same}],
        "ideal": ideal,
    }
    return {
        "id": 4,
        "model_id": 7,
        "new": {"Kc": 1.0, "Ti": 0.5},
        "gain_units": {"Kc": "%/%", "Ti": "min"},
        "decision": base | decision,
    }


def _notice(proposal: dict[str, Any]) -> str:
    return proposal_notice(
        proposal,
        PAGE,
        window=WINDOW,
        page_model=ProcessModel(K=12.0, T=1.1, delay=0.45),
        page_method="oe",
        windows_of_models={7: 12, 5: 10},
    )


def test_the_same_gains_are_said_to_be_the_same() -> None:
    inside = {"Kc": PAGE.Kc * (1.0 + 0.5 * SAME_GAINS), "Ti": PAGE.Ti}
    line = _notice(_proposal(ideal={"new": inside, "undetuned": inside}))
    assert line.startswith("the online proposal #4 from this window: Kc 0.0402, Ti 1 s (rule simc)")
    assert line.endswith("the gains above, within 1 %")


def test_a_partial_move_is_the_reason() -> None:
    moved = {"Kc": 0.02, "Ti": 1.0}
    line = _notice(_proposal(ideal={"old": {"Kc": 0.01, "Ti": 1.0}, "undetuned": moved,
                                    "new": moved}))  # fmt: skip
    assert "it differs from the gains above (Kc 0.04, Ti 1 s) by up to 50 %" in line
    assert "moves only 50 % of the way (move_fraction, geometric)" in line
    assert "from the gains in the PLC then (Kc 0.01, Ti 1 s)" in line
    for other in ("rule lambda", "fit of this window", "weighted mean", "clipped", "detuned"):
        assert other not in line


def test_each_step_that_moves_the_gains_is_named_in_order() -> None:
    own = {"Kc": 0.05, "Ti": 1.0}
    mean = {"Kc": 0.06, "Ti": 1.2}
    clipped = {"Kc": 0.06, "Ti": 1.1}
    undetuned = {"Kc": 0.05, "Ti": 1.05}
    new = {"Kc": 0.045, "Ti": 1.05}
    line = _notice(
        _proposal(
            rule="lambda",
            window_gains=[{"model_id": 7, **own}, {"model_id": 5, **mean}],
            bounds={"Kc": [0.02, 0.08], "Ti": [0.5, 1.1]},
            clipped=True,
            detune_factor=0.9,
            ideal={
                "target_unclipped": mean,
                "target": clipped,
                "undetuned": undetuned,
                "new": new,
            },
        )
    )
    steps = [
        "the proposal used rule lambda, this page simc",
        "the service's oe fit of this window: K 13 (L/min)/V, T 1 s, θ 0.5 s gives Kc 0.05",
        "this page fits the same samples again (oe: K 12 (L/min)/V, T 1.1 s, θ 0.45 s)",
        "the rule's target rests on the weighted mean of the models of windows #12, #10 "
        "(Kc 0.06, Ti 1.2 s)",
        "the target was clipped to the gain bounds (Kc 0.02–0.08, Ti 0.5–1.1 s: gain_bounds "
        "× the commissioning gains), to Kc 0.06, Ti 1.1 s",
        "moves only 50 % of the way",
        "Kc was detuned ×0.900 to keep Ms ≤ 1.7 on every check",
    ]
    at = [line.find(step) for step in steps]
    assert all(i >= 0 for i in at), [s for s, i in zip(steps, at, strict=True) if i < 0]
    assert at == sorted(at)


def test_another_control_period_is_named() -> None:
    line = _notice(_proposal(control_period_s=0.5, ideal={"new": {"Kc": 0.03, "Ti": 1.0}}))
    assert "the proposal's PLC period was 0.5 s, this page's 1 s" in line


def test_a_proposal_without_ideal_gains_is_shown_in_the_blocks_units() -> None:
    line = _notice({"id": 2, "model_id": 7, "new": {"Kc": 1.0, "Ti": 0.5},
                    "gain_units": {"Kc": "%/%", "Ti": "min"}, "decision": None})  # fmt: skip
    assert line.startswith("the online proposal #2 from this window: Kc 1.0 %/%, Ti 0.5 min")
    assert "no ideal-form gains to compare" in line


def test_what_a_stored_proposal_rests_on_is_read_from_its_detail() -> None:
    """decision_json reads the detail proposal_filing stores (the decision's JSON and more)."""
    detail = {
        "propose": True,
        "reason": "2 independent windows agree",
        "old": {"Kc": 0.01, "Ti": 1.0},
        "new": {"Kc": 0.02, "Ti": 1.0},
        "target": {"Kc": 0.04, "Ti": 1.0},
        "model_ids": [7, 5],
        "clipped": False,
        "detail": {
            "rule": "simc",
            "control_period_s": 1.0,
            "move_fraction": 0.5,
            "ms_target": 1.7,
            "hysteresis": 0.1,
            "target_unclipped": {"Kc": 0.04, "Ti": 1.0},
            "undetuned": {"Kc": 0.02, "Ti": 1.0},
            "detune_factor": 1.0,
            "window_gains": [{"model_id": 7, "Kc": 0.04, "Ti": 1.0, "events_s": [1.0]}],
        },
        "ideal": {"old": {"Kc": 0.01, "Ti": 1.0}, "new": {"Kc": 0.02, "Ti": 1.0}},
    }
    decision = decision_json(detail)
    assert decision is not None
    assert decision["rule"] == "simc"
    assert decision["model_ids"] == [7, 5]
    assert decision["window_gains"] == [{"model_id": 7, "Kc": 0.04, "Ti": 1.0}]
    assert decision["ideal"]["new"] == {"Kc": 0.02, "Ti": 1.0}
    assert decision["ideal"]["target_unclipped"] == {"Kc": 0.04, "Ti": 1.0}


# --- end to end: the store a virtual run wrote ----------------------------------------------------


@pytest.fixture
def loop(dashboard_store: Path, tmp_path: Path) -> Any:
    target = tmp_path / "loop.db"
    shutil.copy(dashboard_store, target)
    reader = SQLiteLoop(target)
    yield reader
    reader.close()


def _notices(page: str) -> list[str]:
    box = re.search(r'<div class="notice" id="notices">(.*?)</div>', page, re.DOTALL)
    if box is None:
        return []
    return [html.unescape(item) for item in re.findall(r"<li>(.*?)</li>", box.group(1), re.DOTALL)]


@pytest.mark.slow  # a window's whole report (identify, tune, six figures): 5 s, the slow set
def test_the_window_report_names_the_proposal_from_its_window(loop: SQLiteLoop) -> None:
    proposals = [p for p in loop.history()["proposals"] if p.get("model_id") is not None]
    assert proposals, "the virtual run filed no proposal"
    proposal = proposals[-1]
    decision = proposal["decision"]
    assert decision is not None
    assert decision["rule"] == "simc"
    assert decision["model_ids"][0] == proposal["model_id"]
    # the stored gains kept their JSON: {"Kc", "Ti"} in the block's units and the ideal form
    assert set(proposal["new"]) == {"Kc", "Ti"}
    assert set(decision["ideal"]["new"]) == {"Kc", "Ti"}

    windows = loop.recent_windows(1000)
    row = next(w for w in windows if w.get("model_id") == proposal["model_id"])
    notices = _notices(window_report_html(loop, row))
    mine = [n for n in notices if n.startswith("the online proposal")]
    assert len(mine) == 1, notices
    line = mine[0]
    new = decision["ideal"]["new"]
    assert line.startswith(
        f"the online proposal #{proposal['id']} from this window: Kc {new['Kc']:.4g}, "
        f"Ti {new['Ti']:.4g} s (rule simc)"
    ), line
    # the proposal moves half way from the commissioning gains: never the page's gains, so
    # the notice says why, and the partial move is among the reasons
    assert "it differs from the gains above" in line, line
    assert "move_fraction" in line, line

    # a window the service filed nothing from has no such notice
    other = next(
        (w for w in windows if w.get("model_id") not in {p["model_id"] for p in proposals}),
        None,
    )
    if other is not None:
        page = window_report_html(loop, other)
        assert not [n for n in _notices(page) if n.startswith("the online proposal")]
