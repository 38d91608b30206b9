"""The first read after connecting, and the tags against the ring: values that cannot be right.

**First read.** Right after the first connection, before anything is stored, the values are
judged (:func:`probe_first_read`): a float32 tag that is tiny but not zero (< 1e-20) or huge
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
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Awaitable, Callable

from fuelid.errors import ConfigError
from fuelid.plc._quality import HUGE, implausible
from fuelid.plc._timebase import HALF_RANGE, UINT32
from fuelid.plc.adapters._base import PlcSource, Reading, RingRecord
from fuelid.plc.site import SiteConfig

__all__ = [
    "PROBE_JUMP_FACTOR",
    "PROBE_RECORDS",
    "PROBE_WAIT_S",
    "RING_CHECK_POLLS",
    "RING_COMMAND_TOLERANCE_V",
    "RING_FLOW_TOLERANCE",
    "RING_FLOW_TOLERANCE_LPM",
    "RingTagCheck",
    "probe_first_read",
    "refusal",
]

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


def refusal(site: SiteConfig, what: str) -> ConfigError:
    """A one-line refusal of implausible first values, with the likely cause."""
    plc = site.plc
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


async def probe_first_read(
    source: PlcSource,
    wait: Callable[[float], Awaitable[None]],
    stopped: Callable[[], bool],
) -> None:
    """Refuse to record values that cannot be right (the first read after connecting).

    A float32 tag that is tiny but not zero or huge (:func:`~fuelid.plc._quality.implausible`),
    an int32/uint32 tag above 1e9 in engineering units, a ring whose newest records all
    hold another seq than their slot should or an implausible float, a counter (``seq`` or
    the ring's head) that advances more than :data:`PROBE_JUMP_FACTOR` times what the wall
    time between two reads allows: a :class:`ConfigError` naming the tag and the value,
    with the word-order hint. A replayed log has no word order: not checked.

    Parameters
    ----------
    source : PlcSource
        The connected link (its ``site`` gives the tags, the ring and the period).
    wait : callable
        Sleeps a number of seconds [s], waking early when the recording stops.
    stopped : callable
        True when the recording stops (or its duration ran out).

    Raises
    ------
    ConfigError
        Implausible first values (``fuelid record`` exits with code 2).
    LinkError
        The link dropped (the check runs again on the next connection).
    """
    site = source.site
    period_s = site.sampling.period_s
    if site.plc.protocol == "replay":
        return
    sent = time.time()
    reading = await source.read()
    for role, tag in site.tags.items():
        value = reading.raw.get(role)
        if role == "seq" or value is None or tag.type not in ("float32", "int32", "uint32"):
            continue
        if tag.type == "float32" and implausible(value):
            raise refusal(site, f"tags.{role} {tag.address} reads {value:.6g} (float32)")
        if tag.type != "float32" and abs(tag.to_engineering(value)) > HUGE:
            raise refusal(site, f"tags.{role} {tag.address} reads {value:.0f} ({tag.type})")
    ring = site.ring
    key, address = "tags.seq", site.tags["seq"].address if "seq" in site.tags else ""
    if ring is not None:
        key, address = "ring.head", ring.head
        sent = time.time()
        first = await source.read_ring_head() % UINT32
        await _probe_records(source, first)
    elif "seq" in site.tags:
        first = int(reading.raw["seq"]) % UINT32
    else:
        return
    await wait(PROBE_WAIT_S)
    if stopped():
        return
    if ring is not None:
        second = await source.read_ring_head() % UINT32
    else:
        second = int((await source.read()).raw["seq"]) % UINT32
    elapsed = time.time() - sent
    step = (second - first) % UINT32
    allowed = PROBE_JUMP_FACTOR * max(elapsed / period_s, 1.0)
    if allowed < step < HALF_RANGE:
        raise refusal(
            site,
            f"{key} {address} jumped from {first} to {second} in {elapsed:.3f} s (at "
            f"{period_s:g} s per sample, about {elapsed / period_s:.0f} samples)",
        )


async def _probe_records(source: PlcSource, head: int) -> None:
    """The newest ring records (ending at ``head``): refused when every one is wrong."""
    ring = source.site.ring
    assert ring is not None
    n = min(PROBE_RECORDS, ring.size, head + 1)
    last_slot = head % ring.size
    slots = [(last_slot - n + 1 + k) % ring.size for k in range(n)]
    records: list[RingRecord] = []
    start = slots[0]
    while len(records) < n:
        count = min(n - len(records), ring.size - start)
        records += await source.read_ring(start, count)
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
        raise refusal(source.site, wrong[-1])


class RingTagCheck:
    """Compares the tags' flow and command with the ring's head record over the first polls.

    The samples come from the ring (scan-consistent); the tags' addresses and scalings are not
    used for them. A median difference (over :data:`RING_CHECK_POLLS` polls: beats the noise and
    the scan skew between the head and the tags) beyond 2 % of the flow tag's eng span (2 L/min
    without a scaling) or 0.1 V of the command is a wrong scaling or a ring mapped wrongly.

    Parameters
    ----------
    site : SiteConfig
        The site (its ``flow`` and ``command`` tags).
    """

    def __init__(self, site: SiteConfig) -> None:
        self.site = site
        self.checked = False
        self._polls = 0
        self._pairs: dict[str, list[tuple[float, float]]] = {"flow": [], "command": []}

    def compare(self, reading: Reading, head: dict[str, float] | None) -> list[str]:
        """Add one poll (the tags' reading and the ring's head record); the mismatches found.

        Returns
        -------
        list of str
            Empty until :data:`RING_CHECK_POLLS` polls are in, then once one line per tag whose
            median differs from the ring (the ``ring_mismatch`` event's detail), then empty.
        """
        if self.checked or head is None:
            return []
        for role, pairs in self._pairs.items():
            a, b = reading.values.get(role, math.nan), head.get(role, math.nan)
            if math.isfinite(a) and math.isfinite(b):
                pairs.append((a, b))
        self._polls += 1
        if self._polls < RING_CHECK_POLLS:
            return []
        self.checked = True
        messages = []
        for role, pairs in self._pairs.items():
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
            messages.append(
                f"tags.{role} {tag.address} reads {tag_value:.4g} {unit}, the ring "
                f"{ring_value:.4g} {unit}: check the tag's raw/eng scaling or the ring's fields"
            )
        return messages
