"""The recorder's time base (fuelid.plc._timebase): the PLC's counter unwrapped, restarts told."""

from __future__ import annotations

import pytest

from fuelid.plc._timebase import HALF_RANGE, UINT32, SampleSequence


def test_the_time_base_unwraps_the_counter_and_keeps_times_regular() -> None:
    seq = SampleSequence(period_s=0.02, last_stored=None)
    assert seq.start(UINT32 - 2, received=100.0) == (True, "")
    assert seq.advance(UINT32 - 1, received=100.02) == (1, "")
    assert seq.advance(1, received=100.06) == (2, "")  # wrapped past 2**32: no restart
    assert seq.stored(seq.u) == UINT32 + 1
    assert seq.time(seq.u) == pytest.approx(100.06)


def test_a_recorder_started_on_a_store_goes_on_from_its_time_base() -> None:
    # a PLC at 20x real time: the stored samples are 7,000 s ahead of the wall clock. The same
    # run of the PLC (its counter past the store's last number) goes on from the stored times;
    # a wall-clock anchor would put the new samples 7,000 s before the stored ones
    wall, ahead = 1_000.0, 8_000.0
    seq = SampleSequence(period_s=0.02, last_stored=1_000, last_time=ahead)
    assert seq.start(1_010, received=wall) == (True, "")
    assert seq.time(seq.u) == pytest.approx(ahead + 10 * 0.02)
    # a PLC restarted since (its counter behind the store): a new run after the stored samples
    seq = SampleSequence(period_s=0.02, last_stored=1_000, last_time=ahead)
    continues, why = seq.start(5, received=wall)
    assert not continues
    assert "behind" in why
    assert seq.time(seq.u) == pytest.approx(ahead + 0.02 + 5 * 0.02)  # the rule: anchor after


def test_the_time_base_tells_a_restart_and_leaves_one_number_out() -> None:
    seq = SampleSequence(period_s=0.02, last_stored=None)
    seq.start(5000, received=100.0)
    seq.mark(seq.stored(seq.u), seq.time(seq.u))
    assert (5000 - 10) % UINT32 < HALF_RANGE < (10 - 5000) % UINT32  # back, not a wrap
    step, why = seq.advance(10, received=101.0)
    assert step < 0
    assert "went back to 10" in why
    assert seq.stored(seq.u) == 5000 + 2 + 10  # one number left out: readers see a break
    assert seq.time(seq.u) == pytest.approx(101.0)  # the wall-clock anchor, after the last
