"""One serialiser name: every result object gives its JSON form by ``to_json()`` (0.2.0).

The 0.1 names ``to_dict()`` (online, store) and ``as_dict()`` (model, tuning) stay for one minor
version as aliases: each warns once with a DeprecationWarning naming the new method and returns
exactly what ``to_json()`` returns.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from fuelid.model import ProcessModel
from fuelid.online.gains import Gains

SRC = Path(__file__).resolve().parents[2] / "src" / "fuelid"


def test_no_result_object_defines_another_serialiser_name() -> None:
    """Every ``to_dict``/``as_dict`` left in src is the deprecated alias, beside a ``to_json``."""
    for path in SRC.rglob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):
            methods = {f.name: f for f in cls.body if isinstance(f, ast.FunctionDef)}
            for old in ("to_dict", "as_dict"):
                if old not in methods:
                    continue
                assert "to_json" in methods, f"{path.name}: {cls.name}.{old} without to_json"
                body = ast.unparse(methods[old])
                assert "warn_renamed" in body, f"{path.name}: {cls.name}.{old} is not the alias"


@pytest.mark.parametrize(
    ("obj", "old"),
    [
        (ProcessModel(K=13.1, T=1.2, delay=0.3), "as_dict"),
        (Gains(0.05, 2.0), "to_dict"),
    ],
)
def test_the_old_name_warns_and_returns_the_json_form(obj: object, old: str) -> None:
    with pytest.warns(DeprecationWarning, match=rf"{type(obj).__name__}\.{old}\(\) is renamed"):
        value = getattr(obj, old)()
    assert value == obj.to_json()  # type: ignore[attr-defined]
