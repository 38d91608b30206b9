"""The file edge of fuelid: logs, tables and model files in, tables and figures' files out.

- :mod:`~fuelid.io.timeseries`: the time-series containers (:class:`TimeSeries`,
  :class:`IOData`) and the default column names;
- :mod:`~fuelid.io.tables`: reading CSV-like and Parquet tables as PLC exports come;
- :mod:`~fuelid.io.logs`: :func:`load_log`, a log's columns, scalings, time stamps, gaps;
- :mod:`~fuelid.io.files`: atomic writes, refusing to overwrite;
- :mod:`~fuelid.io.modelfile`: a model (and covariance) from a JSON result;
- :mod:`~fuelid.io.plantfile`: new parameter values and a ``[calibration]`` table written into a
  plant TOML file, its comments and layout kept (tomlkit).

This layer reads and writes; it computes nothing beyond unit scaling and resampling onto a
uniform grid. Import the submodule you need (pandas is loaded by the readers and writers only).
"""
