"""The figure of the online service's history (``fuelid online history --plot``).

Presentation only (:mod:`fuelid.plots`): it draws :func:`fuelid.online.history_json`'s
object: the identified gain over time and against fuel temperature, the PI gains and proposals.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from fuelid.plots._common import save_figure

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

PROPOSAL_COLOURS = {
    "pending": "tab:orange",
    "approved": "tab:blue",
    "writing": "tab:cyan",
    "applied": "tab:green",
    "failed": "black",
    "rejected": "tab:red",
    "superseded": "tab:gray",
    "reverted": "tab:purple",
}
"""Marker colour of a proposal by its status (``fuelid online history --plot``)."""


def _interval(row: dict[str, Any], key: str = "K") -> tuple[float, float, float] | None:
    """(value, lower error, upper error) of a window's parameter from its model and ci95."""
    model = row.get("model")
    if not isinstance(model, dict) or model.get(key) is None:
        return None
    value = float(model[key])
    ci = row.get("ci95")
    bounds = ci.get(key) if isinstance(ci, dict) else None
    if isinstance(bounds, list | tuple) and len(bounds) == 2 and None not in bounds:
        return value, value - float(bounds[0]), float(bounds[1]) - value
    return value, 0.0, 0.0


def plot_online_history(history: dict[str, Any], path: str | Path) -> Path:
    """The online service's history in one figure: K over time, K(T), the gains and proposals.

    Parameters
    ----------
    history : dict
        :func:`fuelid.online.history_json`'s object (``windows``, ``proposals`` with
        their ``target``, ``writes``, ``gain_units``), every time in plant time.
    path : str or Path
        Where to save (the suffix picks the format).

    Returns
    -------
    Path
        The file written.

    Three panels: the identified K of the accepted windows over time with their 95 % intervals
    (rejected windows marked on the time axis); K against the windows' fuel temperature [°C];
    the gains Kc and Ti over time (the verified writes as steps from the first proposal's old
    gains) with every proposal marked at its proposed gains, coloured by its status.
    """
    from matplotlib.figure import Figure

    windows = [w for w in history.get("windows", []) or [] if isinstance(w, dict)]
    proposals = [p for p in history.get("proposals", []) or [] if isinstance(p, dict)]
    writes = [w for w in history.get("writes", []) or [] if isinstance(w, dict)]
    # every time is plant time (the samples' time base, schema 3): windows, proposals and
    # writes share one axis even when a virtual PLC runs its clock faster than the wall's
    clock = _Clock.of([float(w["end"]) for w in windows] + [float(p["time"]) for p in proposals])

    fig = Figure(figsize=(10, 11), layout="constrained")
    ax_t, ax_T, ax_g = fig.subplots(3, 1)
    accepted = [(w, iv) for w in windows if w.get("accepted") for iv in [_interval(w)] if iv]
    _draw_gain_over_time(ax_t, clock, accepted, windows)
    _draw_gain_against_temperature(fig, ax_T, clock, accepted)
    ax_ti = _draw_gains_and_proposals(ax_g, clock, proposals, writes, history)
    for ax in (ax_t, ax_T, ax_g):
        ax.grid(True, alpha=0.3)
        handles, labels = ax.get_legend_handles_labels()
        if ax is ax_g:  # the integral times on the twin axis share the gains' legend
            more, more_labels = ax_ti.get_legend_handles_labels()
            handles, labels = handles + more, labels + more_labels
        if handles:
            ax.legend(handles, labels, loc="best", fontsize=8)
        else:
            ax.text(0.5, 0.5, "nothing to show yet", ha="center", va="center",
                    transform=ax.transAxes, color="gray")  # fmt: skip
    fig.suptitle("fuelid online: models, K(T) and gains")
    return save_figure(fig, path)


_Window = tuple[dict[str, Any], tuple[float, float, float]]
"""An accepted window with its K's (value, lower error, upper error) (:func:`_interval`)."""


