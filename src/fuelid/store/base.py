"""The storage interface of the sample stream, and the one writer that feeds it.

A store holds the samples of one site (one fuel loop as its PLC exposes it) and the events of the
recording (link down/up, gaps, gain changes, restarts). :class:`SampleStore` is the interface the
recorder and the readers use; :class:`~fuelid.store.sqlite.SQLiteStore` is the default, and a
central PostgreSQL store can follow by implementing the same methods, without touching the
recorder. :class:`SampleWriter` is the one writer: a thread fed by a queue that commits a batch
about once a second.

Times are UTC seconds since the Unix epoch [s]; u in V, y and the setpoint in L/min, the fuel
temperature in °C (as the PLC gives it; :meth:`SampleStore.to_iodata` converts to K).
"""

from __future__ import annotations

import hashlib
import json
import math
import queue
import threading
import time as _time
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from enum import IntEnum
from types import TracebackType
from typing import Any, NamedTuple, Self, cast

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import DataError, FuelidError
from fuelid.io.timeseries import IOData
from fuelid.units import celsius_to_kelvin

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class StoreError(FuelidError):
    """A store cannot be opened, belongs to another site, or refuses a write (one-line reason)."""


class Quality(IntEnum):
    """Quality of a sample, stored as its integer code."""

    OK = 0
    """Every value read fresh and in range."""
    STALE = 1
    """The PLC did not update the values since the last sample."""
    LINK_DOWN = 2
    """No answer from the PLC: the values are not measurements."""
    BAD_VALUE = 3
    """A value was NaN, infinite or out of its tag's range."""


EVENT_KINDS = (
    "link_down",
    "link_up",
    "gap",
    "gain_change",
    "restart",
    "site_mismatch",
    "prune",
)
"""Event kinds fuelid writes; others are stored as given (the column is free text)."""


class Sample(NamedTuple):
    """One sample as stored (the order is the column order of the ``samples`` table).

    Parameters
    ----------
    time : float
        Sample time, UTC seconds since the epoch [s].
    seq : int or None
        Sequence number (the PLC's counter, unwrapped to a monotonic integer by the recorder),
        None without a counter. A sample already stored with the same ``seq`` (or, without one,
        the same ``time``) is ignored, so a restart that re-sends samples adds no duplicates.
    u : float
        Input, the VFD command [V] (NaN when not measured).
    y : float
        Output, the flow [L/min].
    setpoint : float
        Flow setpoint [L/min] (NaN when the PLC does not expose it).
    fuel_temperature : float
        Fuel temperature [°C] (NaN when not exposed).
    mode : int or None
        0 = MAN, 1 = AUTO, None when not exposed.
    quality : int
        A :class:`Quality` code.
    """

    time: float
    seq: int | None
    u: float
    y: float
    setpoint: float = math.nan
    fuel_temperature: float = math.nan
    mode: int | None = None
    quality: int = Quality.OK


class Requalify(NamedTuple):
    """A change of quality of stored samples, applied in the writer's order (after the inserts).

    Samples with ``t_from <= time <= t_to`` [s UTC] whose quality is :attr:`Quality.OK` get
    ``quality``; samples already flagged keep their flag. The recorder uses it to flag the
    first seconds of a stuck flow once the stretch is recognised as stuck, so that it never
    holds samples back from the store.

    Parameters
    ----------
    t_from, t_to : float
        First and last sample time of the stretch [s UTC], both included.
    quality : int
        The new :class:`Quality` code.
    """

    t_from: float
    t_to: float
    quality: int = Quality.BAD_VALUE


class Event(NamedTuple):
    """One event of the recording.

    Parameters
    ----------
    time : float
        UTC seconds since the epoch [s].
    kind : str
        One of :data:`EVENT_KINDS` (link_down, link_up, gap, gain_change, restart, …).
    detail : str
        Free text (a reason, the gains, the gap's length).
    """

    time: float
    kind: str
    detail: str = ""


@dataclass(frozen=True)
class SampleArrays:
    """Samples read back, one array per column, sorted by time.

    ``seq`` and ``mode`` are −1 where the sample has none; missing real values are NaN.
    ``time`` [s UTC], ``u`` [V], ``y`` and ``setpoint`` [L/min], ``fuel_temperature`` [°C],
    ``quality`` the :class:`Quality` codes.
    """

    time: FloatArray
    seq: IntArray
    u: FloatArray
    y: FloatArray
    setpoint: FloatArray
    fuel_temperature: FloatArray
    mode: IntArray
    quality: IntArray

    def __len__(self) -> int:
        return int(self.time.size)

    @classmethod
    def from_rows(cls, rows: Sequence[Sequence[Any]]) -> SampleArrays:
        """Arrays from rows in :class:`Sample` column order (None for SQL NULL)."""

        def floats(i: int) -> FloatArray:
            return np.array([math.nan if r[i] is None else r[i] for r in rows], dtype=np.float64)

        def ints(i: int) -> IntArray:
            return np.array([-1 if r[i] is None else r[i] for r in rows], dtype=np.int64)

        return cls(
            time=floats(0),
            seq=ints(1),
            u=floats(2),
            y=floats(3),
            setpoint=floats(4),
            fuel_temperature=floats(5),
            mode=ints(6),
            quality=ints(7),
        )


