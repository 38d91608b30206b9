"""A replayed log as if it were a PLC: row k of the log is the PLC's state during sample k.

The site file says ``protocol = "replay"`` and ``path = "log.csv"`` (or ``.parquet``); each tag's
address is the name of the log's column that carries it, and its raw → engineering scaling
applies as for a PLC. The log plays at ``[plc] speed`` times real time: row
``k = floor(elapsed · speed / period_s)`` is current, so a recorder polling every period at
``speed = 1`` sees every row once, as it would see a PLC.

With ``[ring]`` in the site file the source also serves a ring buffer of ``size`` records whose
sequence number is the row index (and whose fields are the columns of the ring fields' tags), so
that a log played faster than real time is recorded without losing a row, as from a PLC's ring.

When the last row has been served the source raises
:class:`~fuelid.plc.adapters._base.EndOfSource`, on which the recorder stores what it has and
stops cleanly. Nothing is written anywhere: :meth:`ReplaySource.write` only keeps the values,
and :meth:`ReplaySource.read_write_side` refuses (a log has no write side, so nothing echoes an
apply number).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

from fuelid.errors import ConfigError, DataError
from fuelid.io.tables import find_column, read_table, to_float
from fuelid.plc.adapters._base import EndOfSource, LinkError, PlcSource, Reading, RingRecord
from fuelid.plc.site import SiteConfig

UINT32 = 1 << 32


class ReplaySource(PlcSource):
    """Plays a CSV/Parquet log at ``[plc] speed`` × real time, one row per sample period.

    Parameters
    ----------
    site : SiteConfig
        The site file (``plc.protocol = "replay"``, ``plc.path`` the log).

    Raises
    ------
    ConfigError
        The log cannot be read, or a tag's column is not in it (the columns present are named).
    """

    def __init__(self, site: SiteConfig) -> None:
        super().__init__(site)
        path = site.plc.path
        if path is None:  # the site file's validation requires it
            raise ConfigError("plc.path: replay needs the log to play")
        self.path = Path(path)
        try:
            frame, _ = read_table(self.path)
            source = repr(str(self.path))
            # empty or non-numeric cells become NaN: they are what a broken sensor sends, and the
            # recorder flags them (a replay must show it what the PLC would)
            self._columns = {
                role: to_float(frame[find_column(frame, tag.address, "required", source)])
                for role, tag in site.tags.items()
            }
        except DataError as error:
            raise ConfigError(f"plc.path: {error}") from None
        self.rows = len(frame)
        if self.rows == 0:
            raise ConfigError(f"plc.path: {self.path} has no rows to play")
        self.period_s = site.sampling.period_s
        self.speed = site.plc.speed
        self._t0: float | None = None
        self._connected = False
        self._head_served = False
        self.written: dict[str, float] = {}
        """What was written (the last value of each role)."""

    @property
    def where(self) -> str:
        """``replay of log.csv at 10× real time``, for messages."""
        return f"replay of {self.path.name} at {self.speed:g}× real time"

    def current_row(self) -> int:
        """The row the log is at now (may be past the end)."""
        if self._t0 is None:
            return 0
        elapsed = time.monotonic() - self._t0
        return math.floor(elapsed * self.speed / self.period_s + 1e-9)

    async def connect(self) -> None:
        """Start playing (at the first connect; a reconnect continues where the log is)."""
        if self._t0 is None:
            self._t0 = time.monotonic()
        self._connected = True

    async def close(self) -> None:
        """Stop serving (the log's clock runs on, as a PLC's would)."""
        self._connected = False

    def _require(self) -> None:
        if not self._connected:
            raise LinkError(f"not connected to {self.where}")

    def _row(self, k: int) -> tuple[dict[str, float], dict[str, float]]:
        raw = {role: float(column[k]) for role, column in self._columns.items()}
        values = {role: self.site.tags[role].to_engineering(v) for role, v in raw.items()}
        return values, raw

    async def read(self) -> Reading:
        """The current row's tags (engineering and raw values).

        Raises
        ------
        EndOfSource
            The log has been played to its end (without a ring: with one, the ring's head says
            when, and this keeps returning the last row).
        """
        self._require()
        k = self.current_row()
        if k >= self.rows:
            if not self.has_ring:
                raise EndOfSource(f"end of log: {self.rows} rows of {self.path.name} played")
            k = self.rows - 1
        values, raw = self._row(k)
        return Reading(values=values, raw=raw, received=time.time())

    async def read_ring_head(self) -> int:
        """The newest row's index as a uint32 sequence number.

        Raises
        ------
        EndOfSource
            When the last row's index has already been served as the head.
        """
        self._require()
        if self.site.ring is None:
            raise NotImplementedError("the site file maps no ring buffer ([ring])")
        k = self.current_row()
        if k >= self.rows - 1:
            if self._head_served:
                raise EndOfSource(f"end of log: {self.rows} rows of {self.path.name} played")
            self._head_served = True
            k = self.rows - 1
        return k % UINT32

    async def read_ring(self, first_slot: int, count: int) -> list[RingRecord]:
        """Records of slots ``first_slot …``: slot s holds the newest row k ≡ s (mod size)."""
        self._require()
        ring = self.site.ring
        if ring is None:
            raise NotImplementedError("the site file maps no ring buffer ([ring])")
        head = min(self.current_row(), self.rows - 1)
        records = []
        for slot in range(first_slot, first_slot + count):
            k = head - ((head - slot) % ring.size)
            if k < 0:  # never written: a record whose seq is no sample's
                records.append(RingRecord(seq=(k % UINT32), values={}))
                continue
            values, _ = self._row(k)
            # fields without a tag are not in the log: left out (the recorder takes the
            # setpoint from the tags then), not sent as NaN
            fields = {name: values[name] for name in ring.fields[1:] if name in values}
            records.append(RingRecord(seq=k % UINT32, values=fields))
        return records

    async def write(self, values: Mapping[str, float]) -> None:
        """Keep the values (a log cannot be written); unknown roles are refused."""
        self._require()
        unknown = sorted(set(values) - set(self.site.write))
        if unknown:
            raise ConfigError(f"write.{unknown[0]}: the site file maps no such write tag")
        self.written.update({role: float(v) for role, v in values.items()})

    async def read_write_side(self, roles: Sequence[str]) -> dict[str, float]:
        """Refused: a replayed log has no write side to read back.

        A log holds only what the PLC's read tags said; what :meth:`write` is given is kept, not
        applied, so there is no ``echo`` that could confirm a gain write.

        Raises
        ------
        ConfigError
            Always (naming the first role asked for), whatever the roles and the link's state.
        """
        first = next(iter(roles), "echo") if not isinstance(roles, str) else roles
        raise ConfigError(
            f"write.{first}: cannot be read from {self.where}: a replayed log has no write side "
            "(writes are only kept, nothing applies or echoes them)"
        )
