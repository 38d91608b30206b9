"""The online service: record, identify, track K(T), propose PI gains, write them when allowed.

Every few minutes a gated window; proposals under the rules of :mod:`fuelid.online.proposals`;
writes with an echo check.

One asyncio loop runs

- the recorder (:class:`~fuelid.plc.recorder.Recorder`, exactly as ``fuelid record``) into the
  site's store;
- the schedule: every ``identify_every_s`` of *data* time (the samples' own clock, so a replayed
  or accelerated plant keeps the same schedule) the last ``window_s`` of samples are analysed in
  a worker thread (:class:`~fuelid.online.window.WindowAnalyser`), the verdict and model go into
  the history (:class:`~fuelid.store.OnlineHistory`), accepted models into the K(T) tracker, and
  the proposal rules (:func:`~fuelid.online.proposals.propose`) decide whether to propose;
- with ``write_back`` "approve" or "auto": the heartbeat, and the writes of approved proposals
  on a connection of their own (:class:`GainWriter`).

Restart: the schedule, the warm start, the tracker, the proposals and the last-known-good gains
are read back from the store; an unfinished write (intent recorded, no verdict) is reconciled
from the PLC's echo before anything else is written.

Writes (docs online.md §5): never in MAN, with the command at a limit, while the loop oscillates
or with the link down; the intent is committed before the PLC is written; the echo of the apply
number must come back within ``echo_timeout_s``, otherwise the last-known-good gains are written
back and an event raised. A write is the block (Kc, Ti, a new apply number) in the
``[controller]`` form and units.

Log lines are structured: ``key=value`` pairs after a fixed event word (``start``,
``window``, ``proposal``, ``write``, ``event`` — reverts are ``event kind=revert`` —,
``recorder``), one per line, for journald or a file.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fuelid.errors import ConfigError, FuelidError
from fuelid.io.jsonsafe import json_ready
from fuelid.model import ProcessModel
from fuelid.online.proposals import (
    Gains,
    ProposalDecision,
    WindowModel,
    controller_to_ideal,
    ideal_to_controller,
    propose,
)
from fuelid.online.tracking import GainObservation, KTracker, TrackingError
from fuelid.online.window import WindowAnalyser, WindowResult, window_priors
from fuelid.online.worker import AnalyserSpec, WindowWorker
from fuelid.plc.adapters.base import LinkError, PlcSource
from fuelid.plc.recorder import PRUNE_EVERY_S, Recorder, RecorderStats, site_identity
from fuelid.plc.site import SiteConfig
from fuelid.store.base import SampleWriter
from fuelid.store.online import OnlineHistory
from fuelid.store.sqlite import SQLiteStore

AUTO = 1
SCHEDULE_POLL_S = 0.25
"""Wall time between looks at the store's newest sample [s]."""
MAX_CATCH_UP_WINDOWS = 3
"""After an outage, at most this many overdue windows are analysed; older ones are skipped."""
TRACKER_OBSERVATIONS = 2000
"""Accepted windows kept by the K(T) tracker (a week at 5-minute windows): bounded memory."""
HEARTBEAT_MODULUS = 65536
RECENT_WINDOWS_SPAN = 6.0
"""Windows for a proposal end within this many window lengths (or agree_windows × the
schedule, if longer) of the newest: a model from before an outage of days does not vote."""
TURNED_DOWN_MEMORY = 20
"""Rejected or reverted proposals whose gains are not proposed again (the newest this many)."""
IAE_BASELINE_WINDOWS = 6
"""Windows before a write whose median IAE per unit step is the revert rule's baseline."""
LIMIT_MARGIN_V = 0.01
"""A command within this of a limit counts as at the limit [V]."""


def _log_line(word: str, **fields: Any) -> str:
    """``word key=value …``: floats to 6 significant digits, times [s UTC] to the millisecond."""
    parts = [word]
    for key, value in fields.items():
        if isinstance(value, float):
            # a time since the epoch needs all its digits: 6 significant ones are ±5000 s
            text = f"{value:.3f}" if abs(value) >= 1e6 else f"{value:.6g}"
        else:
            text = str(value)
        if " " in text or not text:
            text = '"' + text.replace('"', "'") + '"'
        parts.append(f"{key}={text}")
    return " ".join(parts)


