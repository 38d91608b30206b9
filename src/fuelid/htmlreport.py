"""The HTML report of one log: figures embedded, rendered from a jinja2 template.

:func:`report_figures` draws the figures of a :class:`~fuelid.workflow.LogAnalysis` with the
functions of :mod:`fuelid.plots`; :func:`render_report` fills ``templates/report.html.j2`` with
the numbers (autoescaped, never string-built); :func:`write_report` writes the page and the same
figures as PNG files beside it, refusing to overwrite anything unless asked. Computation never
lives here: everything shown was computed by :func:`~fuelid.workflow.analyse_log`.
"""

from __future__ import annotations

import base64
import io
import math
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

import jinja2
import numpy as np

from fuelid import __version__
from fuelid.errors import DataError
from fuelid.io.files import atomic_write_bytes
from fuelid.io.timeseries import IOData, TimeSeries
from fuelid.model import ProcessModel
from fuelid.plots import (
    plot_bode,
    plot_correlation_tests,
    plot_identification,
    plot_linear_closed_loop,
    plot_log,
    runs_figure,
    schedule_figure,
)
from fuelid.units import T0, format_celsius, kelvin_to_celsius
from fuelid.workflow import LogAnalysis, gain_unit

__all__ = [
    "FIGURE_KEYS",
    "TEMPLATE",
    "ReportFigure",
    "check_report_path",
    "figure_paths",
    "figure_png",
    "render_report",
    "report_figures",
    "write_report",
]

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from fuelid.tuning import BandCheck, FixedPIEvaluation, GainSchedule, RobustPeak
    from fuelid.tuning.closedloop import ClosedLoopResult

TEMPLATE = "report.html.j2"


@dataclass(frozen=True)
class ReportFigure:
    """One figure of the report: its file-name key, caption and PNG bytes."""

    key: str
    caption: str
    png: bytes

    @property
    def data_uri(self) -> str:
        """The PNG as a ``data:`` URI, so the page needs no other file."""
        return "data:image/png;base64," + base64.b64encode(self.png).decode("ascii")


FIGURE_KEYS = ("overview", "comparison", "residuals", "bode", "closed_loop", "schedule")
"""Every report has these figures, in this order (also the PNG file suffixes)."""


_CAPTIONS = {
    "overview": "The log: VFD command and measured flow.",
    "comparison": "Measured flow against the free-run simulation of each identified model (as in "
    "the article's comparison figure), and the residuals; the shaded part was held out.",
    "residuals": "Residual tests of the model the gains come from: inside the band means "
    "consistent with white noise (autocorrelation) and no unmodelled dynamics "
    "(cross-correlation at positive lags).",
    "bode": "Bode plot of the loop with the gain margin (in dB, at the phase crossover) and the "
    "phase margin (at the crossover) marked, and the sensitivity |S| whose peak is Ms.",
    "runs": "The same gains on the nonlinear plant of the plant file at the coldest and the "
    "warmest fuel; the dashed lines are the drive's signal limits, the dash-dotted line the load "
    "step.",
    "linear": "The gains on the identified model (linear closed loop): unit setpoint step and "
    "unit load step. No plant file was given, so no run on a nonlinear plant: the built-in "
    "reference plant is not your loop.",
    "schedule": "Gains per fuel-temperature band (one line per flow band).",
}
"""The figures' captions (``runs`` or ``linear`` is the closed loop's, as the page has runs)."""


def report_figures(analysis: LogAnalysis) -> dict[str, tuple[Figure, str]]:
    """The report's figures with their captions, keyed as :data:`FIGURE_KEYS`."""
    figures = {
        "overview": (_overview_figure(analysis), _CAPTIONS["overview"]),
        "comparison": (_comparison_figure(analysis), _CAPTIONS["comparison"]),
        "residuals": (_residuals_figure(analysis), _CAPTIONS["residuals"]),
        "bode": (_bode_figure(analysis), _CAPTIONS["bode"]),
        "closed_loop": (
            _closed_loop_figure(analysis),
            _CAPTIONS["runs" if analysis.runs else "linear"],
        ),
    }
    # no plant file of the user's: no schedule (it would not be theirs)
    if analysis.schedule is not None:
        figures["schedule"] = (schedule_figure(analysis.schedule), _CAPTIONS["schedule"])
    return figures


