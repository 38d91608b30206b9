"""Figures (matplotlib) of the plant, simulations, identification and tuning.

Computation never lives here: every function takes results computed elsewhere and draws them.
Figures are built with :class:`matplotlib.figure.Figure` directly (no pyplot state, no GUI
backend), so they work on a headless machine. matplotlib is imported inside the functions, so a
command that draws nothing never loads it (docs/architecture.md, "Rules"). Temperatures arrive in
kelvin and are shown in °C.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import DataError
from fuelid.units import kelvin_to_celsius

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from fuelid.io.timeseries import TimeSeries
    from fuelid.tuning.closedloop import ClosedLoopResult
    from fuelid.tuning.schedule import GainSchedule
    from fuelid.workflow.tune import TuneOutcome

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
    ax_u.step(log.time, log["u_V"], where="post", color="tab:blue", label="VFD command u [V]")
    ax_u.set_ylabel("command u [V]")
    ax_u.legend(loc="upper right", fontsize=8)
    ax_q.plot(log.time, log["q_Lpm"], lw=0.6, color="tab:orange", label="measured q [L/min]")
    if "q_true_Lpm" in log.signals:
        ax_q.plot(
            log.time, log["q_true_Lpm"], lw=1.2, color="k", label="noise-free reading [L/min]"
        )
    ax_q.legend(loc="best", fontsize=8)
    ax_q.set_ylabel("flow q [L/min]")
    if has_temperature:
        ax_t = axes[2]
        temperature = log[FUEL_TEMPERATURE_COLUMN]
        ax_t.plot(log.time, temperature, color="tab:red", label="fuel temperature [°C]")
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


def plot_bode(
    omega: FloatArray,
    loop: NDArray[np.complex128],
    gain_margin: float,
    phase_margin_deg: float,
    Ms: float,
    crossover: float,
    phase_crossover: float,
    title: str = "",
) -> Figure:
    """Bode plot of the loop L = C·G with the margins marked, and the sensitivity |S|."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 7), layout="constrained")
    ax_mag, ax_phase = fig.subplots(2, 1, sharex=True)
    mag_db = 20.0 * np.log10(np.abs(loop))
    sens_db = -20.0 * np.log10(np.abs(1.0 + loop))
    ax_mag.semilogx(omega, mag_db, color="tab:blue", label="|L| loop [dB]")
    ax_mag.semilogx(
        omega,
        sens_db,
        color="tab:red",
        ls="--",
        label=f"|S| [dB] (Ms = {Ms:.2f}, {20 * np.log10(Ms):.1f} dB)",
    )
    ax_mag.axhline(0.0, color="k", lw=0.6)
    ax_mag.set_ylabel("magnitude [dB]")
    phase = np.degrees(np.unwrap(np.angle(loop)))
    ax_phase.semilogx(omega, phase, color="tab:blue", label="phase of L [°]")
    ax_phase.axhline(-180.0, color="k", lw=0.6)
    ax_phase.set_ylabel("phase of L [°]")
    ax_phase.set_xlabel("angular frequency [rad/s]")
    if np.isfinite(crossover):
        ax_mag.axvline(
            crossover, color="tab:green", ls=":", lw=1, label=f"crossover {crossover:.3g} rad/s"
        )
        ax_phase.axvline(crossover, color="tab:green", ls=":", lw=1)
        # the phase margin: the distance from -180° up to the phase at crossover, on the ° axis
        ax_phase.annotate(
            "",
            xy=(crossover, -180.0 + phase_margin_deg),
            xytext=(crossover, -180.0),
            arrowprops={"arrowstyle": "<->", "color": "tab:green", "lw": 1.5},
        )
        ax_phase.annotate(
            f"PM = {phase_margin_deg:.1f}°",
            (crossover, -180.0 + phase_margin_deg / 2),
            textcoords="offset points",
            xytext=(6, 0),
            va="center",
            fontsize=9,
            color="tab:green",
            bbox={"fc": "white", "ec": "none", "alpha": 0.8},
        )
    gm_db = 20.0 * np.log10(gain_margin) if gain_margin > 0 else np.nan
    if np.isfinite(phase_crossover) and np.isfinite(gm_db):
        ax_mag.axvline(
            phase_crossover,
            color="tab:purple",
            ls=":",
            lw=1,
            label=f"phase crossover {phase_crossover:.3g} rad/s",
        )
        ax_phase.axvline(phase_crossover, color="tab:purple", ls=":", lw=1)
        # the gain margin in dB: the distance from |L| at the phase crossover up to 0 dB
        ax_mag.annotate(
            "",
            xy=(phase_crossover, 0.0),
            xytext=(phase_crossover, -gm_db),
            arrowprops={"arrowstyle": "<->", "color": "tab:purple", "lw": 1.5},
        )
        ax_mag.annotate(
            f"GM = {gm_db:.1f} dB (×{gain_margin:.2f})",
            (phase_crossover, -gm_db / 2),
            textcoords="offset points",
            xytext=(6, 0),
            va="center",
            fontsize=9,
            color="tab:purple",
            bbox={"fc": "white", "ec": "none", "alpha": 0.8},
        )
    bottom = max(float(np.min(phase)), -720.0)
    ax_phase.set_ylim(bottom, 0.0)
    low = max(float(np.min(mag_db)), -60.0)
    if np.isfinite(gm_db):
        low = min(low, -gm_db - 5.0)
    ax_mag.set_ylim(low, max(float(np.max(mag_db)), 10.0) + 5.0)
    for ax in (ax_mag, ax_phase):
        ax.grid(True, which="both", alpha=0.3)
    ax_mag.legend(loc="lower left", fontsize=8)
    if title:
        ax_mag.set_title(title)
    return fig


