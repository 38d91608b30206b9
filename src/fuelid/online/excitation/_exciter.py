"""The service's test signal: when it runs, running it, and stopping it at once (issue 40).

The PLC adds the register ``[write.excitation]`` to its PI output, clamps it to its own limit,
and zeroes it when fuelid's heartbeat is stale (docs/how-to/write-back.md, the PLC side): the
signal never depends on fuelid's own stop to end. The :class:`Exciter` decides, every poll:

- **when** (``[excitation] mode``): "always" whenever allowed; "when_unidentified" only when
  the newest window was rejected for lack of excitation or for K's standard error over
  ``[online] max_rel_stderr_K`` and nothing else holds K now (no recent accepted window, or the
  K(T) curve's interval at the fuel's temperature wider than that bound:
  :meth:`Exciter._unidentified`); "off" only on a person's request (``fuelid online excite``,
  the dashboard). A burst of ``max_share × window_s`` starts at most once per ``window_s`` of
  data, so no window holds more than ``max_share`` of signal;
- **never** (:meth:`Exciter.hold_reason`): during a wind-tunnel run (``tags.run``), in MAN,
  with the command (less the signal) within ``margin_to_limits`` of the drive's limits, after a
  bad sample, with the link down or no fresh reading, within ``wait_after_move_s`` after a
  setpoint move, a mode change or a gain write; a running burst stops at once on any of them
  (and on a setpoint move or a gain write during it), the register written to 0;
- **how much**: :func:`~fuelid.online.excitation._design.design_signal` on the newest accepted
  model (else the plant file's at the operating point), the gains in force and the noise
  measured over the last window, capped by ``amplitude``.

Every start and stop is an event (``excitation_start``, ``excitation_stop``,
``excitation_end``, ``excitation_held``) with its reason, amplitude, design and cost; the
state for the status and the dashboard is the ``online_state`` record :data:`STATE_KEY`.
Times are plant time (the samples' clock) [s UTC]; values [V], flows [L/min].
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from fuelid.errors import FuelidError
from fuelid.model import ProcessModel
from fuelid.online._context import RECENT_WINDOWS_SPAN, ServiceContext, model_of
from fuelid.online._writeback import AUTO
from fuelid.online.excitation._design import DesignGoal, LoopNoise, SignalDesign, design_signal
from fuelid.online.excitation._status import INTERRUPTED, STATE_KEY
from fuelid.plc import GainWriter
from fuelid.plc.adapters import LinkError
from fuelid.store import Quality
from fuelid.tuning import PISettings
from fuelid.units import DEFAULT_FUEL_TEMPERATURE_C, celsius_to_kelvin

REQUEST_KEY = "excitation_requested"
"""``online_state`` key: a person's start or stop, left by :func:`~fuelid.online._requests.
apply_request` for the running service."""
POLL_S = 0.02
"""Wall time between the exciter's looks at the newest sample [s]."""
KEPT_BURSTS = 20
"""Bursts kept in the state record's ``bursts`` (newest last)."""
SETPOINT_MOVE_LPM = 0.05
"""A setpoint change larger than this is a move (the wait after it starts again) [L/min]."""
LOOK_EVERY_S = 0.5
"""Wall time between the looks that read the store (requests, writes, the newest window) [s]."""
DEFAULT_WAIT_S = 60.0
"""The wait after a move when no model gives a settling time [s]."""


@dataclass
class Burst:
    """A signal running: its design, when it began, and what was written last."""

    design: SignalDesign
    started: float
    """Plant time of its first control period [s UTC]."""
    reason: str
    who: str
    written: float = math.nan
    """The last value written to the register [V]."""

    def value_at(self, now: float) -> float | None:
        """The signal at plant time ``now`` [V]; None once the burst is over."""
        k = int((now - self.started) // self.design.control_period_s)
        values = self.design.values()
        return float(values[k]) if 0 <= k < values.size else None


class Exciter:
    """Runs the test signal of one loop (see the module docstring).

    Parameters
    ----------
    context : ServiceContext
        The service's shared state (site, history, recorder, writer).
    link : GainWriter
        The write connection (the heartbeat runs on it).
    model : callable
        The newest accepted model, or None.
    plant_model : callable, optional
        The plant file's model at a command [V]; None without a plant file.
    window_end : callable, optional
        The data time the scheduler's next window ends [s UTC]: a burst the schedule asks for
        starts there (:meth:`_boundary`); a person's request starts at once.
    k_interval : callable, optional
        The relative standard error of K the K(T) curve predicts now [-]; None when unknown.
    evidence : callable, optional
        How many accepted windows on separate excitation end after a data time [s UTC].
    """

    def __init__(
        self,
        context: ServiceContext,
        link: GainWriter,
        model: Callable[[], ProcessModel | None],
        plant_model: Callable[[float], ProcessModel | None] | None = None,
        window_end: Callable[[], float | None] | None = None,
        k_interval: Callable[[], float | None] | None = None,
        evidence: Callable[[float], int] | None = None,
    ) -> None:
        self.context = context
        self.link = link
        self.settings = context.site.excitation
        self._model = model
        self._plant_model = plant_model
        self._window_end = window_end
        self._k_interval = k_interval
        self._evidence = evidence
        self._next_look = 0.0
        # (start at [plant s UTC], why, the person's request or None)
        self._pending: tuple[float, str, dict[str, Any] | None] | None = None
        self.burst: Burst | None = None
        record = context.history.state(STATE_KEY) or {}
        self.last_start: float | None = record.get("last_start")
        if record.get("state") == "running":  # killed mid-burst: the PLC zeroed it on its own
            cut = {
                **(record.get("running") or {}),
                "ended": None,
                "end_reason": INTERRUPTED,
            }
            bursts = [*(record.get("bursts") or []), cut][-KEPT_BURSTS:]
            context.history.set_state(
                STATE_KEY, {**record, "state": "idle", "running": None, "bursts": bursts}
            )  # fmt: skip
        if context.history.state(REQUEST_KEY) is not None:
            # left for a service that is gone: it must not fire unseen now
            context.history.set_state(REQUEST_KEY, None)
            context.event(
                "excitation_held", "a start or stop left from before the restart: dropped"
            )
        self.last_move: float | None = None
        self.last_bad: float | None = None  # plant time of the newest sample flagged bad
        self._wait = DEFAULT_WAIT_S  # wait_s() as of the last look that read the store [s]
        self._designed_on = ""  # what the newest design's model came from, for its event
        self._setpoint: float | None = None
        self._mode: float | None = None
        self._flagged = 0
        self._held: str | None = None

    # --- the rules --------------------------------------------------------------------------

    @property
    def amplitude(self) -> float | None:
        """The largest signal allowed [V] (``[excitation] amplitude``)."""
        return self.settings.amplitude

    def margin(self) -> float:
        """No signal while the command is within this of a drive limit [V]."""
        if self.settings.margin_to_limits is not None:
            return float(self.settings.margin_to_limits)
        return 2.0 * float(self.amplitude or 0.0)

    def burst_s(self) -> float:
        """How long a burst runs [s]: ``max_share`` of a window."""
        return self.settings.max_share * self.context.settings.window_s

    def wait_s(self) -> float:
        """The wait after a move [s]: ``wait_after_move_s``, else the model's settling time."""
        if self.settings.wait_after_move_s is not None:
            return float(self.settings.wait_after_move_s)
        model = self._model()
        return model.settling_time() if model is not None else DEFAULT_WAIT_S

    def hold_reason(self, latest: dict[str, float], now: float) -> str | None:
        """Why no signal may run now (plant time ``now`` [s UTC]); None when it may."""
        recorder = self.context.recorder
        if recorder is None or not recorder.connected:
            return "the link is down"
        age = time.time() - recorder.last_reading
        if not age < max(5.0, 10 * self.context.site.sampling.period_s):
            return "no fresh reading from the PLC"
        if latest.get("run", 0.0) >= 0.5:
            return "a wind-tunnel run is on (tags.run)"
        mode = latest.get("mode")
        if mode is None or round(mode) != AUTO:
            return "the loop is not in AUTO"
        u = latest.get("command", math.nan) - latest.get("excitation", 0.0)
        low, high = self.context.priors.u_limits
        margin = self.margin()
        if not (math.isfinite(u) and low + margin < u < high - margin):
            return f"the command is within {margin:.3g} V of a drive limit"
        if self.last_bad is not None and now - self.last_bad < self._wait:
            return f"a bad sample {now - self.last_bad:.0f} s ago"
        return None

    def _watch(self, latest: dict[str, float], now: float) -> None:
        """Note setpoint moves and mode changes (the wait starts again)."""
        setpoint, mode = latest.get("setpoint"), latest.get("mode")
        moved = setpoint is not None and self._setpoint is not None
        if moved and abs(setpoint - self._setpoint) > SETPOINT_MOVE_LPM:  # type: ignore[operator]
            self.last_move = now
        if mode is not None and self._mode is not None and round(mode) != round(self._mode):
            self.last_move = now
        recorder = self.context.recorder
        if recorder is not None and recorder.stats.flagged > self._flagged:
            self._flagged = recorder.stats.flagged
            self.last_bad = now  # a sample flagged bad: the wait starts again
        self._setpoint = setpoint if setpoint is not None else self._setpoint
        self._mode = mode if mode is not None else self._mode

    def _watch_writes(self) -> None:
        """A gain write starts the wait again (its data time, from the store)."""
        written = (self.context.history.state("last_write") or {}).get("data_time")
        if isinstance(written, int | float) and (
            self.last_move is None or written > self.last_move
        ):
            self.last_move = float(written)

    def due(self, now: float) -> str | None:
        """Why a signal should start now by the site's ``mode``; None when not due."""
        mode = self.settings.mode
        if mode == "off":
            return None
        if self.last_start is not None and now - self.last_start < self.context.settings.window_s:
            return None
        if self.last_move is not None and now - self.last_move < self._wait:
            return None
        if mode == "always":
            return 'mode "always"'
        return self._unidentified(now)

    def _unidentified(self, now: float) -> str | None:
        """Why the loop counts as not identified now; None when it is.

        Not identified: the newest window could not identify it (rejected for lack of
        excitation, or K's relative standard error over ``max_rel_stderr_K``) *and* nothing
        else holds K now: fewer than ``agree_windows`` accepted windows on separate excitation
        within the recent span (``RECENT_WINDOWS_SPAN`` window lengths: the evidence a proposal
        rests on, so that a drift of K can be proposed from), or the K(T) curve's interval at
        the fuel's temperature now is wider than ``max_rel_stderr_K`` (the fuel moved away from
        the temperatures identified).
        """
        window = self.context.history.last_window()
        if window is None:
            return None
        detail = window.get("detail") or {}
        reason = str(detail.get("reason") or "")
        gates = (detail.get("gates") or {}).get("measured") or {}
        rel = gates.get("rel_stderr_K")
        bound = self.context.settings.max_rel_stderr_K
        if not detail.get("accepted") and reason.startswith("no excitation"):
            why = f"window {window['id']} rejected: {reason}"
        elif isinstance(rel, int | float) and math.isfinite(rel) and rel > bound:
            why = (
                f"window {window['id']}: the relative standard error of K "
                f"{100.0 * rel:.1f} % > {100.0 * bound:g} %"
            )
        else:
            return None
        span = RECENT_WINDOWS_SPAN * self.context.settings.window_s
        agree = self.context.settings.agree_windows
        found = self._evidence(now - span) if self._evidence is not None else 0
        if found < agree:
            return (
                f"{why}; {found} of the {agree} windows on separate excitation a proposal "
                f"needs in the last {span:.0f} s"
            )
        interval = self._k_interval() if self._k_interval is not None else None
        if interval is None or interval > bound:
            shown = "not known" if interval is None else f"±{100.0 * interval:.1f} %"
            return f"{why}; K at the fuel's temperature now {shown} (> {100.0 * bound:g} %)"
        return None

    # --- running ----------------------------------------------------------------------------

    async def run(self, stopping: asyncio.Event) -> None:
        """Poll until ``stopping``; then the register goes to 0."""
        try:
            while not stopping.is_set():
                await self.step()
                with contextlib.suppress(asyncio.TimeoutError):
                    await asyncio.wait_for(stopping.wait(), POLL_S)
        finally:
            if self.burst is not None:
                await self.stop("the service stops", kind="excitation_stop")

    async def step(self) -> None:
        """One look: go on with a burst, stop it, or start one."""
        writer = self.context.writer
        now = None if writer is None else writer.newest_time()
        if now is None:
            return
        latest = self.context.latest
        self._watch(latest, now)
        slow = time.monotonic() >= self._next_look
        if slow:  # what needs the store: at most every LOOK_EVERY_S
            self._next_look = time.monotonic() + LOOK_EVERY_S
            self._watch_writes()
            self._wait = self.wait_s()  # reads the newest model: not at every poll
        request = self._take_request() if slow else None
        if self.burst is not None:
            await self._go_on(latest, now, request)
            return
        if request is not None:
            self._request_while_idle(latest, now, request)
            return
        if slow:
            self._show_hold(latest, now)
            due = self.due(now)
            if due is None and (self._pending is None or self._pending[2] is None):
                self._pending = None
            elif due is not None and self._pending is None:
                self._pending = (self._boundary(now), due, None)
        if self._pending is not None and now >= self._pending[0]:
            _, due, asked = self._pending
            self._pending = None
            await self._start_now(latest, now, due, asked)

    def _request_while_idle(
        self, latest: dict[str, float], now: float, request: dict[str, Any]
    ) -> None:
        """A person's stop drops a start that waits; a start waits for the next window start.

        A start is held to the site's limits as the schedule's are: at most one burst per
        ``window_s`` (so no window holds more than ``max_share`` of signal), and it begins
        where a window begins, so that the windows that hold it hold all of it.
        """
        if request["action"] == "stop":
            waiting = self._pending is not None
            self._pending = None
            self._finish_request(
                request, "done", "the start that waited is dropped" if waiting else "no signal runs"
            )
            return
        window_s = self.context.settings.window_s
        if self.last_start is not None and now - self.last_start < window_s:
            self._finish_request(
                request,
                "refused",
                f"a burst began {now - self.last_start:.0f} s ago: one per window_s "
                f"({window_s:g} s) at most, so that no window holds more than max_share",
            )
            return
        hold = self.hold_reason(latest, now)
        if hold is not None:
            self._finish_request(request, "refused", f"no signal now: {hold}")
            return
        start = self._boundary(now)
        self._pending = (start, self._requested(request), request)
        self._publish()
        self.context.say(
            "request", kind="excite_start", status="scheduled",
            outcome=f"starts where the next window starts, in {start - now:.0f} s of data",
        )  # fmt: skip

    def _show_hold(self, latest: dict[str, float], now: float) -> None:
        """Keep the record's ``held`` (why no signal may start now) up to date."""
        hold = self.hold_reason(latest, now)
        if hold != self._held:
            self._held = hold
            self._publish(held=hold)

    def _boundary(self, now: float) -> float:
        """The next start of a scheduled window [plant s UTC] (now when unknown).

        A burst that starts there lies whole in the windows that start and end around it (with
        ``window_s`` a multiple of ``identify_every_s``, the default's two), as the design
        assumed: no window sees only a piece of it.
        """
        end = self._window_end() if self._window_end is not None else None
        if end is None:
            return now
        every = self.context.settings.identify_every_s
        while end < now:
            end += every
        return end

    async def _start_now(
        self, latest: dict[str, float], now: float, due: str, request: dict[str, Any] | None
    ) -> None:
        hold = self.hold_reason(latest, now)
        if hold is not None:
            if request is not None:
                self._finish_request(request, "refused", f"no signal now: {hold}")
            elif hold != self._held:
                self._held = hold
                self._publish(held=hold)
            return
        self._held = None
        who = str(request["who"]) if request is not None else "service"
        why_not = await self.start(now, due, who)
        if request is not None:
            if why_not is None:
                self._finish_request(request, "done", "started")
            else:
                self._finish_request(request, "refused", f"no signal: {why_not}")

    async def _go_on(self, latest: dict[str, float], now: float, request: Any) -> None:
        burst = self.burst
        assert burst is not None
        if request is not None and request["action"] == "stop":
            await self.stop(f"stopped by {request['who']}: {request['why']}")
            self._finish_request(request, "done", "signal stopped")
            return
        if request is not None:
            self._finish_request(request, "refused", "a signal runs already")
        hold = self.hold_reason(latest, now)
        if hold is None and self.last_move is not None and self.last_move > burst.started:
            hold = "the setpoint, the mode or the gains changed"
        if hold is not None:
            await self.stop(hold)
            return
        value = burst.value_at(now)
        if value is None:
            await self.stop("the burst is done", kind="excitation_end")
            return
        if value != burst.written:
            try:
                await self.link.set_excitation(value)
                burst.written = value
            except LinkError as error:
                await self.stop(f"the write failed ({error})")

    def _requested(self, request: dict[str, Any]) -> str:
        return f"requested by {request['who']}: {request['why'] or 'no reason given'}"

    async def start(self, now: float, reason: str, who: str) -> str | None:
        """Design and start a burst; None when it started, else why not.

        A burst the schedule asked for and could not start is an ``excitation_held`` event; a
        person's request is answered by its caller (:meth:`_finish_request`).
        """
        why_not = None
        if self.amplitude is None:
            why_not = "no [excitation] amplitude in the site file"
        else:
            self.last_start = now
            try:
                design = await asyncio.to_thread(self._design, now)
            except FuelidError as error:
                why_not = str(error)
        if why_not is not None:
            if who == "service":
                self.context.event("excitation_held", f"{reason}; no signal: {why_not}")
            self._publish()
            return why_not
        self.burst = Burst(design, now, reason, who)
        self.context.event(
            "excitation_start", f"{reason}; {describe(design)}; designed on {self._designed_on}"
        )
        self._publish()
        return None

    async def stop(self, reason: str, *, kind: str = "excitation_stop") -> None:
        """Write 0 to the register at once, then record why."""
        burst, self.burst = self.burst, None
        outcome = "the register is 0"
        try:
            await self.link.set_excitation(0.0)
        except (LinkError, FuelidError) as error:
            outcome = f"the write of 0 failed ({error}): the PLC zeroes it when the heartbeat stops"
        self.context.event(kind, f"{reason}; {outcome}")
        if burst is not None:
            self._publish(ended=burst, why=reason)

    # --- the design's inputs ----------------------------------------------------------------

    def _design(self, now: float) -> SignalDesign:
        """The signal for the loop now (in a thread: it reads the last window's samples)."""
        site = self.context.site
        latest = self.context.latest
        model = self._model()
        self._designed_on = "the newest accepted window's model"
        if model is None and self._plant_model is not None:
            model = self._plant_model(latest.get("command", math.nan))
            self._designed_on = "the plant file's model (no window accepted yet)"
        if model is None:
            raise FuelidError("no model to design it from (no accepted window, no plant file)")
        gains = self.context.current_gains()
        if gains is None:
            raise FuelidError("the gains in force are not known")
        pi = PISettings("in force", gains.Kc, gains.Ti, site.sampling.control_period_s)
        window_s = self.context.settings.window_s
        samples = self.context.store.read(now - window_s, now + site.sampling.period_s)
        ok = (samples.quality == Quality.OK) & ~_touched(
            samples.excitation, model.settling_time(), site.sampling.period_s
        )
        noise = LoopNoise.of_window(
            model,
            np.where(ok, samples.u, np.nan),
            np.where(ok, samples.y, np.nan),
            samples.setpoint,
            site.sampling.period_s,
        )
        assert self.amplitude is not None
        return design_signal(
            model,
            pi,
            noise,
            DesignGoal.of(self.context.settings),
            amplitude_cap_V=float(self.amplitude),
            period_s=site.sampling.period_s,
            window_s=window_s,
            burst_s=self.burst_s(),
            delay_free=self.context.priors.delay is None,
            seed=int(now) % 2**31,
        )

    # --- requests and the state record ------------------------------------------------------

    def _take_request(self) -> dict[str, Any] | None:
        request = self.context.history.state(REQUEST_KEY)
        if not isinstance(request, dict) or request.get("action") not in ("start", "stop"):
            return None
        self.context.history.set_state(REQUEST_KEY, None)
        return request

    def _finish_request(self, request: dict[str, Any], status: str, outcome: str) -> None:
        """Say what became of a person's start or stop.

        A refusal is an event too: the request's row says only that the service took it.
        """
        action = request["action"]
        self.context.say("request", kind=f"excite_{action}", status=status, outcome=outcome)
        if status == "refused":
            self.context.event(
                "excitation_held", f"{action} asked by {request['who']} not carried out: {outcome}"
            )

    def _publish(self, *, held: str | None = None, ended: Burst | None = None,
                 why: str = "") -> None:  # fmt: skip
        """The state record: the signal now, the last start, the bursts' history."""
        history = self.context.history
        record = dict(history.state(STATE_KEY) or {})
        bursts = list(record.get("bursts") or [])
        if ended is not None:
            newest = self.context.writer.newest_time() if self.context.writer else None
            bursts.append(_burst_json(ended) | {"ended": newest, "end_reason": why})
        burst = self.burst
        record.update(
            {
                "mode": self.settings.mode,
                "amplitude_V": self.amplitude,
                "state": "running" if burst is not None else "idle",
                "running": None if burst is None else _burst_json(burst),
                "held": held if held is not None else self._held,
                "next_start": None if self._pending is None else self._pending[0],
                "last_start": self.last_start,
                "bursts": bursts[-KEPT_BURSTS:],
            }
        )
        history.set_state(STATE_KEY, record)


def _touched(signal: np.ndarray[Any, Any], tail_s: float, period_s: float) -> np.ndarray[Any, Any]:
    """Samples a test signal moved: where it was not 0, and one settling time after.

    The noise a design rests on is measured on the others: a window's earlier burst would
    count as noise, and the next signal would be made larger than it needs to be.

    Examples
    --------
    >>> _touched(np.array([0.0, 0.1, 0.0, 0.0, 0.0, np.nan]), 0.02, 0.01).tolist()
    [False, True, True, True, False, False]
    """
    on: np.ndarray[Any, Any] = np.nan_to_num(np.asarray(signal, dtype=float)) != 0.0
    tail = max(math.ceil(tail_s / period_s), 0)
    if tail == 0 or not np.any(on):
        return on
    spread = np.convolve(on.astype(np.int8), np.ones(tail + 1, dtype=np.int8))[: on.size]
    return np.asarray(spread > 0)


def _burst_json(burst: Burst) -> dict[str, Any]:
    return {
        "started": burst.started,
        "reason": burst.reason,
        "who": burst.who,
        "design": burst.design.to_json(),
    }


def describe(design: SignalDesign) -> str:
    """One line: the signal, what it is expected to give and what it costs.

    Examples
    --------
    >>> import numpy as np
    >>> d = SignalDesign("gbn", 0.15, 8.0, 1.0, 180.0, 600.0, 3, np.ones(180),
    ...                  {"K": 0.03, "T": 0.1}, 84.0, 0.08, 21.5, {"K": 0.1}, "K")
    >>> describe(d)  # doctest: +NORMALIZE_WHITESPACE
    'GBN ±0.15 V, mean hold 8 s, for 180 s; expected se(K) 3.0 %, se(T) 10.0 %, fit 84 %;
    cost +0.08 L/min sd, IAE 21.5 (L/min)·s per window'
    """
    rel = design.expected_rel_stderr
    text = (
        f"{design.kind.upper()} ±{design.amplitude_V:.3g} V, mean hold {design.hold_s:g} s, "
        f"for {design.burst_s:g} s; expected se(K) {100.0 * rel.get('K', math.nan):.1f} %, "
        f"se(T) {100.0 * rel.get('T', math.nan):.1f} %, fit {design.expected_fit_percent:.0f} %; "
        f"cost +{design.added_flow_sd_Lpm:.2g} L/min sd, IAE {design.iae_per_window:.3g} "
        "(L/min)·s per window"
    )
    if design.bound == "amplitude":
        text += " (capped at the site's amplitude: the gates may need more than one burst)"
    return text


def newest_model(context: ServiceContext) -> ProcessModel | None:
    """The newest accepted window's model, or None."""
    rows = context.history.accepted_models(limit=1)
    return model_of(rows[0]["model"]) if rows else None


def plant_model_function(
    plant: str | None, context: ServiceContext
) -> Callable[[float], ProcessModel | None] | None:
    """The plant file's model at a command [V] and the fuel's newest temperature; None without.

    What the first signal is designed from on a loop no window has identified yet.
    """
    if plant is None:
        return None
    from fuelid.plant import linearise, load_plant_config

    config = load_plant_config(plant)

    def at(u: float) -> ProcessModel | None:
        T_C = context.latest.get("fuel_temperature", DEFAULT_FUEL_TEMPERATURE_C)
        if not (math.isfinite(u) and math.isfinite(T_C)):
            return None
        try:
            return linearise(config, u, celsius_to_kelvin(T_C)).equivalent_model().model
        except (FuelidError, ValueError):
            return None

    return at
