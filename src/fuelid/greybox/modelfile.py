"""A gray-box model from a plain Python file: states, parameters, f and optionally h, x0.

The file is ordinary Python and is *executed* to read it (only load files you trust)::

    states = ["x1", "x2"]
    parameters = {"k1": (0.05, 0.0, None),           # name: (start, lower, upper); None: unbounded
                  "k2": {"value": 0.04, "lower": 0.0, "fixed": True},
                  "k3": 0.05}                        # a bare number: start, unbounded
    inputs = ["u"]                                   # optional: input column names
    outputs = ["y"]                                  # optional: output names (and columns)

    def f(t, x, u, p):                               # dx/dt; p maps name -> value
        ...

    def h(x, u, p):                                  # optional: measured output(s), default x[0]
        return x[1]

    def x0(p, u0, y0):                               # optional: initial state (or a list
        ...                                          # of numbers, one per state)

A model whose right-hand side jumps where a function of the state changes sign (a valve that
opens above a level) declares that function, and ``f`` takes the switches' modes::

    def above_rim(t, x, u, p):                       # the switch: on where it is > 0
        return x[0] - RIM

    switches = [above_rim]                           # or a dict name -> function

    def f(t, x, u, p, on):                           # on["above_rim"]: True above the rim
        ...

Each switch is then located as a solver event and the sensitivities jump there
(:mod:`fuelid.greybox._switching`). An ``if`` in ``f`` whose test reads the state, undeclared,
is found by reading the file and named with its line (:attr:`ModelFile.undeclared_switches`).

A parameter entry is a number (start, unbounded), a 2-tuple ``(start, lower)``, a 3-tuple
``(start, lower, upper)`` or a dict with ``value`` and optionally ``lower``, ``upper``, ``fixed``
(and ``unit``, ``description``, shown but not used). ``state_scale`` (a typical state size) is
optional, and so are the solver settings ``solver`` (``"auto"``, ``"lsoda"``, ``"bdf"``,
``"radau"``, ``"rk45"`` or ``"rk4"``), ``max_step`` (the longest step [s]) and ``substeps`` (RK4
steps per sample, 1…64), which the command line's ``--solver``, ``--max-step`` and
``--substeps`` override. Other names in the file are the file's own business.

Every error while loading the file becomes a one-line :class:`~fuelid.errors.ConfigError`
naming the file and the line in it. An exception raised later inside ``f``, ``h`` or ``x0``
(during a fit or a simulation) names the line too: a mistake (NameError, KeyError, ...) is a
:class:`ModelFunctionError` (a ConfigError) that stops the fit; an arithmetic failure is a
:class:`ModelArithmeticError` (a :class:`~fuelid.greybox._sensitivity.SimulationError`): the
model cannot be evaluated at that trial point.
"""

from __future__ import annotations

import ast
import importlib.util
import itertools
import math
import sys
import traceback
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import ConfigError, FuelidError
from fuelid.greybox._odemodel import OdeModel
from fuelid.greybox._parameters import ParameterSpec
from fuelid.greybox._solvers import CHOICES, SimulationError, check_max_step, check_substeps
from fuelid.greybox._switch_declaration import declared_switches, undeclared_switches
from fuelid.greybox._switching import Switch

__all__ = [
    "ModelArithmeticError",
    "ModelFile",
    "ModelFunctionError",
    "load_model_file",
    "read_model_file",
]

_ENTRY_KEYS = ("value", "lower", "upper", "fixed")
_INFO_KEYS = ("unit", "description")
_counter = itertools.count()
FloatArray = NDArray[np.float64]


class ModelFunctionError(ConfigError):
    """An exception raised inside the file's f, h or x0; the message names the file's line."""


class ModelArithmeticError(SimulationError):
    """An arithmetic failure inside the file's f, h or x0 (the model cannot be evaluated there).

    The message names the file's line.
    """


