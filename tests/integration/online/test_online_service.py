"""The online service's writes against the virtual PLC on loopback.

Write-back with its echo check, the refusal in MAN, the revert on a lost echo, reconciliation
of a write cut short.

Every run is bounded (a few seconds of wall time at a speed-up); the servers are real (Modbus
TCP on 127.0.0.1).
"""

from __future__ import annotations

import asyncio
import itertools
import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("pymodbus")

from fuelid.online import OnlineService, ServiceSite
from fuelid.plc.adapters import ModbusSource, open_source
from fuelid.plc.virtual import VirtualPlcThread
from support.online import approve_directly as _approved_proposal
from support.online import online_site as _site
from support.online import open_history as _history
from support.waiting import await_until, wait_until

# xdist: one worker runs every module that drives a PLC at speed, one after another
# (tests/conftest.py says why)
pytestmark = pytest.mark.xdist_group("real-time")

SPEED = 20.0
"""Plant time per wall time: the PLC's 10 s heartbeat timeout is 0.5 s of wall time."""
HEARTBEAT_S = 0.05


def _run(site: ServiceSite, seconds: float, **kwargs: Any) -> tuple[OnlineService, list[str]]:
    lines: list[str] = []
    service = OnlineService(site, on_message=lines.append, heartbeat_s=HEARTBEAT_S, **kwargs)
    asyncio.run(service.run(seconds))
    return service, lines


ONLINE_NO_WINDOWS = 'identify_every_s = 3600\nwindow_s = 3600\nwrite_back = "approve"\n'


def test_an_approved_proposal_is_written_once_and_echoed(tmp_path: Path) -> None:
    store = tmp_path / "s.db"
    with VirtualPlcThread(speed=SPEED, setpoint_profile="run") as virtual:
        site = _site(virtual, store, ONLINE_NO_WINDOWS)
        kc0, ti0 = virtual.plc.gains
        kc, ti = round(1.2 * kc0, 6), round(0.9 * ti0, 6)
        pid = _approved_proposal(site, store, kc, ti)
        service, lines = _run(site, 4.0)
        try:
            applied = virtual.plc.gains
            proposal = service.history.proposal(pid)
            writes = service.history.writes()
            assert proposal is not None
            assert proposal["status"] == "applied"
            assert [w["status"] for w in writes] == ["verified"]
            assert writes[0]["who"] == "tester"
            assert service.history.state("last_known_good") == {"Kc": kc0, "Ti": ti0}
        finally:
            service.close()
    assert math.isclose(applied[0], kc, rel_tol=1e-6)
    assert math.isclose(applied[1], ti, rel_tol=1e-6)
    assert any(line.startswith("write ") and "ok=True" in line for line in lines)


