"""Excitation on demand (issue 40): a test signal the PLC adds to its PI output.

The online service designs the signal from the loop's model and noise, with its expected
standard errors and its cost, and runs it (``_design.py``, ``_cost.py``, ``_exciter.py``).
What a reader sees of a run: the exciter's record in the store's ``online_state`` under
:data:`STATE_KEY`, a person's start or stop under :data:`REQUEST_KEY`, and
:func:`excitation_line`, where the run stands in one line (:data:`INTERRUPTED` for a burst a
killed service left running).

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