def _overview_figure(analysis: LogAnalysis) -> Figure:
    """The log's command and flow (and fuel temperature), titled with where its fuel came from."""
    data = analysis.data
    fuel_origin = {"log": "from the log", "option": "as given"}.get(
        str(analysis.operating_point.T_fuel_source), "assumed"
    )
    return plot_log(
        _overview_series(data),
        f"{data.source or 'log'}: {data.n_samples} samples every {data.sample_time:g} s "
        f"(fuel at {format_celsius(analysis.T_fuel)} °C, {fuel_origin})",
    )


def _comparison_figure(analysis: LogAnalysis) -> Figure:
    """The measured flow against every identified model's free run, on oe's time axis."""
    data = analysis.data
    oe = analysis.identifications["oe"]
    curves = [
        (f"{method} model ({r.model.describe(gain_unit(data))})", r.y_hat_at(oe.time))
        for method, r in analysis.identifications.items()
    ]
    return plot_identification(
        oe.time,
        oe.y,
        curves,
        oe.split_time,
        "measured flow and the identified models",
        ylabel="flow q",
        unit=data.y_unit,
    )


def _residuals_figure(analysis: LogAnalysis) -> Figure:
    """The chosen model's residual autocorrelation and input-residual cross-correlation."""
    chosen = analysis.model_result
    whiteness, crossed = analysis.whiteness, analysis.input_correlation
    errors = "prediction-error" if chosen.prediction_errors is not None else "residual"
    return plot_correlation_tests(
        [
            (
                f"{errors} autocorrelation ({chosen.method}, fitted samples; "
                f"p = {whiteness.p_value:.2g})",
                whiteness.lags,
                whiteness.values,
                whiteness.bound,
            ),
            (
                "input-residual cross-correlation (positive lag: residual after input change; "
                f"p = {crossed.p_value:.2g})",
                crossed.lags,
                crossed.values,
                crossed.bound,
            ),
        ],
        sample_time=analysis.data.sample_time,
    )


def _bode_figure(analysis: LogAnalysis) -> Figure:
    """The loop's frequency response with its margins and the sensitivity's peak."""
    rob = analysis.tuning.robustness
    period = analysis.settings.control_period
    return plot_bode(
        analysis.bode_frequency,
        analysis.bode_loop,
        rob.gain_margin,
        rob.phase_margin_deg,
        rob.Ms,
        rob.crossover_frequency,
        rob.phase_crossover_frequency,
        f"loop L = C·G on the {analysis.model_result.method} model, "
        + (
            f"PI sampled every {period:g} s"
            if period  # None only before analyse_log, which refuses it
            else "continuous PI"
        ),
    )


def _closed_loop_figure(analysis: LogAnalysis) -> Figure:
    """The runs on the user's nonlinear plant, or without a plant file the linear closed loop."""
    pi = analysis.tuning.pi
    if analysis.runs:
        return runs_figure(
            analysis.runs,
            f"{pi.rule} gains on the nonlinear plant: setpoint step, then a "
            "0.2 V load step at the drive input",
            label="fuel at {} °C",
        )
    cl = analysis.tuning.closed_loop
    return plot_linear_closed_loop(
        cl.time,
        cl.setpoint_response,
        cl.setpoint_command,
        cl.disturbance_response,
        f"{pi.rule}: Kc = {pi.Kc:.4g} V/(L/min), Ti = {pi.Ti:.3g} s, "
        f"Ms = {analysis.tuning.robustness.Ms:.2f} on the identified "
        f"{analysis.model_result.method} model",
    )


def _overview_series(data: IOData) -> TimeSeries:
    """The log for the overview figure, with its fuel temperature when it has one.

    At every gap a NaN sample one period after the last sample before it breaks the lines:
    none is drawn across missing data, and the command, drawn as held, is held for that one
    period only (a NaN half-way drew it flat across half the gap).
    """
    t, signals = data.t, {"u_V": data.u, "q_Lpm": data.y}
    if data.T_fuel is not None:
        signals["T_fuel_degC"] = data.T_fuel - T0
    starts = np.asarray(data.segment_starts, dtype=int)
    if starts.size:
        breaks = np.minimum(t[starts - 1] + data.sample_time, 0.5 * (t[starts - 1] + t[starts]))
        t = np.insert(t, starts, breaks)
        signals = {name: np.insert(v, starts, np.nan) for name, v in signals.items()}
    return TimeSeries(t, signals, {"u_V": "V", "q_Lpm": "L/min", "T_fuel_degC": "°C"})


