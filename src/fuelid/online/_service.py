"""The online service: record, identify, track K(T), propose PI gains, write them when allowed.

Every few minutes a gated window; proposals under the rules of :mod:`fuelid.online._proposals`;
writes with an echo check. This module wires the parts and runs them in one asyncio loop:

- the recorder (:class:`~fuelid.plc._recorder.Recorder`, exactly as ``fuelid record``) into the
  site's store;
- the schedule (:class:`~fuelid.online._scheduler.Scheduler`): every ``identify_every_s`` of
  data time the last ``window_s`` of samples are analysed, recorded in the history, tracked,
  and the proposal rules consulted (:class:`~fuelid.online._proposal_filing.ProposalFiling`);
- with ``write_back`` "approve" or "auto": the heartbeat, and the writes of approved proposals
  (:class:`~fuelid.online._writeback.WriteBack`) through the PLC handshake on a connection of its
  own (:class:`~fuelid.plc._gain_handshake.GainWriter`);
- the store's retention, hourly;
- with ``[central]``: the sync to the central store every ``send_every_s`` (the outbox, the
  liveness, the central requests: :mod:`fuelid.online._central_link`), in a thread;
- the beat: the ``service`` record of ``online_state`` (:func:`~fuelid.online._liveness.
  service_record`: pid, host, version, settings) has its ``beat`` refreshed every
  :data:`~fuelid.online._liveness.SERVICE_BEAT_S` of wall time, and the waiting requests of the
  CLI and the dashboard are applied (:mod:`fuelid.online._requests`); a clean stop sets its
  ``stopped``. Readers judge the loop with :func:`~fuelid.online._liveness.loop_state`.

Times: the rows the service writes carry plant time in ``time`` (the samples' time base: the
window's analysis time is the newest committed sample's) and the wall clock in ``wall_time``.

Restart: the schedule, the warm start, the tracker, the proposals and the last-known-good gains
are read back from the store; an unfinished write (intent recorded, no verdict) is reconciled
from the PLC's echo before anything else is written.

Failure policy. The tasks run in one :class:`asyncio.TaskGroup`. The recorder is the service:
when it fails (a refusal, a link given up) the other tasks are cancelled and :meth:`run
<OnlineService.run>` raises its error. The schedule (analysis, proposals), the heartbeat and
the retention are supervised: when one fails, ``event kind=task_failed`` is logged at once and
that task ends, while the recorder and the other tasks go on recording and beating — the
recorder never stops for an analysis or a write-back failure. At the end of the run an
unexpected error of a supervised task is raised (a :class:`~fuelid.errors.FuelidError` only
logged), so a bug is not hidden behind a clean exit.

Log lines are structured: ``key=value`` pairs after a fixed event word (``start``,
``window``, ``proposal``, ``write``, ``event`` — reverts are ``event kind=revert`` —,
``recorder``), one per line, for journald or a file; they go to ``on_message`` and to the
``fuelid.online`` logger (:mod:`fuelid.online._logs`).
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Callable, Coroutine
from typing import Any

from fuelid.errors import ConfigError, FuelidError
from fuelid.online._context import (
    COMMISSIONING,
    RECENT_WINDOWS_SPAN,
    TRACKER_OBSERVATIONS,
    ServiceContext,
    ServiceStats,
    model_of,
    observation_of,
)
from fuelid.online._gains import Gains
from fuelid.online._liveness import SERVICE_BEAT_S, service_record
from fuelid.online._proposal_filing import TURNED_DOWN_MEMORY
from fuelid.online._requests import consume_requests
from fuelid.online._scheduler import MAX_CATCH_UP_WINDOWS, SCHEDULE_POLL_S, Scheduler
from fuelid.online._settings import ServiceSite
from fuelid.online._tracking import KTracker, TrackingError
from fuelid.online._window import WindowAnalyser, window_priors
from fuelid.online._worker import AnalyserSpec, WindowWorker
from fuelid.online._writeback import AUTO, IAE_BASELINE_WINDOWS, LIMIT_MARGIN_V, WriteBack
from fuelid.online.excitation._exciter import Exciter, newest_model, plant_model_function
from fuelid.plc import HEARTBEAT_MODULUS, PRUNE_EVERY_S, GainWriter, Recorder
from fuelid.plc.adapters import LinkError, PlcSource
from fuelid.store import SERVICE_KEY, OnlineHistory, SampleWriter, SQLiteStore
from fuelid.tuning import BlockForm


class OnlineService:
    """The online service of one site (see the module docstring).

    Parameters
    ----------
    site : ServiceSite
        The site file.
    store_url : str, optional
        The store (default ``[store] url``).
    source, write_source : PlcSource, optional
        Links to use instead of the site's (tests); the write link defaults to a second
        connection to the same PLC.
    on_message : callable, optional
        Gets each structured log line.
    heartbeat_s : float
        Wall time between heartbeats [s] (the virtual PLC at a speed-up needs them faster).
    step_ls : bool
        Also fit the article's step-ls in every window.
    isolate : bool
        Analyse windows in a worker process (default), so a fit never stalls the recorder;
        False: in a thread of this process.
    """

    def __init__(
        self,
        site: ServiceSite,
        store_url: str | None = None,
        *,
        source: PlcSource | None = None,
        write_source: PlcSource | None = None,
        on_message: Callable[[str], None] | None = None,
        heartbeat_s: float = 1.0,
        step_ls: bool = True,
        isolate: bool = True,
    ) -> None:
        from fuelid.plc import site_identity
        from fuelid.plc.adapters import open_source
        from fuelid.store import open_store

        self.site = site
        self.settings = site.online
        self.heartbeat_s = float(heartbeat_s)
        store = open_store(
            store_url or site.store.url,
            period_s=site.sampling.period_s,
            loop_id=site.site.loop_id,
            **site_identity(site),
        )
        if not isinstance(store, SQLiteStore):  # the history lives in the same SQLite file
            store.close()
            raise ConfigError("store: the online service needs an SQLite store")
        self.store = store
        self.history = OnlineHistory(store)
        self.source = open_source(site) if source is None else source
        self._write_source = write_source
        self.priors, self.k_plant = window_priors(
            site.site.plant, control_period=site.sampling.control_period_s
        )
        self.commissioning = self._commissioning()
        self.context = ServiceContext(
            site, store, self.history, self.priors, self.commissioning, on_message
        )
        self.stats: ServiceStats = self.context.stats
        self.capabilities = self._capabilities()
        self.analyser = WindowAnalyser(
            self.settings,
            self.priors,
            site.sampling.period_s,
            k_plant=self.k_plant,
            step_ls=step_ls,
            ti_s=self.commissioning.Ti if self.commissioning is not None else 1.0,
        )
        self.worker = WindowWorker(
            AnalyserSpec(
                self.settings, self.priors, site.sampling.period_s, site.site.plant, step_ls
            ),
            isolate=isolate,
        )
        self.tracker = KTracker(k_plant=self.k_plant, max_observations=TRACKER_OBSERVATIONS)
        self.write_back = WriteBack(self.context)
        self.scheduler = Scheduler(
            self.context,
            self.analyser,
            self.worker,
            self.tracker,
            self.write_back,
            proposes=bool(self.capabilities["proposes"]),
        )
        self.link: GainWriter | None = None
        """The write connection (gains, heartbeat, test signal); None when nothing writes."""
        self.exciter: Exciter | None = None
        """The test signal (issue 40); None when the site has no ``[write.excitation]``."""
        self._stopping = asyncio.Event()
        self._task_errors: list[BaseException] = []
        self._plant_at_start: float | None = None
        """Plant time the store had reached when this run wrote its record [s UTC]; None: empty."""
        self._resume()

    # --- set-up -----------------------------------------------------------------------------

    def _commissioning(self) -> Gains | None:
        c = self.site.controller
        if c is None or c.kc is None or c.ti is None:
            return None
        return Gains.from_block(
            c.kc,
            c.ti,
            BlockForm.of(c),
            rule=COMMISSIONING,
            control_period=self.site.sampling.control_period_s,
        )

    def _capabilities(self) -> dict[str, Any]:
        """What the service can do with this site's tags, and why not."""
        missing = []
        if "mode" not in self.site.tags:
            missing.append("tags.mode (MAN/AUTO)")
        if "setpoint" not in self.site.tags:
            missing.append("tags.setpoint")
        has_gains = ("kc" in self.site.tags and "ti" in self.site.tags) or (
            self.commissioning is not None
        )
        if not has_gains:
            missing.append("the applied gains (tags.kc and tags.ti) or [controller] kc and ti")
        if self.site.controller is None:
            missing.append("[controller] (the PI block's form and units)")
        proposes = not missing
        writes = proposes and self.settings.write_back != "off"
        excitation = self.site.excitation
        excites = "excitation" in self.site.write and excitation.amplitude is not None
        return {
            "identifies": True,
            "tracks": True,
            "proposes": proposes,
            "writes": writes,
            "excites": excites,
            "excitation": excitation.mode if excites else "off",
            "write_back": self.settings.write_back,
            "missing_for_proposals": missing,
            "plant": self.priors.source,
        }

    def _resume(self) -> None:
        """Warm start, tracker and schedule from the history (a restarted service)."""
        for row in self.history.accepted_models(limit=TRACKER_OBSERVATIONS):
            obs = observation_of(row)
            if obs is not None:
                with contextlib.suppress(TrackingError):
                    self.tracker.update(obs)
        last = self.history.accepted_models(limit=1)
        if last:
            self.analyser.resume(model_of(last[0]["model"]))

    # --- the parts' state, where callers found it before the split --------------------------

    @property
    def on_message(self) -> Callable[[str], None] | None:
        """Gets each structured log line."""
        return self.context.on_message

    @property
    def recorder(self) -> Recorder | None:
        """The recorder (None before :meth:`run`)."""
        return self.context.recorder

    @property
    def writer(self) -> SampleWriter | None:
        """The store's sample writer (None before :meth:`run`)."""
        return self.context.writer

    @property
    def gain_writer(self) -> GainWriter | None:
        """The PLC handshake of the writes (None when the site cannot write)."""
        return self.write_back.gain_writer

    @property
    def fatal(self) -> FuelidError | None:
        """A refusal found while running (the PLC's gains outside the bounds): raised by run."""
        return self.scheduler.fatal

    def current_gains(self) -> Gains | None:
        """The PI's gains now (ideal form, engineering units); see ServiceContext."""
        return self.context.current_gains()

    def next_window_end(self) -> float | None:
        """Data time at which the next window ends [s UTC]; None before any sample."""
        return self.scheduler.next_window_end()

    def gains_refusal(self) -> str | None:
        """Why the PLC's gains make the site's bounds meaningless; None when inside them."""
        return self.scheduler.gains_refusal()

    def write_refusal(self) -> str | None:
        """Why a write may not happen now; None when it may."""
        return self.write_back.write_refusal()

    async def revert(self, *, who: str, why: str, force: bool = False) -> bool:
        """Write the last-known-good gains back (see :meth:`WriteBack.revert`)."""
        return await self.write_back.revert(who=who, why=why, force=force)

    # --- running ----------------------------------------------------------------------------

    async def _housekeeping(self) -> None:
        """The store's retention, at start and hourly, as ``fuelid record`` applies it.

        With an ``[archive]`` table the finished days are archived first (``auto``) and
        retention deletes only archived days (:func:`fuelid.archive._retention.keep_store`).
        """
        from fuelid.archive import keep_store

        archive = self.site.archive
        while not self._stopping.is_set():
            newest = self.store.last_time()
            if newest is not None:
                try:
                    now = newest if self.site.plc.protocol == "replay" else time.time()
                    kept = await asyncio.to_thread(
                        keep_store,
                        self.store,
                        self.site.store.retention_days,
                        self.site.store.thin_to_s,
                        now=now,
                        archive_dir=None if archive is None else archive.dir,
                        auto=archive is not None and archive.auto,
                    )
                    if kept.archive_error is not None:
                        self.context.say("event", kind="archive", detail=kept.archive_error)
                except FuelidError as error:  # retention must never stop the service
                    self.context.say("event", kind="retention", detail=str(error))
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._stopping.wait(), PRUNE_EVERY_S)

    async def _supervised(self, name: str, work: Coroutine[Any, Any, None]) -> None:
        """Run ``work``; a failure is logged and kept, never passed to the task group."""
        try:
            await work
        except Exception as error:  # any failure: the policy of the module docstring
            self._task_errors.append(error)
            detail = f"{name}: {type(error).__name__}: {error}"
            self.context.say("event", kind="task_failed", detail=detail)

    async def _record(self, duration_s: float | None) -> None:
        assert self.recorder is not None
        try:
            await self.recorder.run(duration_s)
        finally:
            self._stopping.set()  # the other tasks end with the recording

    def stop(self) -> None:
        """Ask the service to stop (safe from a signal handler)."""
        self._stopping.set()
        if self.recorder is not None:
            self.recorder.stop()

    async def run(self, duration_s: float | None = None) -> ServiceStats:
        """Run until :meth:`stop`, SIGINT/SIGTERM or ``duration_s`` of wall time."""
        import signal

        loop = asyncio.get_running_loop()
        bound = []
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                loop.add_signal_handler(sig, self.stop)
                bound.append(sig)
            except (NotImplementedError, RuntimeError, ValueError):  # not the main thread
                pass
        writer = SampleWriter(self.store)
        self.context.writer = writer
        # windows, proposals and writes on the clock of the events: the newest sample queued
        self.history.plant_clock = writer.newest_time
        self.context.recorder = Recorder(self.source, writer, on_message=self._recorder_message)
        self.stats.recorder = self.context.recorder.stats
        try:
            async with asyncio.TaskGroup() as tasks:
                await self._start(tasks)
                tasks.create_task(self._record(duration_s), name="recorder")
        except BaseExceptionGroup as group:
            raise group.exceptions[0] from None  # the recorder's error, as itself
        finally:
            self._stopping.set()
            self._mark_stopped()
            if self.link is not None:
                await self.link.close()
            writer.flush()
            for sig in bound:
                loop.remove_signal_handler(sig)
        if self.fatal is not None:
            raise self.fatal
        for error in self._task_errors:
            if not isinstance(error, FuelidError):
                raise error
        return self.stats

    def _mark_stopped(self) -> None:
        """Write the clean stop (``stopped``, wall s UTC) into the service record."""
        with contextlib.suppress(FuelidError):
            running = self.history.state(SERVICE_KEY) or {}
            self.history.set_state(SERVICE_KEY, {**running, "stopped": time.time()})

    async def _start(self, tasks: asyncio.TaskGroup) -> None:
        """Reconcile, say what the service does, start the supervised tasks."""
        from fuelid.plc.adapters import open_source

        if self.capabilities["writes"] or self.capabilities["excites"]:
            # one write connection: the heartbeat runs whenever anything is written (with a
            # test signal on, the PLC zeroes it when the heartbeat stops)
            ws = self._write_source or open_source(self.site)
            self.link = GainWriter(ws, self.settings.echo_timeout_s)
            if self.capabilities["excites"]:
                await self._clear_signal()
            heartbeat = self.link.heartbeat(self._stopping, self.heartbeat_s)
            tasks.create_task(self._supervised("heartbeat", heartbeat), name="heartbeat")
        if self.capabilities["writes"]:
            self.write_back.gain_writer = self.link
            try:
                await self.write_back.reconcile()
            except LinkError as error:
                self.context.say("event", kind="reconcile_deferred", detail=str(error))
        if self.capabilities["excites"]:
            assert self.link is not None
            self.exciter = Exciter(
                self.context,
                self.link,
                model=lambda: newest_model(self.context),
                plant_model=plant_model_function(self.site.site.plant, self.context),
                window_end=self.scheduler.next_window_end,
                k_interval=self._k_interval,
                evidence=self._evidence_since,
            )
            excite = self.exciter.run(self._stopping)
            tasks.create_task(self._supervised("excitation", excite), name="excitation")
        if self.gain_writer is None and self.history.state("revert_requested"):
            # nothing here can write: a request left waiting would fire, unseen, the day
            # write-back is switched on
            self.history.set_state("revert_requested", None)
            self.context.event("revert_refused", "write_back is off: the revert request is dropped")
        record = service_record(self.site, self.site.site.plant)
        record["write_back"] = self.settings.write_back  # where readers before 0.3 look
        # the record's started_plant is set by the beat once this run's first sample is in
        self._plant_at_start = self._plant_reached()
        self.history.set_state(SERVICE_KEY, record)
        tasks.create_task(self._supervised("beat", self._beat()), name="beat")
        self.context.say("start", **self.capabilities)
        if not self.capabilities["proposes"]:
            missing = "; ".join(self.capabilities["missing_for_proposals"])
            self.context.say(
                "event", kind="identify_only", detail=f"no proposals: missing {missing}"
            )
        schedule = self.scheduler.run(self._stopping, self.stop)
        tasks.create_task(self._supervised("schedule", schedule), name="schedule")
        tasks.create_task(self._supervised("retention", self._housekeeping()), name="retention")
        if self.site.central is not None:  # the central store (issue 26): a sync every few s
            from fuelid.online._central_link import CentralLink

            link = CentralLink(
                self.store.path, self.site.central, self.history, self.context.say,
                event=self.context.event,
            )  # fmt: skip
            # the record says stopped before the link's last cycle: the centre learns of it
            sending = link.run(self._stopping, on_stop=self._mark_stopped)
            tasks.create_task(self._supervised("central", sending), name="central")

    async def _beat(self) -> None:
        """Refresh the record's beat and apply the waiting requests, every SERVICE_BEAT_S.

        In a thread: the recorder shares this event loop and never waits on it.
        """
        can_write = self.gain_writer is not None
        setting = self.settings.write_back if can_write else "off"
        started_plant = None
        while not self._stopping.is_set():
            await asyncio.to_thread(self.history.beat)
            if started_plant is None:
                started_plant = await asyncio.to_thread(self._record_started_plant)
            for row in await asyncio.to_thread(consume_requests, self.history, setting):
                self.context.say(
                    "request",
                    id=row["id"],
                    kind=row["kind"],
                    status=row["status"],
                    outcome=row["outcome"],
                    origin=row["origin"],
                )
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._stopping.wait(), SERVICE_BEAT_S)

    def _plant_reached(self) -> float | None:
        """The plant time the store has reached [s UTC]; None when it is empty.

        Its newest sample, or its newest window's analysis time when later (a window judged on
        samples a kill -9 lost before their commit).
        """
        reached = [self.history.plant_now(), (self.history.last_window() or {}).get("time")]
        known = [float(t) for t in reached if isinstance(t, int | float)]
        return max(known) if known else None

    def _record_started_plant(self) -> float | None:
        """Write this run's first sample's plant time into its record (``started_plant``).

        The first sample newer than the plant time the store had reached at the start
        (:meth:`_plant_reached`), once committed; None before. Readers compare it with a
        window's analysis time (plant time) to tell a window judged by this run from one judged
        before its restart (``fuelid.dashboard._fleet``).
        """
        first = self.history.first_sample_after(self._plant_at_start)
        if first is not None:
            self.history.set_record_field("started_plant", first)
        return first

    def _evidence_since(self, t: float) -> int:
        """Accepted windows on separate excitation events ending after ``t`` [s UTC]."""
        from fuelid.online._evidence import independent_windows

        recent = [w for w in self.scheduler.filing.windows_for_proposal() if w.t_to >= t]
        return len(independent_windows(recent, self.settings.agree_windows))

    async def _clear_signal(self) -> None:
        """0 into the signal's register before the first heartbeat.

        A service killed mid-burst left its last value there; the PLC zeroed what it applies
        when the heartbeat stopped, and would apply that value again once the heartbeat comes
        back (unless its own code clears the request, as the how-to's does).
        """
        assert self.link is not None
        try:
            await self.link.set_excitation(0.0)
        except LinkError as error:
            self.context.say(
                "event", kind="excitation_held", detail=f"register not cleared: {error}"
            )

    def _k_interval(self) -> float | None:
        """K's relative standard error the K(T) curve gives at the fuel and command now."""
        latest = self.context.latest
        T_C, u = latest.get("fuel_temperature"), latest.get("command")
        if T_C is None or u is None:
            return None
        try:
            K, se = self.tracker.predict(T_C, u)
        except (TrackingError, FuelidError):
            return None
        return abs(se / K) if K else None

    def _recorder_message(self, message: str) -> None:
        self.context.say("recorder", message=message)

    def close(self) -> None:
        """Close the worker, the writer, the history and the store."""
        self.worker.close()
        if self.writer is not None:
            self.writer.close()
        self.history.close()
        self.store.close()


def _pid() -> int:
    import os

    return os.getpid()


__all__ = [
    "AUTO",
    "HEARTBEAT_MODULUS",
    "IAE_BASELINE_WINDOWS",
    "LIMIT_MARGIN_V",
    "MAX_CATCH_UP_WINDOWS",
    "RECENT_WINDOWS_SPAN",
    "SCHEDULE_POLL_S",
    "TRACKER_OBSERVATIONS",
    "TURNED_DOWN_MEMORY",
    "GainWriter",
    "OnlineService",
    "ServiceStats",
    "observation_of",
]
