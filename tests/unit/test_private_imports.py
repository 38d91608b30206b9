"""No import of a private name from outside the package that owns it.

fuelid promises the names its packages export (``__all__``) and the module paths
tests/unit/test_public_api.py lists; every other module is private (``identify/_oe.py``) and may
move without notice. So a module path or a name with a leading underscore (not a dunder) is
imported only from inside its owner, the top-level package it sits in (``fuelid.online``'s
modules may import ``fuelid.online._window`` and ``fuelid.online.gates._prefit``):

- in ``src/``, a module's package is its top-level package (``fuelid/cli/online/_run.py`` is in
  ``fuelid.cli``); other packages are reached through their surface
  (``from fuelid.identify import OutputError``);
- in ``tests/``, a test under ``tests/unit/<package>/`` or ``tests/integration/<package>/`` is
  inside ``fuelid.<package>`` (it may test its internals); the system tests, the support
  helpers, the conftest files and the cross-cutting checks in ``tests/unit/`` use public names
  only.

Every ``import`` and ``from … import`` counts, at module level or inside a function. The failure
lists each import as file:line.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src"
TESTS = ROOT / "tests"
PACKAGE_FOLDERS = ("unit", "integration")
"""Test folders whose subfolders are named after the package they test."""


def _private(part: str) -> bool:
    return part.startswith("_") and not part.startswith("__")


def _imported_paths(tree: ast.Module) -> Iterator[tuple[int, str]]:
    """(line, dotted path) of every absolute import of fuelid: ``m.n`` for ``from m import n``."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                yield node.lineno, f"{node.module}.{alias.name}"


def _owner(path: str) -> str | None:
    """The top-level package that owns a private path (``fuelid.plc``), None for a public one."""
    parts = path.split(".")
    if parts[0] != "fuelid" or not any(_private(p) for p in parts[1:]):
        return None
    return ".".join(parts[:2])


def _inside(file: Path) -> str | None:
    """The top-level package ``file`` is inside, None for code outside every package."""
    if file.is_relative_to(SRC):
        parts = file.relative_to(SRC).with_suffix("").parts
        return ".".join(parts[:2])  # fuelid.cli for fuelid/cli/online/_run.py
    parts = file.relative_to(TESTS).parts
    if len(parts) > 2 and parts[0] in PACKAGE_FOLDERS:
        return f"fuelid.{parts[1]}"
    return None


def _private_imports() -> tuple[list[str], int]:
    """Imports of a private path from outside its owner (file:line), and the allowed ones."""
    wrong, allowed = [], 0
    for file in sorted([*SRC.rglob("*.py"), *TESTS.rglob("*.py")]):
        inside = _inside(file)
        for line, path in _imported_paths(ast.parse(file.read_text(encoding="utf-8"))):
            owner = _owner(path)
            if owner is None:
                continue
            if owner == inside:
                allowed += 1
            else:
                wrong.append(f"{file.relative_to(ROOT)}:{line}: {path}")
    return wrong, allowed


def test_the_owner_of_a_private_path_is_its_top_level_package() -> None:
    assert _owner("fuelid.plc.adapters._s7.S7Source") == "fuelid.plc"
    assert _owner("fuelid.model._settling_time") == "fuelid.model"
    assert _owner("fuelid.identify.OutputError") is None
    assert _owner("fuelid.__version__") is None
    assert _inside(SRC / "fuelid/cli/online/_run.py") == "fuelid.cli"
    assert _inside(SRC / "fuelid/model.py") == "fuelid.model"
    assert _inside(TESTS / "unit/identify/test_oe.py") == "fuelid.identify"
    assert _inside(TESTS / "unit/test_public_api.py") is None
    assert _inside(TESTS / "system/test_cli.py") is None


def test_no_private_name_is_imported_from_outside_its_package() -> None:
    wrong, allowed = _private_imports()
    # a guard against a vacuous pass: the packages do import their own private modules
    assert allowed > 500
    assert wrong == [], f"{len(wrong)} imports of private names from outside their package"


@pytest.mark.parametrize("folder", PACKAGE_FOLDERS)
def test_a_test_folder_is_named_after_a_package(folder: str) -> None:
    packages = {p.stem for p in (SRC / "fuelid").iterdir() if p.suffix == ".py" or p.is_dir()}
    named = {p.name for p in (TESTS / folder).iterdir() if p.is_dir() and p.name != "__pycache__"}
    assert named - packages == set(), "test folders named after no fuelid package"
