"""Excitation on demand (issue 40): a test signal the PLC adds to its PI output.

``_design.py`` designs the signal from the loop's model and noise, with its expected standard
errors and its cost (``_cost.py``); ``_exciter.py`` runs it beside the service; ``_status.py``
says where a run stands.

The public API
--------------
The names in ``__all__``: what the dashboard shows of a run.
"""

from __future__ import annotations

from fuelid.online.excitation._status import INTERRUPTED, excitation_line

__all__ = [
    "INTERRUPTED",
    "excitation_line",
]
