"""Gray-box models with kinks, limits and switches: simulated, fitted, and refused where they must.

The models are in :mod:`support.kinked_models`: an overflow tank (a kink in the level), a valve
at its stop (a clipped input), a pump that cannot run backwards (a kink in the level), a drain
that switches on the level (the right-hand side jumps and slides), and that drain behind a very
fast actuator (stiff as well). Bands are stated before the checks and come from the solvers'
tolerances or from the statistics of one fit.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fuelid.errors import FuelidError
from fuelid.greybox import GreyBoxEstimator, NotIdentifiableError, OdeModel, ParameterSpec, Record
from fuelid.greybox._parameters import ParameterMap
from fuelid.greybox._sensitivity import simulate_record
from fuelid.greybox._solver_choice import RK4_AGREEMENT, choose_solver
from fuelid.greybox._solvers import SimulationError, Solver
from support.bands import coverage_band
from support.kinked_models import (
    H_RIM,
    TRUTH,
    X0,
    held_steps,
    kinked_model,
    kinked_record,
    stiff_drain_f,
    valve_exact,
)


def simulate_at(
    model: OdeModel, record: Record, values: dict[str, float], solver: Solver
) -> np.ndarray:
    """The model's output over the record at ``values`` with ``solver`` (no sensitivities)."""
    free = [spec.name for spec in model.parameters]
    system = model.bind(values, free, record)
    init = system.initial_state(record.u[0], record.y[0])
    assert init is not None
    return simulate_record(system, record, init[0], solver=solver).outputs[:, 0]


@pytest.mark.parametrize("name", ["overflow", "valve", "pump"])
def test_kinked_models_simulate_as_their_references(name: str) -> None:
    record, clean = kinked_record(name, seed=11)
    model = kinked_model(name, TRUTH[name])
    simulated = simulate_at(model, record, TRUTH[name], Solver())
    # band: LSODA at rtol 1e-6 (atol 1e-9) per step; its global error over 400 samples with a
    # few dozen kinks stays within 1e-4 of the level's size (100× the per-step tolerance)
    assert np.max(np.abs(simulated - clean)) <= 1e-4 * np.max(np.abs(clean))


@pytest.mark.parametrize("name", ["overflow", "valve", "pump"])
def test_each_solver_integrates_a_kinked_model(name: str) -> None:
    record, clean = kinked_record(name, seed=12, n=200)
    model = kinked_model(name, TRUTH[name])
    scale = np.max(np.abs(clean))
    for solver in (Solver("bdf"), Solver("radau"), Solver("rk45"), Solver("rk4", substeps=8)):
        simulated = simulate_at(model, record, TRUTH[name], solver)
        # band: the variable-step methods at rtol 1e-6 as LSODA above; RK4 with 8 steps of
        # 1/8 s on modes of 5 s and slower: local error ~(h/τ)⁵/120 ≈ 1e-9, first order at the
        # kinks (a few dozen steps that straddle one, each ≲ h²·|Δf'|) — 1e-4 of the level
        assert np.max(np.abs(simulated - clean)) <= 1e-4 * scale, solver.describe()


def test_rk4_converges_at_fourth_order_on_a_smooth_model() -> None:
    # the valve inside its limits is linear: exact zero-order-hold solution to compare with
    truth = {"K": 2.0, "T": 2.0, "u_max": 5.0}
    rng = np.random.default_rng(3)
    u = rng.uniform(0.0, 1.0, 120).repeat(5)
    record = Record.from_arrays(np.arange(len(u), dtype=float), u, np.zeros(len(u)))
    exact = valve_exact(u, truth)
    model = kinked_model("valve", truth)
    errors = [
        np.max(np.abs(simulate_at(model, record, truth, Solver("rk4", substeps=s)) - exact))
        for s in (2, 4)
    ]
    # band: RK4's global error is C·h⁴(1 + O(h/T)); from h/T = 1/4 to 1/8 the ratio is
    # 2⁴ = 16 within a few per cent: log₂ of it in [3.8, 4.2]
    assert 3.8 <= math.log2(errors[0] / errors[1]) <= 4.2