@dataclass(frozen=True)
class _Clock:
    """The figure's time axis: hours since the first window or proposal (plant time)."""

    t0: float
    """Plant time of the axis's origin [s]."""
    label: str
    """The axis label, with the origin as a UTC date."""
    times: tuple[float, ...] = ()
    """Every window's end and proposal's time [s]: the gain line runs to the last of them."""

    @classmethod
    def of(cls, times: list[float]) -> _Clock:
        """The axis of these plant times [s] (the origin at 0 when there are none)."""
        from datetime import UTC, datetime

        t0 = min(times) if times else 0.0
        start = datetime.fromtimestamp(t0, tz=UTC).strftime("%Y-%m-%d %H:%M UTC")
        return cls(t0, f"time since {start} [h]" if times else "time [h]", tuple(times))

    def hours(self, t: Any) -> float:
        """Plant time ``t`` [s] on the axis [h]."""
        return (float(t) - self.t0) / 3600.0


def _draw_gain_over_time(
    ax: Axes, clock: _Clock, accepted: list[_Window], windows: list[dict[str, Any]]
) -> None:
    """The accepted windows' K with 95 % intervals over time; rejected ones marked below."""
    hours = clock.hours
    rejected = [w for w in windows if not w.get("accepted")]
    if accepted:
        x = [hours(w["end"]) for w, _ in accepted]
        k = [iv[0] for _, iv in accepted]
        err = np.array([[iv[1] for _, iv in accepted], [iv[2] for _, iv in accepted]])
        ax.errorbar(x, k, yerr=err, fmt="o", ms=3, capsize=2, label="accepted window (95 %)")
        # K depends on the operating point: the plant model's K at each window's mean command
        # and temperature shows how much of the scatter is the operating point, not noise
        with_plant = [(hours(w["end"]), w.get("plant_K")) for w, _ in accepted]
        with_plant = [(t, kp) for t, kp in with_plant if isinstance(kp, int | float)]
        if with_plant:
            ax.plot(*zip(*with_plant, strict=True), "_", ms=10, color="0.3",
                    label="plant model's K at the window's u and T")  # fmt: skip
    if rejected:
        ax.plot(
            [hours(w["end"]) for w in rejected],
            [0.02] * len(rejected),
            "x",
            color="tab:red",
            transform=ax.get_xaxis_transform(),
            label="rejected window",
        )
    ax.set_xlabel(clock.label)
    ax.set_ylabel("K [(L/min)/V]")
    ax.set_title(
        f"identified gain of the accepted windows ({len(accepted)} of {len(windows)} windows)"
    )


def _draw_gain_against_temperature(
    fig: Figure, ax: Axes, clock: _Clock, accepted: list[_Window]
) -> None:
    """K (or K over the plant model's K) against the windows' fuel temperature, coloured by time."""
    with_T = [(w, iv) for w, iv in accepted if w.get("fuel_temperature") is not None]
    # with a plant model, K / K_plant: the operating point's share of K divided out, what is left
    # is what the model does not know (pump wear, a wrong viscosity curve) against temperature
    ratio = bool(with_T) and all(isinstance(w.get("plant_K"), int | float) for w, _ in with_T)
    if with_T:
        T = [float(w["fuel_temperature"]) for w, _ in with_T]
        scale = [float(w["plant_K"]) if ratio else 1.0 for w, _ in with_T]
        k = [iv[0] / d for (_, iv), d in zip(with_T, scale, strict=True)]
        err = np.array([[iv[1] / d for (_, iv), d in zip(with_T, scale, strict=True)],
                        [iv[2] / d for (_, iv), d in zip(with_T, scale, strict=True)]])  # fmt: skip
        ax.errorbar(T, k, yerr=err, fmt="none", ecolor="0.4", capsize=3, zorder=2,
                    label="95 % interval")  # fmt: skip
        when = [clock.hours(w["end"]) for w, _ in with_T]
        dots = ax.scatter(T, k, c=when, s=14, cmap="viridis", zorder=3,
                          label="accepted window (colour: time)")  # fmt: skip
        if ratio:
            ax.axhline(1.0, color="0.3", lw=1.0, ls="--", label="the plant model (ratio 1)")
        fig.colorbar(dots, ax=ax, label="time since the first window [h]", fraction=0.04,
                     pad=0.01)  # fmt: skip
    ax.set_xlabel("fuel temperature [°C]")
    if ratio:
        ax.set_ylabel("K / K_plant [-]")
        ax.set_title(
            "identified gain over the plant model's at each window's command and temperature"
        )
    else:
        ax.set_ylabel("K [(L/min)/V]")
        ax.set_title("identified gain against the window's mean fuel temperature")


