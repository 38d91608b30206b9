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
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import DataError
from fuelid.units import kelvin_to_celsius

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from fuelid.io.timeseries import TimeSeries
    from fuelid.tuning.closedloop import ClosedLoopResult
    from fuelid.tuning.schedule import GainSchedule
    from fuelid.workflow.tune import TuneOutcome

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
    from matplotlib.figure import Figure

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
    from matplotlib.figure import Figure

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
    from matplotlib.figure import Figure

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


def plot_correlation_tests(tests: Sequence[tuple[str, FloatArray, FloatArray, float]]) -> Figure:
    """Residual correlation tests as stem plots with their 95 % bounds.

    Parameters
    ----------
    tests : sequence of (title, lags, values, bound)
        One panel each, e.g. the residual autocorrelation and the input-residual correlation.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 3.2 * len(tests)))
    axes = fig.subplots(len(tests), 1, squeeze=False)[:, 0]
    for ax, (title, lags, values, bound) in zip(axes, tests, strict=True):
        ax.vlines(lags, 0.0, values, color="tab:blue", lw=1.2)
        ax.plot(lags, values, "o", ms=3, color="tab:blue")
        ax.axhspan(-bound, bound, color="tab:green", alpha=0.12, label="95 % bound (white)")
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_title(title, fontsize=10)
        ax.set_ylabel("correlation")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("lag [samples]")
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

    fig = Figure(figsize=(9, 7))
    ax_mag, ax_phase = fig.subplots(2, 1, sharex=True)
    mag_db = 20.0 * np.log10(np.abs(loop))
    sens_db = -20.0 * np.log10(np.abs(1.0 + loop))
    ax_mag.semilogx(omega, mag_db, color="tab:blue", label="|L| loop")
    ax_mag.semilogx(omega, sens_db, color="tab:red", ls="--", label=f"|S| (Ms = {Ms:.2f})")
    ax_mag.axhline(0.0, color="k", lw=0.6)
    ax_mag.set_ylabel("magnitude [dB]")
    phase = np.degrees(np.unwrap(np.angle(loop)))
    ax_phase.semilogx(omega, phase, color="tab:blue")
    ax_phase.axhline(-180.0, color="k", lw=0.6)
    ax_phase.set_ylabel("phase of L [°]")
    ax_phase.set_xlabel("angular frequency [rad/s]")
    if np.isfinite(crossover):
        for ax in (ax_mag, ax_phase):
            ax.axvline(crossover, color="tab:green", ls=":", lw=1)
        ax_phase.annotate(
            f"PM = {phase_margin_deg:.1f}°",
            (crossover, -180.0 + phase_margin_deg),
            textcoords="offset points",
            xytext=(6, 6),
            fontsize=9,
            color="tab:green",
        )
    if np.isfinite(phase_crossover):
        for ax in (ax_mag, ax_phase):
            ax.axvline(phase_crossover, color="tab:purple", ls=":", lw=1)
        ax_mag.annotate(
            f"GM = {gain_margin:.2f}",
            (phase_crossover, -20.0 * np.log10(gain_margin)),
            textcoords="offset points",
            xytext=(6, -12),
            fontsize=9,
            color="tab:purple",
        )
    bottom = max(float(np.min(phase)), -720.0)
    ax_phase.set_ylim(bottom, 0.0)
    ax_mag.set_ylim(max(float(np.min(mag_db)), -60.0), max(float(np.max(mag_db)), 10.0) + 5.0)
    for ax in (ax_mag, ax_phase):
        ax.grid(True, which="both", alpha=0.3)
    ax_mag.legend(loc="lower left")
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
    """Unit setpoint step (output and command) and unit load step of the linear closed loop."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 7))
    ax_y, ax_u, ax_d = fig.subplots(3, 1, sharex=True)
    ax_y.plot(t, setpoint_response, color="tab:blue", label="flow")
    ax_y.axhline(1.0, color="k", lw=0.6, ls="--", label="setpoint")
    ax_y.axhspan(0.98, 1.02, color="tab:green", alpha=0.12, label="2 % band")
    ax_y.set_ylabel("flow per unit\nsetpoint step")
    ax_y.legend(loc="lower right", fontsize=8)
    ax_u.step(t, command, where="post", color="tab:orange")
    ax_u.set_ylabel("command per unit\nsetpoint step [V/(L/min)]")
    ax_d.plot(t, disturbance_response, color="tab:red")
    ax_d.axhline(0.0, color="k", lw=0.6)
    ax_d.set_ylabel("flow per volt\nof load step")
    ax_d.set_xlabel("time after the step [s]")
    for ax in (ax_y, ax_u, ax_d):
        ax.grid(True, alpha=0.3)
    if title:
        ax_y.set_title(title)
    return fig


def plot_closed_loop_runs(
    runs: Sequence[tuple[str, FloatArray, FloatArray, FloatArray, FloatArray]],
    title: str = "",
) -> Figure:
    """Closed-loop runs on the plant: flow against setpoint, and the command with its limits.

    Parameters
    ----------
    runs : sequence of (label, time, setpoint, flow, command)
        Each run's signals [s, L/min, L/min, V].
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 6))
    ax_q, ax_u = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    colors = ("tab:blue", "tab:red", "tab:green", "tab:purple")
    for i, (label, t, r, q, u) in enumerate(runs):
        color = colors[i % len(colors)]
        ax_q.step(
            t, r, where="post", color=color, lw=0.8, ls="--", label="setpoint" if i == 0 else None
        )
        ax_q.plot(t, q, color=color, lw=1.0, label=label)
        ax_u.step(t, u, where="post", color=color, lw=1.0, label=label)
    ax_q.set_ylabel("flow [L/min]")
    ax_u.set_ylabel("command [V]")
    ax_u.set_xlabel("time [s]")
    for ax in (ax_q, ax_u):
        ax.grid(True, alpha=0.3)
    ax_q.legend(loc="best", fontsize=8)
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

    fig = Figure(figsize=(9, 5))
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
    ax_k.legend(loc="best", fontsize=8)
    if title:
        ax_k.set_title(title)
    return fig


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


def runs_figure(runs: Sequence[ClosedLoopResult], title: str = "", label: str = "{} °C") -> Figure:
    """Closed-loop runs on the nonlinear plant, each labelled by its fuel temperature [°C].

    ``label`` is formatted with the temperature, e.g. ``"fuel at {} °C"``.
    """
    drawn = []
    for r in runs:
        name = label.format(f"{kelvin_to_celsius(r.T_fuel):g}")
        drawn.append((name, r.time, r.setpoint, r.flow, r.command))
    return plot_closed_loop_runs(drawn, title)


def tune_figure(outcome: TuneOutcome) -> Figure:
    """The closed-loop figure of ``fuelid tune --plot``.

    The nonlinear runs when there are any, else the unit responses of the linear closed loop on
    the model with the gains and Ms in the title.
    """
    pi = outcome.tuning.pi
    if outcome.runs:
        return runs_figure(outcome.runs, f"{pi.rule} PI on the nonlinear plant")
    cl = outcome.tuning.closed_loop
    return plot_linear_closed_loop(
        cl.time,
        cl.setpoint_response,
        cl.setpoint_command,
        cl.disturbance_response,
        f"{pi.rule}: Kc = {pi.Kc:.4g} V/(L/min), Ti = {pi.Ti:.3g} s, "
        f"Ms = {outcome.tuning.robustness.Ms:.2f}",
    )
