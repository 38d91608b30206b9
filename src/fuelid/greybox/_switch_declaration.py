"""A model file's switches: the declared ones read and checked, the undeclared ``if`` found.

``switches = [g1, g2]`` (functions, named by their ``def``) or ``{"name": g}`` declares the
functions whose sign switches f (:mod:`fuelid.greybox._switching`); f then takes ``on`` as a
fifth argument. An ``if`` (or ``a if test else b``, or ``while``) in f whose test reads the state,
directly or through a variable computed from it, is a switch the solvers and the sensitivities
cannot see: the file is read (not run again) to name its line.
"""

from __future__ import annotations

import ast
import inspect
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from fuelid.errors import ConfigError
from fuelid.greybox._switching import Switch

__all__ = ["declared_switches", "undeclared_switches"]

_GUIDE = "the gray-box guide, 'Declared switches'"


def _positional(function: Callable[..., Any]) -> int | None:
    """How many positional arguments ``function`` takes (None: any number, *args)."""
    try:
        signature = inspect.signature(function)
    except (TypeError, ValueError):
        return None
    count = 0
    for parameter in signature.parameters.values():
        if parameter.kind is inspect.Parameter.VAR_POSITIONAL:
            return None
        if parameter.kind in (
            inspect.Parameter.POSITIONAL_ONLY,
            inspect.Parameter.POSITIONAL_OR_KEYWORD,
        ):
            count += 1
    return count


def declared_switches(value: Any, f: Callable[..., Any], at: Callable[..., str]) -> list[Switch]:
    """The file's ``switches`` as :class:`Switch` es, checked against f's arguments.

    Raises
    ------
    ConfigError
        A switch that is not a function, a nameless one (a lambda in a list), a name repeated,
        or f taking a fifth argument without switches (or four with them).
    """
    arguments = _positional(f)
    if value is None:
        if arguments == 5:
            raise ConfigError(
                f"{at('f')}: f takes a fifth argument (the switches' modes) but the file "
                "declares no switches = [...]"
            )
        return []
    if isinstance(value, Mapping):
        entries = list(value.items())
    elif isinstance(value, list | tuple):
        entries = [(getattr(item, "__name__", None), item) for item in value]
    else:
        raise ConfigError(
            f"{at('switches')}: switches must be a list of functions g(t, x, u, p) or a dict "
            f"name -> function, got {type(value).__name__}"
        )
    if not entries:
        raise ConfigError(f"{at('switches')}: switches is empty")
    switches: list[Switch] = []
    for name, function in entries:
        if not callable(function):
            raise ConfigError(f"{at('switches')}: switch {name!r} is not a function g(t, x, u, p)")
        if not isinstance(name, str) or not name.isidentifier() or name == "<lambda>":
            raise ConfigError(
                f"{at('switches')}: name each switch: a def, or a dict name -> function "
                f"(got {name!r})"
            )
        if _positional(function) not in (None, 4):
            raise ConfigError(f"{at('switches')}: switch {name} must take (t, x, u, p)")
        switches.append(Switch(name, function))
    names = [switch.name for switch in switches]
    if len(set(names)) != len(names):
        raise ConfigError(f"{at('switches')}: switch names repeat: {', '.join(names)}")
    if arguments not in (None, 5):
        raise ConfigError(
            f"{at('f')}: the file declares switches ({', '.join(names)}): f takes their modes "
            "as a fifth argument, f(t, x, u, p, on), and branches on on[name]"
        )
    return switches


def undeclared_switches(file: Path, shown: str, f: Callable[..., Any]) -> tuple[str, ...]:
    """One warning per ``if`` in f whose test reads the state (empty when f has none).

    The state is f's second argument; a variable assigned from an expression that reads it
    reads it too (``x1 = max(x[0], 0.0)``, ``dx1 = ... x1 ...``). The modes (``on``) do not.
    """
    node = _definition(file, f)
    if node is None:
        return ()
    arguments = [argument.arg for argument in node.args.posonlyargs + node.args.args]
    if len(arguments) < 2:
        return ()
    source = file.read_text(encoding="utf-8")
    state = _tainted(node, {arguments[1]})
    found = []
    for branch in ast.walk(node):
        if isinstance(branch, ast.If | ast.IfExp | ast.While) and _reads(branch.test, state):
            test = ast.get_source_segment(source, branch.test) or "..."
            found.append(
                f"{shown} line {branch.lineno}: f switches on the state ({test}), which the "
                "solvers step across blindly and the sensitivities miss (a refusal 'the outputs "
                "do not depend on ...', wrong intervals, a solver's 'Excess work'): declare it "
                "(a function g(t, x, u, p) positive where the branch is taken, switches = [g], "
                f"and f(t, x, u, p, on) branching on on['g']: {_GUIDE}), or smooth it, which "
                "biases the estimates (a dump valve smoothed over 1 % of its level: up to 7.6 "
                "standard errors, the guide's 'What smoothing costs')"
            )
    return tuple(found)


def _definition(file: Path, f: Callable[..., Any]) -> ast.FunctionDef | None:
    """The ``def`` of f in the file (None: f is defined elsewhere, or the file does not parse)."""
    code = getattr(f, "__code__", None)
    if code is None:
        return None
    try:
        if Path(code.co_filename).resolve() != file.resolve():
            return None
        tree = ast.parse(file.read_text(encoding="utf-8"))
    except (OSError, SyntaxError, ValueError, UnicodeDecodeError):
        return None
    for node in ast.walk(tree):
        # the def line (decorators move co_firstlineno to the first of them)
        if isinstance(node, ast.FunctionDef) and (
            node.lineno == code.co_firstlineno
            or any(decorator.lineno == code.co_firstlineno for decorator in node.decorator_list)
        ):
            return node
    return None


def _reads(expression: ast.AST, names: set[str]) -> bool:
    return any(isinstance(node, ast.Name) and node.id in names for node in ast.walk(expression))


def _targets(node: ast.AST) -> list[str]:
    """The names an assignment binds."""
    if isinstance(node, ast.Assign):
        targets: list[ast.AST] = list(node.targets)
    elif isinstance(node, ast.AugAssign | ast.AnnAssign | ast.For | ast.NamedExpr):
        targets = [node.target]
    else:
        return []
    return [n.id for target in targets for n in ast.walk(target) if isinstance(n, ast.Name)]


def _tainted(function: ast.FunctionDef, state: set[str]) -> set[str]:
    """The state's name and every variable computed from it (to a fixed point)."""
    names = set(state)
    while True:
        grown = set(names)
        for node in ast.walk(function):
            value = getattr(node, "iter", None) if isinstance(node, ast.For) else None
            if value is None:
                value = getattr(node, "value", None)
            if isinstance(node, ast.AugAssign) and _reads(node.target, names):
                continue
            if value is not None and _targets(node) and _reads(value, names):
                grown.update(_targets(node))
        if grown == names:
            return names
        names = grown
