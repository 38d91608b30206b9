"""The figure of the online service's history (``fuelid online history --plot``).

Presentation only (:mod:`fuelid.plots`): it draws :func:`fuelid.online.report.history_json`'s
object: the identified gain over time and against fuel temperature, the PI gains and proposals.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from fuelid.plots._common import save_figure

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
        :func:`fuelid.online.report.history_json`'s object (``windows``, ``proposals`` with
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
    from datetime import UTC, datetime

    from matplotlib.figure import Figure

    windows = [w for w in history.get("windows", []) or [] if isinstance(w, dict)]
    proposals = [p for p in history.get("proposals", []) or [] if isinstance(p, dict)]
    writes = [w for w in history.get("writes", []) or [] if isinstance(w, dict)]

    # every time is plant time (the samples' time base, schema 3): windows, proposals and
    # writes share one axis even when a virtual PLC runs its clock faster than the wall's
    def on_data_clock(t: Any) -> float:
        return float(t)

    times = [float(w["end"]) for w in windows] + [on_data_clock(p["time"]) for p in proposals]
    t0 = min(times) if times else 0.0

    def hours(t: Any) -> float:
        return (float(t) - t0) / 3600.0

    def wall_hours(t: Any) -> float:
        return hours(on_data_clock(t))

    start = datetime.fromtimestamp(t0, tz=UTC).strftime("%Y-%m-%d %H:%M UTC")
    time_label = f"time since {start} [h]" if times else "time [h]"
    units = history.get("gain_units") or history.get("gains_units")
    kc_unit, ti_unit = ("the PLC block's units", "the PLC block's units")
    if isinstance(units, dict):
        kc_unit, ti_unit = str(units.get("Kc", kc_unit)), str(units.get("Ti", ti_unit))

    fig = Figure(figsize=(10, 11), layout="constrained")
    ax_t, ax_T, ax_g = fig.subplots(3, 1)

    accepted = [(w, iv) for w in windows if w.get("accepted") for iv in [_interval(w)] if iv]
    rejected = [w for w in windows if not w.get("accepted")]
    if accepted:
        x = [hours(w["end"]) for w, _ in accepted]
        k = [iv[0] for _, iv in accepted]
        err = np.array([[iv[1] for _, iv in accepted], [iv[2] for _, iv in accepted]])
        ax_t.errorbar(x, k, yerr=err, fmt="o", ms=3, capsize=2, label="accepted window (95 %)")
        # K depends on the operating point: the plant model's K at each window's mean command
        # and temperature shows how much of the scatter is the operating point, not noise
        with_plant = [(hours(w["end"]), w.get("plant_K")) for w, _ in accepted]
        with_plant = [(t, kp) for t, kp in with_plant if isinstance(kp, int | float)]
        if with_plant:
            ax_t.plot(*zip(*with_plant, strict=True), "_", ms=10, color="0.3",
                      label="plant model's K at the window's u and T")  # fmt: skip
    if rejected:
        ax_t.plot(
            [hours(w["end"]) for w in rejected],
            [0.02] * len(rejected),
            "x",
            color="tab:red",
            transform=ax_t.get_xaxis_transform(),
            label="rejected window",
        )
    ax_t.set_xlabel(time_label)
    ax_t.set_ylabel("K [(L/min)/V]")
    ax_t.set_title(
        f"identified gain of the accepted windows ({len(accepted)} of {len(windows)} windows)"
    )

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
        ax_T.errorbar(T, k, yerr=err, fmt="none", ecolor="0.4", capsize=3, zorder=2,
                      label="95 % interval")  # fmt: skip
        dots = ax_T.scatter(T, k, c=[hours(w["end"]) for w, _ in with_T], s=14, cmap="viridis",
                            zorder=3, label="accepted window (colour: time)")  # fmt: skip
        if ratio:
            ax_T.axhline(1.0, color="0.3", lw=1.0, ls="--", label="the plant model (ratio 1)")
        fig.colorbar(dots, ax=ax_T, label="time since the first window [h]", fraction=0.04,
                     pad=0.01)  # fmt: skip
    ax_T.set_xlabel("fuel temperature [°C]")
    if ratio:
        ax_T.set_ylabel("K / K_plant [-]")
        ax_T.set_title(
            "identified gain over the plant model's at each window's command and temperature"
        )
    else:
        ax_T.set_ylabel("K [(L/min)/V]")
        ax_T.set_title("identified gain against the window's mean fuel temperature")

    ax_ti = ax_g.twinx()
    steps = [w for w in writes if w.get("status") == "verified"]
    if proposals or steps:
        first = (
            proposals[0]["old"] if proposals and isinstance(proposals[0].get("old"), dict) else None
        )
        t_line: list[float] = []
        kc_line: list[float] = []
        ti_line: list[float] = []
        if first is not None and first.get("Kc") is not None:
            t_line.append(wall_hours(proposals[0]["time"]))
            kc_line.append(float(first["Kc"]))
            ti_line.append(float(first["Ti"]))
        for w in steps:
            t_line.append(wall_hours(w.get("finished") or w["time"]))
            kc_line.append(float(w["Kc"]))
            ti_line.append(float(w["Ti"]))
        if t_line:
            t_end = max([*t_line, *(hours(t) for t in times)])
            ax_g.step([*t_line, t_end], [*kc_line, kc_line[-1]], where="post", color="tab:blue",
                      label="Kc in the PLC")  # fmt: skip
            ax_ti.step([*t_line, t_end], [*ti_line, ti_line[-1]], where="post",
                       color="tab:brown", ls="--", label="Ti in the PLC")  # fmt: skip
    shown: set[str] = set()
    for p in proposals:
        new = p.get("new")
        if not isinstance(new, dict) or new.get("Kc") is None:
            continue
        status = str(p.get("status"))
        colour = PROPOSAL_COLOURS.get(status, "tab:olive")
        label = f"proposal: {status}" if status not in shown else None
        shown.add(status)
        ax_g.plot(wall_hours(p["time"]), float(new["Kc"]), "o", color=colour, label=label)
        ax_ti.plot(wall_hours(p["time"]), float(new["Ti"]), "s", color=colour, mfc="none")
        target = p.get("target")
        if isinstance(target, dict) and target.get("Kc") is not None:
            # the gains the rule moves toward, beside the step it proposes
            first_target = "target" not in shown
            shown.add("target")
            ax_g.plot(wall_hours(p["time"]), float(target["Kc"]), "*", color=colour, ms=9,
                      mfc="none", label="target of the rule" if first_target else None)  # fmt: skip
            if target.get("Ti") is not None:
                ax_ti.plot(wall_hours(p["time"]), float(target["Ti"]), "*", color=colour, ms=9,
                           mfc="none")  # fmt: skip
    reverts = [w for w in writes if w.get("kind") == "revert" and w.get("status") == "verified"]
    for i, w in enumerate(reverts):
        ax_g.plot(wall_hours(w.get("finished") or w["time"]), float(w["Kc"]), "v",
                  color="tab:red", ms=8, label="revert written" if i == 0 else None)  # fmt: skip
    ax_g.set_xlabel(time_label)
    ax_g.set_ylabel(f"Kc [{kc_unit}] (o; ☆ target)")
    ax_ti.set_ylabel(f"Ti [{ti_unit}] (□, dashed; ☆ target)")
    ax_g.set_title(f"PI gains and proposals ({len(proposals)} proposals, {len(steps)} writes)")

    for ax in (ax_t, ax_T, ax_g):
        ax.grid(True, alpha=0.3)
        handles, labels = ax.get_legend_handles_labels()
        if ax is ax_g:
            more, more_labels = ax_ti.get_legend_handles_labels()
            handles, labels = handles + more, labels + more_labels
        if handles:
            ax.legend(handles, labels, loc="best", fontsize=8)
        else:
            ax.text(0.5, 0.5, "nothing to show yet", ha="center", va="center",
                    transform=ax.transAxes, color="gray")  # fmt: skip
    fig.suptitle("fuelid online: models, K(T) and gains")
    return save_figure(fig, path)
