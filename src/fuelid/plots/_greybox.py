"""Figures of a gray-box fit (``fuelid greybox --plot``): measured against simulated, residuals.

Presentation only, like the rest of :mod:`fuelid.plots`: the function takes what the fit computed
and draws it on a :class:`matplotlib.figure.Figure` (no pyplot state, no GUI backend); matplotlib is
imported inside the functions. Units are the user's: the axes carry the output names as given.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from fuelid.errors import DataError
from fuelid.plots._common import (
    FloatArray,
    _band_text,
    _reserve_label_band,
    _unit_of,
    _with_unit,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure


@dataclass(frozen=True)
class FitPanel:
    """One record's column of the figure.

    Attributes
    ----------
    title : str
        E.g. ``"estimation: run1.csv"``.
    t : ndarray, shape (N,)
        Sample times [s].
    y : ndarray, shape (N, n_y)
        Measured outputs (NaN: missing).
    y_hat : ndarray, shape (N, n_y)
        Simulated outputs.
    fit_percent : sequence of float
        NRMSE fit per output [%].
    initial_span_end : float, optional
        End of the stretch the initial state was fitted to [s] (shaded), for a validation record.
    heldout_start : float, optional
        Start of the end stretch left out of the fit and predicted [s] (shaded).
    heldout_fit_percent : sequence of float, optional
        NRMSE fit per output on that stretch [%].
    input_u : ndarray, shape (N, n_u), optional
        The inputs, drawn in a thin row under the first output's residuals.
    input_names : sequence of str
        Their labels.
    """

    title: str
    t: FloatArray
    y: FloatArray
    y_hat: FloatArray
    fit_percent: Sequence[float]
    initial_span_end: float | None = None
    heldout_start: float | None = None
    heldout_fit_percent: Sequence[float] | None = None
    input_u: FloatArray | None = None
    input_names: Sequence[str] = ()


def plot_greybox_fit(
    panels: Sequence[FitPanel], output_names: Sequence[str], title: str = ""
) -> Figure:
    """Measured (dark grey) and simulated (orange, on top) outputs per record, residuals below.

    One column per record (estimation records first, then the validation record), two rows per
    output: the signals (with the fit % in the title) and the residual y − ŷ; a last, thin row
    with the inputs when the panels carry them. Shaded: the stretch a validation record's initial
    state was fitted to, and the held-out end a fit did not see.
    """
    from matplotlib.figure import Figure

    n_cols, n_y = len(panels), len(output_names)
    if n_cols == 0:
        raise DataError("nothing to plot: no record")
    with_inputs = all(panel.input_u is not None for panel in panels)
    rows = 2 * n_y + (1 if with_inputs else 0)
    ratios = [2.2, 1.0] * n_y + ([1.0] if with_inputs else [])
    height = 0.6 + 3.4 * n_y + (1.1 if with_inputs else 0.0)
    fig = Figure(figsize=(max(7.0, 5.2 * n_cols), height), layout="constrained")
    grid = fig.add_gridspec(rows, n_cols, height_ratios=ratios)
    for col, panel in enumerate(panels):
        axes: list[Any] = []
        for k, name in enumerate(output_names):
            ax = fig.add_subplot(grid[2 * k, col], sharex=axes[0] if axes else None)
            ax_res = fig.add_subplot(grid[2 * k + 1, col], sharex=ax)
            axes += [ax, ax_res]
            y, y_hat = panel.y[:, k], panel.y_hat[:, k]
            ax.plot(panel.t, y, lw=0.8, color="0.35", label="measured")
            ax.plot(panel.t, y_hat, lw=1.1, color="tab:orange", alpha=0.9, label="simulated")
            ax_res.plot(panel.t, y - y_hat, lw=0.6, color="tab:red")
            ax_res.axhline(0.0, color="k", lw=0.6)
            if col == 0 and k == 0:
                ax_res.text(
                    0.01, 0.95, "residual = measured − simulated", transform=ax_res.transAxes,
                    va="top", fontsize=7, zorder=5,
                    bbox={"facecolor": "white", "alpha": 0.85, "edgecolor": "none", "pad": 1.0},
                )  # fmt: skip
            _shade(panel, (ax, ax_res), label=k == 0)
            heading = _heading(panel, k)
            ax.set_title(heading if n_y == 1 else f"{heading} ({name})", fontsize=10)
            ax.set_ylabel(name)
            # short: the name is on the panel above (a long label ran into the next one's)
            ax_res.set_ylabel("residual" if n_y == 1 else f"residual {name}")
            if col == 0 and k == 0:
                # in the label band, clear of the curves, beside the spans' names
                corner: Literal["upper center", "upper left"] = (
                    "upper center" if panel.initial_span_end is not None else "upper left"
                )
                ax.legend(loc=corner, fontsize=8, ncols=2)
        if with_inputs and panel.input_u is not None:
            ax_u = fig.add_subplot(grid[rows - 1, col], sharex=axes[0])
            for j in range(panel.input_u.shape[1]):
                label = panel.input_names[j] if j < len(panel.input_names) else f"u{j + 1}"
                ax_u.step(panel.t, panel.input_u[:, j], where="post", lw=0.8, label=label)
            ax_u.set_ylabel(_input_label(panel.input_names))
            ax_u.legend(loc="best", fontsize=7)
            _shade(panel, (ax_u,), label=False)
            axes.append(ax_u)
        for axis in axes[:-1]:
            axis.tick_params(labelbottom=False)
        axes[-1].set_xlabel("time [s]")
    if title:
        fig.suptitle(title)
    fig.align_ylabels()
    return fig


def _heading(panel: FitPanel, k: int) -> str:
    fit = panel.fit_percent[k]
    heading = f"{panel.title}: fit {fit:.1f} %" if np.isfinite(fit) else panel.title
    if panel.heldout_fit_percent is not None and np.isfinite(panel.heldout_fit_percent[k]):
        heading += f", held-out {panel.heldout_fit_percent[k]:.1f} %"
    return heading


def _shade(panel: FitPanel, axes: Sequence[Any], label: bool) -> None:
    """Shade the validation record's initial-state stretch and the held-out end."""
    for axis in axes:
        axis.grid(True, alpha=0.3)
        if panel.initial_span_end is not None:
            axis.axvspan(float(panel.t[0]), panel.initial_span_end, color="tab:olive", alpha=0.12)
        if panel.heldout_start is not None:
            axis.axvspan(panel.heldout_start, float(panel.t[-1]), color="tab:purple", alpha=0.08)
    if not label:
        return
    # the top of the signal axes is kept free of data: the spans' names cannot cover a curve
    _reserve_label_band(axes[0])
    if panel.initial_span_end is not None:
        _band_text(axes[0], float(panel.t[0]), " initial state fitted here")
    if panel.heldout_start is not None:
        _band_text(axes[0], float(panel.t[-1]), "held out: predicted ", ha="right")


def _input_label(names: Sequence[str]) -> str:
    """The input axis' label with its unit.

    The one input's name as the log gives it ("command [V]", "u_V"), "input [V]" when the inputs
    share a unit, else "inputs" (the legend names each with its own unit; a longer label, such
    as a name with "[unit not given]", ran past its short panel into the one above).
    """
    if len(names) == 1:
        return names[0]
    units = {_unit_of(name) for name in names}
    unit = units.pop() if len(units) == 1 else None
    return _with_unit("input", unit) if unit is not None else "inputs"
