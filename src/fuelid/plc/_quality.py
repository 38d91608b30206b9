"""The quality rules of the recorder: which values are bad, and when a sensor is stuck.

A value is **bad** (:attr:`~fuelid.store.Quality.BAD_VALUE`) when it is NaN or infinite, outside
its tag's ``valid`` range (engineering units), or outside its tag's raw span by more than the
usual analog over-range margin. The margin is Siemens's: a 0…27648 analog input reports up to
32511 counts (over-range) and down to −4864 (under-range) before it reports overflow (32767) or a
wire break, i.e. 4864/27648 = 17.6 % of the span on either side. The same fraction is applied to
every scaled tag (4–20 mA: 1.2…22.8 mA; 1–5 V: 0.30…5.70 V): values within it are a real
process at the edge of the range, beyond it a broken sensor, a wire break or a scaling mistake.

A value is also bad when it is **not a plausible engineering value** (:func:`implausible`): not
zero but smaller than :data:`TINY` in magnitude (a float32 denormal, what a float read with the
wrong word order usually gives: 3.0 V sent ABCD and read CDAB is 2.3e-41), or larger than
:data:`HUGE` (the other usual outcome: 59.1 L/min read swapped is 2.7e23). No V, L/min, °C or
gain of a fuel loop is either. And a **command** outside 0…10.5 V (:data:`COMMAND_RANGE_V`: no
drive signal is outside it, after scaling) is bad unless its tag's ``valid`` says otherwise.

A flow reading is **stuck** when it is *exactly* unchanged (bit for bit) for
:data:`STUCK_AFTER_S` seconds of sample time after it has been seen to move at least once in the
recording, and it is not at the low end of its span (within 1 % of it: a stopped pump, or a
flowmeter's low-flow cut-off, reads exactly zero for good reasons). A live flowmeter carries
noise and quantisation steps well above one count (the virtual PLC's flow changes every sample),
so two seconds (100 samples at 50 Hz) of an identical value is a frozen transmitter, a PLC input
card holding its last value, or a dead link that keeps serving a copy.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable

from fuelid.plc.site import Tag
from fuelid.store import Quality, Sample

OVER_RANGE = 4864.0 / 27648.0
"""Fraction of the raw span a value may run over or under it (Siemens analog inputs)."""
STUCK_AFTER_S = 2.0
"""Seconds of sample time of an exactly unchanged flow that mean a stuck sensor [s]."""
LOW_END_FRACTION = 0.01
"""A flow within this fraction of the span of its low end may legitimately be constant."""
TINY = 1e-20
"""Below this magnitude (but not zero) a value is no engineering value: a float32 denormal."""
HUGE = 1e9
"""Above this magnitude a value is no engineering value of a fuel loop."""
COMMAND_RANGE_V = (0.0, 10.5)
"""The VFD command's range [V] without a ``valid`` of its tag: no drive signal is outside it."""
AUX_ROLES = ("setpoint", "fuel_temperature", "mode", "excitation", "run")
"""Roles stored with every sample besides u and y: a bad value is stored as NaN (None), and
the sample stays ``OK``."""
_WITH_CORE = ("setpoint", "excitation")  # read with u and y when a poll or ring record has them


def implausible(value: float) -> bool:
    """Whether a finite value is no plausible engineering value (tiny but not zero, or huge).

    Examples
    --------
    >>> implausible(2.3e-41), implausible(2.7e23), implausible(0.0), implausible(59.1)
    (True, True, False, False)
    """
    magnitude = abs(value)
    return math.isfinite(value) and (0.0 < magnitude < TINY or magnitude > HUGE)


