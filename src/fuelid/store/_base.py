"""The storage interface of the sample stream, and the one writer that feeds it.

A store holds the samples of one site (one fuel loop as its PLC exposes it) and the events of the
recording (link down/up, gaps, gain changes, restarts). :class:`SampleStore` is the interface the
recorder and the readers use; :class:`~fuelid.store._sqlite.SQLiteStore` is the default, and a
central PostgreSQL store can follow by implementing the same methods, without touching the
recorder. :class:`~fuelid.store._writer.SampleWriter` is the one writer: a thread fed by a queue
that commits a batch about once a second (in :mod:`fuelid.store._writer`, which calls this
interface); the records (samples, events, the store's error) are in :mod:`fuelid.store._records`
and re-exported here.

Times are UTC seconds since the Unix epoch [s]; u in V, y and the setpoint in L/min, the fuel
temperature in °C (as the PLC gives it; :meth:`SampleStore.to_iodata` converts to K).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Iterable
from types import TracebackType
from typing import Self, cast

import numpy as np

from fuelid.errors import DataError
from fuelid.io.timeseries import IOData
from fuelid.store._records import (
    EVENT_KINDS,
    Event,
    FloatArray,
    IntArray,
    PruneResult,
    Quality,
    Requalify,
    Sample,
    SampleArrays,
    StateValue,
    StoreError,
    StoreInfo,
    tag_map_hash,
)
from fuelid.units import celsius_to_kelvin

__all__ = [
    "EVENT_KINDS",
    "Event",
    "FloatArray",
    "IntArray",
    "PruneResult",
    "Quality",
    "Requalify",
    "Sample",
    "SampleArrays",
    "SampleStore",
    "StateValue",
    "StoreError",
    "StoreInfo",
    "iodata_from_samples",
    "tag_map_hash",
]


class SampleStore(ABC):
    """The interface of a sample store.

    A store is opened for one site (``site_name`` and ``tag_map_hash``): a new store records that
    identity, an existing one refuses samples from another site with a :class:`StoreError`.
    Opened without an identity, a store can be read but not written. Use as a context manager
    or call :meth:`close`.
    """

    path: str
    site_name: str
    tag_map_hash: str

    @abstractmethod
    def append(
        self,
        samples: Iterable[Sample] = (),
        events: Iterable[Event] = (),
        requalify: Iterable[Requalify] = (),
        state: Iterable[StateValue] = (),
    ) -> int:
        """Store samples and events, then re-flag stretches, in one transaction (committed).

        Samples whose ``seq`` (or, without one, ``time``) is already stored are ignored. The
        :class:`Requalify` changes are applied after the inserts, so they reach the samples of
        this same call too. Each :class:`StateValue` replaces its key's value in the store's
        state (``online_state``, read with :meth:`fuelid.store.OnlineHistory.state`).

        Returns
        -------
        int
            Samples actually added.
        """

    def set_quality(self, t_from: float, t_to: float, quality: int = Quality.BAD_VALUE) -> int:
        """Flag the OK samples with ``t_from <= time <= t_to`` [s UTC] (committed on return).

        Samples already flagged keep their flag. Through a
        :class:`~fuelid.store._writer.SampleWriter` use
        :meth:`~fuelid.store._writer.SampleWriter.set_quality`, which keeps the order of the queue.

        Returns
        -------
        int
            Samples changed.
        """
        return self.requalify([Requalify(float(t_from), float(t_to), int(quality))])

    @abstractmethod
    def requalify(self, changes: Iterable[Requalify]) -> int:
        """Apply :class:`Requalify` changes in one transaction; the samples changed."""

    def append_samples(self, samples: Iterable[Sample]) -> int:
        """Store samples (committed on return); see :meth:`append`."""
        return self.append(samples, ())

    def append_events(self, events: Iterable[Event]) -> None:
        """Store events (committed on return)."""
        self.append((), events)

    @abstractmethod
    def read(self, t_from: float | None = None, t_to: float | None = None) -> SampleArrays:
        """Samples with ``t_from <= time < t_to`` [s UTC] (None: unbounded), sorted by time."""

    @abstractmethod
    def read_events(self, t_from: float | None = None, t_to: float | None = None) -> list[Event]:
        """Events with ``t_from <= time < t_to`` [s UTC], in time order."""

    @abstractmethod
    def info(self) -> StoreInfo:
        """Rows, time span, gaps, link events and size of the store."""

    def last_seq(self) -> int | None:
        """The largest stored sequence number (None when no sample has one).

        The recorder continues from it after a restart, so that the stored numbers stay
        monotonic. This default reads every sample; a store should answer from an index.
        """
        seq = self.read().seq
        seq = seq[seq >= 0]
        return int(seq.max()) if seq.size else None

    def first_time(self) -> float | None:
        """The oldest sample time [s UTC]; None when the store is empty."""
        samples = self.read()
        return float(samples.time[0]) if len(samples) else None

    def last_time(self) -> float | None:
        """The newest sample time [s UTC] (None when the store is empty).

        Retention counts back from it, not from the wall clock, so that data on another time
        base (a virtual PLC at X times real time) are kept as long as the site file says.
        This default reads every sample; a store should answer from an index.
        """
        time = self.read().time
        return float(time.max()) if time.size else None

    @abstractmethod
    def prune(
        self,
        older_than_days: float,
        thin_to_period_s: float | None = 1.0,
        now: float | None = None,
        archived_only: bool = False,
    ) -> PruneResult:
        """Keep raw samples for ``older_than_days`` [d]; thin older ones.

        Parameters
        ----------
        older_than_days : float
            Samples older than this before ``now`` are thinned [d].
        thin_to_period_s : float or None
            Of the older samples keep the first of each period of this length [s]; None deletes
            them all.
        now : float, optional
            Reference time [s UTC]; the current time by default.
        archived_only : bool
            An archive is configured: thin or delete only the samples of archived days.
        """

    @abstractmethod
    def close(self) -> None:
        """Release the store (pending data are already committed by :meth:`append`)."""

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def to_iodata(
        self,
        t_from: float | None = None,
        t_to: float | None = None,
        sample_time: float | None = None,
    ) -> IOData:
        """The stored samples as the record the estimators fit.

        Only samples of quality ``ok`` with a finite u and y are used. A break in the sequence
        number (or, without one, an interval longer than 1.5 sample times) starts a new segment
        (``segment_starts``/``segment_t0``); nothing is interpolated. Within a segment sample k
        is taken ``sample_time`` after sample k−1 (the receipt jitter is dropped).

        Parameters
        ----------
        t_from, t_to : float, optional
            Time range [s UTC], ``t_from <= time < t_to``.
        sample_time : float, optional
            Sampling period [s] (the site's ``sampling.period_s``); the median interval of the
            samples by default.

        Returns
        -------
        IOData
            u [V], y [L/min], times in UTC seconds, ``T_fuel`` [K] when every sample used has a
            fuel temperature.

        Raises
        ------
        DataError
            Fewer than two usable samples in the range.
        """
        return iodata_from_samples(
            self.read(t_from, t_to),
            sample_time,
            source=self.path,
            note=f"read from the store {self.path} (site {self.site_name!r})",
        )


def iodata_from_samples(
    raw: SampleArrays, sample_time: float | None = None, *, source: str = "", note: str = ""
) -> IOData:
    """Samples read from a store as the record the estimators fit.

    The rules of :meth:`SampleStore.to_iodata` (which reads and calls this): only good samples
    with finite u and y, a new segment at every break of the counter or long interval.

    Parameters
    ----------
    raw : SampleArrays
        Samples sorted by time.
    sample_time : float, optional
        Sampling period [s]; the median interval of the usable samples by default.
    source : str
        Where they came from (the record's ``source``, messages).
    note : str
        First note of the record (its origin); the count of samples left out is appended.

    Raises
    ------
    DataError
        Fewer than two usable samples.
    """
    keep = (raw.quality == Quality.OK) & np.isfinite(raw.u) & np.isfinite(raw.y)
    t, seq = raw.time[keep], raw.seq[keep]
    if t.size < 2:
        raise DataError(f"{source}: {t.size} usable sample(s) (quality ok) in the range, need 2")
    dt = np.diff(t)
    h = float(np.median(dt)) if sample_time is None else float(sample_time)
    if not (math.isfinite(h) and h > 0.0):
        raise DataError(f"{source}: cannot find a sample time (median interval {h} s)")
    with_seq = (seq[:-1] >= 0) & (seq[1:] >= 0)
    dseq = np.diff(seq)
    seq_step = int(np.median(dseq[with_seq])) if np.any(with_seq) else 1
    breaks = np.where(with_seq, dseq != seq_step, dt > 1.5 * h)
    # a long silence is a gap even when the counter continues (a stalled PLC, thinned data)
    breaks |= dt > 1.5 * h * max(seq_step, 1)
    starts = tuple(int(i) + 1 for i in np.flatnonzero(breaks))
    left_out = f"{int(np.count_nonzero(~keep))} sample(s) not ok left out"
    notes = [f"{note}, {left_out}" if note else left_out]
    temp = raw.fuel_temperature[keep]
    T_fuel: FloatArray | None = None
    if np.all(np.isfinite(temp)):
        # elementwise: the function is plain arithmetic, numpy broadcasts it
        T_fuel = np.asarray(celsius_to_kelvin(cast(float, temp)), dtype=np.float64)
    elif np.any(np.isfinite(temp)):
        notes.append("fuel temperature missing for some samples: not used")
    return IOData(
        u=raw.u[keep],
        y=raw.y[keep],
        sample_time=h,
        t0=float(t[0]),
        source=source,
        notes=tuple(notes),
        segment_starts=starts,
        segment_t0=tuple(float(t[i]) for i in starts),
        T_fuel=T_fuel,
    )
