"""The recorder's time base: the PLC's counter as a monotonic stored sequence and sample times.

:class:`SampleSequence` maps the raw uint32 counter (a ``seq`` tag or a ring's head) to the
stored sequence number and the sample time, and tells a PLC restart from a wrap or an outage.
The :class:`~fuelid.plc._recorder.Recorder` reads; this decides what the reads mean.

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
back-filled from the ring when it still holds the missed records) and its times go on from the
stored ones (anchor = last stored time − its number · period); if behind, a PLC restart since
the last recording, anchored by the rule above.

**Event times.** With a ring or a ``seq`` tag every event is on the samples' time base (data
time, which runs X times faster than the wall clock on a PLC at X times real time): ``link_down``
at the last sample stored before the outage + one period; ``link_up``, ``restart`` and ``gap`` at
the first sample stored after (they wait for it; at the end of a recording, the last + one
period); gain and mode changes and bad values at the sample where they were seen. So a
``link_down``/``link_up`` pair brackets the hole in the samples. The wall clock of an event is
its stored ``wall_time`` (when it was written), never text in its detail: a detail carries no
second clock. Without either, events are at the receipt time (the wall clock), as the samples
are.
"""

from __future__ import annotations

import math

__all__ = [
    "HALF_RANGE",
    "RESTART_MIN_COUNTS",
    "RESTART_RATE_SLACK",
    "RESTART_SLACK_S",
    "UINT32",
    "SampleSequence",
]

UINT32 = 1 << 32
"""The range of the PLC's counter: it wraps to 0 after ``UINT32 − 1``."""
HALF_RANGE = 1 << 31
"""A step back by more than this is a restart, not a wrap."""
RESTART_RATE_SLACK = 0.1
"""Fraction by which the counter may advance slower than its rate of the run across an outage
before that counts as a restart (rule (2) of the module docstring)."""
RESTART_SLACK_S = 0.5
"""Wall time [s] the counter may lag besides (a PLC or virtual clock catching up)."""
RESTART_MIN_COUNTS = 10
"""Counts a run must have advanced before its rate is trusted for rule (2)."""


class SampleSequence:
    """Maps the PLC's raw uint32 counter to the stored, monotonic sequence and sample times.

    ``stored = offset + u`` and ``time = anchor + u·period`` with ``u`` the counter unwrapped in
    the current run of the PLC (a restart starts a new run: new offset and anchor).
    """

    def __init__(
        self, period_s: float, last_stored: int | None, last_time: float | None = None
    ) -> None:
        self.period_s = period_s
        self.last_stored = last_stored
        self.last_time = -math.inf if last_time is None else float(last_time)
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
            if last is not None and math.isfinite(self.last_time):
                # the same run of the PLC: its time base goes on from the stored samples (a PLC
                # at X times real time is far ahead of the wall clock: re-anchoring to the wall
                # clock would put the new samples before the stored ones)
                self.anchor = self.last_time - last * self.period_s
            return True, ""
        self.offset = last + 2  # one number left out: a break readers see
        # a new run: the wall-clock anchor, but strictly after the last stored sample
        self.anchor = max(self.anchor, self.last_time + self.period_s)
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
        """The stored sequence number of the unwrapped counter value ``u``."""
        return self.offset + u

    def time(self, u: int) -> float:
        """The sample time of the unwrapped counter value ``u`` [s UTC]."""
        return self.anchor + u * self.period_s

    def mark(self, seq: int, t: float) -> None:
        """Note a sample handed to the store (stored number ``seq``, time ``t`` [s UTC])."""
        self.last_stored = seq if self.last_stored is None else max(self.last_stored, seq)
        self.last_time = max(self.last_time, t)
