"""``fuelid report``: one self-contained HTML page from a PLC log, from the data to the gains.

The command checks its options, reads the log, calls :func:`~fuelid.workflow.analyse_log` and
writes the page with :func:`~fuelid.htmlreport.write_report`; the library is imported when the
command runs. While it works, a line on stderr (a terminal only, not with ``--quiet``) names the
current stage, with a bar when its steps are counted (:mod:`fuelid.cli._progress`).
"""

from __future__ import annotations

import enum
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from fuelid.cli._common import (
    AcceptUndeterminedOption,
    BadValues,
    BandWidthOption,
    ControlPeriodOption,
    DriveSpanOption,
    FillGaps,
    FlowBandsOption,
    FlowSpanOption,
    FlowUnit,
    FuelTemperatureColumn,
    InputColumn,
    InputScale,
    LambdaOption,
    LogReadOptions,
    MaxGap,
    MsTargetOption,
    OutputColumn,
    OutputScale,
    RuleChoice,
    RuleOption,
    SampleTime,
    SiteOption,
    SkipRowsOption,
    TauCOption,
    TimeColumn,
    TimeFormatOption,
    TimeZoneOption,
    TMaxOption,
    TMinOption,
    check_spans,
    closed_loop_time,
    emit_json,
    file_sha256,
    fitted_part,
    flow_unit_warning,
    guarded,
    progress_display,
    provenance,
    site_facts,
    temperature_options,
    warn,
)
from fuelid.cli._identify import FullRecordOption
from fuelid.cli._identify_options import (
    DEFAULT_ORDER,
    CovarianceChoice,
    CovarianceOption,
    DelayOption,
    FitOptions,
    FlowmeterDelayOption,
    FlowmeterTOption,
    OrderOption,
    StepsOption,
)
from fuelid.units import DEFAULT_FUEL_TEMPERATURE_C

if TYPE_CHECKING:
    from fuelid.workflow import AnalysisSettings, LogAnalysis, PlantSource


class TuneFrom(enum.StrEnum):
    """Which identification the gains are computed from."""

    oe = "oe"
    step_ls = "step-ls"
    pem = "pem"