def plot_linear_closed_loop(
    t: FloatArray,
    setpoint_response: FloatArray,
    command: FloatArray,
    disturbance_response: FloatArray,
    title: str = "",
) -> Figure:
    """Unit setpoint step (output and command) and unit load step of the linear closed loop.

    The signals are deviations from the operating point per unit step, so the drive's absolute
    1–5 V limits do not apply; the command axis always shows its zero baseline.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 7), layout="constrained")
    ax_y, ax_u, ax_d = fig.subplots(3, 1, sharex=True)
    ax_y.plot(t, setpoint_response, color="tab:blue", label="flow [(L/min)/(L/min)]")
    ax_y.axhline(1.0, color="k", lw=0.6, ls="--", label="setpoint (unit step at t = 0)")
    ax_y.axhspan(0.98, 1.02, color="tab:green", alpha=0.12, label="2 % band")
    ax_y.set_ylabel("flow per unit\nsetpoint step\n[(L/min)/(L/min)]")
    ax_y.legend(loc="lower right", fontsize=8)
    ax_u.step(t, command, where="post", color="tab:orange", label="command change [V/(L/min)]")
    ax_u.axhline(0.0, color="k", lw=0.6)
    _include(ax_u, 0.0)  # the change starts from zero: show the baseline
    ax_u.set_ylabel("command per unit\nsetpoint step\n[V/(L/min)]")
    ax_u.legend(loc="upper right", fontsize=8)
    ax_d.plot(t, disturbance_response, color="tab:red", label="flow change [(L/min)/V]")
    ax_d.axhline(0.0, color="k", lw=0.6)
    ax_d.axvline(0.0, color="tab:brown", ls="-.", lw=1, label="unit load step at t = 0")
    ax_d.set_ylabel("flow per volt\nof load step\n[(L/min)/V]")
    ax_d.legend(loc="upper right", fontsize=8)
    ax_d.set_xlabel("time after the step [s]")
    for ax in (ax_y, ax_u, ax_d):
        ax.grid(True, alpha=0.3)
    if title:
        ax_y.set_title(title)
    return fig


def plot_closed_loop_runs(
    runs: Sequence[tuple[str, FloatArray, FloatArray, FloatArray, FloatArray]],
    title: str = "",
    limits: tuple[float, float] | None = DRIVE_LIMITS,
    load_steps: Sequence[float] = (),
) -> Figure:
    """Closed-loop runs on the plant: flow against setpoint, and the command with its limits.

    Parameters
    ----------
    runs : sequence of (label, time, setpoint, flow, command)
        Each run's signals [s, L/min, L/min, V].
    limits : (low, high), optional
        The drive's command range [V], drawn as horizontal lines on the command axis.
    load_steps : sequence of float
        Times of load steps [s], marked on both axes.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 6), layout="constrained")
    ax_q, ax_u = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    colors = ("tab:blue", "tab:red", "tab:green", "tab:purple")
    for i, (label, t, r, q, u) in enumerate(runs):
        color = colors[i % len(colors)]
        # the runs share the setpoint: one neutral line, not one per run hidden under the last
        ax_q.step(
            t, r, where="post", color="0.25", lw=0.8, ls="--", label="setpoint" if i == 0 else None
        )
        ax_q.plot(t, q, color=color, lw=1.0, label=label)
        ax_u.step(t, u, where="post", color=color, lw=1.0, label=label)
    if limits is not None:
        for i, level in enumerate(limits):
            ax_u.axhline(
                level,
                color="k",
                ls="--",
                lw=0.9,
                label=f"drive limits {limits[0]:g}–{limits[1]:g} V" if i == 0 else None,
            )
        _include(ax_u, *limits)
    for i, t_load in enumerate(dict.fromkeys(load_steps)):
        for ax in (ax_q, ax_u):
            ax.axvline(
                t_load,
                color="tab:brown",
                ls="-.",
                lw=1,
                label=f"load step at {t_load:g} s" if i == 0 and ax is ax_q else None,
            )
    ax_q.set_ylabel("flow [L/min]")
    ax_u.set_ylabel("command [V]")
    ax_u.set_xlabel("time [s]")
    for ax in (ax_q, ax_u):
        ax.grid(True, alpha=0.3)
    ax_q.legend(loc="best", fontsize=8, title="flow [L/min]")
    ax_u.legend(loc="best", fontsize=8, title="command [V]")
    if title:
        ax_q.set_title(title)
    return fig