@pytest.mark.parametrize("name", ["overflow", "valve", "pump"])
def test_parameters_of_kinked_models_are_recovered(name: str) -> None:
    record, _ = kinked_record(name, seed=21)
    start = {key: 1.3 * value for key, value in TRUTH[name].items()}
    if name == "valve":
        start["u_max"] = 0.7  # a start inside the inputs' range, where the stop acts
    estimator = GreyBoxEstimator(kinked_model(name, start)).fit(record)
    for key, value in TRUTH[name].items():
        se = estimator.stderr_[key]
        assert se is not None
        # band: 4 standard errors (a correct estimator misses it with probability 6e-5)
        assert abs(estimator.params_[key] - value) <= 4.0 * se, (key, estimator.params_[key])
        # the sensitivities follow the kinks: the simulated change over one se matches them
        discrepancy = estimator.linearity_[key]
        assert discrepancy is not None
        assert discrepancy < 0.2
    assert estimator.solver_.solver.method == "lsoda"


def test_a_limit_the_data_never_reach_is_refused_without_hold_undetermined() -> None:
    # inputs 0…0.6 never reach the valve's stop: u_max (start 0.9) acts nowhere in the record
    record, _ = kinked_record("valve", seed=31, input_range=(0.0, 0.6))
    start = {"K": 2.5, "T": 10.0, "u_max": 0.9}
    with pytest.raises(NotIdentifiableError, match="u_max"):
        GreyBoxEstimator(kinked_model("valve", start)).fit(record)


def test_hold_undetermined_holds_it_and_fits_the_rest() -> None:
    record, _ = kinked_record("valve", seed=31, input_range=(0.0, 0.6))
    start = {"K": 2.5, "T": 10.0, "u_max": 0.9}
    estimator = GreyBoxEstimator(kinked_model("valve", start), hold_undetermined=True).fit(record)
    assert list(estimator.not_determined_) == ["u_max"]
    assert "held at 0.9" in estimator.not_determined_["u_max"]
    assert estimator.params_["u_max"] == 0.9
    assert estimator.stderr_["u_max"] is None
    assert estimator.ci95_["u_max"] is None
    assert estimator.free_names_ == ("K", "T")
    for key in ("K", "T"):
        se = estimator.stderr_[key]
        assert se is not None
        # band: 4 standard errors, as above
        assert abs(estimator.params_[key] - TRUTH["valve"][key]) <= 4.0 * se


def test_a_held_parameter_that_acts_at_the_estimate_is_freed_again() -> None:
    # at the start (a 40 % low) the level never reaches the rim, so the overflow's c does not
    # act; at the estimate it does, and c must be estimated, not left at its start (without the
    # start search, which would start c where it acts: test_greybox_start_search.py)
    record, _ = kinked_record("overflow", seed=41)
    start = {"a": 0.12, "b": 0.1, "c": 0.5}
    model = kinked_model("overflow", start)
    with pytest.raises(NotIdentifiableError, match="do not depend on c"):
        GreyBoxEstimator(model, start_search=False).fit(record)  # c idle at the start
    estimator = GreyBoxEstimator(model, hold_undetermined=True, start_search=False)
    estimator.fit(record)
    assert estimator.not_determined_ == {}
    for key, value in TRUTH["overflow"].items():
        se = estimator.stderr_[key]
        assert se is not None
        # band: 4 standard errors, as above
        assert abs(estimator.params_[key] - value) <= 4.0 * se


def _outputs(model: OdeModel, record: Record, values: dict[str, float]):  # type: ignore[no-untyped-def]
    def simulate(solver: Solver) -> list[np.ndarray]:
        return [simulate_at(model, record, values, solver)[:, None]]

    return simulate


