"""fuelid: gray-box modelling, identification and PI tuning of fuel flow loops.

A variable-frequency drive turns a motor and a fixed-displacement pump that pushes kerosene
through a long pipeline to the combustor nozzles; a turbine flowmeter closes the loop through a
PLC. fuelid models that chain from physics, simulates it as the PLC sees it, identifies it from
logged data and tunes its PI controller.

The public API
--------------
A user's script may rely on the names each package lists in its ``__all__``, on the top-level
modules (:mod:`fuelid.model`, :mod:`fuelid.units`, :mod:`fuelid.errors`, :mod:`fuelid.lti`,
:mod:`fuelid.params`, :mod:`fuelid.blas`, :mod:`fuelid.numerics_mode`, :mod:`fuelid.htmlreport`,
each with its ``__all__``) and on the module paths below. Every other module is an
implementation module whose name starts with an underscore (``fuelid/identify/_oe.py``): it is
not promised and may move without notice, so import its names from the package
(``from fuelid.identify import OutputError``). A promised path that moves keeps its old path
for at least one minor release, importing with a DeprecationWarning (CHANGELOG.md lists every
move).

- ``fuelid``: the errors (:class:`FuelidError` and its kinds :class:`ConfigError`,
  :class:`DataError`, :class:`NotFittedError`, :class:`OutOfRangeError`) and ``__version__``.
  Importing it loads nothing else (no numpy), so a command starts fast;
- :mod:`fuelid.plant`: the physics: plant configuration, parameters, coefficients, operating
  point, linearisation; :mod:`fuelid.plant.simulate`: the nonlinear plant simulated as the PLC
  sees it;
- :mod:`fuelid.profiles`: the simulator's input profiles; :mod:`fuelid.profiles.runs`: the
  virtual PLC's run profiles;
- :mod:`fuelid.io`: the data edge, by submodule (:mod:`~fuelid.io.timeseries`,
  :mod:`~fuelid.io.logs`, :mod:`~fuelid.io.fitted_model`, :mod:`~fuelid.io.jsonsafe`, …);
- :mod:`fuelid.model`: the equivalent process model (:class:`~fuelid.model.ProcessModel`);
- :mod:`fuelid.identify` (with :mod:`fuelid.identify.preprocess`), :mod:`fuelid.greybox`,
  :mod:`fuelid.calibration`, :mod:`fuelid.tuning`: the computations;
- :mod:`fuelid.workflow`: what each command computes, as library calls;
- :mod:`fuelid.plots`: the figures;
- :mod:`fuelid.online`, :mod:`fuelid.store`, :mod:`fuelid.plc`: the service beside the PLC.

tests/unit/test_public_api.py imports every promised name from its promised path.
"""

from __future__ import annotations

from fuelid.errors import ConfigError, DataError, FuelidError, NotFittedError, OutOfRangeError

__version__ = "0.3.0.dev0"
"""The one place the version is written: pyproject.toml reads it from here (setuptools' dynamic
``attr``), so no command pays for importlib.metadata at start-up."""

__all__ = [
    "ConfigError",
    "DataError",
    "FuelidError",
    "NotFittedError",
    "OutOfRangeError",
    "__version__",
]
