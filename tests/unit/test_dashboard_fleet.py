"""The fleet page's chips and its severity order (fuelid.dashboard.fleet's documented table).

Each loop below differs from a healthy one in exactly one way (or two, for the worst), so the
expected order follows from the documented rule alone: alarms first, more alarms before fewer,
then by the first chip in CHIP_ORDER; warnings next; unknown; healthy last, by loop id.
"""

from __future__ import annotations

import copy
from typing import Any

import pytest

pytest.importorskip("fastapi")

from fuelid.dashboard.fleet import (
    AUTO_WARN,
    CHIP_ORDER,
    DRIFT_WARN,
    IAE_WARN,
    LIMITS_WARN,
    fleet_row,
    loop_chips,
)

RECENT_IAE = [2.0, 2.2, 1.8, 2.1, 1.9]  # median 2.0 s


def healthy() -> dict[str, Any]:
    """A status every chip of which is ok."""
    return {
        "link": {"state": "up", "text": "up (newest sample 0.4 s ago)"},
        "last_window": {"mode": "AUTO"},
        "loop_health": {
            "time_in_auto": 1.0,
            "time_at_limits": 0.0,
            "oscillation": {"oscillating": False},
            "iae_per_unit_step_s": 2.0,
        },
        "k_trend": {"available": True, "drift": {"ratio": 1.01, "se": 0.01}},
        "pending_proposals": [],
        "write_back": {"write_held": None, "revert_requested": None},
        "last_write": {"id": 3, "kind": "proposal", "status": "verified"},
    }


def with_changes(**paths: Any) -> dict[str, Any]:
    """A healthy status with ``a__b=value`` set at status[a][b]."""
    status = copy.deepcopy(healthy())
    for path, value in paths.items():
        keys = path.split("__")
        node = status
        for key in keys[:-1]:
            node = node[key]
        node[keys[-1]] = value
    return status


def levels(status: dict[str, Any]) -> dict[str, str]:
    return {c.name: c.level for c in loop_chips(status, RECENT_IAE)}


def test_a_healthy_loop_has_every_chip_ok_in_the_documented_order() -> None:
    chips = loop_chips(healthy(), RECENT_IAE)
    assert [c.name for c in chips] == list(CHIP_ORDER)
    assert {c.level for c in chips} == {"ok"}


@pytest.mark.parametrize(
    ("changes", "chip", "level"),
    [
        ({"link__state": "stopped"}, "service", "alarm"),
        ({"link__state": "link_down"}, "service", "alarm"),
        ({"link__state": "no_data"}, "service", "unknown"),
        (
            {"loop_health__oscillation": {"oscillating": True, "period_s": 8.0}},
            "oscillation",
            "alarm",
        ),
        ({"last_write__status": "failed"}, "last write", "alarm"),
        ({"write_back__revert_requested": {"who": "op"}}, "last write", "alarm"),
        ({"pending_proposals": [{"id": 4, "status": "pending"}]}, "proposals", "warn"),
        ({"pending_proposals": [{"id": 4, "status": "approved"}]}, "proposals", "warn"),
        # drift: 15 % off with se 1 %: warn; 15 % off with se 10 %: inside 2 se, ok
        ({"k_trend__drift": {"ratio": 1.0 + 1.5 * DRIFT_WARN, "se": 0.01}}, "drift", "warn"),
        ({"k_trend__drift": {"ratio": 1.0 + 1.5 * DRIFT_WARN, "se": 0.1}}, "drift", "ok"),
        ({"k_trend__drift": {"ratio": 1.0 + 0.5 * DRIFT_WARN, "se": 0.001}}, "drift", "ok"),
        ({"loop_health__time_at_limits": 2 * LIMITS_WARN}, "limits", "warn"),
        ({"loop_health__time_at_limits": 0.5 * LIMITS_WARN}, "limits", "ok"),
        ({"loop_health__iae_per_unit_step_s": 2.0 * (IAE_WARN + 0.1)}, "IAE", "warn"),
        ({"loop_health__iae_per_unit_step_s": 2.0 * (IAE_WARN - 0.1)}, "IAE", "ok"),
        ({"loop_health__time_in_auto": AUTO_WARN - 0.05}, "mode", "warn"),
        ({"last_window__mode": "MAN"}, "mode", "warn"),
    ],
)
def test_each_threshold_sets_its_chip(changes: dict[str, Any], chip: str, level: str) -> None:
    got = levels(with_changes(**changes))
    assert got[chip] == level
    assert all(v == "ok" for k, v in got.items() if k != chip), got


def test_the_fleet_is_sorted_by_the_documented_severity_order() -> None:
    loops = {
        "g-healthy": healthy(),
        "f-drift-within-noise": with_changes(k_trend__drift={"ratio": 1.15, "se": 0.1}),
        "a-stopped": with_changes(link__state="stopped"),
        "b-oscillating": with_changes(loop_health__oscillation={"oscillating": True}),
        "c-write-failed": with_changes(last_write__status="failed"),
        "d-proposal": with_changes(pending_proposals=[{"id": 1, "status": "pending"}]),
        "e-drift": with_changes(k_trend__drift={"ratio": 1.15, "se": 0.01}),
        "h-new": {"link": {"state": "no_data"}},
        "z-two-alarms": with_changes(
            link__state="stopped", loop_health__oscillation={"oscillating": True}
        ),
        "y-proposal-and-limits": with_changes(
            pending_proposals=[{"id": 2, "status": "pending"}], loop_health__time_at_limits=0.3
        ),
    }
    rows = [fleet_row(loop_id, "site", status, RECENT_IAE) for loop_id, status in loops.items()]
    order = [r["loop_id"] for r in sorted(rows, key=lambda r: r["sort_key"])]
    assert order == [
        "z-two-alarms",  # two alarms before one
        "a-stopped",  # then by the first alarm chip: service, oscillation, last write
        "b-oscillating",
        "c-write-failed",
        "y-proposal-and-limits",  # two warnings before one
        "d-proposal",  # proposals before drift
        "e-drift",
        "h-new",  # nothing measured: after every warning
        "f-drift-within-noise",  # healthy ones by loop id
        "g-healthy",
    ]
    assert [r["level"] for r in rows if r["loop_id"] in ("a-stopped", "d-proposal", "h-new")] == [
        "alarm",
        "warn",
        "unknown",
    ]


def test_a_propose_only_loop_shows_its_waiting_proposal_as_info() -> None:
    # write_back "off": nothing is written, so a waiting proposal is advice, not a hold-up
    status = with_changes(
        pending_proposals=[{"id": 5, "status": "pending"}], write_back__setting="off"
    )
    chips = {c.name: c for c in loop_chips(status, RECENT_IAE)}
    assert chips["proposals"].level == "info"
    assert chips["proposals"].text == "1 (propose only: nothing is written)"
    row = fleet_row("p-only", "site", status, RECENT_IAE)
    assert row["level"] == "info"
    # sorts after a loop with something unknown and before a healthy one
    rows = [
        row,
        fleet_row("a-healthy", "site", healthy(), RECENT_IAE),
        fleet_row("z-new", "site", {"link": {"state": "no_data"}}, RECENT_IAE),
    ]
    assert [r["loop_id"] for r in sorted(rows, key=lambda r: r["sort_key"])] == [
        "z-new",
        "p-only",
        "a-healthy",
    ]
    # with "approve" the same proposal still warns
    approve = with_changes(
        pending_proposals=[{"id": 5, "status": "pending"}], write_back__setting="approve"
    )
    assert levels(approve)["proposals"] == "warn"
