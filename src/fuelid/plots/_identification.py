"""Figures of logs and identification: a PLC log, step responses, the model against the data.

Presentation only (:mod:`fuelid.plots`): each function draws what :mod:`fuelid.identify` or a
simulation computed.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from fuelid.plots._common import NO_UNIT, FloatArray, _unit_of, _with_unit, pixel_extremes

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from fuelid.io.timeseries import TimeSeries


def plot_log(log: TimeSeries, title: str = "") -> Figure:
    """Command and measured flow of a PLC log on stacked axes sharing time.

    The fuel temperature gets a third axis when the log has the ``T_fuel_degC`` column.
    """
    from matplotlib.figure import Figure

    from fuelid.io.timeseries import FUEL_TEMPERATURE_COLUMN

    has_temperature = FUEL_TEMPERATURE_COLUMN in log.signals
    fig = Figure(figsize=(9, 7.5 if has_temperature else 5.5), layout="constrained")
    axes = fig.subplots(3 if has_temperature else 2, 1, sharex=True)
    ax_u, ax_q = axes[0], axes[1]
    # a long log's lines from their extremes per pixel column: the same figure at its width
    # (pixel_extremes), drawn in a fraction of a second instead of tens
    ax_u.step(
        *pixel_extremes(log.time, log["u_V"]),
        where="post",
        color="tab:blue",
        label="VFD command u [V]",
    )
    ax_u.set_ylabel("command u [V]")
    ax_u.legend(loc="upper right", fontsize=8)
    ax_q.plot(
        *pixel_extremes(log.time, log["q_Lpm"]),
        lw=0.6,
        color="tab:orange",
        label="measured q [L/min]",
    )
    if "q_true_Lpm" in log.signals:
        ax_q.plot(
            *pixel_extremes(log.time, log["q_true_Lpm"]),
            lw=1.2,
            color="k",
            label="noise-free reading [L/min]",
        )
    ax_q.legend(loc="best", fontsize=8)
    ax_q.set_ylabel("flow q [L/min]")
    if has_temperature:
        ax_t = axes[2]
        temperature = log[FUEL_TEMPERATURE_COLUMN]
        ax_t.plot(
            *pixel_extremes(log.time, temperature),
            color="tab:red",
            label="fuel temperature [°C]",
        )
        ax_t.set_ylabel("fuel temperature [°C]")
        # NaN marks a gap in the log (no line across it)
        low, high = float(np.nanmin(temperature)), float(np.nanmax(temperature))
        mid = 0.5 * (low + high)
        half = max((high - low) * 0.6, 2.0)  # a constant reading is not a line
        ax_t.set_ylim(mid - half, mid + half)
        ax_t.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time [s]")
    for ax in axes:
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
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 4.5), layout="constrained")
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


def broken_at_gaps(t: FloatArray, *series: FloatArray) -> list[FloatArray]:
    """``t`` and each series with a NaN sample half-way across every gap: no line drawn over it.

    A gap is a step in ``t`` of more than 1.5 typical (median) sample periods; the segments
    of a record with gaps are simulated each from its own state, and a line joining them
    would draw a transient that is not there.

    Examples
    --------
    >>> t, y = broken_at_gaps(np.array([0.0, 1.0, 5.0, 6.0]), np.array([1.0, 1.0, 3.0, 3.0]))
    >>> t.tolist(), y.tolist()
    ([0.0, 1.0, 3.0, 5.0, 6.0], [1.0, 1.0, nan, 3.0, 3.0])
    """
    t = np.asarray(t, dtype=float)
    arrays = [np.asarray(v, dtype=float) for v in series]
    if t.size < 3:
        return [t, *arrays]
    steps = np.diff(t)
    starts = np.flatnonzero(steps > 1.5 * float(np.median(steps))) + 1
    if not starts.size:
        return [t, *arrays]
    middles = 0.5 * (t[starts - 1] + t[starts])
    return [np.insert(t, starts, middles), *(np.insert(v, starts, np.nan) for v in arrays)]


def plot_identification(
    t: FloatArray,
    y: FloatArray,
    curves: Sequence[tuple[str, FloatArray]],
    split_time: float | None = None,
    title: str = "",
    ylabel: str = "flow q [L/min]",
    unit: str | None = None,
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
    ylabel, unit : str
        The output's name and unit; the unit is appended in brackets unless ``ylabel`` already
        ends with one (``[unit not given]`` when neither states it), and labels the residuals.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 6), layout="constrained")
    ax, ax_res = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    t, y, *model_outputs = broken_at_gaps(t, y, *(y_hat for _, y_hat in curves))
    curves = [(label, y_hat) for (label, _), y_hat in zip(curves, model_outputs, strict=True)]
    # a long record's lines from their extremes per pixel column: the same figure at its
    # width (pixel_extremes), drawn in a fraction of a second instead of tens
    ax.plot(*pixel_extremes(t, y), lw=0.6, color="0.55", label="measured")
    for label, y_hat in curves:
        ax.plot(*pixel_extremes(t, y_hat), lw=1.3, label=label)
        ax_res.plot(*pixel_extremes(t, y - y_hat), lw=0.6, label=label)
    for axis in (ax, ax_res):
        axis.grid(True, alpha=0.3)
        if split_time is not None:
            # named in the legend, which is placed clear of the curves (a text on the span sat
            # on the data line)
            span_label = "validation (held out)" if axis is ax else None
            axis.axvspan(split_time, float(t[-1]), color="tab:olive", alpha=0.08, label=span_label)
    unit = unit or _unit_of(ylabel)
    ax.set_ylabel(_with_unit(ylabel, unit))
    ax.legend(loc="best", fontsize=8)
    ax_res.axhline(0.0, color="k", lw=0.6)
    ax_res.set_ylabel(f"residual y − ŷ [{unit or NO_UNIT}]")
    ax_res.set_xlabel("time [s]")
    if title:
        ax.set_title(title)
    return fig


def plot_correlation_tests(
    tests: Sequence[tuple[str, FloatArray, FloatArray, float]],
    sample_time: float | None = None,
) -> Figure:
    """Residual correlation tests as stem plots with their 95 % bounds.

    Parameters
    ----------
    tests : sequence of (title, lags, values, bound)
        One panel each, e.g. the residual autocorrelation and the input-residual correlation;
        lags in samples.
    sample_time : float, optional
        Sampling interval [s]: when given the lags are drawn in seconds (lag × sample time).
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 3.2 * len(tests)), layout="constrained")
    axes = fig.subplots(len(tests), 1, squeeze=False)[:, 0]
    scale = sample_time if sample_time is not None and sample_time > 0 else 1.0
    for ax, (title, lags, values, bound) in zip(axes, tests, strict=True):
        x = np.asarray(lags, dtype=float) * scale
        ax.vlines(x, 0.0, values, color="tab:blue", lw=1.2)
        ax.plot(x, values, "o", ms=3, color="tab:blue", label="normalised correlation [-]")
        ax.axhspan(
            -bound, bound, color="tab:green", alpha=0.12, label=f"95 % bound ±{bound:.2g} (white)"
        )
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_title(title, fontsize=10)
        ax.set_ylabel("correlation [-]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
        if scale != 1.0:
            ax.set_xlabel(f"lag [s] (lag in samples × {scale:g} s)")
        else:
            ax.set_xlabel("lag [samples]")
    return fig
