"""Figures of a gray-box fit (``fuelid greybox --plot``): measured against simulated, residuals.

Presentation only, like :mod:`fuelid.plots`: the function takes what the fit computed and draws
it on a :class:`matplotlib.figure.Figure` (no pyplot state, no GUI backend); matplotlib is
imported inside the functions. Units are the user's: the axes carry the output names as given.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import DataError

if TYPE_CHECKING:
    from matplotlib.figure import Figure

FloatArray = NDArray[np.float64]


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
    """

    title: str
    t: FloatArray
    y: FloatArray
    y_hat: FloatArray
    fit_percent: Sequence[float]
    initial_span_end: float | None = None


def plot_greybox_fit(
    panels: Sequence[FitPanel], output_names: Sequence[str], title: str = ""
) -> Figure:
    """Measured (grey) and simulated (blue) outputs per record, residuals below each.

    One column per record (estimation records first, then the validation record), two rows per
    output: the signals (with the fit % in the title) and the residual y − ŷ.
    """
    from matplotlib.figure import Figure

    n_cols, n_y = len(panels), len(output_names)
    if n_cols == 0:
        raise DataError("nothing to plot: no record")
    fig = Figure(figsize=(max(7.0, 5.2 * n_cols), 0.6 + 3.4 * n_y), layout="constrained")
    grid = fig.add_gridspec(2 * n_y, n_cols, height_ratios=[2.2, 1.0] * n_y)
    for col, panel in enumerate(panels):
        for k, name in enumerate(output_names):
            ax = fig.add_subplot(grid[2 * k, col])
            ax_res = fig.add_subplot(grid[2 * k + 1, col], sharex=ax)
            y, y_hat = panel.y[:, k], panel.y_hat[:, k]
            ax.plot(panel.t, y, lw=0.7, color="0.55", label="measured")
            ax.plot(panel.t, y_hat, lw=1.4, color="tab:blue", label="simulated")
            ax_res.plot(panel.t, y - y_hat, lw=0.6, color="tab:red")
            ax_res.axhline(0.0, color="k", lw=0.6)
            for axis in (ax, ax_res):
                axis.grid(True, alpha=0.3)
                if panel.initial_span_end is not None:
                    axis.axvspan(
                        float(panel.t[0]), panel.initial_span_end, color="tab:olive", alpha=0.12
                    )
            if panel.initial_span_end is not None and k == 0:
                ax.text(
                    float(panel.t[0]),
                    ax.get_ylim()[1],
                    " initial state fitted here",
                    va="top",
                    fontsize=8,
                )
            fit = panel.fit_percent[k]
            heading = f"{panel.title}: fit {fit:.1f} %" if np.isfinite(fit) else panel.title
            ax.set_title(heading if n_y == 1 else f"{heading} ({name})", fontsize=10)
            ax.tick_params(labelbottom=False)
            ax.set_ylabel(name)
            ax_res.set_ylabel(f"residual {name}")
            if k == n_y - 1:
                ax_res.set_xlabel("time [s]")
            if col == 0 and k == 0:
                ax.legend(loc="best", fontsize=8)
    if title:
        fig.suptitle(title)
    return fig


def save_greybox_figure(fig: Figure, path: str | Path) -> Path:
    """Save the figure (format from the extension), refusing a missing folder clearly."""
    out = Path(path)
    if not out.parent.is_dir():
        raise DataError(f"figure folder {str(out.parent)!r} does not exist")
    fig.savefig(out, dpi=120, bbox_inches="tight")
    return out