def _fuel_temperature_origin(analysis: LogAnalysis) -> str:
    """Where the fuel temperature of the analysis came from, for the page."""
    source = analysis.operating_point.T_fuel_source
    if source == "log":
        return "mean of the log's fuel-temperature column"
    if source == "option":
        return "as given with --fuel-temp"
    return "assumed: the log has no fuel-temperature column and --fuel-temp was not given"


def _priors_rows(priors: dict[str, Any]) -> list[dict[str, str]]:
    """The identification's assumptions as table rows: what, value, where it came from."""
    rows = []
    for key, label, unit in (
        ("flowmeter_T", "flowmeter lag T_f", "s"),
        ("flowmeter_delay", "flowmeter dead time", "s"),
        ("delay", "model dead time", "s"),
        ("order", "process order", ""),
        ("N", "step-ls response length N", "control periods"),
    ):
        entry = priors.get(key)
        if not isinstance(entry, dict):
            continue
        value = entry.get("value")
        shown = "–" if value is None else f"{value:.3g} {unit}".strip()
        source = str(entry.get("source", ""))
        if entry.get("note"):
            source += f" ({entry['note']})"
        rows.append({"what": label, "value": shown, "source": source})
    return rows


def figure_png(fig: Figure) -> bytes:
    """A figure as PNG bytes, at the report's resolution (110 dpi)."""
    # every figure of plots.py lays itself out (layout="constrained"): a "tight" bounding box
    # would draw each one twice for nothing
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    return buffer.getvalue()


def _fmt(value: float | None, spec: str = ".4g") -> str:
    """A number for the page; non-finite values read as a dash."""
    if value is None or not math.isfinite(value):
        return "–"
    return format(value, spec)


def _context(
    analysis: LogAnalysis, figures: list[ReportFigure], source_sha256: str | None
) -> dict[str, Any]:
    """What the template is filled with: every number as the page prints it."""
    s = analysis.settings
    data = analysis.data
    return {
        "title": f"fuelid report: {data.source or 'log'}",
        "generated": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "version": __version__,
        "source": data.source or "log",
        "sha256": source_sha256,
        "data": _data_context(analysis),
        "notices": analysis.notices,
        "plant": analysis.plant.to_json(),
        "priors": _priors_rows(analysis.priors),
        "gain_unit": gain_unit(data),
        "flow_header": "flow L/min",
        "settings": s,
        "t_range": f"{kelvin_to_celsius(s.T_range[0]):g}…{kelvin_to_celsius(s.T_range[1]):g}",
        "identifications": _identification_rows(analysis),
        "warnings": analysis.warnings,
        "pi": _pi_context(analysis),
        "check": _check_context(analysis.check),
        "misfit": _misfit_context(analysis.outcome.misfit_peak),
        "band_check": _band_check_context(analysis.outcome.bands),
        "runs": [_run_row(run) for run in analysis.runs],
        "schedule": _schedule_context(analysis.schedule),
        "figures": figures,
    }


def _formatted(row: dict[str, Any], spec: str) -> dict[str, Any]:
    """A table row with its floats formatted (:func:`_fmt`), its other cells as they are."""
    return {k: _fmt(v, spec) if isinstance(v, float) else v for k, v in row.items()}


def _data_context(analysis: LogAnalysis) -> dict[str, Any]:
    """The log: its samples, ranges, units and notes, the operating point and its fuel."""
    data = analysis.data
    return {
        "n": data.n_samples,
        "h": _fmt(data.sample_time, "g"),
        "duration": _fmt(data.n_samples * data.sample_time, ".4g"),
        "u_range": f"{np.min(data.u):.3g}…{np.max(data.u):.3g}",
        "y_range": f"{np.min(data.y):.4g}…{np.max(data.y):.4g}",
        "u_unit": data.u_unit,
        "y_unit": data.y_unit,
        "notes": list(data.notes),
        "u_operating": _fmt(analysis.u_operating, ".3g"),
        "fuel_temperature": format_celsius(analysis.T_fuel),
        "fuel_temperature_origin": _fuel_temperature_origin(analysis),
    }


