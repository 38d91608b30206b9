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
The package itself exports no names (``__all__`` is empty): a protocol's library loads only when
a site file names it. Promised at their modules: :func:`~fuelid.plc.site.load_site` and
:class:`~fuelid.plc.site.SiteConfig` (:mod:`fuelid.plc.site`), and the names in
:mod:`fuelid.plc.adapters`' ``__all__``. ``fuelid.plc.virtual.profiles`` moved to
:mod:`fuelid.profiles.runs` in 0.2.0 (the old path was removed in 0.3.0).
"""

__all__: list[str] = []
