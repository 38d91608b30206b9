"""The start search: a start off the flat spot where one exists, else the refusal with evidence.

The models are :mod:`support.kinked_models`' overflow tank (its overflow coefficient c acts only
above the rim, H_RIM = 2 m) and valve at its stop (u_max acts only where the input exceeds it).
What is asserted follows from the models: a parameter that acts only beyond a level the
simulation does not reach changes no arithmetic, so its step's effect is exactly 0; a clip the
inputs never reach leaves the sensitivity exactly 0.
"""

from __future__ import annotations

import numpy as np
import pytest

from fuelid.greybox import (
    GreyBoxEstimator,
    NotIdentifiableError,
    OdeModel,
    ParameterSpec,
    _start_search,
)
from fuelid.greybox._start_search import SEARCH_STARTS, NoStartFound
from support.kinked_models import H_RIM, TRUTH, kinked_model, kinked_record, valve_f

OVERFLOW_START = {"a": 0.12, "b": 0.1, "c": 0.5}
"""40 % low in a: the steady level (a·u/b)² stays under the rim over the record's inputs."""


def _overflow_fit() -> GreyBoxEstimator:
    record, _ = kinked_record("overflow", seed=41)
    return GreyBoxEstimator(kinked_model("overflow", OVERFLOW_START)).fit(record)


def test_a_start_where_the_overflow_acts_is_found_and_the_fit_recovers_the_truth() -> None:
    estimator = _overflow_fit()
    search = estimator.start_search_
    assert search is not None
    # at the given start the level stays under the rim: c changes no arithmetic, so its step
    # moves the outputs by exactly 0 either way
    assert search.flat == {"c": (0.0, 0.0)}
    assert search.given_states["level"][1] < H_RIM
    assert search.chosen is not None
    assert search.n_starts == SEARCH_STARTS
    assert 0 < search.n_acting <= search.n_simulated == SEARCH_STARTS
    line = search.line()
    assert line.startswith(f"start search: start {search.chosen} of {SEARCH_STARTS}")
    assert "the given start left c without sensitivity" in line
    assert estimator.not_determined_ == {}
    for key, value in TRUTH["overflow"].items():
        se = estimator.stderr_[key]
        assert se is not None
        # band: 4 standard errors (a correct estimator misses it with probability 6e-5)
        assert abs(estimator.params_[key] - value) <= 4.0 * se, (key, estimator.params_[key])
    as_json = search.to_json()
    assert as_json["used"] is True
    assert as_json["start"] == search.chosen
    assert as_json["reason"] == line


def test_the_search_is_the_same_one_after_another_as_on_worker_processes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    parallel = _overflow_fit()
    monkeypatch.setattr(_start_search, "MAX_WORKERS", 1)
    serial = _overflow_fit()
    assert serial.start_search_ is not None
    assert parallel.start_search_ is not None
    assert serial.start_search_.serial_reason
    assert serial.start_search_.workers == 1
    # seeded starts and the same arithmetic in every process: the same start, the same fit
    assert serial.start_search_.chosen == parallel.start_search_.chosen
    assert serial.start_search_.n_acting == parallel.start_search_.n_acting
    for key, value in parallel.params_.items():
        assert serial.params_[key] == pytest.approx(value, rel=1e-12)


def _valve_within(u_max: ParameterSpec) -> OdeModel:
    return OdeModel(
        valve_f,
        [ParameterSpec("K", 2.5, 0.0), ParameterSpec("T", 10.0, 0.0), u_max],
        ["level"],
        x0=lambda p, u0, y0: [0.0],
    )


def test_a_limit_no_start_in_the_bounds_reaches_is_refused_with_the_evidence() -> None:
    # inputs 0…0.6 (at most 0.503 in this record) and u_max bounded to 0.7…2: the opening
    # min(u, u_max) is u at every sample of every start, so u_max changes nothing anywhere
    record, _ = kinked_record("valve", seed=31, input_range=(0.0, 0.6))
    assert record.u.max() < 0.7
    model = _valve_within(ParameterSpec("u_max", 0.9, 0.7, 2.0))
    with pytest.raises(NoStartFound) as refused:
        GreyBoxEstimator(model).fit(record)
    assert isinstance(refused.value, NotIdentifiableError)
    search = refused.value.search
    assert search.chosen is None
    assert search.n_starts == search.n_simulated == SEARCH_STARTS
    assert search.n_failed == 0
    # none qualifies, so every start's sensitivities were checked: u_max's was 0 at each
    assert search.n_checked == SEARCH_STARTS
    assert search.n_acting == 0
    assert search.seen_in["u_max"] == 0
    assert search.box["u_max"] == pytest.approx((0.7, 2.0), rel=1e-12)
    message = str(refused.value)
    assert "the outputs do not depend on u_max" in message
    assert f"a search of {SEARCH_STARTS} starts in the bounds" in message
    assert "found none where the outputs depend on u_max" in message


def test_a_limit_the_fit_moves_past_the_records_is_refused_with_where_it_went() -> None:
    # with u_max bounded below by 0 only, starts under the inputs' top make it act; but the
    # records (noise 0.01, truth 0.8) never reach the stop, and the fit from such a start moves
    # u_max up to the records' top sample or past it: no sensitivity there, or a ±10 % step
    # that moves the outputs one way only (the edge of what the records reach)
    record, _ = kinked_record("valve", seed=31, input_range=(0.0, 0.6))
    with pytest.raises(NoStartFound) as refused:
        GreyBoxEstimator(kinked_model("valve", {"K": 2.5, "T": 10.0, "u_max": 0.9})).fit(record)
    search = refused.value.search
    assert search.n_acting > 0
    best = min(search.refined, key=lambda refined: refined.cost)
    assert best.lost == ("u_max",)
    assert "moved a parameter to where the outputs do not depend on it" in str(refused.value)


def test_without_the_search_the_flat_start_is_refused_at_once() -> None:
    record, _ = kinked_record("overflow", seed=41)
    estimator = GreyBoxEstimator(kinked_model("overflow", OVERFLOW_START), start_search=False)
    with pytest.raises(NotIdentifiableError, match="do not depend on c") as refused:
        estimator.fit(record)
    assert not isinstance(refused.value, NoStartFound)


def test_a_limit_started_just_beyond_the_records_is_searched_not_blamed_on_a_switch() -> None:
    # the stop at 0.45 clips the inputs' top (up to 0.503): the records determine u_max; started
    # at 0.52 it clips nothing (sensitivity exactly 0), yet a step of −10 % does clip: the edge
    # of the flat spot, not a switch the sensitivities miss
    truth = {"K": 2.0, "T": 8.0, "u_max": 0.45}
    record, _ = kinked_record("valve", seed=31, input_range=(0.0, 0.6), truth=truth)
    start = {"K": 2.5, "T": 10.0, "u_max": 0.52}
    assert float(np.max(record.u)) < start["u_max"] < float(np.max(record.u)) / 0.9
    estimator = GreyBoxEstimator(kinked_model("valve", start)).fit(record)
    search = estimator.start_search_
    assert search is not None
    assert search.chosen is not None
    up, down = search.flat["u_max"]
    assert up == 0.0
    assert down > 3.84
    for key, value in truth.items():
        se = estimator.stderr_[key]
        assert se is not None
        # band: 4 standard errors, as above
        assert abs(estimator.params_[key] - value) <= 4.0 * se, (key, estimator.params_[key])
