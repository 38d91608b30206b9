"""What the online service's parts share: the site, the store and its history, the log, the stats.

The scheduler (:mod:`fuelid.online._scheduler`) and the write-back
(:mod:`fuelid.online._writeback`) each hold one :class:`ServiceContext`; the service
(:mod:`fuelid.online._service`) builds it and sets the recorder once the run starts.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from fuelid.errors import FuelidError
from fuelid.model import ProcessModel
from fuelid.online._gains import Gains
from fuelid.online._logs import LOGGER_NAME, log_event, log_line
from fuelid.online._settings import Online, ServiceSite
from fuelid.online._tracking import GainObservation
from fuelid.online._window import WindowPriors
from fuelid.plc import Recorder, RecorderStats
from fuelid.store import OnlineHistory, SampleWriter, SQLiteStore
from fuelid.tuning import BlockForm

_LOGGER = logging.getLogger(LOGGER_NAME)

TRACKER_OBSERVATIONS = 2000
"""Accepted windows kept by the K(T) tracker (a week at 5-minute windows): bounded memory."""
PLC = "plc"
"""The ``rule`` of the gains read from the PLC's block (:meth:`ServiceContext.current_gains`)."""
COMMISSIONING = "commissioning"
"""The ``rule`` of the ``[controller]`` kc and ti (the commissioning gains)."""
STALE_NEXT = "new windows will propose afresh"
"""What follows a proposal too old to write (:func:`stale_reason`), said of a running service."""
STALE_NEXT_STOPPED = STALE_NEXT + " when the service runs again"
"""The same while no service runs (:func:`stale_while_stopped`): a stopped one proposes nothing."""
RECENT_WINDOWS_SPAN = 6.0
"""Windows for a proposal end within this many window lengths (or agree_windows × the
schedule, if longer) of the newest: a model from before an outage of days does not vote."""


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


@dataclass
class ServiceContext:
    """The state the scheduler and the write-back share (one per service run).

    Parameters
    ----------
    site : ServiceSite
        The site file.
    store : SQLiteStore
        The site's store.
    history : OnlineHistory
        The online history in the same SQLite file.
    priors : WindowPriors
        The window analysis' priors (the command's limits among them).
    commissioning : Gains or None
        The ``[controller]`` kc and ti in the ideal form; None when not given.
    on_message : callable, optional
        Gets each structured log line.
    """

    site: ServiceSite
    store: SQLiteStore
    history: OnlineHistory
    priors: WindowPriors
    commissioning: Gains | None
    on_message: Callable[[str], None] | None = None
    stats: ServiceStats = field(default_factory=ServiceStats)
    recorder: Recorder | None = None
    writer: SampleWriter | None = None

    @property
    def settings(self) -> Online:
        """The site's ``[online]`` table."""
        return self.site.online

    @property
    def latest(self) -> dict[str, float]:
        """The recorder's newest reading of every tag (empty before the run)."""
        return self.recorder.latest if self.recorder is not None else {}

    def say(self, word: str, **fields: Any) -> None:
        """Log one event to the ``fuelid.online`` logger, and its key=value line to on_message."""
        log_event(_LOGGER, word, **fields)
        if self.on_message is not None:
            self.on_message(log_line(word, **fields))

    def event(self, kind: str, detail: str, t: float | None = None) -> None:
        """Record an event in the store and log it."""
        if self.writer is not None:
            self.writer.event(kind, detail, t)
        self.say("event", kind=kind, detail=detail)

    def current_gains(self) -> Gains | None:
        """The PI's gains now (ideal form, engineering units).

        The PLC's when its kc and ti are read, else the last verified write, else the
        commissioning gains.
        """
        c = self.site.controller
        latest = self.latest
        if c is not None and latest.get("kc", 0.0) > 0.0 and latest.get("ti", 0.0) > 0.0:
            return Gains.from_block(
                latest["kc"],
                latest["ti"],
                BlockForm.of(c),
                rule=PLC,
                control_period=self.site.sampling.control_period_s,
            )
        applied = self.history.state("current_gains")
        if applied is not None:
            return Gains(
                float(applied["Kc"]),
                float(applied["Ti"]),
                control_period=self.site.sampling.control_period_s,
            )
        return self.commissioning


def model_of(value: Any) -> ProcessModel | None:
    """A ProcessModel from a stored dict (``{"model": {...}}`` or the model keys themselves).

    Examples
    --------
    >>> model_of({"model": {"K": 2.0, "T": 0.5}}).T
    0.5
    >>> model_of({"K": 2.0}) is None
    True
    """
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


def stale_reason(window_end: float | None, newest: float | None, window_s: float) -> str | None:
    """Why a proposal is too old to write (its newest window long before the newest sample).

    Its evidence predates the recent windows (e.g. across a restart and a change of fuel
    temperature): new windows will propose afresh. The service supersedes such an approved
    proposal instead of writing it; an approval of one is refused with the same reason.

    Parameters
    ----------
    window_end : float or None
        Plant time at which the proposal's newest window ended [s]; None when unknown.
    newest : float or None
        Plant time of the newest sample [s]; None without samples.
    window_s : float
        The service's window length [s] (``[online] window_s``).

    Examples
    --------
    >>> stale_reason(1000.0, 1000.0 + 6 * 600.0 + 1.0, 600.0)[:45]
    'stale: its newest window ended 3601 s of data'
    >>> stale_reason(1000.0, 1600.0, 600.0) is None
    True
    """
    if window_end is None or newest is None:
        return None
    span = RECENT_WINDOWS_SPAN * window_s
    if float(window_end) < newest - span:
        return (
            f"stale: its newest window ended {newest - float(window_end):.0f} s of data "
            f"before the newest sample (> {span:.0f} s); {STALE_NEXT}"
        )
    return None


def stale_while_stopped(reason: str | None) -> str | None:
    """A :func:`stale_reason` as said while no service runs: new windows wait for it.

    The reason itself (how old the proposal's evidence is) holds whether a service runs or
    not; only its promise depends on one.

    >>> stale_while_stopped("stale: …; new windows will propose afresh")
    'stale: …; new windows will propose afresh when the service runs again'
    >>> once = stale_while_stopped("…; new windows will propose afresh")
    >>> stale_while_stopped(once) == once
    True
    >>> stale_while_stopped(None) is None
    True
    """
    if reason is None or STALE_NEXT_STOPPED in reason:
        return reason
    return reason.replace(STALE_NEXT, STALE_NEXT_STOPPED)


__all__ = [
    "RECENT_WINDOWS_SPAN",
    "TRACKER_OBSERVATIONS",
    "ServiceContext",
    "ServiceStats",
    "model_of",
    "observation_of",
    "stale_reason",
    "stale_while_stopped",
]
