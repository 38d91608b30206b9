"""The gates' verdict on one identification window: accepted or not, every reason, the events."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from fuelid.io.jsonsafe import json_ready


@dataclass(frozen=True)
class WindowVerdict:
    """The gates' verdict on one identification window.

    Attributes
    ----------
    accepted : bool
        True when no gate failed (events do not count against a window).
    reasons : tuple of str
        One line per failed gate, in the order the gates run; empty when accepted.
    measured : dict
        What each gate measured, keyed with the unit in the name (``bad_share``,
        ``limit_share``, ``command_step_threshold_V``, ``rel_stderr_K``, ``residual_acf_max``,
        …); None where a gate could not measure.
    excitation_events : tuple of float
        Times of the excitation events [s]: setpoint moves when judged in AUTO, command steps
        in MAN. Two windows rest on separate evidence only when their events differ.
    events : tuple of str
        Flags that do not reject the window but must be seen (the identified K far from the
        plant model's: pump wear).
    mode : str
        "AUTO", "MAN" or "unknown": the mode the window was judged in ("" for post-fit only).
    """

    accepted: bool
    reasons: tuple[str, ...] = ()
    measured: Mapping[str, Any] = field(default_factory=dict)
    excitation_events: tuple[float, ...] = ()
    events: tuple[str, ...] = ()
    mode: str = ""

    @classmethod
    def of(
        cls,
        reasons: Sequence[str],
        measured: Mapping[str, Any],
        *,
        excitation_events: Sequence[float] = (),
        events: Sequence[str] = (),
        mode: str = "",
    ) -> WindowVerdict:
        """A verdict accepted exactly when ``reasons`` is empty."""
        return cls(
            accepted=not reasons,
            reasons=tuple(reasons),
            measured=dict(measured),
            excitation_events=tuple(float(x) for x in excitation_events),
            events=tuple(events),
            mode=mode,
        )

    @property
    def reason(self) -> str:
        """All reasons in one line, or "passed every gate" (the history's ``reason``)."""
        return "; ".join(self.reasons) if self.reasons else "passed every gate"

    def combine(self, other: WindowVerdict) -> WindowVerdict:
        """Both verdicts in one: accepted only if both are; reasons, numbers and events joined.

        Examples
        --------
        >>> a = WindowVerdict.of([], {"bad_share": 0.0}, excitation_events=[12.0], mode="MAN")
        >>> b = WindowVerdict.of(["poor validation fit: 61.0 % < 80 %"], {"fit_percent": 61.0})
        >>> c = a.combine(b)
        >>> c.accepted, c.mode, c.excitation_events, sorted(c.measured)
        (False, 'MAN', (12.0,), ['bad_share', 'fit_percent'])
        """
        return WindowVerdict.of(
            [*self.reasons, *other.reasons],
            {**self.measured, **other.measured},
            excitation_events=sorted({*self.excitation_events, *other.excitation_events}),
            events=[*self.events, *other.events],
            mode=self.mode or other.mode,
        )

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dictionary (non-finite numbers as None).

        Examples
        --------
        >>> WindowVerdict.of([], {"rel_stderr_K": float("nan")}).to_json()["measured"]
        {'rel_stderr_K': None}
        """
        out: dict[str, Any] = json_ready(
            {
                "accepted": self.accepted,
                "reason": self.reason,
                "reasons": list(self.reasons),
                "mode": self.mode,
                "measured": dict(self.measured),
                "excitation_events_s": list(self.excitation_events),
                "events": list(self.events),
            }
        )
        return out


__all__ = ["WindowVerdict"]