@guarded
def report_command(
    file: Annotated[
        Path, typer.Argument(metavar="LOG", help="PLC log: CSV (any of , ; tab) or Parquet.")
    ],
    out: Annotated[
        Path, typer.Option("--out", "-o", help="The HTML report; its figures go beside it.")
    ] = Path("report.html"),
    force: Annotated[
        bool, typer.Option("--force", help="Replace an existing report and its figures.")
    ] = False,
    config: Annotated[
        Path | None,
        typer.Option(
            "--config",
            "-c",
            metavar="PLANT.toml",
            help="Plant TOML of your loop: flowmeter priors, spans, temperature physics, the "
            "nonlinear plant of the closed-loop runs (default: none; then no temperature check, "
            "schedule or nonlinear runs, said on the page: the built-in reference plant is not "
            "your loop).",
            show_default=False,
        ),
    ] = None,
    order: OrderOption = DEFAULT_ORDER,
    delay: DelayOption = None,
    flowmeter_T: FlowmeterTOption = None,
    flowmeter_delay: FlowmeterDelayOption = None,
    n_steps: StepsOption = None,
    covariance: CovarianceOption = CovarianceChoice.auto,
    full_record: FullRecordOption = False,
    accept_signals: Annotated[
        bool,
        typer.Option(
            "--accept-signals",
            help="Tune even though the command or the flow lies outside the spans the gains are "
            "computed for (an unscaled mA or counts column, a wrong unit): refused otherwise.",
        ),
    ] = False,
    method: Annotated[
        TuneFrom,
        typer.Option(
            help="Identification the gains come from (step-ls and oe are always shown; pem, the "
            "fit with a noise model, is added when chosen)."
        ),
    ] = TuneFrom.oe,
    rule: RuleOption = RuleChoice.simc,
    tau_c: TauCOption = None,
    lam: LambdaOption = None,
    control_period: ControlPeriodOption = None,
    site: SiteOption = None,
    accept_undetermined: AcceptUndeterminedOption = False,
    fuel_temp: Annotated[
        float | None,
        typer.Option(
            help="Fuel temperature during the log [°C] (default: the log's T_fuel_degC column, "
            "else 20 °C, said in the report).",
            show_default=False,
        ),
    ] = None,
    t_min: TMinOption = -20.0,
    t_max: TMaxOption = 50.0,
    band_width: BandWidthOption = 10.0,
    ms_target: MsTargetOption = 1.7,
    flow_bands: FlowBandsOption = 3,
    flow_span: FlowSpanOption = None,
    u_span: DriveSpanOption = None,
    validate_split: Annotated[
        float | None,
        typer.Option(help="Hold out the last fraction F of the log for validation (0: none)."),
    ] = 0.3,
    time_col: TimeColumn = "t_s",
    input_col: InputColumn = "u_V",
    output_col: OutputColumn = "q_Lpm",
    sample_time: SampleTime = None,
    input_scale: InputScale = None,
    output_scale: OutputScale = None,
    fuel_temp_col: FuelTemperatureColumn = "T_fuel_degC",
    fill_gaps: FillGaps = None,
    max_gap: MaxGap = None,
    bad_values: BadValues = None,
    flow_unit: FlowUnit = None,
    timezone: TimeZoneOption = None,
    time_format: TimeFormatOption = None,
    skip_rows: SkipRowsOption = None,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print one JSON object (the numbers and the paths).")
    ] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
) -> None:
    """Identify, tune and check a log; write an HTML report with every figure embedded.

    The page holds the data overview, measured versus model (step-ls and oe side by side), the
    residual tests, the Bode plot with the margins, the closed loop on the nonlinear plant at the
    coldest and warmest fuel, the gains in every PLC form and the gain schedule. The figures are
    also written as PNG files beside the page (REPORT_overview.png, ...).
    """
    from fuelid.htmlreport import check_report_path
    from fuelid.plant import load_plant_config
    from fuelid.tuning import BlockForm
    from fuelid.workflow import AnalysisSettings, PlantSource, control_period_from

    check_report_path(out, force)  # before any work: a typo must not cost a minute
    facts = site_facts(site)
    if config is None and facts is not None and facts.plant is not None:
        config = facts.plant  # the plant file the site file names
    period = control_period_from(control_period, None if facts is None else facts.control_period)
    T_fuel, T_range = temperature_options(
        DEFAULT_FUEL_TEMPERATURE_C if fuel_temp is None else fuel_temp, t_min, t_max
    )
    fit = FitOptions(order, delay, flowmeter_T, flowmeter_delay, n_steps, covariance, full_record)
    check_spans(flow_span, u_span)
    settings = AnalysisSettings(
        tune_from=method.value,
        rule=rule.value,
        closed_loop_time=closed_loop_time(rule, tau_c, lam),
        control_period=period.value,
        control_period_basis=period.basis,
        accept_undetermined=accept_undetermined,
        site_spans=(None, None) if facts is None else facts.spans,
        block=None if facts is None or facts.controller is None else BlockForm.of(facts.controller),
        T_fuel=None if fuel_temp is None else T_fuel,
        identify=fit.identify_options(),
        accept_signals=accept_signals,
        T_range=T_range,
        band_width=band_width,
        ms_target=ms_target,
        flow_bands=flow_bands,
        validate_split=validate_split or None,
        y_span=flow_span,
        u_span=u_span,
    )
    plant = PlantSource(load_plant_config(config), None if config is None else str(config))
    log = LogReadOptions(
        time_col=time_col,
        input_col=input_col,
        output_col=output_col,
        sample_time=sample_time,
        input_scale=input_scale,
        output_scale=output_scale,
        fuel_temp_col=fuel_temp_col,
        fill_gaps=fill_gaps,
        max_gap=max_gap,
        bad_values=bad_values,
        flow_unit=flow_unit,
        # a log's stamps without offsets are in the site's zone unless --timezone says otherwise
        timezone=timezone if timezone or facts is None else facts.timezone,
        time_format=time_format,
        skip_rows=skip_rows,
    )
    analysis, written = _analyse_and_write(file, log, plant, settings, out, force, quiet)
    if as_json:
        given = {
            "out": str(out),
            "config": str(config) if config else None,
            **fit.to_json(),
            "accept_signals": accept_signals,
            "method": settings.tune_from,
            "rule": rule.value,
            "tau_c": tau_c,
            "lambda": lam,
            "control_period": control_period,
            "site": str(site) if site else None,
            "accept_undetermined": accept_undetermined,
            "fuel_temp": fuel_temp,
            "t_min": t_min,
            "t_max": t_max,
            "band_width": band_width,
            "ms_target": ms_target,
            "flow_bands": flow_bands,
            "flow_span": flow_span,
            "u_span": u_span,
            "validate_split": validate_split,
        }
        paths = {"report": str(written[0]), "figures": [str(p) for p in written[1:]]}
        emit_json(paths | analysis.to_json() | provenance(given | log.to_json(), file))
        return
    _print_summary(analysis, written)


