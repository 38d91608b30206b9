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


def plot_identification(
    t: FloatArray,
    y: FloatArray,
    curves: Sequence[tuple[str, FloatArray]],
    split_time: float | None = None,
    title: str = "",
    ylabel: str = "flow q [L/min]",
) -> Figure:
    """Measured output against model outputs (the article's comparison figure) and residuals.

    Parameters
    ----------
    t, y : arrays
        Sample times [s] and measured output.
    curves : sequence of (label, array)
        Model outputs (free-run simulations) on the same samples.
    split_time : float, optional
        Where held-out validation data begin [s] (shaded).
    """
    fig = Figure(figsize=(9, 6))
    ax, ax_res = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    ax.plot(t, y, lw=0.6, color="0.55", label="measured")
    for label, y_hat in curves:
        ax.plot(t, y_hat, lw=1.3, label=label)
        ax_res.plot(t, y - y_hat, lw=0.6, label=label)
    for axis in (ax, ax_res):
        axis.grid(True, alpha=0.3)
        if split_time is not None:
            axis.axvspan(split_time, float(t[-1]), color="tab:olive", alpha=0.08)
    if split_time is not None:
        ax.text(split_time, ax.get_ylim()[1], " validation", va="top", fontsize=8)
    ax.set_ylabel(ylabel)
    ax.legend(loc="best")
    ax_res.set_ylabel("residual")
    ax_res.set_xlabel("time [s]")
    if title:
        ax.set_title(title)
    return fig
