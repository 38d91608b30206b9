"""No import cycles between fuelid's modules: no module imports one that imports it back.

The graph is grimp's (the library import-linter stands on), built from the source: every
``import`` and ``from … import`` of a fuelid module, at module level or inside a function, under
``if TYPE_CHECKING:`` too (a cycle through type hints is still two modules that cannot be
understood, or moved, apart). A module ``m`` that imports ``i`` directly lies in a cycle when
``i`` reaches ``m`` back through any chain of imports; the failure prints each such chain.

When it fails, move what the two modules share to its one proper home (often the cycle is a
re-export in one direction), rather than hiding the import inside a function.
"""

from __future__ import annotations

import grimp
import pytest


@pytest.fixture(scope="module")
def graph() -> grimp.ImportGraph:
    return grimp.build_graph("fuelid", include_external_packages=False)


def _cycles(graph: grimp.ImportGraph) -> dict[tuple[str, str], list[str]]:
    """Each pair of modules in a cycle → the chain that closes it (``m`` → ``i`` → … → ``m``)."""
    found: dict[tuple[str, str], list[str]] = {}
    for module in sorted(graph.modules):
        for imported in sorted(graph.find_modules_directly_imported_by(module)):
            pair = (min(module, imported), max(module, imported))
            if pair in found or not graph.chain_exists(importer=imported, imported=module):
                continue
            back = graph.find_shortest_chain(importer=imported, imported=module) or ()
            found[pair] = [module, *back]
    return found


def test_the_graph_holds_the_whole_package(graph: grimp.ImportGraph) -> None:
    # a guard against a vacuous pass: the graph is fuelid's, with its layers and their imports
    assert {"fuelid.cli", "fuelid.identify._procedure", "fuelid.store._sqlite"} <= graph.modules
    assert graph.chain_exists(importer="fuelid.cli._identify", imported="fuelid.units")


def test_no_two_fuelid_modules_import_each_other(graph: grimp.ImportGraph) -> None:
    cycles = _cycles(graph)
    # one wrong import puts many pairs in cycles: the shortest chains show it first
    shortest = sorted(cycles.values(), key=len)[:10]
    chains = "\n".join(" -> ".join(chain) for chain in shortest)
    assert not cycles, f"{len(cycles)} module pairs in import cycles; the shortest:\n{chains}"
