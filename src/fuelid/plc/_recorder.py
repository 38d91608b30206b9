"""The recorder: samples from any :class:`~fuelid.plc.adapters._base.PlcSource` into a store.

Protocol-agnostic and asyncio-based; it owns the connect loop and never dies on a link error.

**Link.** One connect attempt after another with exponential backoff (0.2 s doubling to 5 s);
a message goes to ``on_message`` when the link state or the reason changes, not per attempt.
``link_down`` (with the reason) and ``link_up`` (with the outage's length and what the ring gave
back) events are stored; a link back at the first reconnect attempt (the next poll) is a blip,
and its ``link_up`` says so: "link blip of 0.09 s; 5 samples back-filled"
(:func:`link_up_detail`). The events' wall time is their stored ``wall_time``, not text in
their detail: a detail carries no second clock.
``give_up_after_s`` makes the recorder raise :class:`LinkError` after that long without a link.

**Time base and restarts** (:mod:`fuelid.plc._timebase`): with a ``[ring]`` its records are read
every ``ring_poll_s`` and timed by their sequence number, with a ``seq`` tag the reads follow an
absolute-deadline schedule and are timed by the counter, without either by the receipt time. A
PLC restart (the counter back, or too little advance across an outage) writes a ``restart``
event; the stored sequence continues monotonic with one number left out. Events are timed on
the samples' time base (*Event times* in the same module).

**Outages without a ring** store no rows (no invented values, and no rows of NaN): the
``link_down``/``link_up`` events and a ``gap`` event with the count of samples lost say it, and
the time (or sequence) gap in the samples shows it to every reader.

**First read and ring against tags** (:mod:`fuelid.plc._first_read`): implausible first values
(a wrong word order or byte swap) refuse the recording with a one-line
:class:`~fuelid.errors.ConfigError`; tags that disagree with the ring write a ``ring_mismatch``
event.

**Quality** (:mod:`fuelid.plc._quality`): u and y (and the ring's fields) that are NaN, infinite,
implausible (tiny but not zero, or huge), out of range or, for u, outside 0…10.5 V without a
``valid`` make the sample ``BAD_VALUE`` (values kept as read); a bad setpoint, fuel
temperature, mode, excitation or run flag is stored as NaN (None) and the sample stays ``OK``.
Each bad episode writes one ``bad_value`` event; a stuck flow a ``stuck_sensor`` event and its
samples ``BAD_VALUE``. Applied gains that change write ``gain_change``, MAN/AUTO
``mode_change``.

**Excitation and run** (issue 40): with ``[tags.excitation]`` (the test signal the PLC applied
[V]) and ``[tags.run]`` (the wind-tunnel run flag) every sample carries them, read in the same
poll as u and y; with a ring whose records have the field ``excitation`` the signal comes from
the record (scan-consistent with u and y), else from the tag read at the poll, as the setpoint.
The run flag is stored as 0 or 1. A site without them stores NULL in both columns.

**The PLC's gains as read** (:mod:`fuelid.plc._gain_reading`): with ``[tags.kc]`` and
``[tags.ti]`` the first reading and each change go to the store's state (key ``plc_gains``),
in the block's units, with the reading's plant time (the sample it was taken at) and wall time,
for the processes that do not run the recorder (the dashboard, ``online status``).

**Nothing is held back.** Every sample goes to the writer as soon as it is read, so a crash
(kill -9) loses at most the batch not yet committed (the commit interval, 1 s). A stuck flow is
recognised :data:`~fuelid.plc._quality.STUCK_AFTER_S` after its stretch began: from then on its
samples are flagged as they go, and the earlier samples of the stretch, already queued or
stored, are flagged in the store by a
:meth:`~fuelid.store.SampleWriter.set_quality` queued behind them (applied in the writer's
order, in the transaction of the last of them). A crash between the two leaves the early
samples of the stretch ``OK``; the detection happens again on the restart only if the flow
is still stuck.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import Callable
from typing import Any

from fuelid.plc._first_read import RingTagCheck, probe_first_read
from fuelid.plc._gain_reading import PLC_GAINS_KEY, GainReadings, gain_change_text, stamped
from fuelid.plc._quality import AUX_ROLES, STUCK_AFTER_S, RangeChecks, StuckDetector
from fuelid.plc._record_status import RecorderStats
from fuelid.plc._timebase import UINT32, SampleSequence
from fuelid.plc.adapters._base import EndOfSource, LinkError, PlcSource, Reading, RingRecord
from fuelid.plc.site import SiteConfig
from fuelid.store import Quality, Sample, SampleWriter, tag_map_hash

__all__ = [
    "BACKOFF_FIRST_S",
    "BACKOFF_MAX_S",
    "RING_MARGIN",
    "RING_POLL_S",
    "Recorder",
    "link_up_detail",
    "site_identity",
]

BACKOFF_FIRST_S = 0.2
"""First wait between connect attempts [s]."""
BACKOFF_MAX_S = 5.0
"""Longest wait between connect attempts [s]."""
RING_POLL_S = 0.2
"""Wall time between ring reads [s]."""
RING_MARGIN = 8
"""Fraction 1/RING_MARGIN of the ring left alone when back-filling: the PLC overwrites the
oldest records while they are read."""
_CORE = ("command", "flow", "setpoint", "excitation")
"""Roles a sample takes from the poll it is made of (or the ring record), not the last poll."""


def link_up_detail(outage_s: float, attempts: int, filled: int | None) -> str:
    """The ``link_up`` event's detail: how long the link was lost, and what the ring gave back.

    Parameters
    ----------
    outage_s : float
        Wall time from the last reading before the loss to the link back [s].
    attempts : int
        Connect attempts it took; 1 (back at the next poll) makes the outage a blip.
    filled : int or None
        Samples the ring still held for the hole (read back now); None without a ring (the
        samples of the hole are lost: a ``gap`` event counts them).

    Examples
    --------
    >>> link_up_detail(0.0912, 1, 5)
    'link blip of 0.09 s; 5 samples back-filled'
    >>> link_up_detail(0.0912, 1, None)
    'link blip of 0.09 s; no ring to back-fill from'
    >>> link_up_detail(12.34567, 4, 120)
    'after 12.346 s without a link (4 attempts); 120 samples back-filled'
    """
    head = (
        f"link blip of {outage_s:.2f} s"
        if attempts == 1
        else f"after {outage_s:.3f} s without a link ({attempts} attempts)"
    )
    if filled is None:
        return f"{head}; no ring to back-fill from"
    return f"{head}; {filled} sample{'' if filled == 1 else 's'} back-filled"


def site_identity(site: SiteConfig) -> dict[str, Any]:
    """``site_name`` and ``tag_map_hash`` of a site, as a store records them.

    The hash covers what gives the stored numbers their meaning: the read tags (addresses,
    types, scalings), the ring's layout and the sample period. The write side and the endpoint
    may change without making it another site.
    """
    wiring = site.model_dump(mode="json", include={"tags", "ring"})
    wiring["period_s"] = site.sampling.period_s
    return {"site_name": site.site.name, "tag_map_hash": tag_map_hash(wiring)}


class Recorder:
    """Reads a PLC through a source and feeds a store's writer (see the module docstring).

    Parameters
    ----------
    source : PlcSource
        The link (not yet connected).
    writer : SampleWriter
        The store's one writer; the recorder flushes it when it stops but does not close it.
    ring_poll_s : float
        Wall time between ring reads [s] (with ``[ring]``).
    stuck_after_s : float
        Seconds of an exactly unchanged flow that mean a stuck sensor [s].
    backoff_s : (float, float)
        First and longest wait between connect attempts [s].
    give_up_after_s : float, optional
        Raise :class:`LinkError` after this long without a link [s]; None: retry for ever.
    on_message : callable, optional
        Gets one-line messages (link state changes, restarts, the end of a replayed log).
    """

    def __init__(
        self,
        source: PlcSource,
        writer: SampleWriter,
        *,
        ring_poll_s: float = RING_POLL_S,
        stuck_after_s: float = STUCK_AFTER_S,
        backoff_s: tuple[float, float] = (BACKOFF_FIRST_S, BACKOFF_MAX_S),
        give_up_after_s: float | None = None,
        on_message: Callable[[str], None] | None = None,
    ) -> None:
        self.source = source
        self.site = source.site
        self.writer = writer
        self.period_s = self.site.sampling.period_s
        self.ring_poll_s = float(ring_poll_s)
        self.backoff_s = backoff_s
        self.give_up_after_s = give_up_after_s
        self.on_message = on_message
        self.stats = RecorderStats()
        self._stop = asyncio.Event()
        self._connected = False
        self._down_since = time.monotonic()
        self._down_utc = time.time()
        self._ever_up = False
        self._seq = SampleSequence(self.period_s, writer.store.last_seq(), writer.store.last_time())
        self._checks = RangeChecks(dict(self.site.tags), self._event)
        self._stuck = StuckDetector(
            self.site.tags.get("flow"), self._event_at, stuck_after_s, self._reflag
        )
        self._aux: dict[str, float] = {}  # last finite kc, ti, mode (change events)
        self._gains = GainReadings(self.site)  # the PLC's kc and ti as read, for the store
        self._aux_values: dict[str, float] = {}  # AUX_ROLES attached to samples, checked
        self._next_u: int | None = None  # ring: the next record to read (unwrapped)
        self._last_receipt = math.nan
        self._last_seen = math.nan  # when any reading last arrived [s UTC]
        self._missing_after_outage = False
        ring = self.site.ring
        self._ring_fields = tuple(ring.fields[1:]) if ring is not None else ()
        self._seq_base = ring is not None or "seq" in self.site.tags
        """Sample times are data times (ring or counter): events are put on them too."""
        self._pending: list[tuple[str, str]] = []  # events waiting for the next sample's time
        self._back: tuple[float, int] | None = None  # the link back: (outage [s], attempts)
        self._probed = False
        self._head_record: dict[str, float] | None = None  # ring: this poll's head record
        self._ring_check = RingTagCheck(self.site)

    # --- plumbing -------------------------------------------------------------------------

    def stop(self) -> None:
        """Ask the recorder to stop (safe from a signal handler); :meth:`run` then returns."""
        self._stop.set()

    @property
    def connected(self) -> bool:
        """True while the link is up."""
        return self._connected

    @property
    def latest(self) -> dict[str, float]:
        """The last finite value of every read role (kc, ti, mode, setpoint, command, …).

        In the roles' engineering units: what the online service checks before it writes.
        """
        return dict(self._aux)

    @property
    def last_reading(self) -> float:
        """When the last reading of the tags arrived [s UTC]; NaN before the first."""
        return self._last_seen

    def _say(self, message: str) -> None:
        if self.on_message is not None:
            self.on_message(message)

    def _event(self, kind: str, detail: str, t: float | None = None) -> None:
        """An event at sample time ``t`` [s UTC].

        None: the next sample's time (ring or seq time base, see the module docstring), or now
        (receipt times).
        """
        if t is None and self._seq_base:
            self._pending.append((kind, detail))
            return
        self.writer.event(kind, detail, time=t)

    def _event_at(self, kind: str, detail: str, t: float | None) -> None:
        """An event at ``t`` [s UTC] (None: now, the wall clock), never held back."""
        self.writer.event(kind, detail, time=t)

    def _after_last(self) -> float | None:
        """One period after the last stored sample [s UTC]; None (now) without a data time."""
        last = self._seq.last_time
        if self._seq_base and math.isfinite(last):
            return last + self.period_s
        return None

    def _flush_pending(self, t: float | None) -> None:
        pending, self._pending = self._pending, []
        for kind, detail in pending:
            self.writer.event(kind, detail, time=t)
        gains, self._gains.pending = self._gains.pending, None
        if gains is not None:
            self.writer.set_state(PLC_GAINS_KEY, stamped(gains, t))

    def _take(self, sample: Sample) -> None:
        if self._pending or self._gains.pending is not None:
            self._flush_pending(sample.time)
        if sample.seq is not None:
            self._seq.mark(sample.seq, sample.time)
        sample = self._stuck.push(sample)  # returned at once: nothing is held back
        self.writer.put(sample)
        self.stats.stored += 1
        if sample.quality != Quality.OK:
            self.stats.flagged += 1

    def _reflag(self, t_from: float, t_to: float, count: int) -> None:
        """A stuck stretch found: flag its samples already handed to the writer."""
        self.writer.set_quality(t_from, t_to, Quality.BAD_VALUE)
        self.stats.flagged += count

    async def _wait(self, seconds: float) -> None:
        """Sleep, but wake at once on :meth:`stop`."""
        if seconds <= 0.0 or self._stop.is_set():
            return
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(self._stop.wait(), timeout=seconds)

    # --- link -----------------------------------------------------------------------------

    async def _ensure_link(self, deadline: float | None) -> bool:
        """Connect with backoff; False when stopped (or the duration ran out) before a link."""
        if self._connected:
            return True
        delay, longest = self.backoff_s
        attempts = 0
        while not self._stop.is_set():
            if deadline is not None and time.monotonic() >= deadline:
                return False
            attempts += 1
            try:
                await self.source.connect()
            except LinkError as error:
                reason = str(error)
                if self.stats.link != "down" or reason != self.stats.last_error:
                    self._say(f"link down: {reason}; retrying (backoff up to {longest:g} s)")
                    if self.stats.link == "connecting" and attempts == 1:
                        self._event_at("link_down", reason, self._after_last())
                self.stats.link, self.stats.last_error = "down", reason
                waited = time.monotonic() - self._down_since
                if self.give_up_after_s is not None and waited >= self.give_up_after_s:
                    raise LinkError(
                        f"gave up after {waited:.1f} s without a link to {self.source.where} "
                        f"(--give-up-after {self.give_up_after_s:g}): {reason}"
                    ) from None
                await self._wait(delay)
                delay = min(2.0 * delay, longest)
                continue
            self._connected = True
            outage = time.monotonic() - self._down_since
            if self.stats.link == "down":
                self._back = (outage, attempts)
                if self.site.ring is None:  # nothing to read back: said now
                    self._link_up(None)
                self._say(f"link up: {self.source.where} after {outage:.1f} s")
            else:
                self._say(f"connected to {self.source.where}")
            self.stats.link = "up"
            self._ever_up = True
            return True
        return False

    async def _link_lost(self, reason: str) -> None:
        self._connected = False
        # the outage runs from the last reading that arrived, not from when a failed read said
        # so (that read's timeout would hide most of a short blip)
        quiet = time.time() - self._last_seen if math.isfinite(self._last_seen) else 0.0
        self._down_since = time.monotonic() - max(quiet, 0.0)
        self._down_utc = time.time()
        self.stats.link, self.stats.last_error = "down", reason
        self.stats.drops += 1
        self._missing_after_outage = True
        if self._back is not None:  # lost again before the ring was read: nothing came back
            (outage, attempts), self._back = self._back, None
            self._event_at("link_up", link_up_detail(outage, attempts, 0), self._after_last())
        self._event_at("link_down", reason, self._after_last())
        self._say(f"link down: {reason}; reconnecting")
        self._stuck.reset()  # an outage breaks any stuck run
        await self.source.close()

    def _link_up(self, filled: int | None) -> None:
        """The ``link_up`` event of the outage just ended (at the next sample's time)."""
        if self._back is None:
            return
        (outage, attempts), self._back = self._back, None
        self._event("link_up", link_up_detail(outage, attempts, filled))

    # --- main loop ------------------------------------------------------------------------

    async def run(self, duration_s: float | None = None) -> RecorderStats:
        """Record until :meth:`stop`, the end of a replayed log, or ``duration_s`` [s] of wall time.

        Returns
        -------
        RecorderStats
            The final counts; everything queued has been committed (the writer is flushed).

        Raises
        ------
        LinkError
            Only with ``give_up_after_s``: no link for that long.
        ConfigError
            The PLC has no such address, or the device id is wrong (retrying cannot help).
        """
        self._stop.clear()
        deadline = None if duration_s is None else time.monotonic() + duration_s
        self._down_since = time.monotonic()
        try:
            while not self._stop.is_set():
                if not await self._ensure_link(deadline):
                    break
                try:
                    if not self._probed:
                        await self._probe(deadline)
                        self._probed = True
                    if self.site.ring is not None:
                        await self._ring_loop(deadline)
                    else:
                        await self._poll_loop(deadline)
                    break
                except LinkError as error:
                    await self._link_lost(str(error))
        except EndOfSource as end:
            self._say(str(end))
        finally:
            await self.source.close()
            self._connected = False
            self._link_up(0)  # stopped before the ring was read again: nothing came back
            if self._pending or self._gains.pending is not None:
                self._flush_pending(self._after_last())
            self.writer.flush()
        return self.stats

    def _done(self, deadline: float | None) -> bool:
        return self._stop.is_set() or (deadline is not None and time.monotonic() >= deadline)

    # --- the first read: plausibility, and the tags against the ring -----------------------

    async def _probe(self, deadline: float | None) -> None:
        """The first-read check (:func:`~fuelid.plc._first_read.probe_first_read`)."""
        await probe_first_read(self.source, self._wait, lambda: self._done(deadline))

    def _compare_ring(self, reading: Reading, t: float) -> None:
        """The tags against the ring's head (:class:`~fuelid.plc._first_read.RingTagCheck`)."""
        for message in self._ring_check.compare(reading, self._head_record):
            self._event_at("ring_mismatch", message, t)
            self._say(message)

    # --- auxiliary tags: events and values ------------------------------------------------

    def _watch(self, reading: Reading, t: float | None = None) -> None:
        """Gain and mode change events, and the auxiliary values attached to samples.

        ``t`` [s UTC]: the data time of the sample at which the reading was taken (the events'
        time); None: the next sample's (see :meth:`_event`).
        """
        values = reading.values
        self._last_seen = reading.received
        old = self._aux
        # the block's units, as the tags give them (not necessarily V per L/min and s)
        changes = gain_change_text(values, old, self._gains.units)
        if changes:
            self._event("gain_change", changes, t)
        self._gains_read(reading, t)
        mode, before_mode = values.get("mode"), old.get("mode")
        if (
            mode is not None
            and before_mode is not None
            and math.isfinite(mode)
            and math.isfinite(before_mode)
            and round(mode) != round(before_mode)
        ):
            names = {0: "MAN", 1: "AUTO"}
            was, now = round(before_mode), round(mode)
            self._event("mode_change", f"{names.get(was, was)} → {names.get(now, now)}", t)
        self._aux.update({role: v for role, v in values.items() if math.isfinite(v)})
        self._aux_values = {
            role: (v if self._checks.check(role, v, t) else math.nan)
            for role, v in values.items()
            if role in AUX_ROLES
        }

    def _gains_read(self, reading: Reading, t: float | None) -> None:
        """Keep a new reading of the PLC's gains (the first, or a change) in the store's state.

        At ``t`` when given, else at the next sample's time on a data time base (as the
        events, :meth:`_event`), else at its receipt time.
        """
        new = self._gains.new(reading.values, reading.received)
        if new is not None and t is None and self._seq_base:
            self._gains.pending = new
        elif new is not None:
            self.writer.set_state(PLC_GAINS_KEY, stamped(new, t))

    def _sample(
        self, t: float, seq: int | None, core: dict[str, float], quality: int = Quality.OK
    ) -> Sample:
        """A sample from u, y (and the setpoint) and the last auxiliary values, checked."""
        return self._checks.sample(t, seq, core, self._aux_values, quality)

    # --- (b), (c): polling on an absolute deadline ----------------------------------------

    async def _poll_loop(self, deadline: float | None) -> None:
        has_seq = "seq" in self.site.tags
        period = self.period_s
        t_next = time.monotonic()
        missed_run = 0
        while not self._done(deadline):
            now = time.monotonic()
            if now < t_next:
                await asyncio.sleep(t_next - now)
                if self._done(deadline):
                    break
            sent = time.time()
            reading = await self.source.read()
            self._watch(reading)
            if has_seq:
                self._poll_seq(reading, sent)
            else:
                self._poll_receipt(reading)
            self.stats._tick(time.monotonic())
            t_next += period
            late = time.monotonic() - t_next
            if late > period:  # deadlines passed while reading: those samples are lost
                missed = int(late // period)
                t_next += missed * period
                if not has_seq:
                    self.stats.lost += missed
                    missed_run += missed
            elif missed_run:
                self._event("gap", f"{missed_run} sample(s) lost: missed read deadlines")
                missed_run = 0

    def _poll_seq(self, reading: Reading, sent: float) -> None:
        raw = int(reading.raw["seq"]) % UINT32
        seq = self._seq
        if seq.raw is None:
            continued, why = seq.start(raw, reading.received, sent)
            if not continued:
                self._restart(why)
            elif seq.last_stored is not None and raw > seq.last_stored + 1:
                self._gap(raw - seq.last_stored - 1, "since the last recording")
        else:
            step, why = seq.advance(raw, reading.received, sent, self._missing_after_outage)
            if step == 0:
                self.stats.stale += 1
                return
            if step < 0:
                self._restart(f"the PLC's counter {why}")
            elif step > 1:
                self._gap(step - 1, f"sequence jumped to {raw}")
        self._missing_after_outage = False
        core = _core(reading)
        self._take(self._sample(seq.time(seq.u), seq.stored(seq.u), core))

    def _poll_receipt(self, reading: Reading) -> None:
        t = reading.received
        if self._missing_after_outage and math.isfinite(self._last_receipt):
            lost = max(round((t - self._last_receipt) / self.period_s) - 1, 0)
            if lost:
                self.stats.lost += lost
                self._gap(lost, "during the link outage", count=False)
        self._missing_after_outage = False
        self._last_receipt = t
        core = _core(reading)
        self._take(self._sample(t, None, core))

    def _gap(self, lost: int, why: str, count: bool = True) -> None:
        if count:
            self.stats.lost += lost
        self._event("gap", f"{lost} sample(s) lost: {why}")

    def _restart(self, why: str) -> None:
        self.stats.restarts += 1
        self._event("restart", f"PLC restart: {why}; stored sequence continues")
        self._say(f"PLC restart: {why}")
        self._stuck.reset()

    # --- (a): the ring buffer -------------------------------------------------------------

    async def _ring_loop(self, deadline: float | None) -> None:
        ring = self.site.ring
        assert ring is not None
        seq = self._seq
        next_u = self._next_u
        while not self._done(deadline):
            started = time.monotonic()
            sent = time.time()
            head = await self.source.read_ring_head() % UINT32
            received = time.time()
            reading = await self.source.read()
            if seq.raw is None:
                continued, why = seq.start(head, received, sent)
                if continued and seq.last_stored is not None:
                    next_u = seq.last_stored + 1  # back-fill what the last recording missed
                else:
                    if not continued:
                        self._restart(why)
                    next_u = head
            else:
                step, why = seq.advance(head, received, sent, self._missing_after_outage)
                if step < 0:
                    self._restart(f"the ring's head {why}")
                    next_u = 0  # the new run from its start, as far as the ring holds it
            assert next_u is not None
            # the records since the last read, which the failed read and the outage missed
            self._link_up(max(seq.u - max(next_u, self._oldest_held(seq.u)) + 1, 0))
            self._watch(reading, seq.time(seq.u))  # seen at the head's sample
            self._head_record = None
            next_u = await self._read_records(next_u, seq.u, reading)
            self._compare_ring(reading, seq.time(seq.u))
            self._next_u = next_u
            self._missing_after_outage = False
            self.stats._tick(time.monotonic())
            await self._wait(self.ring_poll_s - (time.monotonic() - started))

    def _oldest_held(self, head_u: int) -> int:
        """The oldest record (unwrapped) safe to read from the ring behind ``head_u``."""
        ring = self.site.ring
        assert ring is not None
        return head_u - ring.size + 1 + ring.size // RING_MARGIN

    async def _read_records(self, first_u: int, head_u: int, reading: Reading) -> int:
        """Read records ``first_u … head_u`` (unwrapped) and store them; the next to read."""
        ring = self.site.ring
        assert ring is not None
        seq = self._seq
        if head_u < first_u:
            return first_u
        oldest = self._oldest_held(head_u)
        if first_u < oldest:
            self._gap(oldest - first_u, f"the ring ({ring.size} records) no longer held them")
            first_u = oldest
        u = first_u
        lost = 0
        while u <= head_u:
            slot = (u % UINT32) % ring.size
            count = min(head_u - u + 1, ring.size - slot)
            records: list[RingRecord] = await self.source.read_ring(slot, count)
            for k, record in enumerate(records):
                expected = (u + k) % UINT32
                if record.seq != expected:  # overwritten while we read: lost, not mislabelled
                    lost += 1
                    continue
                core = dict(record.values)
                if u + k == head_u:
                    self._head_record = core
                self._take(self._sample(seq.time(u + k), seq.stored(u + k), core))
            u += count
        if lost:
            self._gap(lost, "ring records overwritten while they were read")
        return head_u + 1


def _core(reading: Reading) -> dict[str, float]:
    """u, y, the setpoint and the excitation of a reading (those it has)."""
    return {role: v for role, v in reading.values.items() if role in _CORE}