def allowed_range(tag: Tag, role: str = "") -> tuple[float, float]:
    """The engineering range [tag unit] inside which a tag's value is good.

    The raw span widened by :data:`OVER_RANGE` on each side (scaled tags), intersected with the
    tag's ``valid`` range; (−inf, inf) when the tag has neither. ``role = "command"``: without a
    ``valid``, also inside :data:`COMMAND_RANGE_V`.

    Examples
    --------
    >>> lo, hi = allowed_range(Tag(address="ir:0", type="int16", raw=[0, 27648], eng=[0.0, 120.0]))
    >>> round(lo, 3), round(hi, 3)      # −4864 and 32512 counts: 17.6 % of the span each side
    (-21.111, 141.111)
    """
    lo, hi = -math.inf, math.inf
    if tag.raw is not None:
        r0, r1 = sorted(tag.raw)
        margin = OVER_RANGE * (r1 - r0)
        e0, e1 = tag.to_engineering(r0 - margin), tag.to_engineering(r1 + margin)
        lo, hi = min(e0, e1), max(e0, e1)
    if tag.valid is not None:
        lo, hi = max(lo, tag.valid[0]), min(hi, tag.valid[1])
    elif role == "command":
        lo, hi = max(lo, COMMAND_RANGE_V[0]), min(hi, COMMAND_RANGE_V[1])
    return lo, hi


class RangeChecks:
    """Per-role value checks with one event per bad episode (not one per sample).

    Parameters
    ----------
    tags : dict of str to Tag
        The site's read tags by role.
    on_event : callable
        Called as ``on_event(kind, detail, time)`` when a role turns bad (kind ``bad_value``),
        ``time`` the sample time given to :meth:`check` (None: not known).
    """

    def __init__(
        self, tags: dict[str, Tag], on_event: Callable[[str, str, float | None], None]
    ) -> None:
        self._ranges = {role: allowed_range(tag, role) for role, tag in tags.items()}
        if "command" not in self._ranges:  # a ring's command without a tag
            self._ranges["command"] = COMMAND_RANGE_V
        self._units = {role: tag.unit for role, tag in tags.items()}
        self._bad: set[str] = set()
        self._on_event = on_event
        self.episodes = 0
        """Bad-value episodes seen (events written)."""

    def reason(self, role: str, value: float) -> str | None:
        """Why ``value`` of ``role`` is bad, or None when it is good."""
        if not math.isfinite(value):
            return f"{role} = {value!r}"
        if implausible(value):
            return f"{role} = {value:.6g}, not a plausible value"
        lo, hi = self._ranges.get(role, (-math.inf, math.inf))
        if not lo <= value <= hi:
            unit = f" {self._units[role]}" if self._units.get(role) else ""
            return f"{role} = {value:.6g}{unit} outside {lo:.6g}…{hi:.6g}{unit}"
        return None

    def check(self, role: str, value: float, time: float | None = None) -> bool:
        """Whether the value is good; a role turning bad writes one ``bad_value`` event.

        ``time`` [s UTC] is the time of the sample the value belongs to (the event's time).
        """
        why = self.reason(role, value)
        if why is None:
            self._bad.discard(role)
            return True
        if role not in self._bad:
            self._bad.add(role)
            self.episodes += 1
            self._on_event("bad_value", f"{why}: flagged until it is back in range", time)
        return False

    def sample(
        self,
        t: float,
        seq: int | None,
        core: dict[str, float],
        aux: dict[str, float],
        quality: int = Quality.OK,
    ) -> Sample:
        """A sample from u, y (and the setpoint) and the last auxiliary values, checked.

        A bad u or y makes the sample ``BAD_VALUE`` (the values kept as read); a bad setpoint or
        excitation is stored as NaN and the sample stays ``OK``. The run flag is stored as 1
        when it is not zero (a PLC's TRUE may read 1 or −1), else 0.

        Parameters
        ----------
        t : float
            Sample time [s UTC] (the time of a ``bad_value`` event).
        seq : int or None
            Stored sequence number.
        core : dict of str to float
            ``command`` [V], ``flow`` [L/min], and the ``setpoint`` [L/min] and ``excitation``
            [V] when read with them (the same poll, or the same ring record).
        aux : dict of str to float
            The last checked ``setpoint``, ``fuel_temperature`` [°C], ``mode``, ``excitation``
            [V] and ``run`` (NaN: bad; a role left out: not recorded).
        quality : int
            The quality before the checks (a :class:`~fuelid.store.Quality` code).
        """
        good = True
        for role in ("command", "flow"):
            good &= self.check(role, core.get(role, math.nan), t)
        setpoint, excitation = (self._checked(role, core, aux, t) for role in _WITH_CORE)
        mode, run = aux.get("mode", math.nan), aux.get("run", math.nan)
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
            excitation=excitation,
            run=int(run != 0.0) if math.isfinite(run) else None,
        )

    def _checked(self, role: str, core: dict[str, float], aux: dict[str, float], t: float) -> float:
        """A role read with u and y (checked now, NaN when bad), else its last checked value."""
        value = core.get(role)
        if value is None:
            return aux.get(role, math.nan)
        return value if self.check(role, value, t) else math.nan


