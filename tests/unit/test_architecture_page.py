"""The architecture page (docs/explanation/architecture.md) against the code it describes.

The page's layer diagram is checked three ways, so that it cannot drift from the code: it lists
the same layers, in the same order, as the import-linter contract that `make test` enforces; the
import graph itself (built here with grimp, independently of import-linter) has no import that
points up the diagram or across two siblings of one layer; and every module of ``src/fuelid``
stands in the diagram. The module table's file names must exist where the table puts them.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import grimp
import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "explanation" / "architecture.md"
SRC = ROOT / "src" / "fuelid"


def _page() -> str:
    return PAGE.read_text(encoding="utf-8")


def _diagram_layers() -> list[list[str]]:
    """The diagram: the ```text block under "Layers, top to bottom", one layer a line."""
    match = re.search(r"## Layers, top to bottom\n.*?```text\n(.*?)```", _page(), re.S)
    assert match, "the page has no ```text layer diagram under '## Layers, top to bottom'"
    layers = []
    for line in match.group(1).splitlines():
        names = line.split("#", 1)[0].strip()  # a comment after # explains the layer
        if names:
            layers.append([name.strip() for name in names.split("|")])
    return layers


def _contract_layers() -> list[list[str]]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    contracts = config["tool"]["importlinter"]["contracts"]
    (layered,) = [c for c in contracts if c["type"] == "layers"]
    return [[name.strip() for name in layer.split("|")] for layer in layered["layers"]]


def _top_level_names() -> set[str]:
    """Every module and package directly under src/fuelid (what the layers must cover)."""
    names = {p.stem for p in SRC.glob("*.py") if p.stem != "__init__"}
    names |= {p.parent.name for p in SRC.glob("*/__init__.py")}
    return names


def test_the_diagram_is_the_contract_import_linter_enforces() -> None:
    assert _diagram_layers() == _contract_layers()


def test_every_module_of_fuelid_stands_in_the_diagram() -> None:
    placed = {name for layer in _diagram_layers() for name in layer}
    assert _top_level_names() - placed == set(), "modules the page does not place"
    assert placed - _top_level_names() == set(), "the page places modules that do not exist"


def test_no_import_points_up_the_diagram_or_across_siblings() -> None:
    rank = {name: i for i, layer in enumerate(_diagram_layers()) for name in layer}
    graph = grimp.build_graph("fuelid")
    wrong = []
    for importer in graph.modules:
        for imported in graph.find_modules_directly_imported_by(importer):
            if not imported.startswith("fuelid."):
                continue
            upper, lower = importer.split(".")[1:2], imported.split(".")[1]
            if not upper or upper[0] == lower:
                continue  # fuelid/__init__.py, or inside one top-level package
            # a lower rank is higher on the page: the importer must rank strictly above
            if rank[upper[0]] >= rank[lower]:
                wrong.append(f"{importer} imports {imported}")
    assert wrong == []


MODULE_ROW = re.compile(r"^\|[^|]*\| `([a-z_]+)/?` \|(.*)\|$", re.M)


@pytest.mark.parametrize(
    "package", sorted(p.parent.name for p in SRC.glob("*/__init__.py")), ids=str
)
def test_the_files_the_table_names_exist(package: str) -> None:
    rows = {m.group(1): m.group(2) for m in MODULE_ROW.finditer(_page())}
    assert package in rows, f"the module table has no row for {package}/"
    # a path (`virtual/engine.py`, `cli/_common.py`) from the package, a bare name anywhere in it
    named = set(re.findall(r"`([a-z0-9_/]+\.py)`", rows[package]))
    missing = sorted(
        name
        for name in named
        if not (SRC / package / name.removeprefix(f"{package}/")).exists()
        and ("/" in name or not any((SRC / package).rglob(name)))
    )
    assert missing == [], f"{package}/: the page names files that do not exist"
