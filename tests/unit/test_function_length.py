"""No function of fuelid has a body over 100 lines: a reader can hold each one.

The body is measured from its first statement after the docstring to its last line, nested
functions included (a long function that hides its length in inner functions is still long).
ruff's complexity rules (C901, PLR0912, PLR0915 in pyproject.toml) bound the branches and
statements; this bounds what neither counts: long straight-line code and long literals.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "fuelid"
LONGEST_BODY = 100


def _body_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    body = node.body
    first = body[0]
    if (
        isinstance(first, ast.Expr)
        and isinstance(first.value, ast.Constant)
        and isinstance(first.value.value, str)
        and len(body) > 1
    ):
        body = body[1:]  # the docstring is documentation, not length to hold
    end = body[-1].end_lineno or body[-1].lineno
    return end - body[0].lineno + 1


def _long_functions() -> list[str]:
    long = []
    for path in sorted(SRC.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = _body_lines(node)
                if lines > LONGEST_BODY:
                    where = path.relative_to(SRC.parent)
                    long.append(f"{where}:{node.lineno} {node.name}: {lines} lines")
    return long


def test_no_function_body_is_over_100_lines() -> None:
    assert _long_functions() == []


def test_the_measure_counts_from_the_first_statement_after_the_docstring() -> None:
    source = 'def f():\n    """Doc.\n\n    More.\n    """\n    a = 1\n\n    return a\n'
    (node,) = ast.parse(source).body
    assert isinstance(node, ast.FunctionDef)
    assert _body_lines(node) == 3