class StuckDetector:
    """Flags a stuck flow from the first sample of its stretch, without holding samples back.

    Each sample goes through :meth:`push` and is returned at once, so that the recorder hands
    it to the store's writer with no delay (a crash loses at most the uncommitted batch). A
    sample of a stretch already recognised as stuck is returned flagged ``BAD_VALUE``. When a
    stretch becomes stuck (its value unchanged for :data:`STUCK_AFTER_S`), its earlier samples
    have already gone to the writer: ``on_reflag(t_from, t_to)`` then asks for them to be
    flagged in the store (the recorder queues
    :meth:`~fuelid.store.SampleWriter.set_quality`, which the writer applies after those
    samples' inserts), and the sample that completes the window is returned flagged. So the
    whole stretch is flagged from its first sample, and nothing waits for the detection.

    Parameters
    ----------
    flow_tag : Tag or None
        The flow's tag (its span gives the low end); None: no low-end exception.
    on_event : callable
        ``on_event(kind, detail, time)`` when a stuck stretch is found (kind ``stuck_sensor``).
    stuck_after_s : float
        Window [s] of sample time.
    on_reflag : callable, optional
        ``on_reflag(t_from, t_to, count)``: the samples with ``t_from <= time <= t_to`` [s UTC]
        (``count`` of them were returned OK) are to be flagged ``BAD_VALUE`` in the store.
    """

    def __init__(
        self,
        flow_tag: Tag | None,
        on_event: Callable[[str, str, float], None],
        stuck_after_s: float = STUCK_AFTER_S,
        on_reflag: Callable[[float, float, int], None] | None = None,
    ) -> None:
        self.window_s = float(stuck_after_s)
        self._on_event = on_event
        self._on_reflag = on_reflag
        low = -math.inf
        if flow_tag is not None and flow_tag.eng is not None:
            e0, e1 = sorted(flow_tag.eng)
            low = e0 + LOW_END_FRACTION * (e1 - e0)
        self._low = low
        self._value = math.nan
        self._run_start = math.nan
        self._run_ok = 0  # samples of the current run returned OK (to be re-flagged)
        self._moved = False
        self._stuck = False
        self.episodes = 0
        """Stuck stretches found."""

    def push(self, sample: Sample) -> Sample:
        """Take one sample; return it at once, flagged when its stretch is known to be stuck."""
        y = sample.y
        if y == self._value:  # NaN never equals: a NaN run is a bad value, not a stuck one
            if (
                not self._stuck
                and self._moved
                and y > self._low
                and sample.time - self._run_start >= self.window_s
            ):
                self._stuck = True
                self.episodes += 1
                self._on_event(
                    "stuck_sensor",
                    f"flow exactly {y:.6g} for {sample.time - self._run_start:.3g} s while it "
                    "moved before: flagged bad from the start of the stretch until it moves",
                    self._run_start,
                )
                if self._on_reflag is not None and self._run_ok:
                    self._on_reflag(self._run_start, sample.time, self._run_ok)
                self._run_ok = 0
        else:
            if math.isfinite(self._value) and math.isfinite(y):
                self._moved = True
            self._value, self._run_start, self._stuck = y, sample.time, False
            self._run_ok = 0
        if self._stuck:
            return _flag(sample)
        if sample.quality == Quality.OK:
            self._run_ok += 1
        return sample

    def reset(self) -> None:
        """Forget the current run (a link loss or a PLC restart breaks it)."""
        self._value, self._run_start, self._stuck, self._run_ok = math.nan, math.nan, False, 0


def _flag(sample: Sample) -> Sample:
    if sample.quality == Quality.OK:
        return sample._replace(quality=int(Quality.BAD_VALUE))
    return sample


def count_not_ok(samples: Iterable[Sample]) -> int:
    """Samples whose quality is not OK."""
    return sum(1 for s in samples if s.quality != Quality.OK)
