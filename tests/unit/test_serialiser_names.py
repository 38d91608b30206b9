"""One serialiser name: every result object gives its JSON form by ``to_json()``.

0.1 also had ``to_dict()`` (online, store) and ``as_dict()`` (model, tuning); 0.2.0 kept them as
deprecated aliases and 0.3.0 removed them, so a result object defines ``to_json`` and no other.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "fuelid"


def test_no_result_object_defines_another_serialiser_name() -> None:
    found = []
    for path in SRC.rglob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):
            names = {f.name for f in cls.body if isinstance(f, ast.FunctionDef)}
            found += [
                f"{path.name}: {cls.name}.{old}" for old in ("to_dict", "as_dict") if old in names
            ]
    assert not found, found
