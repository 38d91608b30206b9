"""The online service's schedule: when a window is due, its analysis, and what follows it.

Every ``identify_every_s`` of *data* time (the samples' own clock, so a replayed or accelerated
plant keeps the same schedule) the last ``window_s`` of samples are analysed in a worker
(:class:`~fuelid.online._worker.WindowWorker`); the verdict and model go into the history
(:class:`~fuelid.store.OnlineHistory`), accepted models into the K(T) tracker, then the
write-back judges its last write and the proposal rules may file a proposal. After an outage
at most :data:`MAX_CATCH_UP_WINDOWS` overdue windows are analysed; a window already in the
history (a service killed before moving the schedule on) is never analysed twice. Between
windows the scheduler lets the write-back do the writes that are due.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import Callable
from typing import Any

from fuelid.errors import ConfigError, FuelidError
from fuelid.online._context import ServiceContext, observation_of
from fuelid.online._proposal_filing import ProposalFiling
from fuelid.online._tracking import KTracker, TrackingError
from fuelid.online._window import WindowAnalyser, WindowResult
from fuelid.online._worker import WindowWorker
from fuelid.online._writeback import WriteBack
from fuelid.tuning import BlockForm, from_block

SCHEDULE_POLL_S = 0.25
"""Wall time between looks at the store's newest sample [s]."""
MAX_CATCH_UP_WINDOWS = 3
"""After an outage, at most this many overdue windows are analysed; older ones are skipped."""


