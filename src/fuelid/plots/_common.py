"""What the figures share: units on their axes, the drive's command range, saving a figure.

Every figure of :mod:`fuelid.plots` labels an axis ``quantity [unit]`` (:data:`NO_UNIT` in the
brackets when a log does not state it) and is saved by :func:`save_figure`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import DataError

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

FloatArray = NDArray[np.float64]

DRIVE_LIMITS = (1.0, 5.0)
"""The drive's command range [V] (the reference plant's ``u_min_V``/``u_max_V``), drawn as lines
on the command axis of closed-loop figures."""
NO_UNIT = "unit not given"
"""Shown in brackets on an axis whose unit the log does not state."""


def _unit_of(label: str) -> str | None:
    """The unit in a label's trailing brackets, ``"flow q [L/min]"`` → ``"L/min"``."""
    label = label.strip()
    if label.endswith("]") and "[" in label:
        return label[label.rindex("[") + 1 : -1]
    return None


def _with_unit(label: str, unit: str | None) -> str:
    """``label [unit]``, unless the label already ends with a unit in brackets."""
    if _unit_of(label) is not None:
        return label
    return f"{label} [{unit or NO_UNIT}]"


def _include(ax: Axes, *values: float) -> None:
    """Widen an axis' y range so that it shows ``values`` with a margin (e.g. a zero baseline)."""
    lo, hi = ax.get_ylim()
    new_lo, new_hi = min(lo, *values), max(hi, *values)
    pad = 0.05 * (new_hi - new_lo) if new_hi > new_lo else 1.0
    ax.set_ylim(new_lo - pad if new_lo < lo else lo, new_hi + pad if new_hi > hi else hi)


def save_figure(fig: Figure, path: str | Path) -> Path:
    """Save a figure (format from the extension), refusing a missing folder clearly."""
    out = Path(path)
    if not out.parent.is_dir():
        raise DataError(f"figure folder {str(out.parent)!r} does not exist")
    fig.savefig(out, dpi=120, bbox_inches="tight")
    return out


LABEL_BAND = 0.14
"""Share of an axes' height kept free of data at its top for labels (a span's name, a legend)."""

LABEL_BOX = {"facecolor": "white", "alpha": 0.85, "edgecolor": "none", "pad": 1.5}
"""The background of a label drawn over a figure's shading and grid."""


def _reserve_label_band(ax: Axes) -> None:
    """Raise the y range's top so that the top :data:`LABEL_BAND` of ``ax`` holds no data.

    Call after the data are drawn (the range is the data's) and before labels go into the band:
    a label there, at an axes y of 1 − LABEL_BAND or more, cannot cover a curve.
    """
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo, hi + (hi - lo) * LABEL_BAND / (1.0 - LABEL_BAND))


def _band_text(ax: Axes, x: float, text: str, ha: str = "left") -> None:
    """``text`` at time ``x`` in the label band at the top of ``ax``, on a white box."""
    ax.text(
        x, 0.975, text, transform=ax.get_xaxis_transform(), ha=ha, va="top", fontsize=8,
        zorder=5, bbox=LABEL_BOX,
    )  # fmt: skip


MAX_LINE_POINTS = 100_000
"""A line of more samples than this is drawn from its extremes per pixel column
(:func:`pixel_extremes`); a shorter one is drawn as it is."""
PIXEL_COLUMNS = 2_000
"""Time bins of :func:`pixel_extremes`: more than the pixel columns of any figure's axes (the
widest, 9 in at 120 dpi, is 1,080 pixels), so each column holds at least one whole bin."""


def pixel_extremes(
    t: FloatArray, y: FloatArray, columns: int = PIXEL_COLUMNS
) -> tuple[FloatArray, FloatArray]:
    """The samples of ``(t, y)`` a line drawing shows at ``columns`` pixel columns: M4.

    In each of ``columns`` equal runs of samples the first, the last, the lowest and the
    highest are kept, in time order (Jugel et al., "M4: a visualization-oriented time series
    data aggregation", Proc. VLDB Endow. 7 (2014) 797–808): a line through them covers, in
    every pixel column, the same vertical span as the line through all samples, and enters
    and leaves it at the same heights, so the figure looks the same at its pixel width. A
    NaN (a gap: no line across it) is kept with its neighbours, so the line still breaks
    there. A series of at most :data:`MAX_LINE_POINTS` samples is returned as it is; a day at
    50 Hz (4.3 million samples, which matplotlib took 10 s and 0.4 GB per line to draw) keeps
    under 8,000.

    Examples
    --------
    >>> t = np.arange(200_000.0)
    >>> y = np.sin(t / 1000.0)
    >>> y[150_000] = np.nan
    >>> tr, yr = pixel_extremes(t, y)
    >>> tr.size < 9_000, float(np.nanmax(yr)) == float(np.nanmax(y)), int(np.isnan(yr).sum())
    (True, True, 1)
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    n = y.size
    if n <= MAX_LINE_POINTS:
        return t, y
    width = -(-n // columns)
    rows = -(-n // width)
    padded = np.full(rows * width, np.nan)
    padded[:n] = y
    blocks = padded.reshape(rows, width)
    missing = np.isnan(blocks)
    starts = np.arange(rows) * width
    lowest = starts + np.argmin(np.where(missing, np.inf, blocks), axis=1)
    highest = starts + np.argmax(np.where(missing, -np.inf, blocks), axis=1)
    gaps = np.flatnonzero(np.isnan(y))
    keep = np.unique(
        np.concatenate(
            [starts, np.minimum(starts + width, n) - 1, lowest, highest, gaps - 1, gaps, gaps + 1]
        )
    )
    keep = keep[(keep >= 0) & (keep < n)]
    return t[keep], y[keep]
