"""The PLC link: the site file and the register codec.

:mod:`~fuelid.plc.site` reads and validates a site file; :mod:`~fuelid.plc.codec` packs values
into 16-bit registers. The acquisition adapters, the virtual PLC and the recorder follow
(issue 14). Nothing here is imported by the computation layers.
"""
