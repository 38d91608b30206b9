"""The accepted windows a proposal rests on: separate evidence, and their weighted mean model.

Overlapping windows that contain the same excitation event are one piece of evidence
(:func:`independent_windows`); the target model is the inverse-variance weighted mean of the
windows kept (:func:`weighted_mean_model`).
"""

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from fuelid.errors import FuelidError
from fuelid.model import ProcessModel

EVENT_TOLERANCE_S = 1e-6
"""Two excitation events within this time of each other are the same event [s]."""


@dataclass(frozen=True)
class WindowModel:
    """One accepted identification window, as the service keeps it.

    Attributes
    ----------
    model_id : int
        The store's id of the identified model.
    t_from, t_to : float
        Start and end of the window [s since the epoch, UTC].
    model : ProcessModel
        The identified model (K [(L/min)/V], times [s]).
    stderr : Mapping
        Standard errors of the model's parameters by name (``"K"`` [(L/min)/V], ``"T"`` [s], …);
        None where not determined.
    T_fuel_C : float or None
        Mean fuel temperature over the window [°C].
    u_mean : float
        Mean command over the window [V].
    events : tuple of float
        Times of the excitation events (command steps, setpoint moves) the window contains [s]
        (:attr:`fuelid.online.gates.WindowVerdict.excitation_events`).
    """

    model_id: int
    t_from: float
    t_to: float
    model: ProcessModel
    stderr: Mapping[str, float | None]
    T_fuel_C: float | None
    u_mean: float
    events: tuple[float, ...]

    @property
    def se_K(self) -> float | None:
        """The standard error of K if usable (finite, > 0) [(L/min)/V], else None."""
        se = self.stderr.get("K")
        if se is None or not (math.isfinite(se) and se > 0.0):
            return None
        return float(se)


def _shares_event(events: Sequence[float], taken: Sequence[float]) -> bool:
    return any(abs(a - b) <= EVENT_TOLERANCE_S for a in events for b in taken)


def independent_windows(windows: Sequence[WindowModel], n: int) -> list[WindowModel]:
    """Up to ``n`` windows that rest on separate excitation events, newest first.

    Windows are taken by end time, newest first; a window counts only if it has at least one
    event and none of its events (within :data:`EVENT_TOLERANCE_S`) is an event of a window
    already counted: overlapping windows around one step are one piece of evidence.

    Parameters
    ----------
    windows : sequence of WindowModel
        Accepted windows, in any order.
    n : int
        How many are wanted [-].

    Returns
    -------
    list of WindowModel
        At most ``n``, newest first.

    Examples
    --------
    >>> m = ProcessModel(K=13.0, T=1.0, delay=0.5)
    >>> def w(i, t, ev):
    ...     return WindowModel(i, t - 600.0, t, m, {"K": 0.1}, 20.0, 3.0, ev)
    >>> ws = [w(1, 600.0, (100.0,)), w(2, 900.0, (100.0, 700.0)), w(3, 1500.0, (1200.0,))]
    >>> [x.model_id for x in independent_windows(ws, 3)]
    [3, 2]
    """
    ordered = sorted(windows, key=lambda w: (w.t_to, w.model_id), reverse=True)
    counted: list[WindowModel] = []
    taken: list[float] = []
    for window in ordered:
        if len(counted) >= n:
            break
        if not window.events or _shares_event(window.events, taken):
            continue
        counted.append(window)
        taken.extend(window.events)
    return counted


def weighted_mean_model(windows: Sequence[WindowModel]) -> tuple[ProcessModel, list[float]]:
    """Inverse-variance weighted mean of the windows' models.

    Every parameter (K, T, T2, T_f, delay) is averaged with the weights w = 1/se(K)²,
    normalised to sum 1; when any window lacks a usable se(K), all weigh alike.

    Returns
    -------
    tuple
        (mean model, normalised weights in the windows' order).

    Examples
    --------
    >>> a = WindowModel(1, 0.0, 600.0, ProcessModel(K=12.0, T=1.0), {"K": 0.1}, None, 3.0, (1.0,))
    >>> b = WindowModel(2, 0.0, 600.0, ProcessModel(K=13.0, T=1.0), {"K": 0.2}, None, 3.0, (2.0,))
    >>> model, w = weighted_mean_model([a, b])
    >>> round(model.K, 12), [round(x, 12) for x in w]
    (12.2, [0.8, 0.2])
    """
    if not windows:
        raise FuelidError("a mean model needs at least one window")
    ses = [w.se_K for w in windows]
    raw = [1.0 / se**2 for se in ses if se is not None]
    weights = raw if len(raw) == len(windows) else [1.0] * len(windows)
    total = sum(weights)
    weights = [x / total for x in weights]
    params = {
        name: sum(wt * getattr(w.model, name) for wt, w in zip(weights, windows, strict=True))
        for name in ("K", "T", "T2", "T_f", "delay")
    }
    return ProcessModel(**params), weights


__all__ = ["EVENT_TOLERANCE_S", "WindowModel", "independent_windows", "weighted_mean_model"]
