"""Figures (matplotlib) for the plant, simulations and (later) identification and tuning.

Computation never lives here: every function takes results computed elsewhere and draws them.
Figures are built with :class:`matplotlib.figure.Figure` directly (no pyplot state, no GUI
backend), so they work on a headless machine.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from fuelid.errors import DataError
from fuelid.signals import TimeSeries

FloatArray = NDArray[np.float64]


def save_figure(fig: Figure, path: str | Path) -> Path:
    """Save a figure (format from the extension), refusing a missing folder clearly."""
    out = Path(path)
    if not out.parent.is_dir():
        raise DataError(f"figure folder {str(out.parent)!r} does not exist")
    fig.savefig(out, dpi=120, bbox_inches="tight")
    return out


def plot_log(log: TimeSeries, title: str = "") -> Figure:
    """Command and measured flow of a PLC log, on two stacked axes sharing time."""
    fig = Figure(figsize=(9, 5.5))
    ax_u, ax_q = fig.subplots(2, 1, sharex=True)
    ax_u.step(log.time, log["u_V"], where="post", color="tab:blue")
    ax_u.set_ylabel("command u [V]")
    ax_q.plot(log.time, log["q_Lpm"], lw=0.6, color="tab:orange", label="measured q")
    if "q_true_Lpm" in log.signals:
        ax_q.plot(log.time, log["q_true_Lpm"], lw=1.2, color="k", label="noise-free reading")
        ax_q.legend(loc="best")
    ax_q.set_ylabel("flow q [L/min]")
    ax_q.set_xlabel("time [s]")
    for ax in (ax_u, ax_q):
        ax.grid(True, alpha=0.3)
    if title:
        fig.suptitle(title)
    return fig


def plot_step_responses(
    t: FloatArray,
    curves: Sequence[tuple[str, FloatArray]],
    settling_times: Sequence[float] = (),
    title: str = "",
    ylabel: str = "flow change per volt [(L/min)/V]",
) -> Figure:
    """Several step responses on one axis, with optional vertical marks at settling times."""
    fig = Figure(figsize=(8, 4.5))
    ax = fig.subplots()
    styles = ("-", "--", ":")
    colors = ("tab:blue", "tab:red", "tab:green", "tab:purple")
    group = len(styles) if len(curves) > len(styles) else 1
    for i, (label, y) in enumerate(curves):
        # curves come in groups (e.g. nonlinear, linear, reduced per temperature): one colour per
        # group, one line style per member, so curves that coincide stay distinguishable
        ax.plot(t, y, label=label, ls=styles[i % group], color=colors[(i // group) % len(colors)])
    for ts in settling_times:
        if np.isfinite(ts):
            ax.axvline(ts, color="grey", ls=":", lw=1)
    ax.set_xlabel("time after the step [s]")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right")
    if title:
        ax.set_title(title)
    return fig