class ModelFile:
    """What a model file holds besides the model: its path, input names, parameter units.

    Attributes
    ----------
    path : Path
        The file.
    model : OdeModel
        The model, its functions wrapped so that an exception names the file's line.
    input_names : tuple of str or None
        ``inputs`` of the file (None when it has none).
    output_names : tuple of str or None
        ``outputs`` of the file (None when it has none).
    units : dict
        ``unit`` of the parameter entries that give one.
    has_x0 : bool
        The file defines ``x0``.
    solver : str or None
        ``solver`` of the file (None: not given; the fit's default is ``auto``).
    max_step : float or None
        ``max_step`` of the file [s].
    substeps : int or None
        ``substeps`` of the file (RK4 steps per sample).
    undeclared_switches : tuple of str
        One warning per ``if`` in ``f`` whose test reads the state, naming its line and the
        choice (declare it as a switch, or smooth it at the cost the guide measured).
    """

    def __init__(
        self,
        path: Path,
        model: OdeModel,
        input_names: tuple[str, ...] | None,
        output_names: tuple[str, ...] | None,
        units: dict[str, str],
        has_x0: bool,
        solver: str | None = None,
        max_step: float | None = None,
        substeps: int | None = None,
        undeclared_switches: tuple[str, ...] = (),
    ) -> None:
        self.path = path
        self.undeclared_switches = undeclared_switches
        self.model = model
        self.input_names = input_names
        self.output_names = output_names
        self.units = units
        self.has_x0 = has_x0
        self.solver = solver
        self.max_step = max_step
        self.substeps = substeps

    def check(self, t0: float, u0: FloatArray) -> None:
        """Call ``f`` and ``h`` once at the start values, refusing outputs of the wrong size.

        Parameters
        ----------
        t0 : float
            A record's first time [s].
        u0 : ndarray
            Its first input row.

        Raises
        ------
        ConfigError
            If ``f`` does not return one derivative per state, ``h`` one value per output, or
            either raises (the line in the file is named).
        """
        model = self.model
        n, n_y = len(model.state_names), len(model.output_names)
        x = np.full(n, model.state_scale)
        values = {spec.name: spec.value for spec in model.parameters}
        shown = str(self.path)
        for name, function, args, size, what in (
            (
                "f",
                model.f,
                (t0, x, u0, values),
                n,
                f"{n} state(s) ({', '.join(model.state_names)})",
            ),
            (
                "h",
                model.h,
                (x, u0, values),
                n_y,
                f"{n_y} output(s) ({', '.join(model.output_names)})",
            ),
        ):
            try:
                with np.errstate(all="ignore"):
                    out = np.asarray(function(*args), dtype=float)
            except ModelArithmeticError:
                return  # not evaluable at this state: the fit decides (and names the line)
            except FuelidError:
                raise
            except (TypeError, ValueError) as exc:  # a ragged list, a non-number
                raise ConfigError(
                    f"{shown}: {name} returned what is not a list of numbers ({exc})"
                ) from None
            if out.size != size:
                hint = " (name the outputs: outputs = [...])" if name == "h" else ""
                raise ConfigError(f"{shown}: {name} returned {out.size} value(s) for {what}{hint}")


def load_model_file(path: str | Path) -> OdeModel:
    """Execute a model file and build its :class:`~fuelid.greybox._odemodel.OdeModel`.

    Parameters
    ----------
    path : str or Path
        A Python file of the shape in the module docstring. It runs as Python: only load files
        you trust.

    Returns
    -------
    OdeModel

    Raises
    ------
    ConfigError
        One line naming the file and, where there is one, the line: a missing file, a syntax
        error, an exception while it runs, a missing or malformed ``states``, ``parameters``,
        ``f``, ``h``, ``x0``, ``outputs``, ``inputs``, inconsistent bounds.
    """
    return read_model_file(path).model


