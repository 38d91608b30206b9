"""The recorder: samples from any :class:`~fuelid.plc.adapters.base.PlcSource` into a store.

Protocol-agnostic and asyncio-based; it owns the connect loop and never dies on a link error.

**Link.** One connect attempt after another with exponential backoff (0.2 s doubling to 5 s);
a message goes to ``on_message`` when the link state or the reason changes, not per attempt.
``link_down`` (with the reason) and ``link_up`` (with the outage's length) events are stored.
``give_up_after_s`` makes the recorder raise :class:`LinkError` after that long without a link.

**Time base**, in order of preference:

(a) ``[ring]``: every ``ring_poll_s`` (0.2 s of wall time) the head and the new records are read
    in blocks. Sample time = ``anchor + u·period_s`` with u the sequence number unwrapped past
    uint32 wrap-around and the anchor (UTC) fixed at the first read, so times are as regular as
    the PLC's cyclic interrupt. A link drop is back-filled from the ring (from the last stored
    record + 1), and a ``gap`` event counts what the ring no longer holds. The other tags
    (fuel temperature, mode, gains, the setpoint if not in the ring) are read once per poll and
    attached to that poll's records.
(b) a ``seq`` tag without a ring: reads on an absolute-deadline schedule (``t_next += period``,
    no drift); time from the unwrapped sequence number as in (a). A repeated number is no new
    sample (counted stale, not stored: it already is), a skipped one a gap.
(c) neither: the receipt time; a missed deadline is a lost sample (counted; one ``gap`` event per
    run of misses).

**Restarts.** A PLC restart is seen in two ways. (1) The counter jumps back (by more than half
its range: not a wrap). (2) After a link outage, the counter advanced less than the wall time
of the outage allows: less than the counter's rate in this run (a lower bound: the counts
since the run's first read over the longest wall time they can have taken) × ``(1 −
RESTART_RATE_SLACK)`` × the wall time surely between the two reads (the request of the new one
minus the receipt of the last one), less :data:`RESTART_SLACK_S` of counting. A PLC that
restarted during a long outage can count past the last number seen before it (its new run is
longer than the old one was): (1) alone misses it, (2) does not, and rate and times are bounds,
so a PLC that ran on through the outage is never taken for a restart. Only the first read after
an outage is judged by (2): a PLC whose clock stalls while the link is up is no restart.

A restart writes a ``restart`` event, the stored sequence continues monotonic, leaving one
number out so that readers see a break (:meth:`~fuelid.store.SampleStore.to_iodata` starts a
new segment), and the new run is read from its first record (as far as the ring holds it).
Its times are re-anchored by the rule: ``anchor = max(receipt − head·period, last stored time
+ period)``, the wall-clock anchor of a first connection unless that would put the new run's
first sample at or before the last stored one. At X times real time the data time runs ahead
of the wall clock (X s per s), so after a restart the second term usually wins: the new run
follows the old one one period later, sample times stay strictly increasing and never collide
with stored ones, and the outage shows as the break in the sequence (the events give its wall
time). A recorder started on a store continues after its largest stored number: if the PLC's
counter is ahead of it, the PLC is taken to be the same run (stored number = the PLC's,
back-filled from the ring when it still holds the missed records); if behind, a PLC restart
since the last recording.

**Outages without a ring** store no rows (no invented values, and no rows of NaN): the
``link_down``/``link_up`` events and a ``gap`` event with the count of samples lost say it, and
the time (or sequence) gap in the samples shows it to every reader.

**Event times.** With a ring or a ``seq`` tag every event is on the samples' time base (data
time, which runs X times faster than the wall clock on a PLC at X times real time): ``link_down``
at the last sample stored before the outage + one period; ``link_up``, ``restart`` and ``gap`` at
the first sample stored after (they wait for it; at the end of a recording, the last + one
period); gain and mode changes and bad values at the sample where they were seen. So a
``link_down``/``link_up`` pair brackets the hole in the samples. The link events keep the wall
clock in their detail (``at 12:22:26 UTC wall clock``). Without either, events are at the
receipt time (the wall clock), as the samples are.

**First read.** Right after the first connection, before anything is stored, the values are
judged (:meth:`Recorder._probe`): a float32 tag that is tiny but not zero (< 1e-20) or huge
(> 1e9), an int32/uint32 tag above 1e9, a ring whose newest records all hold another seq than
their slot should (or an implausible float), or a counter that advances more than
:data:`PROBE_JUMP_FACTOR` times what the wall time allows, is what a wrong word order or byte
swap gives: the recording is refused with a one-line :class:`~fuelid.errors.ConfigError` naming
the tag, the value and the word-order hint (``fuelid record`` exits with 2).

**Ring against tags.** With a ring, u and y come from its records (scan-consistent), not from
``[tags.flow]``/``[tags.command]``. Over the first :data:`RING_CHECK_POLLS` polls the tags' flow
and command are compared with the head record of each poll; a median difference beyond 2 % of
the flow tag's eng span (2 L/min without a scaling) or 0.1 V writes a ``ring_mismatch`` event
and a message naming both (a wrong scaling, or a ring mapped to other fields).

**Quality** (:mod:`fuelid.plc.quality`): u and y (and the ring's fields) that are NaN, infinite,
implausible (tiny but not zero, or huge), out of range or, for u, outside 0…10.5 V without a
``valid`` make the sample ``BAD_VALUE`` (values kept as read); a bad setpoint, fuel
temperature or mode is stored as NaN (None) and the sample stays ``OK``. Each bad episode writes
one ``bad_value`` event; a stuck flow a ``stuck_sensor`` event and its samples ``BAD_VALUE``.
Applied gains that change write ``gain_change``, MAN/AUTO ``mode_change``.

**Nothing is held back.** Every sample goes to the writer as soon as it is read, so a crash
(kill -9) loses at most the batch not yet committed (the commit interval, 1 s). A stuck flow is
recognised :data:`~fuelid.plc.quality.STUCK_AFTER_S` after its stretch began: from then on its
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
import statistics
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from fuelid.errors import ConfigError, FuelidError
from fuelid.plc.adapters.base import EndOfSource, LinkError, PlcSource, Reading, RingRecord
from fuelid.plc.quality import HUGE, STUCK_AFTER_S, RangeChecks, StuckDetector, implausible
from fuelid.plc.site import SiteConfig
from fuelid.store import Quality, Sample, SampleWriter, tag_map_hash

UINT32 = 1 << 32
HALF_RANGE = 1 << 31
BACKOFF_FIRST_S = 0.2
"""First wait between connect attempts [s]."""
BACKOFF_MAX_S = 5.0
"""Longest wait between connect attempts [s]."""
RING_POLL_S = 0.2
"""Wall time between ring reads [s]."""
RING_MARGIN = 8
"""Fraction 1/RING_MARGIN of the ring left alone when back-filling: the PLC overwrites the
oldest records while they are read."""
RESTART_RATE_SLACK = 0.1
"""Fraction by which the counter may advance slower than its rate of the run across an outage
before that counts as a restart (rule (2) of the module docstring)."""
RESTART_SLACK_S = 0.5
"""Wall time [s] the counter may lag besides (a PLC or virtual clock catching up)."""
RESTART_MIN_COUNTS = 10
"""Counts a run must have advanced before its rate is trusted for rule (2)."""
_CORE = ("command", "flow", "setpoint")
RATE_WINDOW_S = 5.0
"""Window of the live sample rate [s]."""
STATUS_WIDTH = 80
"""Longest live status line [characters]: one line of an 80-column terminal."""
PROBE_RECORDS = 8
"""Ring records read by the first-read check (the newest ones, ending at the head)."""
PROBE_WAIT_S = 0.1
"""Wall time between the two counter reads of the first-read check [s]."""
PROBE_JUMP_FACTOR = 1 << 14
"""A counter that advances more than this many times the samples the wall time between two reads
allows is garbled (a word-swapped uint32 advances 65536 times too fast; a virtual PLC or a
replay runs at most 1000 times real time)."""
RING_CHECK_POLLS = 10
"""Ring polls over which the tags' flow and command are compared with the ring's records."""
RING_FLOW_TOLERANCE = 0.02
"""Largest median difference of the flow tag and the ring, as a fraction of the tag's eng span."""
RING_FLOW_TOLERANCE_LPM = 2.0
"""The same without a scaling [L/min]."""
RING_COMMAND_TOLERANCE_V = 0.1
"""Largest median difference of the command tag and the ring [V]."""


