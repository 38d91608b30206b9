"""The virtual PLC: the nonlinear fuel loop with its PLC emulated, on real protocol servers.

The public API
--------------
The names in ``__all__`` (:class:`VirtualPLC`, the server thread and its runner), each loaded on
first use: a protocol's server library loads only when that protocol is served.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

if TYPE_CHECKING:
    from fuelid.plc.virtual._engine import VirtualPLC
    from fuelid.plc.virtual._frontend import ReplyTiming
    from fuelid.plc.virtual._runner import (
        DEFAULT_PORTS,
        VirtualPlcThread,
        frontend_class,
        frontend_kwargs,
        serve_until_stopped,
    )
    from fuelid.plc.virtual._sitefile import site_text

# Each name is imported from its private module on first use (lazy_loader, SPEC 1), so
# that importing the package stays cheap.
__getattr__ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "_engine": ["VirtualPLC"],
        "_frontend": ["ReplyTiming"],
        "_runner": [
            "DEFAULT_PORTS",
            "VirtualPlcThread",
            "frontend_class",
            "frontend_kwargs",
            "serve_until_stopped",
        ],
        "_sitefile": ["site_text"],
    },
)[0]

__all__ = [
    "DEFAULT_PORTS",
    "ReplyTiming",
    "VirtualPLC",
    "VirtualPlcThread",
    "frontend_class",
    "frontend_kwargs",
    "serve_until_stopped",
    "site_text",
]
