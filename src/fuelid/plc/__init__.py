"""The PLC link: the site file, the register codec, the adapters, the recorder, the virtual PLC.

- :mod:`~fuelid.plc.site`: a site file read and validated (:func:`~fuelid.plc.site.load_site`);
- :mod:`~fuelid.plc._codec`: values packed into 16-bit registers and back;
- :mod:`~fuelid.plc.adapters`: the protocol links behind one interface
  (:class:`~fuelid.plc.adapters.PlcSource`, :func:`~fuelid.plc.adapters.open_source`);
- :mod:`~fuelid.plc._quality`: the quality checks of a sample (range, stuck readings);
- :mod:`~fuelid.plc._recorder`: samples from a source into the store (``fuelid record``);
- :mod:`~fuelid.plc.virtual`: the nonlinear fuel loop with its PLC emulated, on real protocol
  servers (``fuelid plant serve``); its run profiles are :mod:`fuelid.profiles.runs`.

Nothing here is imported by the computation layers.

The public API
--------------
The names in ``__all__`` (the recorder, the gain handshake, the quality limits, the site file's
``[archive]`` and ``[central]`` tables), each loaded on first use: importing the package loads
none of its modules, and a protocol's library loads only when a site file names it. Promised at
their modules: :func:`~fuelid.plc.site.load_site` and
:class:`~fuelid.plc.site.SiteConfig` (:mod:`fuelid.plc.site`), and the names in
:mod:`fuelid.plc.adapters`' ``__all__``. ``fuelid.plc.virtual.profiles`` moved to
:mod:`fuelid.profiles.runs` in 0.2.0 (the old path was removed in 0.3.0).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from fuelid.plc._codec import WordOrder, decode, encode
    from fuelid.plc._gain_handshake import HEARTBEAT_MODULUS, GainWriter
    from fuelid.plc._gain_reading import PLC_GAINS_KEY
    from fuelid.plc._quality import LOW_END_FRACTION, STUCK_AFTER_S
    from fuelid.plc._record_runner import PRUNE_EVERY_S, record_site
    from fuelid.plc._record_status import RecorderStats
    from fuelid.plc._recorder import Recorder, site_identity
    from fuelid.plc._site_fleet import Archive, Central

_HOMES = {
    "Archive": "fuelid.plc._site_fleet",
    "Central": "fuelid.plc._site_fleet",
    "decode": "fuelid.plc._codec",
    "encode": "fuelid.plc._codec",
    "GainWriter": "fuelid.plc._gain_handshake",
    "HEARTBEAT_MODULUS": "fuelid.plc._gain_handshake",
    "LOW_END_FRACTION": "fuelid.plc._quality",
    "PLC_GAINS_KEY": "fuelid.plc._gain_reading",
    "PRUNE_EVERY_S": "fuelid.plc._record_runner",
    "record_site": "fuelid.plc._record_runner",
    "Recorder": "fuelid.plc._recorder",
    "RecorderStats": "fuelid.plc._record_status",
    "site_identity": "fuelid.plc._recorder",
    "STUCK_AFTER_S": "fuelid.plc._quality",
    "WordOrder": "fuelid.plc._codec",
}
"""Exported name → the private module that defines it, imported on first use (PEP 562)."""

__all__ = [
    "HEARTBEAT_MODULUS",
    "LOW_END_FRACTION",
    "PLC_GAINS_KEY",
    "PRUNE_EVERY_S",
    "STUCK_AFTER_S",
    "Archive",
    "Central",
    "GainWriter",
    "Recorder",
    "RecorderStats",
    "WordOrder",
    "decode",
    "encode",
    "record_site",
    "site_identity",
]


def __getattr__(name: str) -> Any:
    # imported on use: importing the package loads none of its modules
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