def site_identity(site: SiteConfig) -> dict[str, Any]:
    """``site_name`` and ``tag_map_hash`` of a site, as a store records them.

    The hash covers what gives the stored numbers their meaning: the read tags (addresses,
    types, scalings), the ring's layout and the sample period. The write side and the endpoint
    may change without making it another site.
    """
    wiring = site.model_dump(mode="json", include={"tags", "ring"})
    wiring["period_s"] = site.sampling.period_s
    return {"site_name": site.site.name, "tag_map_hash": tag_map_hash(wiring)}


@dataclass
class RecorderStats:
    """What the recorder has done so far (the live status line)."""

    link: str = "connecting"
    """``connecting``, ``up`` or ``down``."""
    stored: int = 0
    """Samples handed to the store."""
    lost: int = 0
    """Samples known lost (sequence gaps, missed deadlines, ring overrun)."""
    stale: int = 0
    """Reads that returned no new sample (a repeated sequence number)."""
    flagged: int = 0
    """Samples stored with a quality other than OK."""
    drops: int = 0
    """Link losses after a link was up."""
    restarts: int = 0
    """PLC restarts seen."""
    last_error: str = ""
    """The last link error, one line."""
    _recent: deque[tuple[float, int]] = field(default_factory=deque, repr=False)

    def _tick(self, now: float) -> None:
        self._recent.append((now, self.stored))
        while self._recent and self._recent[0][0] < now - RATE_WINDOW_S:
            self._recent.popleft()

    @property
    def rate(self) -> float:
        """Samples stored per second over the last few seconds of wall time [1/s]."""
        if len(self._recent) < 2:
            return 0.0
        (t0, n0), (t1, n1) = self._recent[0], self._recent[-1]
        return (n1 - n0) / (t1 - t0) if t1 > t0 else 0.0

    def line(self) -> str:
        """One status line of at most :data:`STATUS_WIDTH` characters in every state.

        Link, rate, stored, lost, flagged (and drops, restarts when there were some); the reason
        of a link loss is not in it (it goes once per change to the recorder's messages).
        """
        parts = [
            f"link {self.link}",
            f"{self.rate:.1f}/s",
            f"{self.stored} stored",
            f"{self.lost} lost",
            f"{self.flagged} flagged",
        ]
        if self.drops:
            parts.append(f"{self.drops} drops")
        if self.restarts:
            parts.append(f"{self.restarts} restarts")
        text = " | ".join(parts)
        if len(text) > STATUS_WIDTH:
            text = text[: STATUS_WIDTH - 1] + "…"
        return text


