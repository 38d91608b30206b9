"""The gray-box fit figure: what it shades, what it titles and which rows it draws."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from fuelid.errors import DataError
from fuelid.plots import FitPanel, plot_greybox_fit


def _panel(**extra: object) -> FitPanel:
    t = np.arange(100) * 0.5
    y = np.sin(t)[:, None]
    return FitPanel("log.csv", t, y, y + 0.01, [98.5], **extra)  # type: ignore[arg-type]


def _spans(ax: Any) -> list[tuple[float, float]]:
    """The time extents of the shaded spans (axvspan rectangles) of an axes."""
    out = []
    for patch in ax.patches:
        x0, _, width, _ = patch.get_bbox().bounds
        out.append((round(x0, 6), round(x0 + width, 6)))
    return out


def test_the_held_out_end_is_shaded_and_its_fit_is_in_the_title() -> None:
    panel = _panel(heldout_start=40.0, heldout_fit_percent=[97.25])
    fig = plot_greybox_fit([panel], ["flow [L/min]"])
    signal, residual = fig.axes[:2]
    assert _spans(signal) == [(40.0, 49.5)]
    assert _spans(residual) == [(40.0, 49.5)]
    assert signal.get_title() == "log.csv: fit 98.5 %, held-out 97.2 %"
    assert any(text.get_text().strip() == "held out: predicted" for text in signal.texts)


def test_the_inputs_get_a_row_of_their_own_with_the_time_axis() -> None:
    t = np.arange(100) * 0.5
    u = np.repeat([1.0, 2.0], 50)[:, None]
    fig = plot_greybox_fit([_panel(input_u=u, input_names=["u_V"])], ["h_dm"])
    assert len(fig.axes) == 3  # signal, residual, input
    ax_u = fig.axes[2]
    assert ax_u.get_xlabel() == "time [s]"
    assert fig.axes[1].get_xlabel() == ""
    (line,) = ax_u.get_lines()
    np.testing.assert_array_equal(line.get_xdata(), t)
    assert ax_u.get_legend().get_texts()[0].get_text() == "u_V"


def test_simulated_is_drawn_over_measured() -> None:
    fig = plot_greybox_fit([_panel()], ["y"])
    labels = [line.get_label() for line in fig.axes[0].get_lines()]
    assert labels == ["measured", "simulated"]  # later lines are drawn on top


def test_no_panel_is_refused() -> None:
    with pytest.raises(DataError, match="no record"):
        plot_greybox_fit([], ["y"])
