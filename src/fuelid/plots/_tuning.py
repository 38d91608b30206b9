"""Figures of tuning: the loop's Bode plot, closed-loop responses and runs, the gain schedule.

Presentation only (:mod:`fuelid.plots`): each function draws what :mod:`fuelid.tuning` or
:mod:`fuelid.workflow._tune` computed. Temperatures arrive in kelvin and are shown in °C.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from fuelid.plots._common import DRIVE_LIMITS, LABEL_BAND, LABEL_BOX, FloatArray, _include
from fuelid.units import format_celsius, kelvin_to_celsius

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from fuelid.tuning import GainSchedule
    from fuelid.tuning.closedloop import ClosedLoopResult
    from fuelid.workflow import TuneOutcome


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
        # named in the band at the top of the axes, which the phase curve stays below (beside
        # the arrow, the label sat on the curve where it falls through -180°)
        ax_phase.annotate(
            f"PM = {phase_margin_deg:.1f}°",
            (crossover, 0.975),
            xycoords=("data", "axes fraction"),
            textcoords="offset points",
            xytext=(4, 0),
            va="top",
            fontsize=9,
            color="tab:green",
            bbox=LABEL_BOX,
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
    # the top LABEL_BAND of the phase axes free of the curve, for the PM label
    top = float(np.max(phase))
    ax_phase.set_ylim(bottom, max(0.0, top + (top - bottom) * LABEL_BAND / (1.0 - LABEL_BAND)))
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
        temperature = format_celsius(r.T_fuel)
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
