"""How far a long identification has got: its stages, and the steps within a stage.

:func:`~fuelid.identify._procedure.identify` and :meth:`~fuelid.identify._oe.OutputError.fit`
take an optional ``progress`` callback, the same kind :mod:`fuelid.workflow._progress` and
:func:`fuelid.io.logs.load_log` take: it is called with a stage's name as the stage starts
(:data:`FITTING`, :data:`DIAGNOSING`). A display that can also show how far a stage has got is
a :class:`StepDisplay`: it has a method ``step(done, total, what)`` as well, told as each step of
the stage starts how many of its ``total`` steps are done and what the next one is (the fit's
structures, its search, its polish on a long record, its standard errors). A plain callable such
as ``list.append`` gets the stages only. The library prints nothing itself.

Examples
--------
>>> seen: list[str] = []
>>> announce(seen.append, FITTING)
>>> advance(seen.append, 1, 4, "order 2")  # a plain callable is not told the steps
>>> seen
['fitting the model']
>>> class Steps(list):
...     def __call__(self, stage: str) -> None:
...         self.append(stage)
...     def step(self, done: int, total: int, what: str = "") -> None:
...         self.append(f"{done}/{total} {what}")
>>> steps = Steps()
>>> advance(steps, 1, 4, "order 2")
>>> announce(steps_only(steps), FITTING)  # the steps of a stage another caller named
>>> advance(steps_only(steps), 2, 4)
>>> steps
['1/4 order 2', '2/4 ']
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol, runtime_checkable

StageCallback = Callable[[str], None]
"""Called with a stage's name as the stage starts."""

FITTING = "fitting the model"
"""The estimator's search and standard errors (:func:`~fuelid.identify._procedure.identify`)."""
DIAGNOSING = "testing the residuals"
"""The fit's diagnostics: residual tests, gain per band, misfit, lead check."""


@runtime_checkable
class StepDisplay(Protocol):
    """A progress callback that also shows how far the current stage has got."""

    def __call__(self, stage: str) -> None:
        """``stage`` starts."""

    def step(self, done: int, total: int, what: str = "") -> None:
        """``done`` of the stage's ``total`` steps are done; ``what`` starts now."""


def announce(progress: StageCallback | None, stage: str) -> None:
    """Tell ``progress`` (if any) that ``stage`` starts."""
    if progress is not None:
        progress(stage)


def advance(progress: StageCallback | None, done: int, total: int, what: str = "") -> None:
    """Tell ``progress`` how far the stage has got, when it can show it (a :class:`StepDisplay`)."""
    if isinstance(progress, StepDisplay):
        progress.step(done, total, what)


class _StepsOnly:
    """A display's steps without its stage announcements (see :func:`steps_only`)."""

    def __init__(self, display: StepDisplay) -> None:
        self._display = display

    def __call__(self, stage: str) -> None:
        """Not passed on: the caller names the stage."""

    def step(self, done: int, total: int, what: str = "") -> None:
        """Passed on to the display."""
        self._display.step(done, total, what)


class StepCounter:
    """A stage's steps, numbered for a progress display: ``counter(what)`` as each starts.

    Examples
    --------
    >>> class Show(list):
    ...     def __call__(self, stage: str) -> None: ...
    ...     def step(self, done: int, total: int, what: str = "") -> None:
    ...         self.append(f"{done}/{total} {what}")
    >>> show = Show()
    >>> count = StepCounter(show, 2)
    >>> count.label = "order 1: "
    >>> count("search"); count("standard errors")
    >>> show
    ['0/2 order 1: search', '1/2 order 1: standard errors']
    """

    def __init__(self, progress: StageCallback | None, total: int) -> None:
        self._progress, self._total, self._done = progress, total, 0
        self.label = ""
        """Put before each step's description (the structure being fitted, say)."""

    def __call__(self, what: str) -> None:
        """Step ``what`` starts."""
        advance(self._progress, self._done, self._total, self.label + what)
        self._done += 1

    def extend(self, more: int) -> None:
        """``more`` steps found necessary after the count began (a second covariance, say)."""
        self._total += more


def steps_only(progress: StageCallback | None) -> StepDisplay | None:
    """``progress``'s steps, not its stages: for a call inside a stage the caller announced.

    :func:`~fuelid.workflow._analysis.analyse_log` announces "identification" and lets the
    identification show how far it has got, without announcing stages of its own.
    """
    return _StepsOnly(progress) if isinstance(progress, StepDisplay) else None


__all__ = [
    "DIAGNOSING",
    "FITTING",
    "StageCallback",
    "StepCounter",
    "StepDisplay",
    "advance",
    "announce",
    "steps_only",
]
