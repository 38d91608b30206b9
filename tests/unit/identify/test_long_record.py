"""Long records (issue 38): the search on a copy of spread-out stretches, the optimum on the whole.

The day-long case is benchmarks/bench_day_log.py's (4.32 M samples); here the same rule runs on a
record of 60,000 samples with the thresholds lowered, against the whole record's own search: the
estimates must agree to a small fraction of a standard error, the standard errors to rounding, and
the result must say what was done.
"""

from __future__ import annotations

import numpy as np
import pytest

from fuelid.identify import OutputError, long_record_note
from fuelid.identify import _long_record as long_record
from fuelid.identify._long_record import long_record_json, search_copy
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel, simulate_model

TRUE = ProcessModel(K=13.5, T=1.2, T2=0.3, delay=0.26)
H = 0.02


@pytest.fixture(scope="module")
def record() -> IOData:
    """20 minutes at 50 Hz: steps every 15 s among four levels, white noise."""
    rng = np.random.default_rng(38)
    levels = rng.choice([1.0, 1.5, 2.0, 2.5], 80)
    u = np.repeat(levels, 750)
    y = 14.0 + simulate_model(TRUE, u - u[0], H) + rng.normal(0.0, 0.1, u.size)
    return IOData(u, y, H)


@pytest.fixture
def long_rule(monkeypatch: pytest.MonkeyPatch) -> None:
    """The long-record rule for records over 30,000 samples, searched on 12,000."""
    monkeypatch.setattr(long_record, "LONG_RECORD", 30_000)
    monkeypatch.setattr(long_record, "SEARCH_SAMPLES", 12_000)


def test_the_polished_optimum_is_the_whole_records(
    record: IOData, monkeypatch: pytest.MonkeyPatch
) -> None:
    # order auto: both structures polished, the order rule on the whole record's fits
    whole = OutputError(order="auto").fit(record)
    assert whole.long_record_ == {}
    monkeypatch.setattr(long_record, "LONG_RECORD", 30_000)
    monkeypatch.setattr(long_record, "SEARCH_SAMPLES", 12_000)
    polished = OutputError(order="auto", full_record=True).fit(record)
    assert set(polished.long_record_) == {1, 2}
    assert all(s.converged for s in polished.long_record_.values())
    assert polished.order_choice_.chosen == whole.order_choice_.chosen
    for name in ("K", "T", "T2", "delay"):
        se = whole.stderr_[name]
        if se is None:
            assert polished.stderr_[name] is None
            continue
        moved = abs(getattr(polished, f"{name}_") - getattr(whole, f"{name}_")) / se
        assert moved < 0.05, (name, moved)
        assert polished.stderr_[name] == pytest.approx(se, rel=0.01)
    assert polished.fit_percent_ == pytest.approx(whole.fit_percent_, abs=1e-6)


def test_a_short_record_is_searched_on_itself(record: IOData) -> None:
    # below the threshold nothing changes: no copy, no polish, no note
    est = OutputError(order=1).fit(record.segment(0, 20_000))
    assert est.long_record_ == {}
    assert long_record_json(est.long_record_) is None
    assert long_record_note(None) is None


def test_the_json_and_the_note_say_what_was_done(record: IOData, long_rule: None) -> None:
    est = OutputError(order="auto", full_record=True).fit(record)
    info = long_record_json(est.long_record_)
    assert info is not None
    assert info["samples"] == record.n_samples
    assert info["copy_samples"] == 12_000
    assert set(info["polish_steps"]) == {"1", "2"}
    note = long_record_note(info)
    assert note is not None
    assert "12,000 samples" in note
    assert "whole record's" in note


def test_by_default_a_long_record_is_fitted_on_its_copy(record: IOData, long_rule: None) -> None:
    # the copy's estimates and standard errors (√(N/n) times the whole record's), the whole
    # record's fit % and fitted state
    est = OutputError(order="auto").fit(record)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(long_record, "LONG_RECORD", 10**9)
        whole = OutputError(order="auto").fit(record)
    assert est.copy_ is not None
    assert est.copy_.n_samples == 12_000
    ratio = np.sqrt(record.n_samples / est.copy_.n_samples)
    for name in ("K", "T", "T2", "delay"):
        se, se_whole = est.stderr_[name], whole.stderr_[name]
        assert se is not None
        assert se_whole is not None
        assert abs(getattr(est, f"{name}_") - getattr(whole, f"{name}_")) < 3.0 * se, name
        assert se == pytest.approx(ratio * se_whole, rel=0.25), name
    assert est.n_samples_ == record.n_samples
    assert est.fit_percent_ == pytest.approx(whole.fit_percent_, abs=0.05)
    assert est.simulate(record).shape == (record.n_samples,)
    info = long_record_json(est.long_record_)
    assert info is not None
    assert info["fitted_on"] == "copy"
    assert info["polish_steps"] == {}
    note = long_record_note(info, H)
    assert note is not None
    assert "fitted on a copy of the record: 12,000 of 60,000 samples" in note


def test_the_copy_spreads_over_the_record_and_keeps_its_gaps() -> None:
    n = 10_000
    data = IOData(
        np.arange(n, dtype=float),
        np.zeros(n),
        0.1,
        segment_starts=(5_000,),
        segment_t0=(900.0,),
    )
    copy = search_copy(data, samples=2_000, stretches=4)
    assert copy.n_samples == 2_000
    # the first stretch starts the record, the last ends it; none crosses the gap
    assert copy.u[0] == 0.0
    assert copy.u[-1] == n - 1
    firsts = copy.u[[0, *copy.segment_starts]]
    assert np.all(np.diff(firsts) > 0)
    for a, b in copy.segment_bounds():
        piece = copy.u[a:b]
        assert np.all(np.diff(piece) == 1.0)  # contiguous in the record
        assert (piece < 5_000).all() or (piece >= 5_000).all()
    # times carry on from each piece's first sample (the second segment's clock starts at 900 s)
    t = copy.t
    assert t[0] == 0.0
    later = copy.segment_starts[-1]
    assert t[later] == pytest.approx(900.0 + 0.1 * (copy.u[later] - 5_000))