def _identification_rows(analysis: LogAnalysis) -> list[dict[str, Any]]:
    """One row per estimator: the model, its standard errors, fits and whiteness test."""
    rows = []
    for method, r in analysis.identifications.items():
        d = r.to_json()
        rows.append(
            {
                "method": method,
                "K": _fmt(r.model.K),
                "K_se": _fmt(d["stderr"]["K"], ".2g"),
                "T": _fmt(r.model.T, ".3g"),
                "T_se": _fmt(d["stderr"]["T"], ".2g"),
                "T2": _fmt(r.model.T2, ".3g"),
                "T_f": _fmt(r.model.T_f, ".3g"),
                "delay": _fmt(r.model.delay, ".3g"),
                "fit": _fmt(r.fit_percent, ".2f"),
                "validation": _fmt(r.validation_fit_percent, ".2f"),
                "white_p": _fmt(d["diagnostics"]["residual_whiteness"]["p_value"], ".2g"),
                "chosen": method == analysis.settings.tune_from,
            }
        )
    return rows


def _pi_context(analysis: LogAnalysis) -> dict[str, Any]:
    """The gains in every form, their margins, linear step response and the other structures'."""
    tuning = analysis.tuning.to_json()
    plc = tuning["plc"]
    span = plc["percent_of_span"]
    rob = analysis.tuning.robustness
    step = tuning["closed_loop"]["setpoint_step"]
    return {
        "rule": tuning["rule"],
        "Kc": _fmt(tuning["Kc"], ".5g"),
        "Ti": _fmt(tuning["Ti"], ".4g"),
        "Ki": _fmt(tuning["Ki"], ".5g"),
        "h": _fmt(tuning["control_period"], "g"),
        "h_basis": analysis.settings.control_period_basis,
        "span_Kc": None if span is None else _fmt(span["Kc"], ".4g"),
        "span_Ti_min": None if span is None else _fmt(span["Ti_min"], ".4g"),
        "span_note": analysis.span_note,
        "block": _block_row(analysis),
        "discrete": None if plc["discrete"] is None else _formatted(plc["discrete"], ".5g"),
        "gain_margin": _fmt(rob.gain_margin, ".2f"),
        "phase_margin": _fmt(rob.phase_margin_deg, ".1f"),
        "Ms": _fmt(rob.Ms, ".2f"),
        "crossover": _fmt(rob.crossover_frequency, ".3g"),
        "overshoot": _fmt(step["overshoot_percent"], ".1f"),
        "settling": _fmt(step["settling_time"], ".1f"),
        "structures": [
            {
                "model": _describe_model(item.model),
                "Kc": _fmt(item.pi.Kc, ".5g"),
                "Ti": _fmt(item.pi.Ti, ".4g"),
                "Ms": _fmt(item.Ms_of_chosen_gains, ".2f"),
            }
            for item in analysis.outcome.structures
        ],
    }


def _check_context(check: FixedPIEvaluation | None) -> dict[str, Any] | None:
    """The gains over fuel temperature on the user's plant file (None: no plant file)."""
    if check is None:
        return None
    return {
        "worst_Ms": _fmt(check.worst_Ms, ".2f"),
        "worst_overshoot": _fmt(check.worst_overshoot, ".1f"),
        "worst_gain_margin": _fmt(check.worst_gain_margin, ".2f"),
        "worst_phase_margin": _fmt(check.worst_phase_margin, ".1f"),
        "all_stable": check.all_stable,
        "cases": [_formatted(row, ".3g") for row in check.rows()],
    }


def _misfit_context(peak: RobustPeak | None) -> dict[str, Any] | None:
    """The Ms bound allowing for the misfit the log shows (None: none computed)."""
    if peak is None:
        return None
    return {
        "Ms": _fmt(peak.Ms, ".2f"),
        "up_to": _fmt(peak.up_to, ".3g"),
        "bounded": math.isfinite(peak.Ms),
    }


def _band_check_context(bands: BandCheck | None) -> dict[str, Any] | None:
    """The gains over the log's command bands, K per band (None: not checked)."""
    if bands is None:
        return None
    return {
        "u_range": f"{bands.u_range[0]:.3g}…{bands.u_range[1]:.3g}",
        "worst_Ms": _fmt(bands.worst_Ms, ".2f"),
        "worst_overshoot": _fmt(bands.worst_overshoot, ".1f"),
        "worst_gain_margin": _fmt(bands.worst_gain_margin, ".2f"),
        "all_stable": bands.all_stable,
        "cases": [_formatted(case.to_json(), ".3g") for case in bands.cases],
    }


