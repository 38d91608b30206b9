"""Excitation on demand (issue 40): a test signal the PLC adds to its PI output.

``_design.py`` designs the signal from the loop's model and noise, with its expected standard
errors and its cost (``_cost.py``); ``_exciter.py`` runs it beside the service; ``_status.py``
says where a run stands.

The public API
--------------
The names in ``__all__``: what the dashboard shows of a run.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

from fuelid.online.excitation._status import INTERRUPTED, STATE_KEY, excitation_line

if TYPE_CHECKING:
    from fuelid.online.excitation._exciter import REQUEST_KEY

# Each name is imported from its private module on first use (lazy_loader, SPEC 1), so
# that importing the package stays cheap.
__getattr__ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "_exciter": ["REQUEST_KEY"],
    },
)[0]

__all__ = [
    "INTERRUPTED",
    "REQUEST_KEY",
    "STATE_KEY",
    "excitation_line",
]
