"""The file edge of fuelid: logs, tables and model files in, tables and figures' files out.

- :mod:`~fuelid.io.timeseries`: the time-series containers (:class:`TimeSeries`,
  :class:`IOData`) and the default column names;
- :mod:`~fuelid.io.tables`: reading CSV-like and Parquet tables as PLC exports come;
- :mod:`~fuelid.io.logs`: :func:`load_log`, a log's columns, scalings, time stamps, gaps;
- :mod:`~fuelid.io.files`: atomic writes, refusing to overwrite;
- :mod:`~fuelid.io.jsonsafe`: :func:`~fuelid.io.jsonsafe.json_ready`, the one conversion of
  results to what ``json.dumps`` accepts (NaN and infinities as null);
- :mod:`~fuelid.io.fitted_model`: a fitted model (and covariance) from a JSON result;
- :mod:`~fuelid.io.plantfile`: new parameter values and a ``[calibration]`` table written into a
  plant TOML file, its comments and layout kept (tomlkit).

This layer reads and writes; it computes nothing beyond unit scaling and resampling onto a
uniform grid. Import the submodule you need (pandas is loaded by the readers and writers only).

The public API
--------------
The names in ``__all__`` (the helpers other packages share: the log's grid and bad-value
markers, clock formatting), each loaded on first use, so that importing the package loads no
pandas. Promised at their submodules: :class:`~fuelid.io.timeseries.TimeSeries` and
:class:`~fuelid.io.timeseries.IOData` (:mod:`fuelid.io.timeseries`),
:func:`~fuelid.io.logs.load_log` (:mod:`fuelid.io.logs`), :func:`~fuelid.io.tables.read_table`
(:mod:`fuelid.io.tables`), :func:`~fuelid.io.files.write_table` (:mod:`fuelid.io.files`),
:class:`~fuelid.io.fitted_model.FittedModel` and :func:`~fuelid.io.fitted_model.load_fitted_model`
(:mod:`fuelid.io.fitted_model`; ``fuelid.io.modelfile``'s ``ModelFile`` and ``load_model_file``
before 0.2.0, removed in 0.3.0), :func:`~fuelid.io.jsonsafe.json_ready`
(:mod:`fuelid.io.jsonsafe`), :func:`~fuelid.io.plantfile.update_plant_file`
(:mod:`fuelid.io.plantfile`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import lazy_loader

if TYPE_CHECKING:
    from fuelid.io._bad_values import parse_bad_values
    from fuelid.io._clock import format_age, format_time
    from fuelid.io._log_grid import FILL_GAPS_MAX_PERIODS

# Each name is imported from its private module on first use (lazy_loader, SPEC 1), so
# that importing the package stays cheap.
__getattr__ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "_bad_values": ["parse_bad_values"],
        "_clock": ["format_age", "format_time"],
        "_log_grid": ["FILL_GAPS_MAX_PERIODS"],
    },
)[0]

__all__ = [
    "FILL_GAPS_MAX_PERIODS",
    "format_age",
    "format_time",
    "parse_bad_values",
]
