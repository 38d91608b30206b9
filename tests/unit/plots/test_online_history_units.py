"""The history plot labels the gains in the PLC block's units, with the targets."""

from __future__ import annotations

import pytest


def test_the_history_plot_labels_the_gains_in_the_blocks_units_with_the_targets(
    tmp_path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from fuelid.plots import _online as online_plots

    figures = []
    monkeypatch.setattr(online_plots, "save_figure", lambda fig, path: figures.append(fig))
    t = 1_795_000_000.0
    history = {
        "windows": [],
        "writes": [],
        "gain_units": {"Kc": "%/%", "Ti": "%/% per min"},
        "proposals": [
            {
                "id": 1,
                "time": t,
                "status": "pending",
                "old": {"Kc": 1.0, "Ti": 2.0},
                "new": {"Kc": 1.2, "Ti": 1.8},
                "target": {"Kc": 1.44, "Ti": 1.6},
            }
        ],
    }
    online_plots.plot_online_history(history, tmp_path / "h.png")
    (fig,) = figures
    ax_g = fig.axes[2]
    ax_ti = next(ax for ax in fig.axes[3:] if "Ti [" in ax.get_ylabel())
    assert ax_g.get_ylabel().startswith("Kc [%/%]")
    assert ax_ti.get_ylabel().startswith("Ti [%/% per min]")
    stars = [line for line in ax_g.get_lines() if line.get_marker() == "*"]
    assert [tuple(line.get_ydata()) for line in stars] == [(1.44,)]
    assert [tuple(line.get_ydata()) for line in ax_ti.get_lines() if line.get_marker() == "*"] == [
        (1.6,)
    ]