@dataclass(frozen=True)
class StoreInfo:
    """What a store holds (``fuelid store info``).

    Attributes
    ----------
    path : str
        Where the store is (file or URL).
    site_name, tag_map_hash : str
        The site the store belongs to and the SHA-256 of its tag map.
    schema_version : int
        Version of the store's schema.
    rows : int
        Samples stored.
    t_first, t_last : float or None
        Time of the first and last sample [s UTC] (None when empty).
    span_s : float
        ``t_last − t_first`` [s].
    gaps : int
        Breaks in the sample stream: jumps of the sequence number, or, for samples without one,
        intervals longer than 1.5 sample periods (when the period is known).
    missing_samples : int
        Samples missing inside the sequence-number gaps. A PLC restart leaves one sequence
        number out on purpose (a break readers see), and its ``restart`` event is timed at the
        first sample after it: a jump of the sequence at a sample that carries a ``restart``
        event at its exact time counts one number less (a jump of exactly 2 there is a gap
        with no sample missing), so this agrees with the recorder's count of lost samples.
    quality : dict
        Samples per quality name.
    events : dict
        Events per kind (``link_down`` and ``link_up`` are the link events).
    size_bytes : int
        Size on disk [B] (for SQLite the file and its write-ahead log).
    """

    path: str
    site_name: str
    tag_map_hash: str
    schema_version: int
    rows: int
    t_first: float | None
    t_last: float | None
    span_s: float
    gaps: int
    missing_samples: int
    quality: dict[str, int] = field(default_factory=dict)
    events: dict[str, int] = field(default_factory=dict)
    size_bytes: int = 0

    def to_dict(self) -> dict[str, Any]:
        """Plain dictionary with a ``units`` map (for ``--json``)."""
        out = asdict(self)
        out["units"] = {"t_first": "s", "t_last": "s", "span_s": "s", "size_bytes": "B"}
        return out


@dataclass(frozen=True)
class PruneResult:
    """What :meth:`SampleStore.prune` did: samples deleted and kept before the cutoff [s UTC]."""

    cutoff: float
    deleted: int
    kept_thinned: int


