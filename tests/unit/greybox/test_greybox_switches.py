"""Declared switches: located as events, the sensitivities' jumps, a fit of the switching level.

The plant is the overflow tank with a dump valve (examples/overflow_tank_switch.py) whose rim is
a parameter: dx/dt = a·u − b·√x − d·[x > rim]. Over the record the level crosses the rim both
ways and slides along it (the valve empties faster than the pump's excess fills), so every kind
of transition is met: crossings, entering and leaving a sliding mode, and switches at an input
change. Bands are stated before each check, from the solver's tolerances, the finite
difference's truncation error or the fit's statistics.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fuelid.errors import ConfigError
from fuelid.greybox import ConvergenceError, GreyBoxEstimator, OdeModel, ParameterSpec, Record
from fuelid.greybox._sensitivity import simulate_record
from fuelid.greybox._solvers import SimulationError, Solver
from fuelid.greybox._switching import Switch, _Switching
from fuelid.greybox.modelfile import read_model_file

TRUTH = {"a": 0.2, "b": 0.1, "d": 0.05, "rim": 2.0}
X0 = 1.0
NOISE = 0.01
FINE = Solver("lsoda", rtol=1e-10)
EXAMPLES = Path(__file__).resolve().parents[3] / "examples"


def dump_valve(t: float, x: Any, u: Any, p: Any, on: Any) -> list[Any]:
    rate = p["a"] * u[0] - p["b"] * math.sqrt(max(x[0], 0.0))
    if on["above_rim"]:
        rate -= p["d"]
    return [rate]


def dump_valve_numpy(t: float, x: Any, u: Any, p: Any, on: Any) -> list[Any]:
    """The same f written with numpy: it takes a batch of states (one call per step)."""
    return [p["a"] * u[0] - p["b"] * np.sqrt(np.maximum(x[0], 0.0)) - p["d"] * on["above_rim"]]


def above_rim(t: float, x: Any, u: Any, p: Any) -> Any:
    return x[0] - p["rim"]


def tank(start: dict[str, float], f: Any = dump_valve) -> OdeModel:
    specs = [ParameterSpec(name, value, 0.0) for name, value in start.items()]
    return OdeModel(f, specs, ["level"], switches=[Switch("above_rim", above_rim)])


def record(seed: int = 3, y: np.ndarray | None = None) -> Record:
    """600 s at 1 s, the pump voltage held 30 s at a time between 0.2 and 1.6 V."""
    rng = np.random.default_rng(seed)
    t = np.arange(600.0)
    u = np.repeat(rng.uniform(0.2, 1.6, 20), 30)
    return Record.from_arrays(t, u, np.zeros(600) if y is None else y)


def simulate(
    values: dict[str, float],
    solver: Solver = FINE,
    sensitivities: bool = False,
    f: Any = dump_valve,
    x0: float = X0,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Outputs (and ∂y/∂[θ, x0], θ in natural units) over :func:`record` from X0."""
    free = list(values)
    system = tank(values, f).bind(values, free, record())
    s0 = np.zeros((1, len(free) + 1))
    s0[0, -1] = 1.0
    trajectory = simulate_record(
        system,
        record(),
        np.array([x0]),
        s0 if sensitivities else None,
        np.ones(len(free)) if sensitivities else None,
        solver=solver,
    )
    sens = trajectory.output_sensitivity
    return trajectory.outputs[:, 0], None if sens is None else sens[:, 0, :]


def central_differences(values: dict[str, float], relative: float) -> np.ndarray:
    """∂y/∂θ by central differences of simulations at the fine tolerance (x0's column last)."""
    columns = []
    for name in values:
        step = relative * values[name]
        up, down = dict(values), dict(values)
        up[name] += step
        down[name] -= step
        columns.append((simulate(up)[0] - simulate(down)[0]) / (2.0 * step))
    # the initial state's column
    step = relative * X0
    columns.append(
        (simulate(values, x0=X0 + step)[0] - simulate(values, x0=X0 - step)[0]) / (2.0 * step)
    )
    return np.column_stack(columns)