def read_model_file(path: str | Path) -> ModelFile:
    """:func:`load_model_file` with the file's extras (input and output names, units)."""
    file = Path(path)
    shown = str(path)
    if not file.is_file():
        raise ConfigError(f"model file {shown} does not exist or is not a file")
    if file.suffix != ".py":
        raise ConfigError(f"model file {shown}: name it .py (it is a Python file)")
    namespace = _execute(file, shown)
    lines = _assignment_lines(file)

    def at(name: str, key: str | None = None) -> str:
        line = lines.get((name, key)) or lines.get((name, None))
        return f"{shown} line {line}" if line else shown

    states = _names(namespace, "states", at, required=True)
    assert states is not None
    outputs = _names(namespace, "outputs", at, required=False)
    inputs = _names(namespace, "inputs", at, required=False)
    specs, units = _parameters(namespace, at)
    f = namespace.get("f")
    if f is None:
        raise ConfigError(f"{shown}: no function f(t, x, u, p) returning dx/dt")
    h = namespace.get("h")
    x0 = _constant_state(namespace.get("x0"), len(states), at)
    for name, value in (("f", f), ("h", h), ("x0", x0)):
        if value is not None and not callable(value):
            raise ConfigError(f"{at(name)}: {name} must be a function")
    state_scale = namespace.get("state_scale", 1.0)
    if (
        isinstance(state_scale, bool)
        or not isinstance(state_scale, int | float)
        or not (math.isfinite(state_scale) and state_scale > 0.0)
    ):
        raise ConfigError(
            f"{at('state_scale')}: state_scale must be a positive number, got {state_scale!r}"
        )
    solver, max_step, substeps = _solver_settings(namespace, at)
    switches = declared_switches(namespace.get("switches"), f, at)
    try:
        model = OdeModel(
            f=_located(f, file, shown, "f"),
            parameters=specs,
            state_names=states,
            h=None if h is None else _located(h, file, shown, "h"),
            x0=None if x0 is None else _located(x0, file, shown, "x0"),
            output_names=outputs,
            n_outputs=1 if outputs is None else len(outputs),
            state_scale=float(state_scale),
            switches=[
                Switch(s.name, _located(s.function, file, shown, f"switch {s.name}"))
                for s in switches
            ],
        )
    except ConfigError as exc:
        raise ConfigError(f"{shown}: {exc}") from None
    return ModelFile(
        file,
        model,
        inputs,
        outputs,
        units,
        x0 is not None,
        solver,
        max_step,
        substeps,
        undeclared_switches(file, shown, f),
    )


def _solver_settings(
    namespace: Mapping[str, Any], at: Callable[..., str]
) -> tuple[str | None, float | None, int | None]:
    """The file's ``solver``, ``max_step`` and ``substeps`` (None where not given), checked."""
    solver = namespace.get("solver")
    max_step = namespace.get("max_step")
    substeps = namespace.get("substeps")
    if solver is not None and (not isinstance(solver, str) or solver not in CHOICES):
        raise ConfigError(
            f"{at('solver')}: solver must be one of {', '.join(CHOICES)}, got {solver!r}"
        )
    for name, value, check in (
        ("max_step", max_step, check_max_step),
        ("substeps", substeps, check_substeps),
    ):
        try:
            check(value)
        except ConfigError as exc:
            raise ConfigError(f"{at(name)}: {exc}") from None
    return solver, None if max_step is None else float(max_step), substeps


# --- running the file ----------------------------------------------------------------------------


def _execute(file: Path, shown: str) -> dict[str, Any]:
    """Run the file as a module of its own; any failure is a ConfigError with the file's line."""
    name = f"fuelid_model_{next(_counter)}"
    spec = importlib.util.spec_from_file_location(name, file)
    if spec is None or spec.loader is None:  # pragma: no cover - a .py file always has a loader
        raise ConfigError(f"model file {shown} cannot be loaded as Python")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses and typing look their module up while it runs
    try:
        spec.loader.exec_module(module)
    except SyntaxError as exc:
        where = f" line {exc.lineno}" if exc.lineno else ""
        raise ConfigError(f"{shown}{where}: SyntaxError: {exc.msg}") from None
    except OSError as exc:
        raise ConfigError(f"cannot read model file {shown}: {exc.strerror or exc}") from None
    except Exception as exc:
        raise ConfigError(_describe(exc, file, shown, "while loading")) from None
    finally:
        sys.modules.pop(name, None)
    return dict(vars(module))


