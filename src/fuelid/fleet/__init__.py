"""Fleet re-identification of archived history on Dask (issue 26).

:mod:`fuelid.fleet._task` is one loop-day (the online service's window analysis over the
archive's samples, written atomically as Parquet), :mod:`fuelid.fleet._run` the run (Dask
distributed, resumable, the progress), :mod:`fuelid.fleet._summary` the per-loop pass (the K(T)
tracker, K drift, the summary). ``fuelid reidentify`` is the command; docs/how-to/reidentify.md
the guide. Dask (the ``fleet`` extra) is imported only when a run starts.

The public API: :func:`~fuelid.fleet._run.reidentify`, :class:`~fuelid.fleet._run.ReidentifyRun`,
:class:`~fuelid.fleet._run.FleetError`, :func:`~fuelid.fleet._task.reidentify_day`,
:class:`~fuelid.fleet._task.LoopSettings`, :func:`~fuelid.fleet._task.loop_settings`,
:data:`~fuelid.fleet._task.RESULT_SCHEMA`.
"""

from fuelid.fleet._run import FleetError, ReidentifyRun, online_from_toml, reidentify
from fuelid.fleet._task import (
    RESULT_SCHEMA,
    TIMING_COLUMNS,
    LoopSettings,
    loop_settings,
    reidentify_day,
)

__all__ = [
    "RESULT_SCHEMA",
    "TIMING_COLUMNS",
    "FleetError",
    "LoopSettings",
    "ReidentifyRun",
    "loop_settings",
    "online_from_toml",
    "reidentify",
    "reidentify_day",
]
