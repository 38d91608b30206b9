"""The raw archive: a loop's samples and events as hive-partitioned Parquet (issue 26).

:mod:`fuelid.archive._layout` is the format (paths, columns, atomic writes, readers); the writer
from a store is :mod:`fuelid.archive._writer`.
"""