def _draw_gains_and_proposals(
    ax: Axes,
    clock: _Clock,
    proposals: list[dict[str, Any]],
    writes: list[dict[str, Any]],
    history: dict[str, Any],
) -> Axes:
    """Kc (and Ti on a twin axis, returned) in the PLC over time, every proposal and revert."""
    units = history.get("gain_units") or history.get("gains_units")
    kc_unit, ti_unit = ("the PLC block's units", "the PLC block's units")
    if isinstance(units, dict):
        kc_unit, ti_unit = str(units.get("Kc", kc_unit)), str(units.get("Ti", ti_unit))
    ax_ti = ax.twinx()
    steps = [w for w in writes if w.get("status") == "verified"]
    _draw_gains_in_the_plc(ax, ax_ti, clock, proposals, steps)
    _draw_proposals(ax, ax_ti, clock, proposals)
    reverts = [w for w in steps if w.get("kind") == "revert"]
    for i, w in enumerate(reverts):
        ax.plot(clock.hours(w.get("finished") or w["time"]), float(w["Kc"]), "v",
                color="tab:red", ms=8, label="revert written" if i == 0 else None)  # fmt: skip
    ax.set_xlabel(clock.label)
    ax.set_ylabel(f"Kc [{kc_unit}] (o; ☆ target)")
    ax_ti.set_ylabel(f"Ti [{ti_unit}] (□, dashed; ☆ target)")
    ax.set_title(f"PI gains and proposals ({len(proposals)} proposals, {len(steps)} writes)")
    return ax_ti


def _draw_gains_in_the_plc(
    ax: Axes,
    ax_ti: Axes,
    clock: _Clock,
    proposals: list[dict[str, Any]],
    steps: list[dict[str, Any]],
) -> None:
    """The verified writes as steps, from the first proposal's old gains to the last time."""
    if not (proposals or steps):
        return
    first = proposals[0]["old"] if proposals and isinstance(proposals[0].get("old"), dict) else None
    t_line: list[float] = []
    kc_line: list[float] = []
    ti_line: list[float] = []
    if first is not None and first.get("Kc") is not None:
        t_line.append(clock.hours(proposals[0]["time"]))
        kc_line.append(float(first["Kc"]))
        ti_line.append(float(first["Ti"]))
    for w in steps:
        t_line.append(clock.hours(w.get("finished") or w["time"]))
        kc_line.append(float(w["Kc"]))
        ti_line.append(float(w["Ti"]))
    if t_line:
        t_end = max([*t_line, *(clock.hours(t) for t in clock.times)])
        ax.step([*t_line, t_end], [*kc_line, kc_line[-1]], where="post", color="tab:blue",
                label="Kc in the PLC")  # fmt: skip
        ax_ti.step([*t_line, t_end], [*ti_line, ti_line[-1]], where="post",
                   color="tab:brown", ls="--", label="Ti in the PLC")  # fmt: skip


def _draw_proposals(ax: Axes, ax_ti: Axes, clock: _Clock, proposals: list[dict[str, Any]]) -> None:
    """Each proposal at its proposed gains, coloured by status, with the rule's target (☆)."""
    shown: set[str] = set()
    for p in proposals:
        new = p.get("new")
        if not isinstance(new, dict) or new.get("Kc") is None:
            continue
        at = clock.hours(p["time"])
        status = str(p.get("status"))
        colour = PROPOSAL_COLOURS.get(status, "tab:olive")
        label = f"proposal: {status}" if status not in shown else None
        shown.add(status)
        ax.plot(at, float(new["Kc"]), "o", color=colour, label=label)
        ax_ti.plot(at, float(new["Ti"]), "s", color=colour, mfc="none")
        target = p.get("target")
        if isinstance(target, dict) and target.get("Kc") is not None:
            # the gains the rule moves toward, beside the step it proposes
            first_target = "target" not in shown
            shown.add("target")
            ax.plot(at, float(target["Kc"]), "*", color=colour, ms=9, mfc="none",
                    label="target of the rule" if first_target else None)  # fmt: skip
            if target.get("Ti") is not None:
                ax_ti.plot(at, float(target["Ti"]), "*", color=colour, ms=9, mfc="none")