def test_the_record_crosses_the_rim_both_ways_and_slides_along_it() -> None:
    level, _ = simulate(TRUTH)
    at_rim = np.abs(level - TRUTH["rim"]) < 1e-6
    # the checks below mean something only if every transition occurs: well above, well
    # below, and held at the rim (a slide) for a good stretch
    assert np.sum(level > TRUTH["rim"] + 0.05) > 50
    assert np.sum(level < TRUTH["rim"] - 0.05) > 50
    assert np.sum(at_rim) > 30


@pytest.mark.parametrize("f", [dump_valve, dump_valve_numpy], ids=["scalar", "numpy"])
def test_sensitivities_jump_as_central_differences_say(f: Any) -> None:
    # band, stated before the run: at rtol 1e-10 the outputs' error is ≲ 1e-10·|y| ≈ 4e-10,
    # which a central difference of step h = 1e-5·θ turns into ≤ 4e-10/h ≤ 2e-4 (θ ≥ 0.05); its
    # truncation error is (h/θ)²·|y| ≈ 1e-10·4; the sensitivity rows carry 100× the state's
    # tolerance, 1e-8 relative per step. So |S − FD| ≤ 1e-4·max|FD| per parameter (≈ 3e-3
    # here) holds with room; a jump left out is an error of the jump's size, O(max|FD|)
    _, sens = simulate(TRUTH, sensitivities=True, f=f)
    assert sens is not None
    differences = central_differences(TRUTH, 1e-5)
    for j, name in enumerate([*TRUTH, "x0"]):
        scale = np.max(np.abs(differences[:, j]))
        assert scale > 0.5, name  # every parameter (and the initial level) moves the level
        assert np.max(np.abs(sens[:, j] - differences[:, j])) <= 1e-4 * scale, name


def test_without_the_jumps_the_sensitivities_miss_the_switch(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # the same comparison with S left continuous at every switch: the error is of the order
    # of the sensitivities themselves (over 10 % of max|FD|), not of the 1e-4 band above
    monkeypatch.setattr(_Switching, "jump", lambda self, k, t, z, *rest: z)
    _, sens = simulate(TRUTH, sensitivities=True)
    assert sens is not None
    differences = central_differences(TRUTH, 1e-5)
    worst = max(
        np.max(np.abs(sens[:, j] - differences[:, j])) / np.max(np.abs(differences[:, j]))
        for j in range(len(TRUTH))
    )
    assert worst > 0.1


def test_a_fit_recovers_the_switching_level() -> None:
    clean, _ = simulate(TRUTH)
    y = clean + NOISE * np.random.default_rng(7).standard_normal(len(clean))
    estimator = GreyBoxEstimator(tank({"a": 0.26, "b": 0.13, "d": 0.04, "rim": 1.8}))
    estimator.fit([record(y=y)])
    # band: each estimate within 3 standard errors of the truth (a 99.7 % event for each of
    # four; the Cramér–Rao errors are right only if the jumps are: the intervals test them)
    for name, true in TRUTH.items():
        error = abs(estimator.params_[name] - true) / estimator.stderr_[name]
        assert error <= 3.0, (name, estimator.params_[name], estimator.stderr_[name])
    # LSODA at the default tolerance integrates the declared switch: no fallback
    assert estimator.solver_.solver.method == "lsoda"
    assert estimator.solver_.reason == ""


def test_rk4_cannot_locate_a_declared_switch() -> None:
    with pytest.raises(SimulationError, match="rk4 cannot locate"):
        simulate(TRUTH, Solver("rk4", substeps=4))


# --- the model file --------------------------------------------------------------------------


def _write(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "model.py"
    path.write_text(
        'states = ["x"]\nparameters = {"a": 1.0}\n' + body,
        encoding="utf-8",
    )
    return path


def test_the_example_declares_its_switch_and_loads_without_a_warning() -> None:
    mf = read_model_file(EXAMPLES / "overflow_tank_switch.py")
    assert [switch.name for switch in mf.model.switches] == ["above_rim"]
    assert mf.undeclared_switches == ()


def test_an_undeclared_if_on_the_state_is_named_with_its_line(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        "def f(t, x, u, p):\n"
        "    level = max(x[0], 0.0)\n"
        "    rate = -p['a'] * level\n"
        "    if u[0] > 0:  # on the input alone: not a switch of the state\n"
        "        rate += 1.0\n"
        "    if rate > 0 and level > 2.0:\n"
        "        rate = 0.0\n"
        "    return [rate if level < 5 else -1.0]\n",
    )
    messages = read_model_file(path).undeclared_switches
    assert len(messages) == 2
    assert messages[0].startswith(f"{path} line 8: f switches on the state (rate > 0 and level")
    assert "switches = [g]" in messages[0]
    assert "What smoothing costs" in messages[0]
    assert f"{path} line 10:" in messages[1]


def test_declared_switches_are_read_from_a_list_or_a_dict(tmp_path: Path) -> None:
    body = (
        "def high(t, x, u, p):\n    return x[0] - 2.0\n"
        "def f(t, x, u, p, on):\n    return [-p['a'] * x[0] - (1.0 if on['high'] else 0.0)]\n"
    )
    listed = read_model_file(_write(tmp_path, body + "switches = [high]\n"))
    assert [s.name for s in listed.model.switches] == ["high"]
    assert listed.undeclared_switches == ()
    named = read_model_file(_write(tmp_path, body + "switches = {'high': high}\n"))
    assert [s.name for s in named.model.switches] == ["high"]
    # unbound (the loader's check), f takes the modes from the switch's sign at its state
    assert named.model.f(0.0, np.array([3.0]), np.zeros(1), {"a": 1.0}) == [-4.0]
    assert named.model.f(0.0, np.array([1.0]), np.zeros(1), {"a": 1.0}) == [-1.0]


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("def f(t, x, u, p, on):\n    return [0.0]\n", "declares no switches"),
        (
            "def g(t, x, u, p):\n    return x[0]\nswitches = [g]\n"
            "def f(t, x, u, p):\n    return [0.0]\n",
            r"fifth argument, f\(t, x, u, p, on\)",
        ),
        (
            "switches = [lambda t, x, u, p: x[0]]\ndef f(t, x, u, p, on):\n    return [0.0]\n",
            "name each switch",
        ),
        ("switches = 3\ndef f(t, x, u, p, on):\n    return [0.0]\n", "list of functions"),
        (
            "def g(x):\n    return x[0]\nswitches = [g]\ndef f(t, x, u, p, on):\n    return [0]\n",
            r"must take \(t, x, u, p\)",
        ),
    ],
)
def test_malformed_switches_are_refused_with_the_line(
    tmp_path: Path, body: str, message: str
) -> None:
    with pytest.raises(ConfigError, match=message) as caught:
        read_model_file(_write(tmp_path, body))
    assert "line" in str(caught.value)