def _run_row(run: ClosedLoopResult) -> dict[str, str]:
    """One closed-loop run on the nonlinear plant: its setpoint step and load step."""
    summary = run.summary()
    return {
        "fuel_temperature": format_celsius(run.T_fuel),
        "setpoint": f"{run.setpoint[0]:.1f} → {run.setpoint[-1]:.1f}",
        "overshoot": _fmt(summary["overshoot_percent"], ".1f"),
        "settling": _fmt(summary["settling_time"], ".1f"),
        "load_peak": _fmt(summary["disturbance_peak"], ".2f"),
        "load_settling": _fmt(summary["disturbance_settling_time"], ".1f"),
        "iae": _fmt(summary["iae"], ".3g"),
        "at_limits": _fmt(summary["time_at_limits"], "g"),
    }


def _schedule_context(schedule: GainSchedule | None) -> dict[str, Any] | None:
    """The gain schedule's bands with their %/% gain (None: no plant file, no schedule)."""
    if schedule is None:
        return None
    return {
        "ms_target": _fmt(schedule.ms_target, "g"),
        "worst_Ms": _fmt(schedule.worst_Ms, ".2f"),
        "bands": [
            _formatted(b.to_json(), ".4g")
            | {"Kc_percent": _fmt(schedule.percent_of_span(b.pi), ".4g")}
            for b in schedule.bands
        ],
    }


def _environment() -> jinja2.Environment:
    return jinja2.Environment(
        loader=jinja2.PackageLoader("fuelid", "templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,  # a misspelt field fails loudly, not as a blank
        trim_blocks=True,
        lstrip_blocks=True,
    )


def render_report(
    analysis: LogAnalysis, figures: list[ReportFigure], source_sha256: str | None = None
) -> str:
    """The report page as HTML text, every figure embedded as a data URI."""
    template = _environment().get_template(TEMPLATE)
    return template.render(**_context(analysis, figures, source_sha256))


def figure_paths(html_path: Path) -> dict[str, Path]:
    """Where the PNG copies of the figures go: ``<stem>_<key>.png`` beside the page."""
    return {key: html_path.with_name(f"{html_path.stem}_{key}.png") for key in FIGURE_KEYS}


def check_report_path(path: str | Path, overwrite: bool = False) -> Path:
    """Validate the report's path (and its figures') before any work is done."""
    out = Path(path)
    if out.suffix.lower() not in (".html", ".htm"):
        raise DataError(
            f"the report is an HTML file: give a name ending in .html, not {out.name!r}"
        )
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise DataError(f"report folder {str(parent)!r} does not exist")
    if out.is_dir():
        raise DataError(f"report path {str(out)!r} is a folder, not a file")
    if not overwrite:
        taken = [p for p in (out, *figure_paths(out).values()) if p.exists()]
        if taken:
            raise DataError(f"{str(taken[0])!r} exists; pass --force to replace the report")
    return out


def write_report(
    analysis: LogAnalysis,
    path: str | Path,
    overwrite: bool = False,
    source_sha256: str | None = None,
) -> list[Path]:
    """Write the page and its figures as PNGs beside it; return every path written.

    Each file is written to a temporary name and renamed, so an interrupted run never leaves a
    half-written report nor destroys an earlier one.
    """
    out = check_report_path(path, overwrite)
    drawn = report_figures(analysis)
    figures = [ReportFigure(key, caption, figure_png(fig)) for key, (fig, caption) in drawn.items()]
    written = []
    targets = figure_paths(out)
    for figure in figures:
        written.append(atomic_write_bytes(targets[figure.key], figure.png))
    html = render_report(analysis, figures, source_sha256)
    written.insert(0, atomic_write_bytes(out, html.encode("utf-8")))
    return written


def _block_row(analysis: LogAnalysis) -> dict[str, str] | None:
    """The gains as the site file's PI block takes them (form, units), or None without one."""
    block = analysis.settings.block
    if block is None:
        return None
    from fuelid.tuning import block_units

    kc, ti = analysis.tuning.pi.to_block(block)
    units = block_units(block)
    return {
        "form": block.form,
        "kc": _fmt(kc, ".5g"),
        "integral": "Ki" if block.form == "parallel" else "Ti",
        "ti": _fmt(ti, ".5g"),
        "units": f"{units['Kc']}, {units['Ti']}",
    }


def _describe_model(model: ProcessModel) -> str:
    """A model in one line: K, the lags and the delay with their units."""
    lags = f"T {model.T:.4g} s" + (f", T2 {model.T2:.4g} s" if model.T2 > 0.0 else "")
    meter = f", T_f {model.T_f:.3g} s" if model.T_f > 0.0 else ""
    return f"K {model.K:.4g} (L/min)/V, {lags}{meter}, delay {model.delay:.3g} s"