def test_auto_falls_back_where_lsoda_fails_and_says_so() -> None:
    noise = 0.05
    record, clean = kinked_record("drain", seed=51, n=300, noise=noise)
    model = kinked_model("drain", TRUTH["drain"])
    with pytest.raises(SimulationError, match="lsoda"):
        simulate_at(model, record, TRUTH["drain"], Solver("lsoda"))
    choice = choose_solver(
        "auto", None, None, _outputs(model, record, TRUTH["drain"]), [record], np.array([noise])
    )
    assert choice.solver.method == "rk4"
    assert "lsoda" in choice.reason
    assert "agrees" in choice.reason
    simulated = simulate_at(model, record, TRUTH["drain"], choice.solver)
    # band: the chosen substeps agree with twice as many within RK4_AGREEMENT noise standard
    # deviations (2-norm over the record); across a sliding switch RK4 converges at first
    # order, so its error is at most ~2× that; the 2,000-step Euler reference adds ~1/60 of it
    assert np.linalg.norm((simulated - clean) / noise) <= 2.2 * RK4_AGREEMENT + 0.02


def test_auto_keeps_lsoda_for_a_stiff_smooth_model() -> None:
    # a 10⁴/s mode under 1 s samples: LSODA turns to BDF and integrates it; RK4 would need
    # thousands of steps per sample
    model = OdeModel(
        lambda t, x, u, p: [p["a"] * (u[0] - x[0]), (x[0] - x[1]) / p["T"]],
        [ParameterSpec("a", 1e4, 0.0), ParameterSpec("T", 5.0, 0.0)],
        ["actuator", "level"],
        h=lambda x, u, p: x[1],
        x0=lambda p, u0, y0: [0.0, 0.0],
    )
    u = np.repeat(np.random.default_rng(5).uniform(0.0, 1.0, 10), 20)
    record = Record.from_arrays(np.arange(200.0), u, np.zeros(200))
    choice = choose_solver(
        "auto",
        None,
        None,
        _outputs(model, record, {"a": 1e4, "T": 5.0}),
        [record],
        np.array([0.01]),
    )
    assert choice.solver.method == "lsoda"
    assert choice.reason == ""


def test_rk4_refuses_a_stiff_model_beyond_its_cap() -> None:
    model = OdeModel(
        lambda t, x, u, p: [p["a"] * (u[0] - x[0])],
        [ParameterSpec("a", 1e4, 0.0)],
        ["x"],
        x0=lambda p, u0, y0: [0.0],
    )
    u = np.repeat([0.0, 1.0, 0.5, 0.2], 25)
    record = Record.from_arrays(np.arange(100.0), u, np.zeros(100))
    simulate = _outputs(model, record, {"a": 1e4})
    with pytest.raises(SimulationError, match="too stiff for a fixed step"):
        choose_solver("rk4", None, None, simulate, [record], np.array([0.01]))


def test_auto_refuses_a_stiff_switching_model_with_each_solver_s_reason() -> None:
    model = OdeModel(
        stiff_drain_f,
        [ParameterSpec("a", 0.2, 0.0), ParameterSpec("b", 0.1, 0.0)],
        ["actuator", "level"],
        h=lambda x, u, p: x[1],
        x0=lambda p, u0, y0: [u0[0], X0["drain"]],
    )
    record, _ = kinked_record("drain", seed=52, n=200, noise=0.05)
    with pytest.raises(SimulationError) as refused:
        choose_solver(
            "auto", None, None, _outputs(model, record, TRUTH["drain"]), [record], np.array([0.05])
        )
    message = str(refused.value)
    assert "lsoda" in message
    assert "bdf" in message
    assert "too stiff" in message


def test_a_solver_refused_at_the_start_values_is_a_convergence_error_naming_it() -> None:
    record, _ = kinked_record("drain", seed=53, n=200, noise=0.05)
    model = kinked_model("drain", TRUTH["drain"])
    with pytest.raises(FuelidError, match=r"cannot be simulated at the start values.*lsoda"):
        GreyBoxEstimator(model, solver="lsoda").fit(record)


