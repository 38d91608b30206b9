"""The PLC link: the site file, the register codec, the adapters, the recorder, the virtual PLC.

- :mod:`~fuelid.plc.site`: a site file read and validated (:func:`~fuelid.plc.site.load_site`),
  with its ``[archive]`` and ``[central]`` tables (:class:`Archive`, :class:`Central`);
- :func:`encode`, :func:`decode`: values packed into 16-bit registers and back
  (:class:`WordOrder`);
- :mod:`~fuelid.plc.adapters`: the protocol links behind one interface
  (:class:`~fuelid.plc.adapters.PlcSource`, :func:`~fuelid.plc.adapters.open_source`);
- :class:`Recorder`: samples from a source into the store, each checked (range, stuck
  readings); :func:`record_site` runs it as ``fuelid record`` does;
- :class:`GainWriter`: a block of gains written and the PLC's echo checked;
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

from typing import TYPE_CHECKING

import lazy_loader

if TYPE_CHECKING:
    from fuelid.plc._codec import WordOrder, decode, encode
    from fuelid.plc._gain_handshake import HEARTBEAT_MODULUS, GainWriter
    from fuelid.plc._gain_reading import PLC_GAINS_KEY
    from fuelid.plc._quality import LOW_END_FRACTION, STUCK_AFTER_S
    from fuelid.plc._record_runner import PRUNE_EVERY_S, record_site
    from fuelid.plc._record_status import RecorderStats
    from fuelid.plc._recorder import Recorder, site_identity
    from fuelid.plc._site_fleet import Archive, Central

# Each name is imported from its private module on first use (lazy_loader, SPEC 1), so
# that importing the package stays cheap.
__getattr__ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "_codec": ["WordOrder", "decode", "encode"],
        "_gain_handshake": ["GainWriter", "HEARTBEAT_MODULUS"],
        "_gain_reading": ["PLC_GAINS_KEY"],
        "_quality": ["LOW_END_FRACTION", "STUCK_AFTER_S"],
        "_record_runner": ["PRUNE_EVERY_S", "record_site"],
        "_record_status": ["RecorderStats"],
        "_recorder": ["Recorder", "site_identity"],
        "_site_fleet": ["Archive", "Central"],
    },
)[0]

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
