"""PLC links behind one interface, :class:`PlcSource`.

Each protocol is an optional extra (``pip install 'fuelid[plc]'``), imported only when a site
file names it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from fuelid.errors import ConfigError
from fuelid.plc.adapters._base import EndOfSource, LinkError, PlcSource, Reading, RingRecord
from fuelid.plc.site import SiteConfig

if TYPE_CHECKING:
    from fuelid.plc.adapters._modbus import ModbusSource
    from fuelid.plc.adapters._opcua import OpcUaSource
    from fuelid.plc.adapters._replay import ReplaySource
    from fuelid.plc.adapters._s7 import S7Source

__all__ = [
    "ADAPTERS",
    "EndOfSource",
    "LinkError",
    "ModbusSource",
    "OpcUaSource",
    "PlcSource",
    "Reading",
    "ReplaySource",
    "RingRecord",
    "S7Source",
    "open_source",
]

ADAPTERS = {
    "modbus": ("fuelid.plc.adapters._modbus", "ModbusSource", "pymodbus"),
    "opcua": ("fuelid.plc.adapters._opcua", "OpcUaSource", "asyncua"),
    "s7": ("fuelid.plc.adapters._s7", "S7Source", "snap7"),
    "replay": ("fuelid.plc.adapters._replay", "ReplaySource", None),
}
"""Protocol → (module, class, the third-party package it needs)."""


def open_source(site: SiteConfig) -> PlcSource:
    """The adapter for the site's protocol (not yet connected).

    Raises
    ------
    ConfigError
        The protocol's extra is not installed (the message says how to install it).
    """
    module_name, class_name, package = ADAPTERS[site.plc.protocol]
    if package is not None:
        try:
            importlib.import_module(package)
        except ImportError:
            raise ConfigError(
                f"plc.protocol = {site.plc.protocol!r} needs the {package} package: "
                "pip install 'fuelid[plc]'"
            ) from None
    module = importlib.import_module(module_name)
    source: PlcSource = getattr(module, class_name)(site)
    return source


def __getattr__(name: str) -> Any:
    # an adapter class on first use: importing it loads its protocol's library
    for module_name, class_name, _ in ADAPTERS.values():
        if name == class_name:
            return getattr(importlib.import_module(module_name), class_name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
