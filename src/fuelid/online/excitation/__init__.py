"""Excitation on demand (issue 40): a test signal the PLC adds to its PI output.

``_design.py`` designs the signal from the loop's model and noise, with its expected standard
errors and its cost (``_cost.py``); ``_exciter.py`` runs it beside the service; ``_status.py``
says where a run stands.

The public API
--------------
The names in ``__all__``: what the dashboard shows of a run.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from fuelid.online.excitation._status import INTERRUPTED, STATE_KEY, excitation_line

if TYPE_CHECKING:
    from fuelid.online.excitation._exciter import REQUEST_KEY

_HOMES = {"REQUEST_KEY": "fuelid.online.excitation._exciter"}
"""Names imported on first use: the exciter imports the service's context, which imports this
package (the window reads the excitation's status)."""

__all__ = [
    "INTERRUPTED",
    "REQUEST_KEY",
    "STATE_KEY",
    "excitation_line",
]


def __getattr__(name: str) -> Any:
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