def test_an_approve_filed_by_the_cli_is_applied_by_the_running_service(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import threading

    from fuelid.cli import main

    store = tmp_path / "s.db"
    with VirtualPlcThread(speed=SPEED, setpoint_profile="run") as virtual:
        site = _site(virtual, store, ONLINE_NO_WINDOWS)
        kc0, ti0 = virtual.plc.gains
        kc = round(1.2 * kc0, 6)
        opened, history = _history(site, store)
        pid = history.add_proposal(
            model_id=None,
            old={"Kc": kc0, "Ti": ti0},
            new={"Kc": kc, "Ti": ti0},
            detail={"reason": "test", "target": {"Kc": 1.5 * kc0, "Ti": ti0}},
        )
        history.close()
        opened.close()
        service = OnlineService(site, heartbeat_s=HEARTBEAT_S)
        runner = threading.Thread(target=lambda: asyncio.run(service.run(6.0)))
        runner.start()
        try:

            def beating() -> bool:
                record = service.history.state("service")
                return bool(record and record["beat"] > record["started"])

            # within the service's run (6 s)
            wait_until(beating, 6.0, "the service's first beat")
            code = main(["online", "approve", str(pid), "--store", str(store), "--who", "anna"])
            out = capsys.readouterr().out
        finally:
            runner.join()
        try:
            requests = service.history.requests()
            proposal = service.history.proposal(pid)
        finally:
            service.close()
    assert code == 0
    # the service may have begun the write by the time the command reads the proposal back
    assert any(f"#{pid} {status}: Kc" in out for status in ("approved", "writing", "applied"))
    assert "(target " in out  # the target the rule moves toward, in the block's units
    assert "by anna" in out
    assert [(r["kind"], r["origin"], r["status"]) for r in requests] == [("approve", "cli", "done")]
    assert proposal is not None
    assert proposal["history"][1]["who"] == "anna"
    assert proposal["status"] == "applied"  # and then written by the service


def test_no_write_while_the_loop_is_in_man(tmp_path: Path) -> None:
    store = tmp_path / "s.db"
    # no profile: the virtual PLC starts in MAN at 1 V (and stays there)
    with VirtualPlcThread(speed=SPEED) as virtual:
        site = _site(virtual, store, ONLINE_NO_WINDOWS)
        kc0, ti0 = virtual.plc.gains
        pid = _approved_proposal(site, store, 1.2 * kc0, ti0)
        service, lines = _run(site, 2.5)
        try:
            proposal = service.history.proposal(pid)
            assert proposal is not None
            assert proposal["status"] == "approved"
            assert service.history.writes() == []
        finally:
            service.close()
        assert virtual.plc.gains == (kc0, ti0)
    assert any("held=" in line and "not in AUTO" in line for line in lines)


class _LosesFirstApply(ModbusSource):
    """A real Modbus link that loses the first gain block on its way (the fault injected)."""

    lost = 0

    async def write(self, values: Mapping[str, float]) -> None:
        if "apply" in values and _LosesFirstApply.lost == 0:
            _LosesFirstApply.lost += 1
            return
        await super().write(values)


def test_a_lost_echo_fails_the_proposal_and_reverts_to_last_known_good(tmp_path: Path) -> None:
    store = tmp_path / "s.db"
    with VirtualPlcThread(speed=SPEED, setpoint_profile="run") as virtual:
        online = ONLINE_NO_WINDOWS + "echo_timeout_s = 0.5\n"
        site = _site(virtual, store, online)
        kc0, ti0 = virtual.plc.gains
        pid = _approved_proposal(site, store, 1.3 * kc0, ti0)
        _LosesFirstApply.lost = 0
        service, _lines = _run(site, 4.0, write_source=_LosesFirstApply(site))
        try:
            proposal = service.history.proposal(pid)
            kinds = [(w["kind"], w["status"]) for w in service.history.writes()]
            events = [e.kind for e in service.store.read_events()]
        finally:
            service.close()
        gains = virtual.plc.gains
    assert proposal is not None
    assert proposal["status"] == "failed"
    assert kinds == [("proposal", "failed"), ("revert", "verified")]
    assert "write_failed" in events
    assert "revert" in events
    assert math.isclose(gains[0], kc0, rel_tol=1e-6)
    assert math.isclose(gains[1], ti0, rel_tol=1e-6)


@pytest.mark.parametrize("reached_plc", [True, False])
def test_a_write_cut_short_is_reconciled_from_the_echo_and_never_repeated(
    tmp_path: Path, reached_plc: bool
) -> None:
    store = tmp_path / "s.db"
    with VirtualPlcThread(speed=SPEED, setpoint_profile="run") as virtual:
        site = _site(virtual, store, ONLINE_NO_WINDOWS)
        kc0, ti0 = virtual.plc.gains
        kc = round(1.25 * kc0, 6)
        pid = _approved_proposal(site, store, kc, ti0)
        # the state a kill -9 between "intent recorded" and "echo seen" leaves behind
        opened, history = _history(site, store)
        write_id = history.begin_write(
            kind="proposal", kc=kc, ti=ti0, apply_seq=7, who="tester", why="x", proposal_id=pid
        )
        history.set_proposal_status(pid, "writing", who="service", why="")
        history.close()
        opened.close()
        if reached_plc:

            async def write_block() -> None:
                source = open_source(site)
                async with source:
                    await source.write({"heartbeat": 1.0})  # an advisor is alive
                    await await_until(
                        lambda: not virtual.plc.heartbeat_stale(), 10.0, "a fresh heartbeat"
                    )
                    await source.write({"kc": kc, "ti": ti0, "apply": 7.0})
                    beats = itertools.count(2)

                    async def echoed() -> bool:
                        await source.write({"heartbeat": float(next(beats))})  # kept fresh
                        return bool((await source.read_write_side(["echo"]))["echo"] == 7)

                    await await_until(echoed, 10.0, "the PLC's echo of apply 7")

            asyncio.run(write_block())
        service, _ = _run(site, 2.0)
        try:
            write = service.history.write(write_id)
            proposal = service.history.proposal(pid)
            all_writes = service.history.writes()
        finally:
            service.close()
        gains = virtual.plc.gains
    assert write is not None
    assert proposal is not None
    assert len(all_writes) == 1  # reconciled, not written again
    if reached_plc:
        assert write["status"] == "verified"
        assert proposal["status"] == "applied"
        assert math.isclose(gains[0], kc, rel_tol=1e-6)
    else:
        assert write["status"] == "not_applied"
        assert proposal["status"] == "failed"
        assert gains == (kc0, ti0)


def test_gains_in_the_plc_outside_the_bounds_stop_the_service_with_the_reason(
    tmp_path: Path,
) -> None:
    """[controller] says the commissioning Kc is 3x what the PLC runs: 1/3 < gain_bounds' 0.5."""
    from fuelid.errors import ConfigError

    store = tmp_path / "s.db"
    with VirtualPlcThread(speed=SPEED, setpoint_profile="run") as virtual:
        kc0, _ = virtual.plc.gains
        text = virtual.site_text(store_url=f"sqlite:///{store}")
        lines = [
            f"kc = {3.0 * kc0!r}" if line.startswith("kc = ") else line
            for line in text.splitlines()
        ]
        site = ServiceSite.model_validate(tomllib.loads("\n".join(lines)))
        service = OnlineService(site, heartbeat_s=HEARTBEAT_S, isolate=False)
        try:
            with pytest.raises(ConfigError, match=r"outside \[online\] gain_bounds"):
                asyncio.run(service.run(5.0))
        finally:
            service.close()


MODEL_BEFORE = {"K": 11.0, "T": 0.42, "delay": 0.1}
"""The model the gains in the PLC were tuned for before the write (an earlier write's)."""
MODEL_WRITTEN = {"K": 13.0, "T": 0.38, "delay": 0.1}
"""The model the written proposal's gains were tuned for."""


# the slow set: 6 s each of a real-time run (the fast set's 6-min budget)
@pytest.mark.slow
@pytest.mark.parametrize("tuned_before", [True, False], ids=["earlier-write", "commissioning"])
def test_a_revert_makes_tuned_for_the_model_of_the_gains_it_writes_back(
    tmp_path: Path, tuned_before: bool
) -> None:
    """The drift chip compares K now with ``tuned_for``: after a revert, the reverted-to gains'.

    The PLC runs gains an earlier write tuned for MODEL_BEFORE (or the commissioning gains, for
    no known model); a proposal tuned for MODEL_WRITTEN is written, then a revert is requested.
    """
    from fuelid.online import GOOD_TUNED_FOR

    store = tmp_path / "s.db"
    with VirtualPlcThread(speed=SPEED, setpoint_profile="run") as virtual:
        site = _site(virtual, store, ONLINE_NO_WINDOWS)
        kc0, ti0 = virtual.plc.gains
        old, new = {"Kc": kc0, "Ti": ti0}, {"Kc": round(1.2 * kc0, 6), "Ti": ti0}
        opened, history = _history(site, store)
        if tuned_before:  # what the earlier write left
            history.set_state("current_gains", old)
            history.set_state("tuned_for", MODEL_BEFORE)
        pid = history.add_proposal(
            model_id=None, old=old, new=new,
            detail={"reason": "test", "ideal": {"old": old, "new": new},
                    "target_model": MODEL_WRITTEN},
        )  # fmt: skip
        history.set_proposal_status(pid, "approved", who="tester", why="test")
        history.close()
        opened.close()
        service, _ = _run(site, 3.0)
        try:
            written = (service.history.state("tuned_for"), service.history.state(GOOD_TUNED_FOR))
            service.history.set_state("revert_requested", {"who": "tester", "why": "test"})
        finally:
            service.close()
        service, _ = _run(site, 3.0)
        try:
            kinds = [(w["kind"], w["status"]) for w in service.history.writes()]
            reverted = service.history.state("tuned_for")
            current = service.history.state("current_gains")
        finally:
            service.close()
        gains = virtual.plc.gains
    before = MODEL_BEFORE if tuned_before else None
    assert written == (MODEL_WRITTEN, before)
    assert kinds == [("proposal", "verified"), ("revert", "verified")]
    assert reverted == before  # not the model of the gains reverted away from
    assert current == pytest.approx(old)
    assert gains == pytest.approx((kc0, ti0))