def _analyse_and_write(
    file: Path,
    log: LogReadOptions,
    plant: PlantSource,
    settings: AnalysisSettings,
    out: Path,
    force: bool,
    quiet: bool,
) -> tuple[LogAnalysis, list[Path]]:
    """Read and analyse the log, say its warnings, write the page: (the analysis, paths written).

    The paths are the page's first, then its figures'.
    """
    from fuelid.htmlreport import write_report
    from fuelid.workflow import analyse_log

    # reading, gridding and the fits of a day at 50 Hz take seconds each: shown on stderr
    with progress_display(quiet) as stage:
        data = log.read(file, stage)
        analysis = analyse_log(data, plant, settings, progress=stage)
    unit_warning = flow_unit_warning(data, log.output_col)
    if unit_warning:  # the report's gains take the flow as L/min: the page says so too
        analysis.warnings.append(unit_warning)
    for message in analysis.notices + analysis.warnings:
        warn(message)
    digest = file_sha256(file)
    with progress_display(quiet) as stage:
        stage("figures")
        written = write_report(analysis, out, overwrite=force, source_sha256=digest)
    return analysis, written


def _fitted_part(analysis: LogAnalysis) -> str:
    """Which part of the log the models were fitted on: identify's default differs."""
    data, result = analysis.data, analysis.model_result
    log = (float(data.t[0]), float(data.t[-1]))
    if result.split_time is None:
        return fitted_part(log, log, None)
    line = fitted_part(log, (log[0], result.split_time), "the rest")
    return f"{line} (--validate-split 0 fits all of it, as fuelid identify does)"


def _print_summary(analysis: LogAnalysis, written: list[Path]) -> None:
    from rich.console import Console

    console = Console(emoji=False)  # ":100:" in a suggested --input-scale is not an emoji
    console.print(_fitted_part(analysis), highlight=False, soft_wrap=True)
    from fuelid.workflow import gain_unit

    pi = analysis.tuning.pi
    rob = analysis.tuning.robustness
    model = analysis.model_result.model
    k_unit = gain_unit(analysis.data)
    console.print(
        f"{analysis.settings.tune_from} model: {model.describe(k_unit)} "
        f"(fit {analysis.model_result.fit_percent:.1f} %)"
    )
    h = pi.control_period
    period = f"h = {h:g} s ({analysis.settings.control_period_basis})" if h > 0 else "continuous"
    console.print(
        f"{pi.rule} PI for {period}: Kc = {pi.Kc:.4g} V/(L/min), Ti = {pi.Ti:.3g} s; on the "
        f"identified model GM {rob.gain_margin:.2f}, PM {rob.phase_margin_deg:.1f}°, "
        f"Ms {rob.Ms:.2f}",
        highlight=False,
    )
    check, bands, schedule = analysis.check, analysis.outcome.bands, analysis.schedule
    if check is not None:
        console.print(f"over fuel temperature (your plant file): worst Ms {check.worst_Ms:.2f}")
    misfit = analysis.outcome.misfit_peak
    if misfit is not None:
        console.print(
            f"allowing for the misfit the log shows (up to {misfit.up_to:.3g} rad/s, 95 %): "
            + ("Ms not bounded" if not math.isfinite(misfit.Ms) else f"Ms ≤ {misfit.Ms:.2f}"),
            highlight=False,
        )
    if bands is not None:
        low, high = bands.u_range
        console.print(
            f"over the log's commands {low:.3g}…{high:.3g} V (K per band): worst Ms "
            f"{bands.worst_Ms:.2f}",
            highlight=False,
        )
    if schedule is not None:
        console.print(
            "one set of gains suffices over the schedule's bands"
            if schedule.single_set_suffices
            else f"schedule of {len(schedule.bands)} bands, worst Ms {schedule.worst_Ms:.2f}"
        )
    form = analysis.tuning.plc_form()["percent_of_span"]
    if form is None:
        console.print(f"no %/% gains: {analysis.span_note}", highlight=False, markup=False)
    else:
        console.print(
            f"percent of span: Kc = {form['Kc']:.4g} %/% ({analysis.span_note})", highlight=False
        )
    if not analysis.plant.is_reference:
        console.print(f"plant: {analysis.plant.config.name} from {analysis.plant.path}")
    for notice in analysis.notices:
        console.print(f"[bold]note:[/bold] {notice}", highlight=False)
    console.print(f"report: {written[0]}")