class Scheduler:
    """Runs the windows on the data clock (see the module docstring).

    Parameters
    ----------
    context : ServiceContext
        The service's shared state.
    analyser : WindowAnalyser
        Keeps the warm start (the last accepted model) and the integral time between windows.
    worker : WindowWorker
        Analyses one window in a thread or a worker process.
    tracker : KTracker
        Gets every accepted window's K.
    write_back : WriteBack
        Judges the last write after each window, and writes between windows.
    proposes : bool
        False when the site lacks what proposals need (identify and track only).
    """

    def __init__(
        self,
        context: ServiceContext,
        analyser: WindowAnalyser,
        worker: WindowWorker,
        tracker: KTracker,
        write_back: WriteBack,
        *,
        proposes: bool,
    ) -> None:
        self.context = context
        self.history = context.history
        self.settings = context.settings
        self.analyser = analyser
        self.worker = worker
        self.tracker = tracker
        self.write_back = write_back
        self.proposes = proposes
        self.filing = ProposalFiling(context, tracker)
        self.fatal: FuelidError | None = None
        """A refusal found while running (the PLC's gains outside the bounds)."""

    def next_window_end(self) -> float | None:
        """Data time at which the next window ends [s UTC]; None before any sample."""
        due = self.history.state("next_window_end")
        if due is not None:
            return float(due)
        first = self.history.state("first_sample_time")
        if first is None:
            first = self.context.store.first_time()
            if first is None:
                return None
            self.history.set_state("first_sample_time", first)
        return float(first) + self.settings.window_s

    def gains_refusal(self) -> str | None:
        """Why the PLC's gains make the site's bounds meaningless; None when they are inside.

        The hard bounds are ``gain_bounds`` × the commissioning gains; gains in the PLC outside
        them (set by hand, or a wrong ``[controller]`` table) would make every proposal a jump:
        the service refuses to propose from them.
        """
        c = self.context.site.controller
        commissioning = self.context.commissioning
        latest = self.context.latest
        if c is None or commissioning is None or "kc" not in latest or "ti" not in latest:
            return None
        if not (latest["kc"] > 0.0 and latest["ti"] > 0.0):
            return None
        Kc, Ti = from_block(latest["kc"], latest["ti"], BlockForm.of(c))
        low, high = self.settings.gain_bounds
        for name, value, base in (
            ("Kc", Kc, commissioning.Kc),
            ("Ti", Ti, commissioning.Ti),
        ):
            if not low * base * (1 - 1e-6) <= value <= high * base * (1 + 1e-6):
                return (
                    f"the PLC's {name} = {value:.6g} lies outside [online] gain_bounds "
                    f"[{low:g}, {high:g}] x the commissioning {name} {base:.6g} ([controller]): "
                    "correct [controller] kc/ti or the bounds"
                )
        return None

    def _gains_known(self) -> bool:
        """True once the gains to check are known (the first reading of tags kc/ti, if any)."""
        if not self.proposes or self.context.recorder is None:
            return False
        return "kc" in self.context.latest or "kc" not in self.context.site.tags

    async def run(self, stopping: asyncio.Event, stop: Callable[[], None]) -> None:
        """Analyse the windows as they fall due until ``stopping`` is set.

        Parameters
        ----------
        stopping : asyncio.Event
            Set when the service stops.
        stop : callable
            Stops the service (called, with :attr:`fatal` set, when the PLC's gains lie
            outside the bounds).
        """
        checked = False
        while not stopping.is_set():
            if not checked and self._gains_known():
                checked = True
                refusal = self.gains_refusal()
                if refusal is not None:
                    self.fatal = ConfigError(refusal)
                    stop()
                    return
            newest = self.context.store.last_time()
            due = self.next_window_end()
            if newest is not None and due is not None and newest >= due:
                every = self.settings.identify_every_s
                overdue = int((newest - due) // every)
                if overdue >= MAX_CATCH_UP_WINDOWS:
                    skipped = overdue - MAX_CATCH_UP_WINDOWS + 1
                    due += skipped * every
                    self.context.event(
                        "windows_skipped", f"{skipped} window(s) overdue after an outage"
                    )
                last = self.history.last_window()
                if last is not None and float(last["t_to"]) >= due:
                    # stopped between recording this window and moving the schedule on (kill
                    # -9): the window is in the history already; never analyse it twice
                    self.history.set_state("next_window_end", float(last["t_to"]) + every)
                    continue
                await self.window(due, due + every)
                continue
            await self.write_back.writes_due()
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(stopping.wait(), SCHEDULE_POLL_S)

    async def window(self, t_to: float, next_end: float) -> None:
        """Analyse the window ending at ``t_to`` [s UTC] and move the schedule to ``next_end``."""
        t_from = t_to - self.settings.window_s
        samples = await asyncio.to_thread(self.context.store.read, t_from, t_to)
        gains = self.context.current_gains()
        ti_s = gains.Ti if gains is not None else self.analyser.ti_s
        result = await self.worker.analyse(samples, t_from, t_to, ti_s, self.analyser.last_model_)
        self._record_window(result)
        # the schedule moves on at once: what follows (a proposal, a revert waiting for its
        # echo) may be cut short by a kill, the window must not be analysed again
        self.history.set_state("next_window_end", next_end)
        if result.accepted:
            self.analyser.accept(result)
        await self._after_window(result)

    def _record_window(self, result: WindowResult) -> None:
        context = self.context
        detail = result.to_json()
        model = None
        if result.accepted and result.model is not None:
            model = {
                **(result.model_json() or {}),
                "T_fuel": result.T_fuel_C,
                "u_mean": result.u_mean,
                "events": list(result.verdict.excitation_events),
                "plant_K": result.plant_K,
                "window_end": result.t_to,
            }
        window_id, model_id = self.history.add_window(
            t_from=result.t_from,
            t_to=result.t_to,
            accepted=result.accepted,
            reason=result.reason,
            T_fuel=result.T_fuel_C,
            u_mean=result.u_mean,
            detail=detail,
            model=model,
        )
        context.stats.windows += 1
        context.stats.accepted += int(result.accepted)
        context.stats.last_window = {"id": window_id, **detail}
        if result.accepted:  # a rejected window's K is no evidence of pump wear
            for flag in result.verdict.events:
                context.event("plant_ratio", flag, result.t_to)
        K = result.model.K if result.model is not None else math.nan
        context.say(
            "window",
            id=window_id,
            end=result.t_to,
            accepted=result.accepted,
            mode=result.verdict.mode or "-",
            K=K,
            T_fuel=result.T_fuel_C if result.T_fuel_C is not None else math.nan,
            seconds=result.seconds,
            reason=result.reason,
        )
        if model_id is not None and result.model is not None and result.u_mean is not None:
            self._track({"id": model_id, "model": model, "t_to": result.t_to})

    def _track(self, row: dict[str, Any]) -> None:
        obs = observation_of(row)
        if obs is None:
            return
        try:
            self.tracker.update(obs)
        except TrackingError as error:
            if len(self.tracker.observations) >= 2:  # one window is not a failure
                self.context.say("event", kind="tracking", detail=str(error))

    async def _after_window(self, result: WindowResult) -> None:
        await self.write_back.check_revert(result)
        if not self.proposes:
            return
        if self.write_back.settling():  # judge the last write before proposing the next
            return
        self.filing.consider(result)


__all__ = ["MAX_CATCH_UP_WINDOWS", "SCHEDULE_POLL_S", "Scheduler"]