def plot_schedule(
    bands: Sequence[tuple[float, float, str, float, float]], title: str = ""
) -> Figure:
    """Gain schedule: Kc and Ti per fuel-temperature band, one line per flow band.

    Parameters
    ----------
    bands : sequence of (t_low, t_high, flow_label, Kc, Ti)
        One entry per band [°C, °C, -, V/(L/min), s].
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 5), layout="constrained")
    ax_k, ax_i = fig.subplots(2, 1, sharex=True)
    labels = list(dict.fromkeys(b[2] for b in bands))
    for label in labels:
        rows = [b for b in bands if b[2] == label]
        t = [x for b in rows for x in (b[0], b[1])]
        ax_k.plot(t, [b[3] for b in rows for _ in (0, 1)], label=label)
        ax_i.plot(t, [b[4] for b in rows for _ in (0, 1)], label=label)
    ax_k.set_ylabel("Kc [V/(L/min)]")
    ax_i.set_ylabel("Ti [s]")
    ax_i.set_xlabel("fuel temperature [°C]")
    for ax in (ax_k, ax_i):
        ax.grid(True, alpha=0.3)
        _sensible_range(ax)
    ax_k.legend(loc="best", fontsize=8, title="command band")
    ax_i.legend(loc="best", fontsize=8, title="command band")
    if title:
        ax_k.set_title(title)
    return fig


def _sensible_range(ax: Axes, margin: float = 0.10) -> None:
    """Y limits at least ±``margin`` around the data's middle, so a small change looks small.

    Positive data whose range then reaches below zero start at zero instead.
    """
    values = np.concatenate([np.asarray(line.get_ydata(), dtype=float) for line in ax.lines])
    values = values[np.isfinite(values)]
    if values.size == 0:
        return
    lo, hi = float(values.min()), float(values.max())
    mid = 0.5 * (lo + hi)
    half = max(0.5 * (hi - lo) * 1.15, margin * abs(mid), 1e-12)
    bottom, top = mid - half, mid + half
    if lo >= 0.0 and bottom < 0.0:
        bottom, top = 0.0, max(top, hi * 1.05)
    ax.set_ylim(bottom, top)


def schedule_figure(schedule: GainSchedule) -> Figure:
    """Kc and Ti per fuel-temperature band [°C], one line per flow band."""
    return plot_schedule(
        [
            (
                kelvin_to_celsius(b.T_low),
                kelvin_to_celsius(b.T_high),
                f"{b.u_low:.2f}…{b.u_high:.2f} V",
                b.pi.Kc,
                b.pi.Ti,
            )
            for b in schedule.bands
        ],
        f"gain schedule ({schedule.rule}, Ms ≤ {schedule.ms_target:g})",
    )


def _load_step_time(run: ClosedLoopResult) -> float | None:
    """When the run's load disturbance first changes [s], or None without one."""
    d = np.asarray(run.disturbance, dtype=float)
    changed = np.flatnonzero(np.abs(d - d[0]) > 0.0) if d.size else np.array([], dtype=int)
    return float(run.time[changed[0]]) if changed.size else None


