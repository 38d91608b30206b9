"""Setpoint moves: the one detector of the setpoint's steps and ramps in a window.

A move begins with a change of the setpoint between successive samples; further changes join
it by a :class:`MergeRule`. Two callers, two rules:

- the excitation gate (:func:`fuelid.online.gates.setpoint_moves`) merges every change made
  within ``gap_s`` of the previous one (:meth:`MergeRule.ramp`): a slow disturbance must not
  merge two steps into one piece of evidence, so whether the flow settled is not asked;
- the setpoint responses of loop health (:func:`fuelid.online.health.setpoint_responses`)
  merge a change in the move's direction made within ``gap_s`` of the previous one *or before
  the flow settled* into the band around the setpoint of the moment
  (:meth:`MergeRule.ramp_or_unsettled`): the staircase of small changes a ramped setpoint
  becomes in the PLC is one move from its first value to its last, a reversal begins a new one
  (:attr:`MergeRule.same_direction` says exactly when).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

RAMP_GAP_S = 2.0
"""Setpoint changes at most this far apart form one ramped move [s]."""


@dataclass(frozen=True)
class MergeRule:
    """How close setpoint changes merge into one move.

    A change joins the current move when it comes within ``gap_s`` of the previous change, or
    (``until_settled``) while the flow has not settled in the band; with ``same_direction`` a
    change against the move's direction always begins a new move.
    """

    gap_s: float = RAMP_GAP_S
    """Changes at most this far apart are one move [s]."""
    same_direction: bool = False
    """A change may join only when the move's net change, counted from its start to the new
    setpoint, has the change's own direction: a reversal begins a new move unless it carries
    the setpoint back past the move's start (then the move is that net change)."""
    until_settled: bool = False
    """A change also joins while the flow has not settled into the band (needs the flow)."""

    @classmethod
    def ramp(cls, gap_s: float = RAMP_GAP_S) -> MergeRule:
        """Every change within ``gap_s`` [s] of the previous one joins (the gates' rule)."""
        return cls(gap_s=gap_s)

    @classmethod
    def ramp_or_unsettled(cls, gap_s: float = RAMP_GAP_S) -> MergeRule:
        """A same-direction change joins within ``gap_s`` [s] or before the flow settled."""
        return cls(gap_s=gap_s, same_direction=True, until_settled=True)


@dataclass(frozen=True)
class SetpointMove:
    """One move: sample indices into the arrays given to :func:`detect_moves`."""

    first: int
    """The first sample with a new setpoint (the move's first change)."""
    last: int
    """The move's last change (the first sample with the setpoint it ends at)."""
    end: int
    """One past the move's last sample: the next move's first change, or the arrays' length."""
    start: float
    """Setpoint before the move [L/min]."""
    target: float
    """Setpoint after the move's last change [L/min]."""

    @property
    def size(self) -> float:
        """Net change, target − start [L/min]."""
        return self.target - self.start


def detect_moves(
    t: ArrayLike,
    setpoint: ArrayLike,
    rule: MergeRule,
    *,
    y: ArrayLike | None = None,
    band: float | None = None,
    band_fraction: float = 0.05,
    min_band: float = 0.0,
) -> list[SetpointMove]:
    """The setpoint's moves in order, by ``rule``, whatever their size.

    Parameters
    ----------
    t : array
        Sample times [s].
    setpoint : array
        Setpoint [L/min].
    rule : MergeRule
        How close changes merge into one move.
    y : array, optional
        Flow [L/min]; needed by ``rule.until_settled``.
    band : float, optional
        Settling band's half width [L/min]; default ``band_fraction`` of the move so far.
    band_fraction : float
        Settling band as a share of the move so far [-].
    min_band : float
        Narrowest settling band's half width [L/min].

    Returns
    -------
    list of SetpointMove

    Raises
    ------
    ValueError
        ``rule.until_settled`` without ``y``.

    Examples
    --------
    A ramp of two changes 1 s apart, then a step back 10 s later:

    >>> t = np.arange(0.0, 30.0, 1.0)
    >>> sp = np.where(t < 5, 40.0, np.where(t < 6, 42.0, np.where(t < 16, 45.0, 40.0)))
    >>> [(m.first, m.start, m.target) for m in detect_moves(t, sp, MergeRule.ramp())]
    [(5, 40.0, 45.0), (16, 45.0, 40.0)]
    """
    tt = np.asarray(t, dtype=float)
    sp = np.asarray(setpoint, dtype=float)
    if rule.until_settled and y is None:
        raise ValueError("a merge rule until the flow settles needs the flow y")
    yy = None if y is None else np.asarray(y, dtype=float)
    n = tt.size
    resolution = 1e-9 * max(1.0, float(np.max(np.abs(sp), initial=0.0)))
    changes = (np.flatnonzero(np.abs(np.diff(sp)) > resolution) + 1).tolist()
    nexts = [*changes[1:], n] if changes else []
    bounds: list[tuple[int, int, int]] = []  # (first change, last change, end)
    settled, previous = True, 0
    for k, following in zip(changes, nexts, strict=True):
        joins = bool(bounds) and tt[k] - tt[previous] <= rule.gap_s
        if bounds and rule.until_settled and not settled:
            joins = True
        if joins and rule.same_direction:
            first = bounds[-1][0]
            joins = np.sign(sp[k] - sp[first - 1]) == np.sign(sp[k] - sp[k - 1])
        if joins:
            bounds[-1] = (bounds[-1][0], k, following)
        else:
            bounds.append((k, k, following))
        if yy is not None:
            first = bounds[-1][0]
            half = abs(band) if band is not None else band_fraction * abs(sp[k] - sp[first - 1])
            settled = bool(abs(yy[following - 1] - sp[k]) <= max(half, min_band))
        previous = k
    return [SetpointMove(a, k, b, float(sp[a - 1]), float(sp[k])) for a, k, b in bounds]


__all__ = ["RAMP_GAP_S", "MergeRule", "SetpointMove", "detect_moves"]