@dataclass
class ServiceStats:
    """What the service has done in this run."""

    windows: int = 0
    accepted: int = 0
    proposals: int = 0
    writes: int = 0
    reverts: int = 0
    recorder: RecorderStats | None = None
    last_window: dict[str, Any] = field(default_factory=dict)

    def line(self) -> str:
        """One status line."""
        rec = self.recorder.line() if self.recorder is not None else "recorder not started"
        return (
            f"{rec} | {self.windows} windows, {self.accepted} accepted, "
            f"{self.proposals} proposals, {self.writes + self.reverts} writes "
            f"({self.reverts} reverts)"
        )


class GainWriter:
    """Writes one gain block and checks the PLC's echo, on a connection of its own.

    Parameters
    ----------
    source : PlcSource
        A second connection to the PLC (the recorder keeps its own).
    timeout_s : float
        How long to wait for the echo [s of wall time].
    """

    def __init__(self, source: PlcSource, timeout_s: float) -> None:
        self.source = source
        self.timeout_s = float(timeout_s)
        self._connected = False
        self._heartbeat = 0
        self._lock: asyncio.Lock | None = None

    async def _ensure(self) -> None:
        if not self._connected:
            await self.source.connect()
            self._connected = True

    async def close(self) -> None:
        """Close the write connection (also after a link error, so no socket is left open)."""
        with contextlib.suppress(Exception):
            await self.source.close()
        self._connected = False

    def _guard(self) -> asyncio.Lock:
        # one request at a time on this link: the heartbeat task and a write must not race
        # (two connects of one client leave a transport open)
        if self._lock is None:
            self._lock = asyncio.Lock()
        return self._lock

    async def beat(self) -> None:
        """Change the heartbeat word (any change counts; the uint16 wraps)."""
        async with self._guard():
            try:
                await self._ensure()
                self._heartbeat = (self._heartbeat + 1) % HEARTBEAT_MODULUS
                await self.source.write({"heartbeat": float(self._heartbeat)})
            except LinkError:
                await self.close()
                raise

    async def echo(self) -> int | None:
        """The PLC's echo of the last apply number taken; None when it cannot be read."""
        async with self._guard():
            return await self._echo()

    async def _echo(self) -> int | None:
        try:
            await self._ensure()
            values = await self.source.read_write_side(["echo"])
        except LinkError:
            await self.close()
            return None
        value = values.get("echo", math.nan)
        return round(value) if math.isfinite(value) else None

    async def write_block(self, kc: float, ti: float, apply_seq: int) -> bool:
        """Write (kc, ti, apply) in one request and wait for the echo; True when echoed."""
        async with self._guard():
            try:
                await self._ensure()
                await self.source.write({"kc": kc, "ti": ti, "apply": float(apply_seq)})
            except LinkError:
                await self.close()
                # it may or may not have arrived: the echo says
        deadline = time.monotonic() + self.timeout_s
        while time.monotonic() < deadline:
            if await self.echo() == apply_seq:
                return True
            await asyncio.sleep(min(0.05, self.timeout_s / 20.0))
        return False


