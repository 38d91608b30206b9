"""The record command's runner: a site's source and store, a :class:`Recorder`, signals, retention.

:func:`record_site` is what ``fuelid record`` runs: it opens the site's PLC source and its store
(with the site's identity), feeds a :class:`~fuelid.plc._recorder.Recorder` through the store's
one writer in an asyncio loop with SIGINT and SIGTERM bound to a clean stop, reports the live
statistics and applies the store's retention once an hour (:data:`PRUNE_EVERY_S`) and at the end.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Callable
from typing import Any

from fuelid.errors import FuelidError
from fuelid.plc._record_status import RecorderStats
from fuelid.plc._recorder import Recorder, site_identity
from fuelid.plc.adapters._base import PlcSource
from fuelid.plc.site import SiteConfig
from fuelid.store import SampleStore, SampleWriter

__all__ = ["PRUNE_EVERY_S", "record_error", "record_site"]

PRUNE_EVERY_S = 3600.0
"""How often the recorder applies the store's retention (and once at start) [s]."""


def record_error(error: BaseException) -> str:
    """One line for an error that stopped a recording."""
    if isinstance(error, FuelidError):
        return " ".join(str(error).split())
    return f"{type(error).__name__}: {error}"


def record_site(
    site: SiteConfig,
    store_url: str | None = None,
    *,
    duration_s: float | None = None,
    give_up_after_s: float | None = None,
    on_message: Callable[[str], None] | None = None,
    on_status: Callable[[RecorderStats], None] | None = None,
    status_every_s: float = 1.0,
    commit_interval_s: float = 1.0,
    source: PlcSource | None = None,
    archiver: Callable[[SampleStore], object] | None = None,
    **options: Any,
) -> RecorderStats:
    """Record a site into its store until SIGINT/SIGTERM, the duration, or the end of a replay.

    Opens the site's source and store (``store_url``, default ``[store] url``), runs a
    :class:`Recorder` in an asyncio loop with SIGINT and SIGTERM bound to a clean stop (the
    writer commits what is queued before this returns) and calls ``on_status`` about every
    ``status_every_s`` seconds.

    Parameters
    ----------
    site : SiteConfig
        The site file.
    store_url : str, optional
        ``sqlite:///path.db`` or a plain file path.
    duration_s, give_up_after_s : float, optional
        See :meth:`Recorder.run` and :class:`Recorder` [s].
    on_message, on_status : callable, optional
        One-line messages; the live statistics.
    status_every_s, commit_interval_s : float
        Status and commit intervals [s].
    source : PlcSource, optional
        A source to use instead of the site's (tests).
    archiver : callable, optional
        Archives the store's finished days before each retention (the site's ``[archive]``
        with ``auto``: :func:`fuelid.archive.archiver`, passed in by the command, as
        the recorder's layer does not import the archive's). With an ``[archive]`` table
        retention deletes only archived days, whether or not this archives them.
    **options
        Further :class:`Recorder` settings (``ring_poll_s``, ``stuck_after_s``, ``backoff_s``).

    Raises
    ------
    StoreError, ConfigError, LinkError
        The store cannot be opened or written, the PLC refuses an address or device id, or no
        link for ``give_up_after_s``.
    """
    from fuelid.plc.adapters import open_source
    from fuelid.store import open_store

    plc = open_source(site) if source is None else source
    store = open_store(
        store_url or site.store.url,
        period_s=site.sampling.period_s,
        loop_id=site.site.loop_id,
        **site_identity(site),
    )
    try:
        writer = SampleWriter(store, commit_interval_s=commit_interval_s)
        try:
            recorder = Recorder(
                plc, writer, give_up_after_s=give_up_after_s, on_message=on_message, **options
            )

            def housekeeping() -> None:
                # retention counts back from the newest sample (the data's own time base)
                newest = store.last_time()
                if newest is not None:
                    if archiver is not None:
                        try:  # a failed archive only keeps more: retention below is safe
                            archiver(store)
                        except FuelidError as error:
                            recorder._say(f"archive not written: {record_error(error)}")
                    store.prune(
                        site.store.retention_days,
                        site.store.thin_to_s,
                        # a replayed log's own time base; else the wall clock (the samples carry
                        # wall_time: an accelerated virtual PLC's plant time runs ahead of it)
                        now=time.time() if site.plc.protocol != "replay" else newest,
                        archived_only=site.archive is not None,
                    )

            stats = asyncio.run(
                _record(recorder, duration_s, on_status, status_every_s, housekeeping)
            )
            writer.flush()
            try:  # and once at the end, counting back from the newest sample
                housekeeping()
            except FuelidError as error:  # the recording is committed: say it, do not fail
                recorder._say(f"retention not applied: {error}")
            return stats
        finally:
            writer.close()
    finally:
        store.close()


async def _record(
    recorder: Recorder,
    duration_s: float | None,
    on_status: Callable[[RecorderStats], None] | None,
    status_every_s: float,
    housekeeping: Callable[[], None] | None = None,
) -> RecorderStats:
    import signal

    loop = asyncio.get_running_loop()
    bound = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            loop.add_signal_handler(sig, recorder.stop)
            bound.append(sig)
        except (NotImplementedError, RuntimeError, ValueError):  # not the main thread
            pass

    async def status() -> None:
        while True:
            await asyncio.sleep(status_every_s)
            if on_status is not None:
                on_status(recorder.stats)

    async def keep() -> None:
        while housekeeping is not None:
            try:
                await asyncio.to_thread(housekeeping)
            except FuelidError as error:  # retention must never stop the recording
                recorder._say(f"retention not applied: {error}")
            await asyncio.sleep(PRUNE_EVERY_S)

    reporter = asyncio.create_task(status())
    keeper = asyncio.create_task(keep())
    try:
        return await recorder.run(duration_s)
    finally:
        for task in (reporter, keeper):
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
        for sig in bound:
            loop.remove_signal_handler(sig)