@pytest.mark.parametrize(
    ("settings", "match"),
    [
        ({"solver": "euler"}, "solver must be one of"),
        ({"solver": "rk4", "substeps": 0}, "substeps must be an integer from 1 to 64"),
        ({"solver": "rk4", "substeps": 65}, "substeps must be an integer from 1 to 64"),
        ({"solver": "lsoda", "substeps": 4}, "substeps apply to the rk4 solver only"),
        ({"max_step": -1.0}, "max_step must be a positive"),
        ({"max_step": math.nan}, "max_step must be a positive"),
    ],
)
def test_bad_solver_settings_are_refused(settings: dict[str, object], match: str) -> None:
    record, _ = kinked_record("valve", seed=61, n=50)
    with pytest.raises(FuelidError, match=match):
        GreyBoxEstimator(kinked_model("valve", TRUTH["valve"]), **settings).fit(record)  # type: ignore[arg-type]


def test_rk4_with_given_substeps_is_used_as_given_and_reported() -> None:
    record, _ = kinked_record("pump", seed=71, n=200)
    estimator = GreyBoxEstimator(
        kinked_model("pump", {k: 1.2 * v for k, v in TRUTH["pump"].items()}),
        solver="rk4",
        substeps=4,
    ).fit(record)
    assert estimator.solver_.solver == Solver("rk4", None, 4)
    assert estimator.solver_.to_json() == {
        "method": "rk4",
        "max_step": None,
        "substeps": 4,
        "rtol": None,
        "requested": "rk4",
        "reason": "",
    }
    lsoda = GreyBoxEstimator(
        kinked_model("pump", {k: 1.2 * v for k, v in TRUTH["pump"].items()})
    ).fit(record)
    for key in TRUTH["pump"]:
        se = lsoda.stderr_[key]
        assert se is not None
        # band: RK4 with 4 steps of 0.25 s on a 10 s mode differs from LSODA's simulation by
        # ~(h/T)⁴ ≈ 4e-7 of the level (plus first-order kink terms ≲ 1e-4): 0.1 se at most
        assert abs(estimator.params_[key] - lsoda.params_[key]) <= 0.1 * se


def test_parameter_map_of_a_held_fit_keeps_the_held_value() -> None:
    spec = ParameterSpec("u_max", 0.9, 0.0)
    assert ParameterMap((spec,)).values(np.array([math.log(0.9)]))["u_max"] == pytest.approx(0.9)


COVERAGE_RUNS = 150


@pytest.mark.slow
@pytest.mark.parametrize("name", ["overflow", "pump"])
def test_intervals_cover_on_kinked_models(name: str) -> None:
    """95 % intervals of a model whose level crosses its kinks, over independent records.

    The sensitivities jump where the level crosses a kink (the overflow's rim, the pump's
    check valve); the covariance is the Cramér–Rao bound only if the forward sensitivities
    follow those crossings, which this checks by coverage.
    """
    # band, stated before running: each parameter's misses of 150 correct 95 % intervals lie
    # in the two-sided binomial band at 0.1 % false alarm (support.bands.coverage_band)
    low, high = coverage_band(COVERAGE_RUNS)
    misses = dict.fromkeys(TRUTH[name], 0)
    start = {key: 1.2 * value for key, value in TRUTH[name].items()}
    for run in range(COVERAGE_RUNS):
        record, _ = kinked_record(name, seed=1000 + run)
        estimator = GreyBoxEstimator(kinked_model(name, start)).fit(record)
        for key, value in TRUTH[name].items():
            interval = estimator.ci95_[key]
            assert interval is not None
            misses[key] += not interval[0] <= value <= interval[1]
    for key, missed in misses.items():
        assert low <= missed <= high, (key, missed, (low, high))


