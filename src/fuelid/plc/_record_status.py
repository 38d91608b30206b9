"""What the recorder has done so far: counts, the live sample rate and the one-line status."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

__all__ = ["RATE_WINDOW_S", "STATUS_WIDTH", "RecorderStats"]

RATE_WINDOW_S = 5.0
"""Window of the live sample rate [s]."""
STATUS_WIDTH = 80
"""Longest live status line [characters]: one line of an 80-column terminal."""


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
