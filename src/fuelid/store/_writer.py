"""The one writer of a store: a thread fed by a queue that commits a batch about once a second."""

from __future__ import annotations

import queue
import threading
import time as _time
from collections.abc import Callable, Iterable, Sequence
from types import TracebackType
from typing import TYPE_CHECKING, Any, Self

from fuelid.store._records import Event, Quality, Requalify, Sample, StateValue, StoreError

if TYPE_CHECKING:
    from fuelid.store._base import SampleStore

__all__ = ["SampleWriter"]

_FLUSH = object()
_STOP = object()


class SampleWriter:
    """The one writer of a store: a thread fed by a queue that commits in batches.

    Samples and events put on the queue are committed together about every
    ``commit_interval_s``; :meth:`flush` and :meth:`close` commit what is pending and wait for it.
    :meth:`set_quality` re-flags a stretch of samples in queue order: it is applied after the
    inserts of the batch it joins, in the same transaction, so it reaches every sample queued
    before it (whether already committed or not) and never races an insert. :meth:`set_state`
    sets a value of the store's state (``online_state``) in the batch's transaction too, the
    newest of a key in a batch winning. A crash loses at most the uncommitted batch. An error
    of the store (a full disk) stops the writer and is raised by the next :meth:`put`,
    :meth:`flush` or :meth:`close`.

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
        self._newest_time: float | None = None  # plant time of the newest sample queued
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
        self._see(sample)
        self._queue.put(sample)

    def put_many(self, samples: Iterable[Sample]) -> None:
        """Queue samples (returns at once)."""
        self._check()
        for sample in samples:
            self._see(sample)
            self._queue.put(sample)

    def newest_time(self) -> float | None:
        """Plant time of the newest sample queued so far [s UTC]; None before the first."""
        return self._newest_time

    def _see(self, sample: Sample) -> None:
        if self._newest_time is None or sample.time > self._newest_time:
            self._newest_time = float(sample.time)

    def event(self, kind: str, detail: str = "", time: float | None = None) -> None:
        """Queue an event at plant ``time`` [s UTC].

        By default the newest sample queued so far (plant time: the samples' time base),
        else the store's newest, else the wall clock; the store adds the wall clock of the
        commit as ``wall_time``.
        """
        self._check()
        if time is None:
            time = self._newest_time
        if time is None:
            time = self.store.last_time()
        self._queue.put(Event(_time.time() if time is None else time, kind, detail))

    def set_quality(self, t_from: float, t_to: float, quality: int = Quality.BAD_VALUE) -> None:
        """Queue a re-flag of the samples with ``t_from <= time <= t_to`` [s UTC] (if OK).

        Applied in queue order: it reaches every sample queued before it, in the same
        transaction as the last of them (see :meth:`SampleStore.set_quality`).
        """
        self._check()
        self._queue.put(Requalify(float(t_from), float(t_to), int(quality)))

    def set_state(self, key: str, value: Any) -> None:
        """Queue ``value`` (JSON; NaN as null) for the store's state under ``key``.

        Committed with the next batch, in its transaction; it replaces the key's value (read
        with :meth:`fuelid.store.OnlineHistory.state`). For values written seldom (on a
        change), not every sample.

        Raises
        ------
        StoreError
            An empty key or a value without a JSON form (refused here, in the caller).
        """
        self._check()
        self._queue.put(StateValue.of(key, value))

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

    def _commit(
        self,
        samples: list[Sample],
        events: list[Event],
        changes: list[Requalify],
        state: dict[str, StateValue],
    ) -> None:
        if not samples and not events and not changes and not state:
            return
        self.rows_written += self.store.append(samples, events, changes, state.values())
        self.commits += 1
        if self.on_commit is not None:
            self.on_commit(samples, events)
        samples.clear()
        events.clear()
        changes.clear()
        state.clear()

    def _run(self) -> None:
        samples: list[Sample] = []
        events: list[Event] = []
        changes: list[Requalify] = []
        state: dict[str, StateValue] = {}  # by key: the newest of the batch wins
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
                elif isinstance(item, StateValue):
                    state[item.key] = item
                elif item is _STOP:
                    self._commit(samples, events, changes, state)
                    return
                elif isinstance(item, tuple) and item and item[0] is _FLUSH:
                    self._commit(samples, events, changes, state)
                    item[1].set()
                if _time.monotonic() >= deadline:
                    self._commit(samples, events, changes, state)
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