def _fast_pump(t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    """A pump whose flow follows its command within ``p["lag"]`` s, filling a draining tank."""
    return [(p["k"] * u[0] - x[0]) / p["lag"], x[0] - x[1] / p["T"]]


def _fast_pump_fit(lag: float) -> GreyBoxEstimator:
    truth = {"k": 0.5, "T": 8.0, "lag": lag}
    rng = np.random.default_rng(91)
    u = held_steps(rng, 300, 0.2, 1.0)
    x = np.array([truth["k"] * u[0], 3.0])  # the tank not at rest: its level is estimated
    level = np.empty(len(u))
    for k, u_k in enumerate(u):
        level[k] = x[1]
        x = solve_ivp(
            lambda t, z, c=u_k: _fast_pump(t, z, [c], truth), (0.0, 1.0), x,
            method="Radau", rtol=1e-10, atol=1e-12,
        ).y[:, -1]  # fmt: skip
    y = level + 0.01 * rng.standard_normal(len(u))
    record = Record.from_arrays(np.arange(len(u), dtype=float), u, y)
    model = OdeModel(
        _fast_pump,
        [
            ParameterSpec("k", 0.6, 0.0),
            ParameterSpec("T", 10.0, 0.0),
            ParameterSpec("lag", lag, 0.0, fixed=True),
        ],
        ["flow", "level"],
        h=lambda x, u, p: x[1],
    )
    estimator = GreyBoxEstimator(model).fit(record)
    for key in ("k", "T"):
        se = estimator.stderr_[key]
        assert se is not None
        # band: 4 standard errors (a correct estimator misses it with probability 6e-5)
        assert abs(estimator.params_[key] - truth[key]) <= 4.0 * se
    return estimator


def test_a_fast_mode_s_initial_state_is_held_and_the_rest_fitted() -> None:
    # a 1 ms lag: the flow's initial value is gone at once but for the volume it moved into
    # the tank (flow·0.001): the data see it only to some 50 times the states' size
    estimator = _fast_pump_fit(1e-3)
    assert list(estimator.not_determined_) == ["x0[flow]"]
    assert estimator.solver_.solver.method == "lsoda"
    assert estimator.identifiability_.identifiable


def test_a_slower_mode_s_initial_state_is_estimated_with_its_uncertainty() -> None:
    # a 10 ms lag: the flow's initial value is seen to about twice the states' size, under
    # the hold's limit (ten times): it stays estimated, and the report says it is not determined
    estimator = _fast_pump_fit(1e-2)
    assert estimator.not_determined_ == {}
    assert "x0[flow] is not determined" in estimator.identifiability_.message()


def _clamped_f(t: float, x: Any, u: Any, p: Mapping[str, Any]) -> Any:
    """The overflow tank as a switch a user writes: full and filling, the level stays."""
    rate = p["a"] * u[0] - p["b"] * math.sqrt(max(x[0], 0.0))
    if x[0] >= p["xmax"] and rate > 0:
        rate = 0.0
    return [rate]


def test_a_switch_level_the_sensitivities_cannot_see_is_refused_naming_the_switch() -> None:
    """A switch level hides from the sensitivities; the refusal says the simulation sees it.

    The forward sensitivities differentiate f on one branch: the switch level xmax is in
    neither, so they see no effect of it, while the simulated level is clamped at xmax.
    Refused as before (no sensitivity to steer by), but the refusal must say the simulation
    does depend on xmax. Band from theory: a 10 % step of the clamp (0.2 m) against 0.01 m
    noise costs (0.2/0.01)² = 400 per sample at the rim; the record has tens of them, so the
    quoted rise exceeds 1000.
    """
    record, clean = kinked_record("overflow", seed=7)
    assert np.sum(clean > H_RIM) > 20
    model = OdeModel(
        _clamped_f,
        [
            ParameterSpec("a", 0.2, 0.0),
            ParameterSpec("b", 0.1, 0.0),
            ParameterSpec("xmax", 2.0, 0.0),
        ],
        ["level"],
        x0=lambda p, u0, y0: [1.0],
    )
    with pytest.raises(NotIdentifiableError) as caught:
        GreyBoxEstimator(model).fit(record)
    found = re.search(
        r"simulation does depend on xmax \(a step of ±10 % moves the simulated "
        r"weighted cost by ([0-9.e+]+)\)",
        str(caught.value),
    )
    assert found is not None, str(caught.value)
    assert float(found.group(1)) > 1000.0
    assert "a switch (an if on a state)" in str(caught.value)
