"""The virtual PLC's excitation on demand and run flag: the engine alone, no sockets.

The PLC adds ``excitation_request``, clamped to ±``excitation_limit_V`` and zeroed while the
heartbeat is stale or the request is not finite, to its PI's output (or the manual command) at
each scan, the sum within the drive's 1–5 V; the PI never sees it. Expected values are the clamp
written out, the PI algorithm replayed from the ring (:class:`DiscretePI`) and the same engine
without a request.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import pytest

from fuelid.errors import ConfigError
from fuelid.plc.virtual import VirtualPLC
from fuelid.plc.virtual._engine import STATUS_AT_LIMIT
from fuelid.plc.virtual._modbus_server import HR_COUNT, IR_POINTS_COUNT
from fuelid.plc.virtual._points import (
    POINTS,
    RING_FIELDS,
    RING_FIRST_REGISTER,
    RING_RECORD_REGISTERS,
    ring_slot_register,
)
from fuelid.plc.virtual._s7_server import RECORD_BYTES, db1_size, db2_size
from fuelid.tuning import DiscretePI, PISettings

N_CONTROL = 50  # samples per control period (1 s / 0.02 s)
EXCITATION = RING_FIELDS.index("excitation")
COMMAND = RING_FIELDS.index("command")
_WORDS = {"float32": 2, "uint32": 2, "int16": 1, "uint16": 1}


def _rows(records: Mapping[int, np.ndarray]) -> np.ndarray:
    return np.array(list(records.values()))


class _Advisor:
    """Keeps the heartbeat fresh: a new value before every control period.

    Made one sample before a scan (the engine advanced to it), so that each period it advances
    starts with a scan: its rows are one control period, its first row the scan's sample.
    """

    def __init__(self, plc: VirtualPLC) -> None:
        self.plc = plc
        self.beats = 0
        plc.advance((-plc.seq - 1) % N_CONTROL)

    def periods(self, n: int, writes: Mapping[str, float] | None = None) -> np.ndarray:
        """Write ``writes`` with a heartbeat, then advance ``n`` control periods; the ring rows."""
        rows = []
        for i in range(n):
            self.beats += 1
            self.plc.write_points(
                {**(writes if i == 0 and writes else {}), "heartbeat": self.beats}
            )
            rows.append(_rows(self.plc.advance(N_CONTROL)))
        return np.concatenate(rows)


def _man_at(u: float, **kwargs: object) -> tuple[VirtualPLC, _Advisor]:
    """A PLC in MAN at ``u`` [V] with a fresh heartbeat, one sample before a scan (sample 99)."""
    plc = VirtualPLC(seed=7, **kwargs)  # type: ignore[arg-type]
    advisor = _Advisor(plc)
    advisor.periods(2, {"manual_command": u})
    assert plc.seq % N_CONTROL == N_CONTROL - 1
    return plc, advisor


# -- the points and the ring layout -------------------------------------------------------------


def test_new_points_are_in_the_table_as_specified() -> None:
    request, applied, run = POINTS["excitation_request"], POINTS["excitation"], POINTS["run"]
    assert (request.modbus, request.type, request.unit, request.opcua, request.s7) == (
        "hr:22",
        "float32",
        "V",
        "FuelLoop.ExcitationRequest",
        "DB2.DBD44",
    )
    assert (applied.modbus, applied.type, applied.unit, applied.opcua, applied.s7) == (
        "ir:20",
        "float32",
        "V",
        "FuelLoop.Excitation",
        "DB1.DBD40",
    )
    assert (run.modbus, run.type, run.opcua, run.s7) == (
        "ir:22",
        "uint16",
        "FuelLoop.Run",
        "DB1.DBW44",
    )


@pytest.mark.parametrize("access", ["read", "write"])
def test_no_two_points_share_a_register(access: str) -> None:
    owner: dict[int, str] = {}
    for name, point in POINTS.items():
        if point.access != access:
            continue
        for register in range(point.register, point.register + _WORDS[point.type]):
            assert register not in owner, f"{name} overlaps {owner.get(register)}"
            owner[register] = name
    assert max(owner) < RING_FIRST_REGISTER


def test_ring_record_has_excitation_last_and_fits_every_protocol() -> None:
    assert RING_FIELDS == ("seq", "command", "flow", "setpoint", "excitation")
    assert RING_RECORD_REGISTERS == 10
    assert ring_slot_register(1) - ring_slot_register(0) == 10
    from fuelid.plc.virtual._engine import MAX_RING_SIZE

    assert ring_slot_register(MAX_RING_SIZE) <= 65536  # the last slot ends inside Modbus
    assert RECORD_BYTES == 20
    assert db1_size() < 65536  # the default ring (2048 records): DB1 under 64 KiB
    assert db2_size() >= 2 * 22 + 4  # the excitation request fits DB2
    assert IR_POINTS_COUNT >= 23
    assert HR_COUNT == 24
    with pytest.raises(ConfigError, match="ring_size"):
        VirtualPLC(ring_size=MAX_RING_SIZE + 1)


# -- settings ---------------------------------------------------------------------------------


@pytest.mark.parametrize("limit", [0.0, -0.5, math.nan, math.inf])
def test_excitation_limit_must_be_finite_and_positive(limit: float) -> None:
    with pytest.raises(ConfigError, match="excitation_limit_V"):
        VirtualPLC(excitation_limit_V=limit)


@pytest.mark.parametrize(
    "window", [(5.0, 5.0), (6.0, 5.0), (math.nan, 1.0), (0.0, math.inf), (1.0,)]
)
def test_run_windows_must_be_finite_with_start_before_end(window: tuple[float, ...]) -> None:
    with pytest.raises(ConfigError, match="run window"):
        VirtualPLC(run_windows=[window])  # type: ignore[list-item]


# -- the clamp, the zeroing, the hold ----------------------------------------------------------


@pytest.mark.parametrize(
    ("limit", "asked", "applied"),
    [(0.5, 0.2, 0.2), (0.5, 2.0, 0.5), (0.5, -2.0, -0.5), (0.2, 0.3, 0.2), (0.2, -0.15, -0.15)],
)
def test_the_request_is_clamped_to_the_plcs_limit(
    limit: float, asked: float, applied: float
) -> None:
    plc, advisor = _man_at(3.0, excitation_limit_V=limit)
    rows = advisor.periods(1, {"excitation_request": asked})
    points = plc.read_points()
    assert points["excitation"] == applied
    assert points["command"] == 3.0 + applied  # MAN: the manual command plus the signal
    assert set(rows[:, EXCITATION]) == {applied}
    assert set(rows[:, COMMAND]) == {3.0 + applied}


def test_the_signal_is_zero_until_a_heartbeat_and_after_it_goes_stale() -> None:
    plc = VirtualPLC(seed=7, heartbeat_timeout_s=3.0)
    plc.write_points({"manual_command": 3.0, "excitation_request": 0.4})
    rows = _rows(plc.advance(3 * N_CONTROL))
    assert set(rows[:, EXCITATION]) == {0.0}  # no advisor has proven it is alive
    assert set(rows[N_CONTROL - 1 :, COMMAND]) == {3.0}  # from the scan at sample 50
    # a request made while stale died with it: a heartbeat alone brings nothing back
    plc.write_points({"heartbeat": 1})  # at t = 3 s
    rows = _rows(plc.advance(N_CONTROL))
    assert set(rows[:, EXCITATION]) == {0.0}
    plc.write_points({"excitation_request": 0.4})  # the advisor, alive, asks again
    rows = _rows(plc.advance(N_CONTROL))  # the scan at sample 250 (t = 5 s) applies it
    assert set(rows[:-1, EXCITATION]) == {0.0}
    assert rows[-1, EXCITATION] == 0.4
    # no further heartbeat: stale once more than 3 s have passed (the scan at t = 7 s)
    rows = _rows(plc.advance(5 * N_CONTROL))
    by_scan = rows[::N_CONTROL, EXCITATION]
    assert by_scan.tolist() == [0.4, 0.4, 0.0, 0.0, 0.0]
    assert plc.heartbeat_stale()
    assert plc.read_points()["command"] == 3.0
    # and the request went with the heartbeat: a new beat does not bring the signal back
    plc.write_points({"heartbeat": 2})
    rows = _rows(plc.advance(2 * N_CONTROL))
    assert set(rows[:, EXCITATION]) == {0.0}


@pytest.mark.parametrize("asked", [math.nan, math.inf, -math.inf])
def test_a_request_that_is_not_finite_applies_nothing(asked: float) -> None:
    plc, advisor = _man_at(3.0)
    advisor.periods(1, {"excitation_request": 0.3})
    assert plc.read_points()["excitation"] == 0.3
    rows = advisor.periods(1, {"excitation_request": asked})
    assert set(rows[:, EXCITATION]) == {0.0}
    assert plc.read_points()["command"] == 3.0


def test_the_signal_is_held_over_the_control_period() -> None:
    plc, advisor = _man_at(3.0)
    advisor.periods(1)
    plc.advance(11)  # mid-period: the PLC acts on the request at its next scan only
    plc.write_points({"excitation_request": -0.25})
    rows = _rows(plc.advance(2 * N_CONTROL))
    waiting, held = rows[: N_CONTROL - 11], rows[N_CONTROL - 11 : 2 * N_CONTROL - 11]
    assert set(waiting[:, EXCITATION]) == {0.0}
    assert set(waiting[:, COMMAND]) == {3.0}
    assert int(held[0, 0]) % N_CONTROL == 0  # the scan
    assert set(held[:, EXCITATION]) == {-0.25}
    assert set(held[:, COMMAND]) == {2.75}


def test_the_sum_is_clamped_to_the_drive_and_read_back_as_applied() -> None:
    plc, advisor = _man_at(4.8)
    advisor.periods(1, {"excitation_request": 0.5})
    points = plc.read_points()
    assert points["command"] == 5.0  # 4.8 + 0.5 clipped at the drive's top
    assert points["excitation"] == 0.5  # the PLC's own clamp: the sum's clip is the drive's
    assert int(points["status"]) & STATUS_AT_LIMIT
    low, advisor = _man_at(1.2)
    advisor.periods(1, {"excitation_request": -0.5})
    assert low.read_points()["command"] == 1.0


def test_a_known_step_of_the_request_moves_the_command_by_exactly_the_clamped_amount() -> None:
    _plc, advisor = _man_at(2.5, excitation_limit_V=0.25)
    before = advisor.periods(3)
    after = advisor.periods(10, {"excitation_request": 0.8})  # clamped to 0.25
    assert set(before[:, COMMAND]) == {2.5}
    assert set(after[:, COMMAND]) == {2.75}  # exactly the clamped amount
    # the flow responds to the command read back: the same plant stepped by hand to 2.75 V
    # (same seed, same noise) gives the same flow, sample for sample
    _twin, twin_advisor = _man_at(2.5)
    twin_advisor.periods(3)
    stepped = twin_advisor.periods(10, {"manual_command": 2.75})
    np.testing.assert_array_equal(after[:, :4], stepped[:, :4])
    assert after[-1, 2] - before[-1, 2] > 2.0  # K·0.25 with K ≈ 13 (L/min)/V


# -- the PI does not see the signal -------------------------------------------------------------


def test_the_pi_is_its_own_the_signal_is_added_after_it() -> None:
    """Replay the PI from the ring: the command is clip(PI output + signal) at every scan."""
    plc = VirtualPLC(seed=11)
    advisor = _Advisor(plc)
    plc.write_points({"manual_command": 2.5, "setpoint_request": 62.0})  # 4.57 V steady
    advisor.periods(4, {"excitation_request": 0.4})  # MAN with the signal: 2.9 V applied
    assert plc.read_points()["command"] == pytest.approx(2.9)
    plc.write_points({"mode_request": 1})
    rows = np.concatenate(
        [
            advisor.periods(1, {"excitation_request": (-0.5, 0.5)[i % 2]})
            for i in range(30)  # a square wave: near the top the sum is clipped
        ]
    )
    scans = rows[::N_CONTROL]
    assert int(scans[0, 0]) % N_CONTROL == 0
    kc, ti = plc.gains
    pi = DiscretePI(PISettings("replay", kc, ti, 1.0), plc.u_min, plc.u_max, u0=2.5)
    e0 = scans[0, 3] - scans[0, 2]
    pi.integral = 2.5 - kc * e0  # bumpless from the manual command without the signal
    clipped = 0
    for seq, command, flow, setpoint, excitation in scans:
        u_pi = pi.update(setpoint, flow)
        expected = min(max(u_pi + excitation, plc.u_min), plc.u_max)
        assert command == pytest.approx(expected, abs=1e-12), f"scan at seq {seq:.0f}"
        clipped += u_pi + excitation > plc.u_max
    assert clipped > 0  # the test saw the drive's clamp on the sum


# -- the run flag ----------------------------------------------------------------------------


def test_run_windows_raise_the_run_flag_on_the_plcs_clock() -> None:
    plc = VirtualPLC(seed=0, run_windows=[(1.0, 2.0), (3.0, 3.5)])
    assert plc.read_points()["run"] == 0.0
    flags = []
    for _ in range(200):
        plc.advance(1)
        flags.append((round(plc.time_s, 2), plc.read_points()["run"]))
    on = [t for t, flag in flags if flag == 1.0]
    assert (on[0], on[49], on[50], on[-1]) == (1.0, 1.98, 3.0, 3.48)
    assert len(on) == 50 + 25  # [start, end): the end sample is outside


def test_set_run_raises_it_by_hand_and_does_not_zero_the_signal() -> None:
    plc, advisor = _man_at(3.0)
    plc.set_run(True)
    rows = advisor.periods(1, {"excitation_request": 0.2})
    points = plc.read_points()
    assert points["run"] == 1.0
    assert set(rows[:, EXCITATION]) == {0.2}  # fuelid, not the virtual PLC, stops exciting
    assert points["command"] == 3.2
    plc.set_run(False)
    assert plc.read_points()["run"] == 0.0


# -- nothing changes without a request --------------------------------------------------------


@pytest.mark.parametrize(
    "options",
    [
        {"seed": 3},
        {"seed": 4, "setpoint_profile": "run"},
        {"seed": 5, "command_profile": "steps", "disturbance_sd_Lpm": 0.3},
    ],
)
def test_without_a_request_the_samples_are_unchanged(options: dict[str, object]) -> None:
    def run(**extra: object) -> tuple[np.ndarray, dict[str, float]]:
        plc = VirtualPLC(**options, **extra)  # type: ignore[arg-type]
        advisor = _Advisor(plc)
        plc.write_points({"manual_command": 2.5, "setpoint_request": 45.0})
        rows = [advisor.periods(3)]
        plc.write_points({"mode_request": 1})
        rows.append(advisor.periods(12))
        return np.concatenate(rows), plc.read_points()

    plain, points = run()
    assert set(plain[:, EXCITATION]) == {0.0}
    assert (points["excitation"], points["run"]) == (0.0, 0.0)
    other, other_points = run(excitation_limit_V=0.1, run_windows=[(0.0, 5.0)])
    np.testing.assert_array_equal(plain, other)  # bit for bit
    assert other_points == points
