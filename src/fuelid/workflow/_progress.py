"""Which stage a long call is in: the callback the workflow calls and the names of its stages.

:func:`~fuelid.workflow._analysis.analyse_log`, :func:`~fuelid.workflow._tune.tune_model` and
:func:`~fuelid.workflow._tune.schedule_gains` take an optional ``progress`` callback and call it
with a stage's name as that stage starts, in the order of :data:`ANALYSIS_STAGES` (a stage that
is not asked for, such as the sweep, is not announced). :func:`fuelid.io.logs.load_log`
announces reading and gridding the same way, and
:func:`~fuelid.workflow._identification.identify_log` the fit and its diagnostics
(:data:`IDENTIFY_STAGES`). A callback that is also a :class:`StepDisplay` (it has a
``step(done, total, what)`` method) is told besides how far a stage with countable steps has
got: the fit's structures, a long record's search and polish, its standard errors
(:mod:`fuelid.identify._progress`); ``analyse_log`` passes those steps on under its
"identification" stage. The library prints nothing itself: the command line shows the stage
on stderr (a bar when the steps are known, a spinner otherwise), a service may log it.

Examples
--------
>>> seen: list[str] = []
>>> announce(seen.append, IDENTIFICATION)
>>> announce(None, SCHEDULE)  # no callback: nothing happens
>>> seen
['identification']
"""

from __future__ import annotations

from collections.abc import Callable

from fuelid.identify import DIAGNOSING, FITTING, StepDisplay, advance, steps_only
from fuelid.io.logs import GRIDDING, READING

Progress = Callable[[str], None]
"""Called with a stage's name as the stage starts."""

IDENTIFICATION = "identification"
"""Both estimators on the log (``analyse_log``)."""
TUNING = "tuning"
"""The rule's gains, their margins and the linear closed loop on the model."""
TEMPERATURE_CHECK = "temperature check"
"""The gains on the plant over the fuel-temperature range and the drive's range."""
RUNS = "closed-loop runs"
"""The standard test on the nonlinear plant at the coldest and the warmest fuel."""
SWEEP = "sweep"
"""The gains on plant variants drawn from the model's covariance."""
SCHEDULE = "schedule"
"""Gains per temperature (and flow) band."""
DIAGNOSTICS = "diagnostics"
"""Residual tests and the loop's frequency response (``analyse_log``)."""

TUNE_STAGES = (TUNING, TEMPERATURE_CHECK, RUNS, SWEEP)
"""The stages of :func:`~fuelid.workflow._tune.tune_model`, in order."""
ANALYSIS_STAGES = (IDENTIFICATION, TUNING, TEMPERATURE_CHECK, RUNS, SCHEDULE, DIAGNOSTICS)
"""The stages of :func:`~fuelid.workflow._analysis.analyse_log`, in order."""
IDENTIFY_STAGES = (READING, GRIDDING, FITTING, DIAGNOSING)
"""The stages of ``fuelid identify``: :func:`~fuelid.io.logs.load_log`'s, then
:func:`~fuelid.workflow._identification.identify_log`'s (an oe or pem fit), in order."""


def announce(progress: Progress | None, stage: str) -> None:
    """Tell ``progress`` (if any) that ``stage`` starts."""
    if progress is not None:
        progress(stage)


__all__ = [
    "ANALYSIS_STAGES",
    "DIAGNOSING",
    "DIAGNOSTICS",
    "FITTING",
    "GRIDDING",
    "IDENTIFICATION",
    "IDENTIFY_STAGES",
    "READING",
    "RUNS",
    "SCHEDULE",
    "SWEEP",
    "TEMPERATURE_CHECK",
    "TUNE_STAGES",
    "TUNING",
    "Progress",
    "StepDisplay",
    "advance",
    "announce",
    "steps_only",
]