def runs_figure(
    runs: Sequence[ClosedLoopResult],
    title: str = "",
    label: str = "{} °C",
    limits: tuple[float, float] | None = DRIVE_LIMITS,
) -> Figure:
    """Closed-loop runs on the nonlinear plant, each labelled by its fuel temperature [°C].

    ``label`` is formatted with the temperature, e.g. ``"fuel at {} °C"``. The title names the
    temperatures shown; the drive limits and the load-step time are marked.
    """
    drawn = []
    temperatures = []
    for r in runs:
        temperature = f"{kelvin_to_celsius(r.T_fuel):g}"
        temperatures.append(temperature)
        drawn.append((label.format(temperature), r.time, r.setpoint, r.flow, r.command))
    loads = [t for t in (_load_step_time(r) for r in runs) if t is not None]
    if temperatures:
        shown = f"fuel at {', '.join(temperatures)} °C"
        title = f"{title}\n({shown})" if title else shown
    return plot_closed_loop_runs(drawn, title, limits=limits, load_steps=loads)


def tune_figure(outcome: TuneOutcome) -> Figure:
    """The closed-loop figure of ``fuelid tune --plot``.

    The nonlinear runs when there are any, else the unit responses of the linear closed loop on
    the model with the gains and Ms in the title.
    """
    pi = outcome.tuning.pi
    if outcome.runs:
        return runs_figure(
            outcome.runs,
            f"{pi.rule} PI (Kc = {pi.Kc:.4g} V/(L/min), Ti = {pi.Ti:.3g} s) on the nonlinear plant",
        )
    cl = outcome.tuning.closed_loop
    m = outcome.tuning.model
    return plot_linear_closed_loop(
        cl.time,
        cl.setpoint_response,
        cl.setpoint_command,
        cl.disturbance_response,
        f"{pi.rule}: Kc = {pi.Kc:.4g} V/(L/min), Ti = {pi.Ti:.3g} s, "
        f"Ms = {outcome.tuning.robustness.Ms:.2f}\non the linear model "
        f"({m.describe()}) at u = {outcome.u:.3g} V",
    )


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
        :func:`fuelid.online.report.history_json`'s object (``windows``, ``proposals``,
        ``writes``, ``gains_units``).
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
    # windows are on the samples' clock, proposals and writes on the service's wall clock: an
    # accelerated (virtual) PLC runs ahead of it, so wall times are mapped onto the data clock
    # through the windows' (analysed at, end) pairs; for a real PLC the two clocks agree
    pairs = sorted((float(w["time"]), float(w["end"])) for w in windows if w.get("time"))
    wall = np.array([a for a, _ in pairs])
    data = np.array([b for _, b in pairs])

    def on_data_clock(t: Any) -> float:
        x = float(t)
        if wall.size < 2 or not np.all(np.diff(wall) > 0.0):
            return x if wall.size == 0 else x + float(data[-1] - wall[-1])
        if x <= wall[0] or x >= wall[-1]:  # outside: the nearest window's clock offset
            i = 0 if x <= wall[0] else -1
            return x + float(data[i] - wall[i])
        return float(np.interp(x, wall, data))

    times = [float(w["end"]) for w in windows] + [on_data_clock(p["time"]) for p in proposals]
    t0 = min(times) if times else 0.0

    def hours(t: Any) -> float:
        return (float(t) - t0) / 3600.0

    def wall_hours(t: Any) -> float:
        return hours(on_data_clock(t))

    start = datetime.fromtimestamp(t0, tz=UTC).strftime("%Y-%m-%d %H:%M UTC")
    time_label = f"time since {start} [h]" if times else "time [h]"
    units = history.get("gains_units")
    kc_unit, ti_unit = ("controller units", "controller units")
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
    reverts = [w for w in writes if w.get("kind") == "revert" and w.get("status") == "verified"]
    for i, w in enumerate(reverts):
        ax_g.plot(wall_hours(w.get("finished") or w["time"]), float(w["Kc"]), "v",
                  color="tab:red", ms=8, label="revert written" if i == 0 else None)  # fmt: skip
    ax_g.set_xlabel(time_label)
    ax_g.set_ylabel(f"Kc [{kc_unit}] (o)")
    ax_ti.set_ylabel(f"Ti [{ti_unit}] (□, dashed)")
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