class OnlineService:
    """The online service of one site (see the module docstring).

    Parameters
    ----------
    site : SiteConfig
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
        site: SiteConfig,
        store_url: str | None = None,
        *,
        source: PlcSource | None = None,
        write_source: PlcSource | None = None,
        on_message: Callable[[str], None] | None = None,
        heartbeat_s: float = 1.0,
        step_ls: bool = True,
        isolate: bool = True,
    ) -> None:
        from fuelid.plc.adapters import open_source
        from fuelid.store import open_store

        self.site = site
        self.settings = site.online
        self.on_message = on_message
        self.heartbeat_s = float(heartbeat_s)
        self.stats = ServiceStats()
        store = open_store(
            store_url or site.store.url, period_s=site.sampling.period_s, **site_identity(site)
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
                self.settings,
                self.priors,
                site.sampling.period_s,
                _plant_path(site),
                step_ls,
            ),
            isolate=isolate,
        )
        self.tracker = KTracker(k_plant=self.k_plant, max_observations=TRACKER_OBSERVATIONS)
        self.recorder: Recorder | None = None
        self.writer: SampleWriter | None = None
        self.gain_writer: GainWriter | None = None
        self._stopping = asyncio.Event()
        self.fatal: FuelidError | None = None
        """A refusal found while running (the PLC's gains outside the bounds): raised by run."""
        self._resume()

    # --- set-up -----------------------------------------------------------------------------

    def _commissioning(self) -> Gains | None:
        c = self.site.controller
        if c is None or c.kc is None or c.ti is None:
            return None
        return controller_to_ideal(c.kc, c.ti, c)

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
        return {
            "identifies": True,
            "tracks": True,
            "proposes": proposes,
            "writes": writes,
            "write_back": self.settings.write_back,
            "missing_for_proposals": missing,
            "plant": self.priors.source,
        }

    def _resume(self) -> None:
        """Warm start, tracker and schedule from the history (a restarted service)."""
        for row in self.history.accepted_models(limit=TRACKER_OBSERVATIONS):
            obs = _observation(row)
            if obs is not None:
                with contextlib.suppress(TrackingError):
                    self.tracker.update(obs)
        last = self.history.accepted_models(limit=1)
        if last:
            self.analyser.resume(_model_of(last[0]["model"]))

    def _say(self, word: str, **fields: Any) -> None:
        if self.on_message is not None:
            self.on_message(_log_line(word, **fields))

    def _event(self, kind: str, detail: str, t: float | None = None) -> None:
        if self.writer is not None:
            self.writer.event(kind, detail, t)
        self._say("event", kind=kind, detail=detail)

    # --- the current gains ------------------------------------------------------------------

    def current_gains(self) -> Gains | None:
        """The PI's gains now (ideal form, engineering units).

        The PLC's when its kc and ti are read, else the last verified write, else the
        commissioning gains.
        """
        c = self.site.controller
        latest = self.recorder.latest if self.recorder is not None else {}
        if c is not None and latest.get("kc", 0.0) > 0.0 and latest.get("ti", 0.0) > 0.0:
            return controller_to_ideal(latest["kc"], latest["ti"], c)
        applied = self.history.state("current_gains")
        if applied is not None:
            return Gains(float(applied["Kc"]), float(applied["Ti"]))
        return self.commissioning

    # --- the schedule -----------------------------------------------------------------------

    def next_window_end(self) -> float | None:
        """Data time at which the next window ends [s UTC]; None before any sample."""
        due = self.history.state("next_window_end")
        if due is not None:
            return float(due)
        first = self.history.state("first_sample_time")
        if first is None:
            first = self.store.first_time()
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
        c = self.site.controller
        latest = self.recorder.latest if self.recorder is not None else {}
        if c is None or self.commissioning is None or "kc" not in latest or "ti" not in latest:
            return None
        if not (latest["kc"] > 0.0 and latest["ti"] > 0.0):
            return None
        now = controller_to_ideal(latest["kc"], latest["ti"], c)
        low, high = self.settings.gain_bounds
        for name, value, base in (
            ("Kc", now.Kc, self.commissioning.Kc),
            ("Ti", now.Ti, self.commissioning.Ti),
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
        if not self.capabilities["proposes"] or self.recorder is None:
            return False
        return "kc" in self.recorder.latest or "kc" not in self.site.tags

    async def _schedule(self) -> None:
        checked = False
        while not self._stopping.is_set():
            if not checked and self._gains_known():
                checked = True
                refusal = self.gains_refusal()
                if refusal is not None:
                    self.fatal = ConfigError(refusal)
                    self.stop()
                    return
            newest = self.store.last_time()
            due = self.next_window_end()
            if newest is not None and due is not None and newest >= due:
                every = self.settings.identify_every_s
                overdue = int((newest - due) // every)
                if overdue >= MAX_CATCH_UP_WINDOWS:
                    skipped = overdue - MAX_CATCH_UP_WINDOWS + 1
                    due += skipped * every
                    self._event("windows_skipped", f"{skipped} window(s) overdue after an outage")
                last = self.history.last_window()
                if last is not None and float(last["t_to"]) >= due:
                    # stopped between recording this window and moving the schedule on (kill
                    # -9): the window is in the history already; never analyse it twice
                    self.history.set_state("next_window_end", float(last["t_to"]) + every)
                    continue
                await self._window(due, due + every)
                continue
            await self._writes_due()
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._stopping.wait(), SCHEDULE_POLL_S)

    async def _window(self, t_to: float, next_end: float) -> None:
        t_from = t_to - self.settings.window_s
        samples = await asyncio.to_thread(self.store.read, t_from, t_to)
        gains = self.current_gains()
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
        detail = result.to_dict()
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
        self.stats.windows += 1
        self.stats.accepted += int(result.accepted)
        self.stats.last_window = {"id": window_id, **detail}
        if result.accepted:  # a rejected window's K is no evidence of pump wear
            for flag in result.verdict.events:
                self._event("plant_ratio", flag, result.t_to)
        K = result.model.K if result.model is not None else math.nan
        self._say(
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
            obs = _observation({"id": model_id, "model": model, "t_to": result.t_to})
            if obs is not None:
                try:
                    self.tracker.update(obs)
                except TrackingError as error:
                    if len(self.tracker.observations_) >= 2:  # one window is not a failure
                        self._say("event", kind="tracking", detail=str(error))

    # --- proposals --------------------------------------------------------------------------

    def _windows_for_proposal(self) -> list[WindowModel]:
        """The recent accepted windows: evidence older than the recency span does not vote."""
        rows = self.history.accepted_models(limit=50)
        if not rows:
            return []
        span = RECENT_WINDOWS_SPAN * max(
            self.settings.window_s, self.settings.identify_every_s * self.settings.agree_windows
        )
        newest = max(float(row["t_to"]) for row in rows)
        out = []
        for row in rows:
            if float(row["t_to"]) < newest - span:
                continue
            m = row["model"]
            model = _model_of(m)
            if model is None:
                continue
            out.append(
                WindowModel(
                    model_id=int(row["id"]),
                    t_from=float(row["t_from"]),
                    t_to=float(row["t_to"]),
                    model=model,
                    stderr=dict(m.get("stderr") or {}),
                    T_fuel_C=m.get("T_fuel"),
                    u_mean=float(m.get("u_mean") or math.nan),
                    events=tuple(float(e) for e in m.get("events") or ()),
                )
            )
        return out

    def _k_range(self, result: WindowResult) -> tuple[float, float] | None:
        if result.model is None or len(self.tracker.observations_) < 2:
            return None
        T_C = result.T_fuel_C if result.T_fuel_C is not None else 20.0
        try:
            K, se = self.tracker.predict(T_C, result.u_mean, K_plant=result.plant_K)
        except TrackingError:
            return None
        if not (math.isfinite(K) and math.isfinite(se)):
            return None
        return max(K - 2.0 * se, 1e-9), K + 2.0 * se

    async def _after_window(self, result: WindowResult) -> None:
        await self._check_revert(result)
        if not self.capabilities["proposes"]:
            return
        gains = self.current_gains()
        if gains is None or self.commissioning is None:
            return
        if self._settling():  # judge the last write before proposing the next
            return
        oscillating = bool(result.health is not None and result.health.oscillation.oscillating)
        tuned_for = _model_of(self.history.state("tuned_for"))
        decision = propose(
            self._windows_for_proposal(),
            gains,
            self.commissioning,
            self.settings,
            control_period=self.site.sampling.control_period_s,
            tuned_for=tuned_for,
            K_range=self._k_range(result),
            oscillating=oscillating,
        )
        if not decision.propose or decision.new is None:
            return
        self._new_proposal(decision)

    def _new_proposal(self, decision: ProposalDecision) -> int:
        c = self.site.controller
        assert c is not None
        assert decision.new is not None
        old_kc, old_ti = ideal_to_controller(decision.old, c)
        new_kc, new_ti = ideal_to_controller(decision.new, c)
        open_ones = self.history.proposals(["pending", "approved"])
        for old in open_ones:
            if self._same_gains(old, new_kc, new_ti, 0.5 * self.settings.hysteresis):
                return int(old["id"])  # the open proposal says the same: keep it (and approval)
        turned_down = self.history.proposals(["rejected", "reverted"])[-TURNED_DOWN_MEMORY:]
        for old in reversed(turned_down):
            if self._same_gains(old, new_kc, new_ti, self.settings.hysteresis):
                # a person rejected these gains, or they were reverted: do not ask again until
                # the evidence moves them by more than the hysteresis
                if self.history.state("held_proposal") != old["id"]:
                    self.history.set_state("held_proposal", old["id"])
                    self._say(
                        "proposal",
                        held=f"the gains of #{old['id']} ({old['status']}) are not proposed again",
                        Kc=new_kc,
                        Ti=new_ti,
                    )
                return int(old["id"])
        for old in open_ones:
            self.history.set_proposal_status(
                old["id"], "superseded", who="service", why="a newer proposal"
            )
        detail = json_ready(
            {
                **decision.to_dict(),
                "Ms": decision.Ms,
                "reason": decision.reason,
                "ideal": {"old": decision.old.to_dict(), "new": decision.new.to_dict()},
                "target_model": self._target_model(decision),
            }
        )
        pid = self.history.add_proposal(
            model_id=decision.model_ids[0] if decision.model_ids else None,
            old={"Kc": old_kc, "Ti": old_ti},
            new={"Kc": new_kc, "Ti": new_ti},
            detail=detail,
        )
        self.stats.proposals += 1
        self._say("proposal", id=pid, Kc=new_kc, Ti=new_ti, reason=decision.reason)
        if self.settings.write_back == "auto":
            self.history.set_proposal_status(
                pid, "approved", who="service (write_back = auto)", why="passed every rule"
            )
        return pid

    @staticmethod
    def _same_gains(proposal: dict[str, Any], kc: float, ti: float, tolerance: float) -> bool:
        """True when ``proposal``'s new gains are within ``tolerance`` (relative) of kc, ti."""
        new = proposal.get("new") or {}
        try:
            return all(
                abs(float(new[key]) / value - 1.0) <= tolerance
                for key, value in (("Kc", kc), ("Ti", ti))
            )
        except (KeyError, TypeError, ValueError, ZeroDivisionError):
            return False

    def _target_model(self, decision: ProposalDecision) -> dict[str, Any] | None:
        if not decision.model_ids:
            return None
        row = self.history.model(decision.model_ids[0])
        return None if row is None else row["model"].get("model")

    # --- writes -----------------------------------------------------------------------------

    def write_refusal(self) -> str | None:
        """Why a write may not happen now; None when it may."""
        if self.recorder is None or not self.recorder.connected:
            return "the link is down"
        latest = self.recorder.latest
        age = time.time() - self.recorder.last_reading
        if not (age < max(5.0, 10 * self.site.sampling.period_s)):
            return "no fresh reading from the PLC"
        mode = latest.get("mode")
        if mode is None or round(mode) != AUTO:
            return "the loop is not in AUTO"
        u = latest.get("command", math.nan)
        low, high = self.priors.u_limits
        if not math.isfinite(u) or u <= low + LIMIT_MARGIN_V or u >= high - LIMIT_MARGIN_V:
            return "the command is at an output limit"
        last = self.history.last_window()
        if last is not None:
            health = last["detail"].get("health") or {}
            if (health.get("oscillation") or {}).get("oscillating"):
                return "the loop oscillates"
        return None

    async def _writes_due(self) -> None:
        if self.gain_writer is None:
            return
        if self.history.unfinished_writes():  # a write left half done: settle it first
            try:
                await self._reconcile()
            except LinkError:
                return
        revert = self.history.state("revert_requested")
        if revert:
            refusal = self.write_refusal()
            if refusal is None or refusal == "the loop oscillates":
                self.history.set_state("revert_requested", None)
                why = str(revert.get("why") or "requested")
                await self.revert(who=str(revert.get("who", "user")), why=why)
            return
        for proposal in self.history.proposals("approved"):
            stale = self._stale(proposal)
            if stale is not None:
                self.history.set_proposal_status(proposal["id"], "superseded", who="service",
                                                 why=stale)  # fmt: skip
                self._say("write", proposal=proposal["id"], held=stale)
                continue
            refusal = self.write_refusal()
            if refusal is not None:
                if self.history.state("write_held") != refusal:
                    self.history.set_state("write_held", refusal)
                    self._say("write", proposal=proposal["id"], held=refusal)
                return
            self.history.set_state("write_held", None)
            await self._write_proposal(proposal)

    def _stale(self, proposal: dict[str, Any]) -> str | None:
        """Why an approved proposal is too old to write; None when fresh.

        Its evidence predates the recent windows (e.g. across a restart and a change of fuel
        temperature): new windows will propose afresh.
        """
        model_id = proposal.get("model_id")
        newest = self.store.last_time()
        if model_id is None or newest is None:
            return None
        row = self.history.model(int(model_id))
        if row is None:
            return None
        span = RECENT_WINDOWS_SPAN * self.settings.window_s
        if float(row["t_to"]) < newest - span:
            return (
                f"stale: its newest window ended {newest - float(row['t_to']):.0f} s of data "
                f"before the newest sample (> {span:.0f} s); new windows will propose afresh"
            )
        return None

    async def _next_apply(self) -> int:
        assert self.gain_writer is not None
        echo = await self.gain_writer.echo()
        last = self.history.last_apply_seq() or 0
        return max(last, echo or 0) + 1

    async def _write_proposal(self, proposal: dict[str, Any]) -> None:
        assert self.gain_writer is not None
        kc, ti = float(proposal["new"]["Kc"]), float(proposal["new"]["Ti"])
        apply_seq = await self._next_apply()
        history = proposal.get("history") or []
        who = history[-1]["who"] if history else "service"
        write_id = self.history.begin_write(
            kind="proposal",
            kc=kc,
            ti=ti,
            apply_seq=apply_seq,
            who=who,
            why=f"proposal {proposal['id']}: {proposal['detail'].get('reason', '')}",
            proposal_id=proposal["id"],
        )
        self.history.set_proposal_status(proposal["id"], "writing", who="service", why="")
        echoed = await self.gain_writer.write_block(kc, ti, apply_seq)
        self.stats.writes += 1
        if echoed:
            self.history.finish_write(write_id, "verified", {"echo": apply_seq})
            self.history.set_proposal_status(proposal["id"], "applied", who="service", why="echo")
            self._applied(proposal)
            self._say("write", proposal=proposal["id"], apply=apply_seq, Kc=kc, Ti=ti, ok=True)
            return
        self.history.finish_write(write_id, "failed", {"reason": "no echo"})
        self.history.set_proposal_status(
            proposal["id"], "failed", who="service", why="no echo within the timeout"
        )
        self._event("write_failed", f"proposal {proposal['id']}: no echo of apply {apply_seq}")
        await self.revert(who="service", why="no echo of the last write", force=True)

    def _applied(self, proposal: dict[str, Any]) -> None:
        detail = proposal["detail"]
        ideal = detail.get("ideal") or {}
        old = ideal.get("old")
        if old is not None:
            self.history.set_state("last_known_good", old)
        self.history.set_state("current_gains", ideal.get("new"))
        self.history.set_state("tuned_for", detail.get("target_model"))
        self.history.set_state(
            "last_write",
            {
                "proposal": proposal["id"],
                "time": time.time(),
                "data_time": self.store.last_time(),
                "iae_before": self._iae_before(),
                "judged": False,
            },
        )

    def _iae_before(self) -> float | None:
        """Median IAE per unit setpoint step of the last windows before a write [s]."""
        values = []
        for window in self.history.windows(limit=IAE_BASELINE_WINDOWS):
            iae = (window["detail"].get("health") or {}).get("iae_per_unit_step_s")
            if isinstance(iae, int | float) and math.isfinite(iae):
                values.append(float(iae))
        return float(np.median(values)) if values else None

    async def revert(self, *, who: str, why: str, force: bool = False) -> bool:
        """Write the last-known-good gains back (the commissioning gains when none is kept).

        Not written when the PLC already reads those gains, unless ``force`` (after a write
        whose echo was lost the PLC's state is not known for sure: the block is written).
        """
        if self.gain_writer is None or self.site.controller is None:
            return False
        good = self.history.state("last_known_good")
        gains = Gains(float(good["Kc"]), float(good["Ti"])) if good else self.commissioning
        if gains is None:
            self._event("revert_failed", "no last-known-good or commissioning gains")
            return False
        now = None if force else self.current_gains()
        if now is not None and all(
            math.isclose(a, b, rel_tol=1e-6) for a, b in ((now.Kc, gains.Kc), (now.Ti, gains.Ti))
        ):
            self._event("revert", f"nothing to write: the PLC holds those gains ({why}, by {who})")
            return True
        kc, ti = ideal_to_controller(gains, self.site.controller)
        apply_seq = await self._next_apply()
        write_id = self.history.begin_write(
            kind="revert", kc=kc, ti=ti, apply_seq=apply_seq, who=who, why=why
        )
        echoed = await self.gain_writer.write_block(kc, ti, apply_seq)
        self.history.finish_write(write_id, "verified" if echoed else "failed", {})
        self.stats.reverts += 1
        self._say("write", kind="revert", apply=apply_seq, Kc=kc, Ti=ti, ok=echoed, why=why)
        if echoed:
            for applied in self.history.proposals("applied")[-1:]:
                self.history.set_proposal_status(applied["id"], "reverted", who=who, why=why)
            self.history.set_state("current_gains", gains.to_dict())
            self.history.set_state("last_write", None)
        self._event("revert" if echoed else "revert_failed", f"{why} (by {who})")
        return echoed

    def _settling(self) -> bool:
        """True until a whole window under the gains of the last write has been seen."""
        last = self.history.state("last_write")
        return bool(last) and not last.get("seen_after", False)

    async def _check_revert(self, result: WindowResult) -> None:
        """Revert automatically after one of our writes when the loop misbehaves.

        Judged on windows wholly under the new gains (``t_from`` after the write's data time):
        any such window in which the loop oscillates reverts; the first such window with
        setpoint changes reverts when its IAE per unit step exceeds ``revert_iae_factor``
        times the median of the windows before the write (one noisy window before is not the
        baseline).
        """
        last = self.history.state("last_write")
        if not last or self.gain_writer is None or result.health is None:
            return
        written_at = last.get("data_time")
        if written_at is None or result.t_from < float(written_at):
            return  # the window still holds samples under the old gains
        if not last.get("seen_after"):
            last = {**last, "seen_after": True}
            self.history.set_state("last_write", last)
        refusal = self.write_refusal()
        if refusal not in (None, "the loop oscillates"):
            return  # a revert is a write too: not in MAN, at a limit or with the link down
        if result.health.oscillation.oscillating:
            await self.revert(who="service", why="the loop oscillates after a write")
            return
        before = last.get("iae_before")
        now = result.health.iae_per_unit_step
        if last.get("judged") or not (before and math.isfinite(now)):
            return
        if now > self.settings.revert_iae_factor * before:
            await self.revert(
                who="service",
                why=f"IAE per setpoint change {now:.3g} s > {self.settings.revert_iae_factor:g}"
                f" × {before:.3g} s before the write",
            )
            return
        self.history.set_state("last_write", {**last, "judged": True, "iae_after": now})

    async def _reconcile(self) -> None:
        """Settle writes a stopped service left half done, from the PLC's echo."""
        assert self.gain_writer is not None
        for write in self.history.unfinished_writes():
            echo = await self.gain_writer.echo()
            if echo is None:
                raise LinkError("cannot read the echo to reconcile an unfinished write")
            applied = echo == int(write["apply_seq"])
            self.history.finish_write(
                write["id"], "verified" if applied else "not_applied", {"echo": echo}
            )
            pid = write.get("proposal_id")
            if pid is not None:
                proposal = self.history.proposal(pid)
                if proposal is not None and proposal["status"] == "writing":
                    if applied:
                        self.history.set_proposal_status(
                            pid, "applied", who="service", why="reconciled from the echo"
                        )
                        self._applied(proposal)
                    else:
                        self.history.set_proposal_status(
                            pid, "failed", who="service", why="not applied (service stopped)"
                        )
            self._event(
                "write_reconciled",
                f"write {write['id']} (apply {write['apply_seq']}): "
                + ("applied" if applied else "not applied"),
            )

    async def _heartbeat(self) -> None:
        assert self.gain_writer is not None
        while not self._stopping.is_set():
            with contextlib.suppress(LinkError, FuelidError):
                await self.gain_writer.beat()
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._stopping.wait(), self.heartbeat_s)

    async def _housekeeping(self) -> None:
        """The store's retention, at start and hourly, as ``fuelid record`` applies it."""
        while not self._stopping.is_set():
            newest = self.store.last_time()
            if newest is not None:
                try:
                    now = newest if self.site.plc.protocol == "replay" else max(newest, time.time())
                    await asyncio.to_thread(
                        self.store.prune,
                        self.site.store.retention_days,
                        self.site.store.thin_to_s,
                        now=now,
                    )
                except FuelidError as error:  # retention must never stop the service
                    self._say("event", kind="retention", detail=str(error))
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._stopping.wait(), PRUNE_EVERY_S)

    # --- running ----------------------------------------------------------------------------

    def stop(self) -> None:
        """Ask the service to stop (safe from a signal handler)."""
        self._stopping.set()
        if self.recorder is not None:
            self.recorder.stop()

    async def run(self, duration_s: float | None = None) -> ServiceStats:
        """Run until :meth:`stop`, SIGINT/SIGTERM or ``duration_s`` of wall time."""
        import signal

        from fuelid.plc.adapters import open_source

        loop = asyncio.get_running_loop()
        bound = []
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                loop.add_signal_handler(sig, self.stop)
                bound.append(sig)
            except (NotImplementedError, RuntimeError, ValueError):  # not the main thread
                pass
        self.writer = SampleWriter(self.store)
        self.recorder = Recorder(self.source, self.writer, on_message=self._recorder_message)
        self.stats.recorder = self.recorder.stats
        tasks = []
        try:
            if self.capabilities["writes"]:
                ws = self._write_source or open_source(self.site)
                self.gain_writer = GainWriter(ws, self.settings.echo_timeout_s)
                tasks.append(asyncio.create_task(self._heartbeat()))
                try:
                    await self._reconcile()
                except LinkError as error:
                    self._say("event", kind="reconcile_deferred", detail=str(error))
            if self.gain_writer is None and self.history.state("revert_requested"):
                # nothing here can write: a request left waiting would fire, unseen, the day
                # write-back is switched on
                self.history.set_state("revert_requested", None)
                self._event("revert_refused", "write_back is off: the revert request is dropped")
            self.history.set_state(
                "service",
                {"write_back": self.settings.write_back, "started": time.time(), "pid": _pid()},
            )
            self._say("start", **{k: v for k, v in self.capabilities.items() if k != "missing"})
            if not self.capabilities["proposes"]:
                missing = "; ".join(self.capabilities["missing_for_proposals"])
                self._say("event", kind="identify_only", detail=f"no proposals: missing {missing}")
            tasks.append(asyncio.create_task(self._schedule()))
            tasks.append(asyncio.create_task(self._housekeeping()))
            recording = asyncio.create_task(self.recorder.run(duration_s))
            await recording
        finally:
            self._stopping.set()
            with contextlib.suppress(FuelidError):
                running = self.history.state("service") or {}
                self.history.set_state("service", {**running, "stopped": time.time()})
            for task in tasks:
                with contextlib.suppress(asyncio.CancelledError, FuelidError):
                    await task
            if self.gain_writer is not None:
                await self.gain_writer.close()
            self.writer.flush()
            for sig in bound:
                loop.remove_signal_handler(sig)
        if self.fatal is not None:
            raise self.fatal
        return self.stats

    def _recorder_message(self, message: str) -> None:
        self._say("recorder", message=message)

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


def _plant_path(site: SiteConfig) -> str | None:
    return site.site.plant


def _model_of(value: Any) -> ProcessModel | None:
    """A ProcessModel from a stored dict (``{"model": {...}}`` or the model keys themselves)."""
    if not isinstance(value, dict):
        return None
    inner = value.get("model", value)
    if not isinstance(inner, dict) or "K" not in inner or "T" not in inner:
        return None
    try:
        return ProcessModel(
            K=float(inner["K"]),
            T=float(inner["T"]),
            T2=float(inner.get("T2") or 0.0),
            T_f=float(inner.get("T_f") or 0.0),
            delay=float(inner.get("delay") or 0.0),
        )
    except (TypeError, ValueError, FuelidError):
        return None


def observation_of(row: dict[str, Any]) -> GainObservation | None:
    """A tracker observation from a stored accepted model (None when it lacks a value)."""
    m = row.get("model") or {}
    model = m.get("model") or {}
    se = (m.get("stderr") or {}).get("K")
    values = [model.get("K"), se, m.get("T_fuel"), m.get("u_mean")]
    found = [float(v) for v in values if v is not None]
    if len(found) < len(values) or not all(math.isfinite(v) for v in found):
        return None
    K, se_K, T_fuel, u = found
    return GainObservation(
        float(m.get("window_end") or row.get("t_to") or 0.0),
        T_fuel,
        u,
        K,
        se_K,
        None if m.get("plant_K") is None else float(m["plant_K"]),
    )


_observation = observation_of


__all__ = ["GainWriter", "OnlineService", "ServiceStats", "observation_of"]
