"""Figures (matplotlib) of the plant, simulations, identification, tuning and gray-box fits.

Computation never lives here: every function takes results computed elsewhere and draws them.
Figures are built with :class:`matplotlib.figure.Figure` directly (no pyplot state, no GUI
backend), so they work on a headless machine. matplotlib is imported inside the functions, so a
command that draws nothing never loads it (docs/explanation/architecture.md, "Rules"). Temperatures
arrive in kelvin and are shown in °C.

- identification: a PLC log (:func:`plot_log`), step responses (:func:`plot_step_responses`),
  the model against the data (:func:`plot_identification`) and the residual correlation tests
  (:func:`plot_correlation_tests`);
- tuning: the loop's Bode plot (:func:`plot_bode`), the linear closed loop
  (:func:`plot_linear_closed_loop`), closed-loop runs on the plant
  (:func:`plot_closed_loop_runs`), the gain schedule (:func:`plot_schedule`), and the figures of
  ``fuelid tune --plot`` (:func:`tune_figure`, :func:`runs_figure`, :func:`schedule_figure`);
- :func:`plot_greybox_fit`: a gray-box fit, measured against simulated, with residuals;
- :func:`plot_online_history`: the online service's history.

The public API
--------------
Every name in ``__all__`` is promised at ``fuelid.plots`` itself (as when it was one module,
before 0.2.0): :func:`save_figure` saves any of the figures, the ``plot_*`` and ``*_figure``
functions draw them, :class:`FitPanel` is one record's column of the gray-box figure,
:data:`DRIVE_LIMITS`, :data:`NO_UNIT` and :data:`PROPOSAL_COLOURS` are the drawing's constants.
The old module ``fuelid.plots_greybox`` was removed in 0.3.0: the gray-box figure is
:func:`plot_greybox_fit`, saved with :func:`save_figure`.
"""

from __future__ import annotations

from fuelid.plots._common import DRIVE_LIMITS, NO_UNIT, FloatArray, save_figure
from fuelid.plots._greybox import FitPanel, plot_greybox_fit
from fuelid.plots._identification import (
    plot_correlation_tests,
    plot_identification,
    plot_log,
    plot_step_responses,
)
from fuelid.plots._online import PROPOSAL_COLOURS, plot_online_history
from fuelid.plots._tuning import (
    plot_bode,
    plot_closed_loop_runs,
    plot_linear_closed_loop,
    plot_schedule,
    runs_figure,
    schedule_figure,
    tune_figure,
)

__all__ = [
    "DRIVE_LIMITS",
    "NO_UNIT",
    "PROPOSAL_COLOURS",
    "FitPanel",
    "FloatArray",
    "plot_bode",
    "plot_closed_loop_runs",
    "plot_correlation_tests",
    "plot_greybox_fit",
    "plot_identification",
    "plot_linear_closed_loop",
    "plot_log",
    "plot_online_history",
    "plot_schedule",
    "plot_step_responses",
    "runs_figure",
    "save_figure",
    "schedule_figure",
    "tune_figure",
]
