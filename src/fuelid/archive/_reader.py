"""One loop of an archive read like a store (``fuelid export DIR --loop ID``).

:class:`ArchiveLoop` answers the read calls a store answers (:meth:`read`, :meth:`read_events`,
:meth:`first_time`, :meth:`last_time`) from the loop's Parquet days, opening only the days a
range touches. It is read-only: nothing in the archive is written through it.
"""

from __future__ import annotations

from pathlib import Path

from fuelid.archive._layout import (
    arrays_of,
    day_bounds,
    list_loop_days,
    read_day_table,
    read_range_table,
)
from fuelid.store import Event, SampleArrays, StoreError

__all__ = ["ArchiveLoop", "archive_loops"]


def archive_loops(root: str | Path) -> list[str]:
    """The loop ids with samples in the archive at ``root``, sorted.

    Raises
    ------
    StoreError
        ``root`` is not an archive (no ``samples/`` folder).
    """
    return sorted({day.loop_id for day in list_loop_days(root)})


class ArchiveLoop:
    """One loop's archived samples and events, read as a store reads them.

    Parameters
    ----------
    root : str or Path
        The archive folder.
    loop_id : str, optional
        The loop; may be left out when the archive holds one loop only.

    Raises
    ------
    StoreError
        Not an archive, no such loop in it, or no loop named while it holds several.
    """

    def __init__(self, root: str | Path, loop_id: str | None = None) -> None:
        self.root = Path(root)
        loops = archive_loops(self.root)
        if loop_id is None:
            if len(loops) != 1:
                raise StoreError(
                    f"{root}: the archive holds the loops {', '.join(loops) or 'none'}: "
                    "name one with --loop"
                )
            loop_id = loops[0]
        if loop_id not in loops:
            raise StoreError(
                f"{root}: no loop {loop_id!r} in the archive (it holds: "
                f"{', '.join(loops) or 'none'})"
            )
        self.loop_id = loop_id
        self.path = f"{self.root} (loop {loop_id})"

    def dates(self) -> list[str]:
        """The loop's archived UTC dates (YYYY-MM-DD), ascending."""
        return [day.date for day in list_loop_days(self.root, [self.loop_id])]

    def read(self, t_from: float | None = None, t_to: float | None = None) -> SampleArrays:
        """Samples with ``t_from <= time < t_to`` [plant s UTC], sorted by time.

        Nulls come back as NaN (floats) and −1 (seq, mode), as a store reads them.
        """
        return arrays_of(read_range_table(self.root, "samples", self.loop_id, t_from, t_to))

    def read_events(self, t_from: float | None = None, t_to: float | None = None) -> list[Event]:
        """Events with ``t_from <= time < t_to`` [plant s UTC], in time order."""
        table = read_range_table(self.root, "events", self.loop_id, t_from, t_to)
        return [
            Event(float(t), str(k), str(d))
            for t, k, d in zip(
                table.column("time").to_pylist(),
                table.column("kind").to_pylist(),
                table.column("detail").to_pylist(),
                strict=True,
            )
        ]

    def first_time(self) -> float | None:
        """The oldest archived sample time [plant s UTC] (None when there is none)."""
        return self._end(first=True)

    def last_time(self) -> float | None:
        """The newest archived sample time [plant s UTC] (None when there is none)."""
        return self._end(first=False)

    def _end(self, first: bool) -> float | None:
        dates = self.dates()
        for date in dates if first else reversed(dates):
            day_bounds(date)
            time = read_day_table(self.root, "samples", self.loop_id, date).column("time")
            if len(time):
                return float(time[0].as_py() if first else time[-1].as_py())
        return None