class _Sequence:
    """Maps the PLC's raw uint32 counter to the stored, monotonic sequence and sample times.

    ``stored = offset + u`` and ``time = anchor + u·period`` with ``u`` the counter unwrapped in
    the current run of the PLC (a restart starts a new run: new offset and anchor).
    """

    def __init__(self, period_s: float, last_stored: int | None) -> None:
        self.period_s = period_s
        self.last_stored = last_stored
        self.last_time = -math.inf
        self.offset = 0
        self.anchor = math.nan
        self.raw: int | None = None
        self.u = 0
        self._origin = (math.nan, 0)  # (request wall time, u) of the run's first read
        self._last_read = (math.nan, 0)  # (receipt wall time, u) of the last read

    def _new_run(self, raw: int, sent: float, received: float) -> None:
        self.raw, self.u = raw, raw
        self._origin = (sent, raw)
        self._last_read = (received, raw)

    def min_rate(self) -> float | None:
        """A lower bound of the counter's rate in this run [counts per wall s], or None.

        Counts between the first and the last read over the longest wall time they can span
        (the first request to the last receipt); None before :data:`RESTART_MIN_COUNTS`.
        """
        (sent0, u0), (received1, u1) = self._origin, self._last_read
        span = received1 - sent0
        if u1 - u0 < RESTART_MIN_COUNTS or not span > 0.0:
            return None
        return (u1 - u0) / span

    def too_slow(self, step: int, sent: float) -> bool:
        """Whether a forward ``step`` read at ``sent`` is less than the run's rate allows."""
        rate = self.min_rate()
        if rate is None:
            return False
        quiet = sent - self._last_read[0]  # wall time surely between the two counter readings
        least = rate * ((1.0 - RESTART_RATE_SLACK) * quiet - RESTART_SLACK_S)
        return step < least

    def start(self, raw: int, received: float, sent: float | None = None) -> tuple[bool, str]:
        """The first counter value of this process; (continues the store?, why if not)."""
        self._new_run(raw, received if sent is None else sent, received)
        self.anchor = received - raw * self.period_s
        last = self.last_stored
        if last is None or raw > last:
            self.offset = 0  # the stored number is the PLC's own
            return True, ""
        self.offset = last + 2  # one number left out: a break readers see
        return False, f"the PLC's counter ({raw}) is behind the store's last sample ({last})"

    def advance(
        self, raw: int, received: float, sent: float | None = None, after_outage: bool = False
    ) -> tuple[int, str]:
        """Step to a new counter value; (step, why it is a restart).

        The step is 0 for a repeat, > 0 forward, < 0 a restart (rules (1) and (2) of the module
        docstring; (2) only ``after_outage``).
        """
        assert self.raw is not None
        sent = received if sent is None else sent
        step = (raw - self.raw) % UINT32
        why = ""
        if step >= HALF_RANGE:  # back by more than half the range: not a wrap, a restart
            why = f"went back to {raw}"
        elif after_outage and self.too_slow(step, sent):
            quiet = sent - self._last_read[0]
            why = (
                f"advanced only {step} in {quiet:.1f} s without a link (from {self.raw} to "
                f"{raw}; it counted at least {self.min_rate() or 0.0:.4g} per s before)"
            )
        if why:
            last = self.last_stored if self.last_stored is not None else self.offset + self.u
            self.offset = last + 2
            # the wall-clock anchor, but the new run strictly after the last stored sample
            self.anchor = max(received - raw * self.period_s, self.last_time + self.period_s)
            self._new_run(raw, sent, received)
            return -1, why
        self.raw = raw
        self.u += step
        self._last_read = (received, self.u)
        return step, ""

    def stored(self, u: int) -> int:
        return self.offset + u

    def time(self, u: int) -> float:
        return self.anchor + u * self.period_s

    def mark(self, seq: int, t: float) -> None:
        self.last_stored = seq if self.last_stored is None else max(self.last_stored, seq)
        self.last_time = max(self.last_time, t)


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
        self._seq = _Sequence(self.period_s, writer.store.last_seq())
        self._checks = RangeChecks(dict(self.site.tags), self._event)
        self._stuck = StuckDetector(
            self.site.tags.get("flow"), self._event_at, stuck_after_s, self._reflag
        )
        self._aux: dict[str, float] = {}  # last finite kc, ti, mode (change events)
        self._aux_values: dict[str, float] = {}  # setpoint, temperature, mode attached, checked
        self._next_u: int | None = None  # ring: the next record to read (unwrapped)
        self._last_receipt = math.nan
        self._last_seen = math.nan  # when any reading last arrived [s UTC]
        self._missing_after_outage = False
        ring = self.site.ring
        self._ring_fields = tuple(ring.fields[1:]) if ring is not None else ()
        self._seq_base = ring is not None or "seq" in self.site.tags
        """Sample times are data times (ring or counter): events are put on them too."""
        self._pending: list[tuple[str, str]] = []  # events waiting for the next sample's time
        self._probed = False
        self._head_record: dict[str, float] | None = None  # ring: this poll's head record
        self._ring_pairs: dict[str, list[tuple[float, float]]] = {"flow": [], "command": []}
        self._ring_polls = 0
        self._ring_checked = False

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

    def _wall(self) -> str:
        """`` (at 12:22:26 UTC wall clock)`` for events on a data time base, else nothing."""
        if not self._seq_base:
            return ""
        return f" (at {time.strftime('%H:%M:%S', time.gmtime())} UTC wall clock)"

    def _take(self, sample: Sample) -> None:
        if self._pending:
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
                        self._event_at("link_down", reason + self._wall(), self._after_last())
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
                self._event(
                    "link_up",
                    f"after {outage:.3f} s without a link ({attempts} attempts){self._wall()}",
                )
                self._say(f"link up: {self.source.where} after {outage:.1f} s")
            else:
                self._say(f"connected to {self.source.where}")
            self.stats.link = "up"
            self._ever_up = True
            return True
        return False

    async def _link_lost(self, reason: str) -> None:
        self._connected = False
        self._down_since = time.monotonic()
        self._down_utc = time.time()
        self.stats.link, self.stats.last_error = "down", reason
        self.stats.drops += 1
        self._missing_after_outage = True
        self._event_at("link_down", reason + self._wall(), self._after_last())
        self._say(f"link down: {reason}; reconnecting")
        self._stuck.reset()  # an outage breaks any stuck run
        await self.source.close()

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
            if self._pending:
                self._flush_pending(self._after_last())
            self.writer.flush()
        return self.stats

    def _done(self, deadline: float | None) -> bool:
        return self._stop.is_set() or (deadline is not None and time.monotonic() >= deadline)

    # --- the first read: plausibility, and the tags against the ring -----------------------

    def _refusal(self, what: str) -> ConfigError:
        """A one-line refusal of implausible first values, with the likely cause."""
        plc = self.site.plc
        if plc.protocol == "modbus":
            other = "little" if plc.word_order == "big" else "big"
            hint = (
                f"the PLC may send 32-bit values {'low' if other == 'little' else 'high'} word "
                f'first: try word_order = "{other}" or byte_swap = '
                f"{'false' if plc.byte_swap else 'true'}"
            )
        else:
            hint = "check the tag's type and address against the PLC's"
        return ConfigError(
            f"{what}: not a plausible value, so nothing is recorded; {hint} (word_order = "
            f'"{plc.word_order}", byte_swap = {"true" if plc.byte_swap else "false"} in the '
            "site file)"
        )

    async def _probe(self, deadline: float | None) -> None:
        """Refuse to record values that cannot be right (the first read after connecting).

        A float32 tag that is tiny but not zero or huge (:func:`~fuelid.plc.quality.implausible`),
        an int32/uint32 tag above 1e9 in engineering units, a ring whose newest records all
        hold another seq than their slot should or an implausible float, a counter (``seq`` or
        the ring's head) that advances more than :data:`PROBE_JUMP_FACTOR` times what the wall
        time between two reads allows: a :class:`ConfigError` naming the tag and the value,
        with the word-order hint. A replayed log has no word order: not checked.

        Raises
        ------
        ConfigError
            Implausible first values (``fuelid record`` exits with code 2).
        LinkError
            The link dropped (the check runs again on the next connection).
        """
        site = self.site
        if site.plc.protocol == "replay":
            return
        sent = time.time()
        reading = await self.source.read()
        for role, tag in site.tags.items():
            value = reading.raw.get(role)
            if role == "seq" or value is None or tag.type not in ("float32", "int32", "uint32"):
                continue
            if tag.type == "float32" and implausible(value):
                raise self._refusal(f"tags.{role} {tag.address} reads {value:.6g} (float32)")
            if tag.type != "float32" and abs(tag.to_engineering(value)) > HUGE:
                raise self._refusal(f"tags.{role} {tag.address} reads {value:.0f} ({tag.type})")
        ring = site.ring
        key, address = "tags.seq", site.tags["seq"].address if "seq" in site.tags else ""
        if ring is not None:
            key, address = "ring.head", ring.head
            sent = time.time()
            first = await self.source.read_ring_head() % UINT32
            await self._probe_records(first)
        elif "seq" in site.tags:
            first = int(reading.raw["seq"]) % UINT32
        else:
            return
        await self._wait(PROBE_WAIT_S)
        if self._done(deadline):
            return
        if ring is not None:
            second = await self.source.read_ring_head() % UINT32
        else:
            second = int((await self.source.read()).raw["seq"]) % UINT32
        elapsed = time.time() - sent
        step = (second - first) % UINT32
        allowed = PROBE_JUMP_FACTOR * max(elapsed / self.period_s, 1.0)
        if allowed < step < HALF_RANGE:
            raise self._refusal(
                f"{key} {address} jumped from {first} to {second} in {elapsed:.3f} s (at "
                f"{self.period_s:g} s per sample, about {elapsed / self.period_s:.0f} samples)"
            )

    async def _probe_records(self, head: int) -> None:
        """The newest ring records (ending at ``head``): refused when every one is wrong."""
        ring = self.site.ring
        assert ring is not None
        n = min(PROBE_RECORDS, ring.size, head + 1)
        last_slot = head % ring.size
        slots = [(last_slot - n + 1 + k) % ring.size for k in range(n)]
        records: list[RingRecord] = []
        start = slots[0]
        while len(records) < n:
            count = min(n - len(records), ring.size - start)
            records += await self.source.read_ring(start, count)
            start = 0
        wrong = []
        for k, record in enumerate(records):
            expected = (head - n + 1 + k) % UINT32
            odd = [f"{name} = {v:.6g}" for name, v in record.values.items() if implausible(v)]
            if record.seq != expected:
                wrong.append(
                    f"ring.head {ring.head} reads {head}, but slot {slots[k]} of the ring at "
                    f"{ring.address} holds seq {record.seq}, not {expected}"
                )
            elif odd:
                wrong.append(f"ring record {record.seq} at {ring.address} holds {odd[0]}")
        if wrong and len(wrong) == len(records):
            raise self._refusal(wrong[-1])

    def _compare_ring(self, reading: Reading, t: float) -> None:
        """Compare the tags' flow and command with the ring's head record over the first polls.

        The samples come from the ring (scan-consistent); the tags' addresses and scalings are
        not used for them. A median difference (over :data:`RING_CHECK_POLLS` polls: beats the
        noise and the scan skew between the head and the tags) beyond 2 % of the flow tag's eng
        span (2 L/min without a scaling) or 0.1 V of the command writes one ``ring_mismatch``
        event and message: a wrong scaling or a ring mapped wrongly.
        """
        head = self._head_record
        if self._ring_checked or head is None:
            return
        for role, pairs in self._ring_pairs.items():
            a, b = reading.values.get(role, math.nan), head.get(role, math.nan)
            if math.isfinite(a) and math.isfinite(b):
                pairs.append((a, b))
        self._ring_polls += 1
        if self._ring_polls < RING_CHECK_POLLS:
            return
        self._ring_checked = True
        for role, pairs in self._ring_pairs.items():
            tag = self.site.tags.get(role)
            if tag is None or not pairs:
                continue
            if role == "flow":
                limit = RING_FLOW_TOLERANCE_LPM
                if tag.eng is not None:
                    limit = RING_FLOW_TOLERANCE * abs(tag.eng[1] - tag.eng[0])
            else:
                limit = RING_COMMAND_TOLERANCE_V
            difference = statistics.median(a - b for a, b in pairs)
            if abs(difference) <= limit:
                continue
            unit = tag.unit or ("L/min" if role == "flow" else "V")
            tag_value = statistics.median(a for a, _ in pairs)
            ring_value = statistics.median(b for _, b in pairs)
            message = (
                f"tags.{role} {tag.address} reads {tag_value:.4g} {unit}, the ring "
                f"{ring_value:.4g} {unit}: check the tag's raw/eng scaling or the ring's fields"
            )
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
        changes = []
        for role, unit in (("kc", "V per L/min"), ("ti", "s")):
            new = values.get(role)
            before = old.get(role)
            if new is None or before is None or not math.isfinite(new):
                continue
            if not math.isclose(new, before, rel_tol=1e-6, abs_tol=0.0):
                changes.append(f"{role} {before:.6g} → {new:.6g} {unit}")
        if changes:
            self._event("gain_change", ", ".join(changes), t)
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
            if role in ("setpoint", "fuel_temperature", "mode")
        }

    def _sample(
        self, t: float, seq: int | None, core: dict[str, float], quality: int = Quality.OK
    ) -> Sample:
        """A sample from u, y (and the setpoint) and the last auxiliary values, checked."""
        aux = self._aux_values
        good = True
        for role in ("command", "flow"):
            good &= self._checks.check(role, core.get(role, math.nan), t)
        setpoint = core.get("setpoint")
        if setpoint is None:
            setpoint = aux.get("setpoint", math.nan)
        elif not self._checks.check("setpoint", setpoint, t):
            setpoint = math.nan
        mode = aux.get("mode", math.nan)
        if quality == Quality.OK and not good:
            quality = Quality.BAD_VALUE
        return Sample(
            time=t,
            seq=seq,
            u=core.get("command", math.nan),
            y=core.get("flow", math.nan),
            setpoint=setpoint,
            fuel_temperature=aux.get("fuel_temperature", math.nan),
            mode=round(mode) if math.isfinite(mode) else None,
            quality=int(quality),
        )

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
            self._watch(reading, seq.time(seq.u))  # seen at the head's sample
            self._head_record = None
            next_u = await self._read_records(next_u, seq.u, reading)
            self._compare_ring(reading, seq.time(seq.u))
            self._next_u = next_u
            self._missing_after_outage = False
            self.stats._tick(time.monotonic())
            await self._wait(self.ring_poll_s - (time.monotonic() - started))

    async def _read_records(self, first_u: int, head_u: int, reading: Reading) -> int:
        """Read records ``first_u … head_u`` (unwrapped) and store them; the next to read."""
        ring = self.site.ring
        assert ring is not None
        seq = self._seq
        if head_u < first_u:
            return first_u
        oldest = head_u - ring.size + 1 + ring.size // RING_MARGIN
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
    """u, y and the setpoint of a reading (those it has)."""
    return {role: v for role, v in reading.values.items() if role in _CORE}


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
        store_url or site.store.url, period_s=site.sampling.period_s, **site_identity(site)
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
                    store.prune(
                        site.store.retention_days,
                        site.store.thin_to_s,
                        now=max(newest, time.time()) if site.plc.protocol != "replay" else newest,
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


PRUNE_EVERY_S = 3600.0
"""How often the recorder applies the store's retention (and once at start) [s]."""


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
