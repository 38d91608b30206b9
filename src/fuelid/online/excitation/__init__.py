"""Excitation on demand (issue 40): a test signal the PLC adds to its PI output.

- :mod:`~fuelid.online.excitation._design`: the signal designed from the loop's model and
  noise, with its expected standard errors and its cost.
"""
