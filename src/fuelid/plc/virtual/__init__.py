"""The virtual PLC: the nonlinear fuel loop with its PLC emulated, on real protocol servers.

The public API
--------------
The names in ``__all__`` (:class:`VirtualPLC`, the server thread and its runner), each loaded on
first use: a protocol's server library loads only when that protocol is served.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

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

_HOMES = {
    "DEFAULT_PORTS": "fuelid.plc.virtual._runner",
    "ReplyTiming": "fuelid.plc.virtual._frontend",
    "VirtualPLC": "fuelid.plc.virtual._engine",
    "VirtualPlcThread": "fuelid.plc.virtual._runner",
    "frontend_class": "fuelid.plc.virtual._runner",
    "frontend_kwargs": "fuelid.plc.virtual._runner",
    "serve_until_stopped": "fuelid.plc.virtual._runner",
    "site_text": "fuelid.plc.virtual._sitefile",
}
"""Exported name → the private module that defines it, imported on first use (PEP 562)."""

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


def __getattr__(name: str) -> Any:
    # imported on use: importing the package loads none of its modules
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
