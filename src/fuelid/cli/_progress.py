"""The progress display of the long commands: a rich bar (or spinner) on stderr, a terminal only.

:func:`~fuelid.cli._common.progress_display` yields a :class:`StageBar` while a command works.
The library calls it with each stage's name as the stage starts (reading the log, gridding,
fitting, testing the residuals, the report's tuning stages: :mod:`fuelid.workflow._progress`)
and, for a stage whose steps it can count, ``step(done, total, what)``: the line then carries a
bar with ``done/total`` and what runs now; a stage without a count shows a spinner. Either way
the line shows the time the stage has taken, and appears only once the stage has run for
:data:`SHOW_AFTER` seconds, so a quick command prints nothing. It is transient (gone when the
command ends) and on stderr only: the JSON of ``--json`` on stdout stays one object.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    ProgressColumn,
    SpinnerColumn,
    Task,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
)
from rich.text import Text

if TYPE_CHECKING:
    from rich.console import Console, RenderableType

SHOW_AFTER = 1.0
"""A stage's line appears once the stage has run this long [s]: only steps that may take over
about two seconds are shown."""


class _Counted(ProgressColumn):
    """A column shown only for a stage whose steps are counted (a bar, ``done/total``)."""

    def __init__(self, column: ProgressColumn) -> None:
        super().__init__()
        self._column = column

    def render(self, task: Task) -> RenderableType:
        """The wrapped column, or nothing while the stage has no count."""
        return Text("") if task.total is None else self._column.render(task)


class _Delayed(Progress):
    """A rich progress display that shows nothing until its stage has run a while."""

    def __init__(self, *columns: ProgressColumn, show_after: float, console: Console) -> None:
        super().__init__(*columns, console=console, transient=True)
        self.show_after = show_after

    def get_renderables(self) -> Iterable[RenderableType]:
        """The table of the tasks, once a task has run :attr:`show_after` seconds."""
        if any((task.elapsed or 0.0) >= self.show_after for task in self.tasks):
            yield from super().get_renderables()


class StageBar:
    """The callback of :mod:`fuelid.workflow._progress`: one line for the stage running now."""

    def __init__(self, display: Progress) -> None:
        self._display = display
        self._task: TaskID | None = None
        self._stage = ""

    def __call__(self, stage: str) -> None:
        """``stage`` starts: it replaces the previous stage's line (a spinner, no count)."""
        if self._task is not None:
            self._display.remove_task(self._task)
        self._stage = stage
        self._task = self._display.add_task(f"{stage}…", total=None)

    def step(self, done: int, total: int, what: str = "") -> None:
        """``done`` of the stage's ``total`` steps are done and ``what`` runs now: a bar."""
        if self._task is None:
            self(what or "working")
        assert self._task is not None
        label = f"{self._stage}: {what}" if what else self._stage
        self._display.update(self._task, total=total, completed=done, description=f"{label}…")


def stage_bar(console: Console, show_after: float = SHOW_AFTER) -> tuple[Progress, StageBar]:
    """The rich display (to be entered as a context) and its callback, on ``console``."""
    display = _Delayed(
        SpinnerColumn(),
        TextColumn("{task.description}"),
        _Counted(BarColumn(bar_width=24)),
        _Counted(MofNCompleteColumn()),
        TimeElapsedColumn(),
        console=console,
        show_after=show_after,
    )
    return display, StageBar(display)