# --- a solver failing where the fit did not look ---------------------------------------------


def test_a_solver_failing_on_a_validation_record_falls_back_and_says_so(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import fuelid.greybox._estimator as estimator_module

    clean, _ = simulate(TRUTH)
    y = clean + NOISE * np.random.default_rng(7).standard_normal(len(clean))
    estimator = GreyBoxEstimator(tank(dict(TRUTH)))
    estimator.fit([record(y=y)])
    assert estimator.solver_.solver.method == "lsoda"
    expected = estimator.predict(record(y=y))
    real = estimator_module.simulate_record

    def lsoda_fails(*args: Any, **kwargs: Any) -> Any:
        if kwargs["solver"].method == "lsoda":
            raise SimulationError("the ODE solver (lsoda) failed: Excess work done on this call.")
        return real(*args, **kwargs)

    monkeypatch.setattr(estimator_module, "simulate_record", lsoda_fails)
    validation = Record(record().t, record().u, y[:, None], name="validation")
    predicted = estimator.predict(validation)
    # the initial state fitted to the record's head and the record simulated with BDF (auto's
    # next): LSODA's outputs to the solvers' tolerances (1e-6 relative of a level of a few
    # metres, and the head's fit to its own tolerance: 1e-4 m, a hundredth of the noise)
    assert np.max(np.abs(predicted - expected)) <= 1e-4
    assert "lsoda failed at the head of record validation" in estimator.solver_.reason
    assert "lsoda failed at record validation" in estimator.solver_.reason
    assert "fell back to bdf" in estimator.solver_.reason


def test_rk4_asked_for_is_refused_for_what_it_is(tmp_path: Path) -> None:
    clean, _ = simulate(TRUTH)
    estimator = GreyBoxEstimator(tank(dict(TRUTH)), solver="rk4")
    with pytest.raises(ConvergenceError, match="rk4 cannot locate the model's declared switches"):
        estimator.fit([record(y=clean)])