def _line_in_file(exc: BaseException, file: Path) -> int | None:
    """The line of the innermost traceback frame that lies in ``file``."""
    target = str(file.resolve())
    line = None
    for frame in traceback.extract_tb(exc.__traceback__):
        try:
            same = str(Path(frame.filename).resolve()) == target
        except OSError:  # pragma: no cover - an unresolvable frame name is not the file
            same = False
        if same:
            line = frame.lineno
    return line


def _describe(exc: BaseException, file: Path, shown: str, where: str) -> str:
    """``MODEL.py line N: TypeName: message (where)`` on one line."""
    line = _line_in_file(exc, file)
    text = " ".join(str(exc).split()) or "(no message)"
    place = f"{shown} line {line}" if line is not None else shown
    return f"{place}: {type(exc).__name__}: {text} ({where})"


def _located(function: Callable[..., Any], file: Path, shown: str, role: str) -> Callable[..., Any]:
    """``function`` with any exception it raises turned into one that names the file's line.

    An arithmetic failure (ZeroDivisionError, ``math.sqrt`` of a negative: ArithmeticError or
    ValueError) becomes a :class:`ModelArithmeticError`, a
    :class:`~fuelid.greybox._sensitivity.SimulationError`: the estimator treats the trial point
    as one where the model cannot be simulated (and reports it, line included, if that is the
    start). Any other exception (a NameError, KeyError, TypeError: a mistake in the file) is a
    :class:`ModelFunctionError` and stops the fit. Both are ValueErrors, so the estimator's
    probe of whether ``f`` takes a batch of states still falls back to scalar calls when a batch
    call fails.
    """

    def call(*args: Any) -> Any:
        try:
            return function(*args)
        except FuelidError as exc:
            if _line_in_file(exc, file) is None:
                raise
            raise ModelFunctionError(_describe(exc, file, shown, f"raised in {role}")) from None
        except (ArithmeticError, ValueError) as exc:
            raise ModelArithmeticError(_describe(exc, file, shown, f"raised in {role}")) from None
        except Exception as exc:
            raise ModelFunctionError(_describe(exc, file, shown, f"raised in {role}")) from None

    call.__name__ = getattr(function, "__name__", role)
    call.__doc__ = getattr(function, "__doc__", None)
    call.__wrapped__ = function  # type: ignore[attr-defined]  # (the fast path calls it directly)
    return call


# --- reading what it defines ---------------------------------------------------------------------


def _assignment_lines(file: Path) -> dict[tuple[str, str | None], int]:
    """Line of each top-level name's definition, and of each key of a dict literal assigned."""
    try:
        tree = ast.parse(file.read_text(encoding="utf-8"))
    except (SyntaxError, ValueError, OSError, UnicodeDecodeError):  # it ran, so this is rare
        return {}
    lines: dict[tuple[str, str | None], int] = {}
    for node in tree.body:
        targets: list[ast.expr] = []
        value: ast.expr | None = None
        if isinstance(node, ast.Assign):
            targets, value = list(node.targets), node.value
        elif isinstance(node, ast.AnnAssign):
            targets, value = [node.target], node.value
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            lines[(node.name, None)] = node.lineno
            continue
        for target in targets:
            if not isinstance(target, ast.Name):
                continue
            lines[(target.id, None)] = node.lineno
            if isinstance(value, ast.Dict):
                for key in value.keys:
                    if isinstance(key, ast.Constant) and isinstance(key.value, str):
                        lines[(target.id, key.value)] = key.lineno
    return lines


def _constant_state(value: Any, n_states: int, at: Callable[..., str]) -> Any:
    """``x0 = [1.0, 0.5]`` (numbers, one per state) as the function x0(p, u0, y0)."""
    if callable(value) or not isinstance(value, list | tuple):
        return value
    if len(value) != n_states or not all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value
    ):
        raise ConfigError(
            f"{at('x0')}: x0 must be a function x0(p, u0, y0) or {n_states} finite numbers, one "
            f"per state, got {value!r}"
        )
    state = [float(v) for v in value]

    def constant(p: Any, u0: Any, y0: Any) -> list[float]:
        return list(state)

    return constant


