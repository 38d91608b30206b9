"""The one setpoint-move detector (fuelid.online._moves) and its merge rules."""

from __future__ import annotations

import numpy as np
import pytest

from fuelid.online._moves import MergeRule, detect_moves
from fuelid.online.gates import setpoint_moves
from fuelid.online.health import setpoint_responses


def _staircase() -> tuple[np.ndarray, np.ndarray]:
    """Up 40 → 41 → 42 one second apart, up to 45 after 5 s, then back to 43 after 1 s."""
    t = np.arange(0.0, 40.0, 0.5)
    sp = np.select([t < 10.0, t < 11.0, t < 16.0, t < 17.0], [40.0, 41.0, 42.0, 45.0], 43.0)
    return t, sp


def test_changes_within_the_gap_merge_whatever_their_direction() -> None:
    t, sp = _staircase()
    moves = detect_moves(t, sp, MergeRule.ramp(gap_s=2.0))
    # 10 → 11 (1 s): one move; 16 is 5 s later: a new one; 17 (1 s after 16, reversed) joins it
    assert [(m.first, m.last, m.start, m.target) for m in moves] == [
        (20, 22, 40.0, 42.0),
        (32, 34, 42.0, 43.0),
    ]


def test_a_longer_gap_merges_more_and_a_shorter_one_less() -> None:
    t, sp = _staircase()
    assert len(detect_moves(t, sp, MergeRule.ramp(gap_s=10.0))) == 1
    assert len(detect_moves(t, sp, MergeRule.ramp(gap_s=0.5))) == 4


def test_a_reversal_begins_a_new_move_under_the_same_direction_rule() -> None:
    t, sp = _staircase()
    rule = MergeRule(gap_s=2.0, same_direction=True)
    assert [(m.start, m.target) for m in detect_moves(t, sp, rule)] == [
        (40.0, 42.0),
        (42.0, 45.0),
        (45.0, 43.0),
    ]


def test_a_reversal_back_past_the_moves_start_is_that_net_move() -> None:
    t = np.arange(0.0, 40.0, 0.5)
    sp = np.select([t < 16.0, t < 17.0], [42.0, 45.0], 40.0)  # 42 → 45, 1 s later → 40
    rule = MergeRule(gap_s=2.0, same_direction=True)
    assert [(m.start, m.target) for m in detect_moves(t, sp, rule)] == [(42.0, 40.0)]


def test_an_unsettled_flow_merges_a_later_change_in_the_same_direction() -> None:
    t = np.arange(0.0, 60.0, 0.5)
    sp = np.where(t < 10.0, 40.0, np.where(t < 20.0, 45.0, 50.0))
    rule = MergeRule.ramp_or_unsettled(gap_s=2.0)
    lagging = np.where(t < 10.0, 40.0, 41.0)  # never reaches 45 before the next change
    settled = np.where(t < 10.0, 40.0, np.where(t < 20.0, 45.0, 50.0))
    assert [m.target for m in detect_moves(t, sp, rule, y=lagging)] == [50.0]
    assert [m.target for m in detect_moves(t, sp, rule, y=settled)] == [45.0, 50.0]


def test_the_settled_rule_needs_the_flow() -> None:
    t, sp = _staircase()
    with pytest.raises(ValueError, match="flow"):
        detect_moves(t, sp, MergeRule.ramp_or_unsettled())


def test_no_change_no_move() -> None:
    assert detect_moves(np.arange(5.0), np.full(5, 40.0), MergeRule.ramp()) == []


def test_the_gate_and_the_health_callers_use_their_rules() -> None:
    t, sp = _staircase()
    # the gate: net moves > 0.5 L/min under the ramp rule (16 s: 42 → 43 net)
    assert setpoint_moves(t, sp, 0.5) == [10.0, 16.0]
    assert setpoint_moves(t, sp, 1.5) == [10.0]
    # the health: the reversal at 17 s is a move of its own (the flow follows the setpoint);
    # the move at 16 s lasts two samples, fewer than a response needs
    moves = detect_moves(t, sp, MergeRule.ramp_or_unsettled(), y=sp)
    assert [(m.start, m.target) for m in moves] == [(40.0, 42.0), (42.0, 45.0), (45.0, 43.0)]
    responses = setpoint_responses(t, sp, sp, threshold=0.5)
    assert [(r.time, r.start, r.target) for r in responses] == [
        (10.0, 40.0, 42.0),
        (17.0, 45.0, 43.0),
    ]