def tag_map_hash(tag_map: Mapping[str, Any] | str) -> str:
    """SHA-256 (hex) of a tag map, the identity of a site's wiring.

    Parameters
    ----------
    tag_map : mapping or str
        The tag map as a plain dictionary (hashed as JSON with sorted keys, so key order does not
        matter) or as a string (hashed as UTF-8).

    Examples
    --------
    >>> tag_map_hash({"flow": {"address": "ir:20"}}) == tag_map_hash('{"flow":{"address":"ir:20"}}')
    True
    """
    text = (
        tag_map
        if isinstance(tag_map, str)
        else json.dumps(tag_map, sort_keys=True, separators=(",", ":"), default=str)
    )
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


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
    ) -> int:
        """Store samples and events, then re-flag stretches, in one transaction (committed).

        Samples whose ``seq`` (or, without one, ``time``) is already stored are ignored. The
        :class:`Requalify` changes are applied after the inserts, so they reach the samples of
        this same call too.

        Returns
        -------
        int
            Samples actually added.
        """

    def set_quality(self, t_from: float, t_to: float, quality: int = Quality.BAD_VALUE) -> int:
        """Flag the OK samples with ``t_from <= time <= t_to`` [s UTC] (committed on return).

        Samples already flagged keep their flag. Through a :class:`SampleWriter` use
        :meth:`SampleWriter.set_quality`, which keeps the order of the queue.

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
        self, older_than_days: float, thin_to_period_s: float | None = 1.0, now: float | None = None
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


_FLUSH = object()
_STOP = object()


class SampleWriter:
    """The one writer of a store: a thread fed by a queue that commits in batches.

    Samples and events put on the queue are committed together about every
    ``commit_interval_s``; :meth:`flush` and :meth:`close` commit what is pending and wait for it.
    :meth:`set_quality` re-flags a stretch of samples in queue order: it is applied after the
    inserts of the batch it joins, in the same transaction, so it reaches every sample queued
    before it (whether already committed or not) and never races an insert.
    A crash loses at most the uncommitted batch. An error of the store (a full disk) stops the
    writer and is raised by the next :meth:`put`, :meth:`flush` or :meth:`close`.

    Parameters
    ----------
    store : SampleStore
        The store, opened with the site's identity.
    commit_interval_s : float
        Time between commits [s].
    on_commit : callable, optional
        Called in the writer thread after each commit with the samples and events committed.
    """

    def __init__(
        self,
        store: SampleStore,
        commit_interval_s: float = 1.0,
        on_commit: Callable[[Sequence[Sample], Sequence[Event]], None] | None = None,
    ) -> None:
        if not commit_interval_s > 0.0:
            raise StoreError(f"commit interval must be positive, got {commit_interval_s} s")
        self.store = store
        self.commit_interval_s = float(commit_interval_s)
        self.on_commit = on_commit
        self.rows_written = 0
        self.commits = 0
        self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._error: BaseException | None = None
        self._closed = False
        self._thread = threading.Thread(target=self._run, name="fuelid-store-writer", daemon=True)
        self._thread.start()

    def put(self, sample: Sample) -> None:
        """Queue one sample (returns at once)."""
        self._check()
        self._queue.put(sample)

    def put_many(self, samples: Iterable[Sample]) -> None:
        """Queue samples (returns at once)."""
        self._check()
        for sample in samples:
            self._queue.put(sample)

    def event(self, kind: str, detail: str = "", time: float | None = None) -> None:
        """Queue an event at ``time`` [s UTC] (now by default)."""
        self._check()
        self._queue.put(Event(_time.time() if time is None else time, kind, detail))

    def set_quality(self, t_from: float, t_to: float, quality: int = Quality.BAD_VALUE) -> None:
        """Queue a re-flag of the samples with ``t_from <= time <= t_to`` [s UTC] (if OK).

        Applied in queue order: it reaches every sample queued before it, in the same
        transaction as the last of them (see :meth:`SampleStore.set_quality`).
        """
        self._check()
        self._queue.put(Requalify(float(t_from), float(t_to), int(quality)))

    def flush(self, timeout: float | None = 30.0) -> None:
        """Commit everything queued so far and wait for it [timeout in s]."""
        self._check()
        done = threading.Event()
        self._queue.put((_FLUSH, done))
        if not done.wait(timeout):
            raise StoreError(f"{self.store.path}: the writer did not commit within {timeout} s")
        self._check()

    def close(self, timeout: float | None = 30.0) -> None:
        """Commit what is pending and stop the writer thread (the store stays open)."""
        if self._closed:
            return
        self._closed = True
        self._queue.put(_STOP)
        self._thread.join(timeout)
        if self._error is not None:
            raise StoreError(f"{self.store.path}: the writer failed: {self._error}")

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def _check(self) -> None:
        if self._error is not None:
            raise StoreError(f"{self.store.path}: the writer failed: {self._error}")
        if self._closed:
            raise StoreError(f"{self.store.path}: the writer is closed")

    def _commit(self, samples: list[Sample], events: list[Event], changes: list[Requalify]) -> None:
        if not samples and not events and not changes:
            return
        self.rows_written += self.store.append(samples, events, changes)
        self.commits += 1
        if self.on_commit is not None:
            self.on_commit(samples, events)
        samples.clear()
        events.clear()
        changes.clear()

    def _run(self) -> None:
        samples: list[Sample] = []
        events: list[Event] = []
        changes: list[Requalify] = []
        deadline = _time.monotonic() + self.commit_interval_s
        item: Any = None
        try:
            while True:
                try:
                    item = self._queue.get(timeout=max(deadline - _time.monotonic(), 0.0))
                except queue.Empty:
                    item = None
                if isinstance(item, Sample):
                    samples.append(item)
                elif isinstance(item, Event):
                    events.append(item)
                elif isinstance(item, Requalify):
                    changes.append(item)  # applied after this batch's inserts: queue order
                elif item is _STOP:
                    self._commit(samples, events, changes)
                    return
                elif isinstance(item, tuple) and item and item[0] is _FLUSH:
                    self._commit(samples, events, changes)
                    item[1].set()
                if _time.monotonic() >= deadline:
                    self._commit(samples, events, changes)
                    deadline = _time.monotonic() + self.commit_interval_s
        except BaseException as error:  # handed to the caller by the next call
            self._error = error
            if isinstance(item, tuple) and item and item[0] is _FLUSH:
                item[1].set()
            while True:  # release whoever waits on a flush
                try:
                    item = self._queue.get_nowait()
                except queue.Empty:
                    return
                if isinstance(item, tuple) and item and item[0] is _FLUSH:
                    item[1].set()