def _names(
    namespace: Mapping[str, Any], key: str, at: Callable[..., str], *, required: bool
) -> tuple[str, ...] | None:
    """A list of unique, non-empty names (``states``, ``outputs``, ``inputs``)."""
    if key not in namespace or namespace[key] is None:
        if required:
            raise ConfigError(f'{at(key)}: no {key} list (e.g. {key} = ["x1", "x2"])')
        return None
    value = namespace[key]
    if isinstance(value, str) or not isinstance(value, list | tuple):
        raise ConfigError(f"{at(key)}: {key} must be a list of names, got {value!r}")
    if not value:
        raise ConfigError(f"{at(key)}: {key} is empty")
    for name in value:
        if not isinstance(name, str) or not name.strip():
            raise ConfigError(f"{at(key)}: {key} must hold names (text), got {name!r}")
    if len(set(value)) != len(value):
        raise ConfigError(f"{at(key)}: {key} repeat a name: {', '.join(value)}")
    return tuple(value)


def _parameters(
    namespace: Mapping[str, Any], at: Callable[..., str]
) -> tuple[list[ParameterSpec], dict[str, str]]:
    """The ``parameters`` dict as ParameterSpecs, and the units its entries give."""
    entries = namespace.get("parameters")
    if entries is None:
        raise ConfigError(
            f"{at('parameters')}: no parameters dict (e.g. parameters = "
            '{"k1": (0.05, 0.0, None)})'
        )
    if not isinstance(entries, Mapping):
        raise ConfigError(
            f"{at('parameters')}: parameters must be a dict name -> (start, lower, upper), got "
            f"{type(entries).__name__}"
        )
    if not entries:
        raise ConfigError(f"{at('parameters')}: parameters is empty")
    specs: list[ParameterSpec] = []
    units: dict[str, str] = {}
    for name, entry in entries.items():
        where = at("parameters", name) if isinstance(name, str) else at("parameters")
        if not isinstance(name, str) or not name.isidentifier():
            raise ConfigError(f"{where}: parameter name {name!r} is not an identifier")
        try:
            spec, unit = _parameter(name, entry)
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        specs.append(spec)
        if unit:
            units[name] = unit
    return specs, units


def _number(name: str, what: str, value: Any, optional: bool) -> float | None:
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"parameter {name}: {what} must be a number, got {value!r}")
    return float(value)


def _parameter(name: str, entry: Any) -> tuple[ParameterSpec, str]:
    """One entry: a number, (start, lower), (start, lower, upper) or a dict."""
    forms = (
        "give a number, (start, lower), (start, lower, upper) or "
        '{"value": ..., "lower": ..., "upper": ..., "fixed": ...}'
    )
    fixed = False
    unit = ""
    if isinstance(entry, Mapping):
        unknown = [key for key in entry if key not in _ENTRY_KEYS + _INFO_KEYS]
        if unknown:
            raise ConfigError(
                f"parameter {name}: unknown key(s) {', '.join(map(repr, unknown))}; valid: "
                f"{', '.join(_ENTRY_KEYS + _INFO_KEYS)}"
            )
        if "value" not in entry:
            raise ConfigError(f'parameter {name}: the dict needs a "value" (its start value)')
        value = _number(name, "value", entry["value"], optional=False)
        lower = _number(name, "lower", entry.get("lower"), optional=True)
        upper = _number(name, "upper", entry.get("upper"), optional=True)
        fixed_value = entry.get("fixed", False)
        if not isinstance(fixed_value, bool):
            raise ConfigError(f"parameter {name}: fixed must be True or False, got {fixed_value!r}")
        fixed = fixed_value
        unit = str(entry.get("unit", "") or "")
    elif isinstance(entry, tuple | list):
        if len(entry) not in (2, 3):
            raise ConfigError(f"parameter {name}: {len(entry)} values in {entry!r}; {forms}")
        value = _number(name, "the start value", entry[0], optional=False)
        lower = _number(name, "the lower bound", entry[1], optional=True)
        upper = (
            _number(name, "the upper bound", entry[2], optional=True) if len(entry) == 3 else None
        )
    else:
        value = _number(name, "its value", entry, optional=False)
        lower = upper = None
    assert value is not None
    return ParameterSpec(name, value, lower, upper, fixed), unit
