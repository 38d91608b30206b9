"""Figure labels sit where no curve can be: the comparison, calibration and Bode figures.

A new user's figures had "validation" and "held out: predicted" written on the data line, the
Bode figure's PM label on the phase curve, and the calibration figure's input axis labelled
"input" with no unit.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fuelid.plots import FitPanel, plot_bode, plot_greybox_fit, plot_identification


def _axes_fraction(ax: Any, value: float) -> float:
    lo, hi = ax.get_ylim()
    return float((value - lo) / (hi - lo))


def _highest_line(ax: Any) -> float:
    """The top of the curves (not of axhline/axvline, two points in axes units)."""
    curves = [line.get_ydata() for line in ax.get_lines() if len(line.get_ydata()) > 2]
    return max(float(np.nanmax(y)) for y in curves)


def _text_fraction(text: Any) -> float:
    """A label's height in axes units (drawn in axes units, or at a data y)."""
    ax = text.axes
    if text.get_transform() == ax.get_xaxis_transform() or getattr(text, "xycoords", None) == (
        "data",
        "axes fraction",
    ):
        return float(text.xy[1] if hasattr(text, "xy") else text.get_position()[1])
    return _axes_fraction(ax, text.xy[1] if hasattr(text, "xy") else text.get_position()[1])


def _step_record() -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(0.0, 100.0, 0.1)
    y = np.where(t > 70.0, 32.0, 23.0)  # the highest level in the held-out end
    return t, y


def test_comparison_names_the_validation_span_in_the_legend() -> None:
    t, y = _step_record()
    fig = plot_identification(t, y, [("oe model", y)], split_time=70.0, unit="L/min")
    ax = fig.axes[0]
    legend = ax.get_legend()
    assert legend is not None
    assert "validation (held out)" in [text.get_text() for text in legend.get_texts()]
    assert not [text for text in ax.texts if "validation" in text.get_text()]


def test_calibration_labels_sit_above_the_curves_and_the_input_has_its_unit() -> None:
    t, y = _step_record()
    panel = FitPanel(
        "p2.csv", t, y[:, None], y[:, None], [96.0], heldout_start=70.0,
        heldout_fit_percent=[96.0], input_u=np.where(t > 70.0, 3.5, 2.5)[:, None],
        input_names=["command [V]"],
    )  # fmt: skip
    fig = plot_greybox_fit([panel], ["flow [L/min]"])
    signal = fig.axes[0]
    (label,) = [text for text in signal.texts if text.get_text().strip() == "held out: predicted"]
    assert _text_fraction(label) > _axes_fraction(signal, _highest_line(signal)) + 0.1
    assert fig.axes[2].get_ylabel() == "command [V]"


def test_inputs_sharing_a_unit_label_their_axis_with_it() -> None:
    t, y = _step_record()
    u = np.column_stack([np.ones_like(t), 2 * np.ones_like(t)])
    panel = FitPanel("a.csv", t, y[:, None], y[:, None], [96.0], input_u=u,
                     input_names=["pump [V]", "valve [V]"])  # fmt: skip
    assert plot_greybox_fit([panel], ["flow [L/min]"]).axes[2].get_ylabel() == "input [V]"


def test_bode_phase_margin_label_sits_above_the_phase_curve() -> None:
    omega = np.logspace(-3, 0.5, 400)
    s = 1j * omega
    loop = 0.3 * (1 + 1 / (1.3 * s)) * 8.8 * np.exp(-0.9 * s) / ((0.8 * s + 1) * (0.8 * s + 1))
    fig = plot_bode(omega, loop, 3.6, 54.0, 1.66, 0.33, 0.89)
    ax_phase = fig.axes[1]
    (pm,) = [text for text in ax_phase.texts if text.get_text().startswith("PM")]
    assert _text_fraction(pm) > _axes_fraction(ax_phase, _highest_line(ax_phase)) + 0.1
