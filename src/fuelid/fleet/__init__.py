"""Fleet re-identification of archived history on Dask (issue 26).

:func:`reidentify_day` is one loop-day (the online service's window analysis over the archive's
samples, with a loop's :class:`LoopSettings`, written atomically as Parquet in
:data:`RESULT_SCHEMA`); :func:`reidentify` the run (Dask distributed, resumable, the progress),
ending with the per-loop pass (the K(T) tracker, K drift, the summary); :class:`ReidentifyRun`
what it did.
``fuelid reidentify`` is the command; docs/how-to/reidentify.md the guide. Dask (the ``fleet``
extra) is imported only when a run starts.

The public API: the names in ``__all__``, at ``fuelid.fleet`` itself.
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
