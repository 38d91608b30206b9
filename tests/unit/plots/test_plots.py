"""The figures an engineer puts in a report: units, legends, limits, marks (no image comparison).

Every check inspects the matplotlib Figure that :mod:`fuelid.plots` returns: axis labels carry a
unit in brackets, legends name what is drawn, and the marks (drive limits, load step, margins)
are where the numbers put them.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from fuelid.io.timeseries import TimeSeries
from fuelid.plots import (
    DRIVE_LIMITS,
    NO_UNIT,
    plot_bode,
    plot_closed_loop_runs,
    plot_correlation_tests,
    plot_identification,
    plot_linear_closed_loop,
    plot_log,
    plot_schedule,
    save_figure,
)

UNIT = re.compile(r"\[[^\]]+\]\s*$")


def _legend_texts(ax) -> list[str]:
    legend = ax.get_legend()
    assert legend is not None, f"axis {ax.get_ylabel()!r} has no legend"
    return [t.get_text() for t in legend.get_texts()]


def _has_unit(label: str) -> bool:
    return bool(UNIT.search(label.replace("\n", " ")))


def _hlines(ax) -> list[float]:
    """The y of the horizontal lines (axhline) on an axis."""
    out = []
    for line in ax.lines:
        x, y = line.get_xdata(), line.get_ydata()
        if len(y) == 2 and y[0] == y[1] and list(x) == [0, 1]:
            out.append(float(y[0]))
    return out


def _vlines(ax) -> list[float]:
    out = []
    for line in ax.lines:
        x, y = line.get_xdata(), line.get_ydata()
        if len(x) == 2 and x[0] == x[1] and list(y) == [0, 1]:
            out.append(float(x[0]))
    return out


def _all_labelled(fig) -> None:
    for ax in fig.axes:
        assert _has_unit(ax.get_ylabel()), ax.get_ylabel()
    assert _has_unit(fig.axes[-1].get_xlabel()), fig.axes[-1].get_xlabel()


def test_log_overview_has_units_and_the_fuel_temperature_when_logged():
    t = np.arange(0.0, 10.0, 0.1)
    signals = {"u_V": 1.0 + (t > 5), "q_Lpm": 10.0 + (t > 5), "T_fuel_degC": 20.0 + 0 * t}
    fig = plot_log(TimeSeries(t, signals))
    assert len(fig.axes) == 3
    _all_labelled(fig)
    assert "°C" in fig.axes[2].get_ylabel()
    lo, hi = fig.axes[2].get_ylim()
    assert lo < 20.0 < hi
    assert hi - lo >= 2.0
    assert all(_has_unit(text) for ax in fig.axes for text in _legend_texts(ax))
    without = plot_log(TimeSeries(t, {"u_V": signals["u_V"], "q_Lpm": signals["q_Lpm"]}))
    assert len(without.axes) == 2


def test_identification_axes_carry_the_unit_or_say_it_is_missing():
    t = np.linspace(0.0, 10.0, 50)
    y = np.sin(t)
    fig = plot_identification(t, y, [("model (K = 2 (L/min)/V)", y * 0.9)], split_time=7.0)
    ax, ax_res = fig.axes
    assert ax.get_ylabel() == "flow q [L/min]"
    assert ax_res.get_ylabel().endswith("[L/min]")
    assert "(L/min)/V" in _legend_texts(ax)[1]
    # a raw column name: the unit from the log when given, else said to be missing
    named = plot_identification(t, y, [("m", y)], ylabel="FT101", unit="m3/h")
    assert named.axes[0].get_ylabel() == "FT101 [m3/h]"
    assert named.axes[1].get_ylabel().endswith("[m3/h]")
    bare = plot_identification(t, y, [("m", y)], ylabel="FT101")
    assert bare.axes[0].get_ylabel() == f"FT101 [{NO_UNIT}]"
    assert bare.axes[1].get_ylabel().endswith(f"[{NO_UNIT}]")


def test_correlation_lags_are_in_seconds_when_the_sample_time_is_given():
    lags = np.arange(1.0, 26.0)
    values = np.zeros(25)
    fig = plot_correlation_tests([("auto", lags, values, 0.05)], sample_time=0.02)
    ax = fig.axes[0]
    assert ax.get_xlabel().startswith("lag [s]")
    assert ax.get_xlim()[1] == pytest.approx(0.5, abs=0.1)
    assert ax.get_ylabel() == "correlation [-]"
    samples = plot_correlation_tests([("auto", lags, values, 0.05)])
    assert samples.axes[0].get_xlabel() == "lag [samples]"


def test_bode_marks_the_gain_margin_in_db_on_the_db_axis():
    omega = np.logspace(-2, 1, 400)
    s = 1j * omega
    loop = 2.0 * (1 + 1 / s) * np.exp(-s) / (1 + s)
    fig = plot_bode(omega, loop, 2.5, 45.0, 1.6, 0.8, 1.5)
    ax_mag, ax_phase = fig.axes
    texts = [t.get_text() for t in ax_mag.texts]
    gm = [t for t in ax_mag.texts if t.get_text().startswith("GM")]
    assert gm, texts
    assert f"{20 * np.log10(2.5):.1f} dB" in gm[0].get_text()
    # the marker spans 0 dB down to -GM dB on the magnitude axis
    arrows = [a for a in ax_mag.texts if a.get_text() == ""]
    assert any(a.xy[1] == 0.0 and a.xyann[1] == pytest.approx(-20 * np.log10(2.5)) for a in arrows)
    assert ax_mag.get_ylim()[0] < -20 * np.log10(2.5)
    assert any(t.get_text().startswith("PM") for t in ax_phase.texts)
    assert ax_mag.get_ylabel() == "magnitude [dB]"
    assert ax_phase.get_ylabel() == "phase of L [°]"


def test_linear_closed_loop_shows_the_command_baseline_and_units():
    t = np.linspace(0.0, 10.0, 101)
    command = 5.0 + 0.0 * t  # never near zero: the axis must still include it
    fig = plot_linear_closed_loop(t, 1 - np.exp(-t), command, t * np.exp(-t))
    _all_labelled(fig)
    lo, hi = fig.axes[1].get_ylim()
    assert lo <= 0.0 < hi
    assert 0.0 in _hlines(fig.axes[1])


def test_closed_loop_runs_mark_the_drive_limits_and_the_load_step():
    t = np.linspace(0.0, 60.0, 601)
    r = 30.0 + 10.0 * (t >= 5)
    run = ("fuel at 20 °C", t, r, r, 2.5 + 0.1 * (t > 5))
    fig = plot_closed_loop_runs([run], "title", load_steps=[40.0])
    ax_q, ax_u = fig.axes
    assert set(DRIVE_LIMITS) <= set(_hlines(ax_u))
    lo, hi = ax_u.get_ylim()
    assert lo < DRIVE_LIMITS[0]
    assert hi > DRIVE_LIMITS[1]
    assert 40.0 in _vlines(ax_q)
    assert 40.0 in _vlines(ax_u)
    assert any("drive limits 1–5 V" in text for text in _legend_texts(ax_u))
    assert any("load step at 40 s" in text for text in _legend_texts(ax_q))
    assert ax_q.get_ylabel() == "flow [L/min]"
    assert ax_u.get_ylabel() == "command [V]"


def test_runs_figure_names_the_temperatures_and_finds_the_load_step(tmp_path: Path):
    from fuelid.plots import runs_figure
    from fuelid.tuning.closedloop import ClosedLoopResult
    from fuelid.units import celsius_to_kelvin

    t = np.linspace(0.0, 60.0, 601)
    r = 30.0 + 10.0 * (t >= 5)
    runs = [
        ClosedLoopResult(
            time=t,
            setpoint=r,
            flow=r,
            command=2.5 + 0.1 * (t > 5),
            disturbance=0.2 * (t >= 40.0),
            T_fuel=celsius_to_kelvin(temperature),
            control_period=0.1,
        )
        for temperature in (-20.0, 50.0)
    ]
    fig = runs_figure(runs, "my gains")
    title = fig.axes[0].get_title()
    assert "my gains" in title
    assert "-20" in title
    assert "50 °C" in title
    assert any("load step at 40 s" in text for text in _legend_texts(fig.axes[0]))
    assert set(DRIVE_LIMITS) <= set(_hlines(fig.axes[1]))
    save_figure(fig, tmp_path / "runs.png")


def test_schedule_axes_do_not_blow_up_a_small_change():
    bands = [
        (-20.0, 15.0, "1.00…3.00 V", 0.050, 1.40),
        (15.0, 50.0, "1.00…3.00 V", 0.052, 1.41),  # a 4 % change
        (-20.0, 15.0, "3.00…5.00 V", 0.050, 1.40),
        (15.0, 50.0, "3.00…5.00 V", 0.051, 1.40),
    ]
    fig = plot_schedule(bands)
    ax_k, ax_i = fig.axes
    for ax, mean in ((ax_k, 0.051), (ax_i, 1.40)):
        lo, hi = ax.get_ylim()
        assert hi - lo >= 0.2 * mean * 0.99 or lo == 0.0
        assert lo <= mean <= hi
        assert ax.get_legend().get_title().get_text() == "command band"
        assert _has_unit(ax.get_ylabel())
    assert _has_unit(ax_i.get_xlabel())


def test_nothing_is_clipped_the_figures_use_constrained_layout():
    t = np.linspace(0.0, 10.0, 11)
    fig = plot_linear_closed_loop(t, t, t, t, "a title")
    assert fig.get_layout_engine() is not None
