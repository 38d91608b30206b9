"""``fuelid tune``: PI gains from a model, their margins, closed-loop checks and a schedule.

The command parses and checks its options, builds a :class:`~fuelid.workflow.TuneRequest` and
prints what :func:`~fuelid.workflow.tune_model` or :func:`~fuelid.workflow.schedule_gains`
return. The library is imported when the command runs, not when ``fuelid --help`` is asked for.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from fuelid.cli._common import (
    AcceptUndeterminedOption,
    BandWidthOption,
    ControlPeriodOption,
    DriveSpanOption,
    FlowBandsOption,
    FlowSpanOption,
    ForceFigureOption,
    LambdaOption,
    MsTargetOption,
    RuleChoice,
    RuleOption,
    SiteOption,
    TauCOption,
    TMaxOption,
    TMinOption,
    check_figure_path,
    check_spans,
    closed_loop_time,
    emit_json,
    format_interval,
    guarded,
    progress_display,
    provenance,
    site_facts,
    temperature_options,
    warn,
)
from fuelid.errors import FuelidError
from fuelid.units import DEFAULT_FUEL_TEMPERATURE_C, format_celsius

if TYPE_CHECKING:
    from rich.console import Console
    from rich.table import Table

    from fuelid.cli._common import SiteFacts
    from fuelid.io.fitted_model import FittedModel
    from fuelid.model import ProcessModel
    from fuelid.tuning import BlockForm
    from fuelid.workflow import PlantSource, ScheduleOutcome, TuneOutcome, TuneRequest


@guarded
def tune_command(
    model_file: Annotated[
        Path | None,
        typer.Option(
            "--model",
            metavar="MODEL.json",
            help="Identification result (fuelid identify --json > ident.json).",
            show_default=False,
        ),
    ] = None,
    K: Annotated[
        float | None,
        typer.Option("--K", help="Process gain [(L/min)/V].", show_default=False),
    ] = None,
    T: Annotated[
        float | None, typer.Option("--T", help="Process time constant [s].", show_default=False)
    ] = None,
    T2: Annotated[
        float | None,
        typer.Option("--T2", help="Second time constant [s] (default 0).", show_default=False),
    ] = None,
    T_f: Annotated[
        float | None,
        typer.Option(
            "--flowmeter-T",
            "--T-f",
            metavar="SECONDS",
            help="Flowmeter lag T_f [s] (default 0; alias --T-f).",
            show_default=False,
        ),
    ] = None,
    delay: Annotated[
        float | None,
        typer.Option("--delay", help="Total dead time [s] (default 0).", show_default=False),
    ] = None,
    rule: RuleOption = RuleChoice.simc,
    tau_c: TauCOption = None,
    lam: LambdaOption = None,
    control_period: ControlPeriodOption = None,
    site: SiteOption = None,
    config: Annotated[
        Path | None,
        typer.Option(
            "--config",
            "-c",
            metavar="PLANT.toml",
            help="Plant TOML of your loop: spans, temperature physics and the nonlinear plant "
            "(default: none; then no temperature check, schedule or --simulate: the built-in "
            "reference plant is not your loop, and the range check is the log's command bands).",
            show_default=False,
        ),
    ] = None,
    flow_span: FlowSpanOption = None,
    u_span: DriveSpanOption = None,
    fuel_temp: Annotated[
        float | None,
        typer.Option(
            help="Fuel temperature the model was identified at [°C] (default: the model file's "
            "operating point, else 20 °C, said in the output).",
            show_default=False,
        ),
    ] = None,
    u: Annotated[
        float | None,
        typer.Option(
            "--u",
            help="Command the model was identified around [V] (default: the model file's "
            "operating point, else mid-range).",
            show_default=False,
        ),
    ] = None,
    accept_signals: Annotated[
        bool,
        typer.Option(
            "--accept-signals",
            help="Tune a model file whose identification found the command or the flow outside "
            "the spans the gains are computed for (refused otherwise).",
        ),
    ] = False,
    accept_undetermined: AcceptUndeterminedOption = False,
    t_min: TMinOption = -20.0,
    t_max: TMaxOption = 50.0,
    band_width: BandWidthOption = 10.0,
    ms_target: MsTargetOption = 1.7,
    flow_bands: FlowBandsOption = 3,
    schedule: Annotated[
        bool, typer.Option("--schedule", help="Print the gain schedule over fuel temperature.")
    ] = False,
    simulate: Annotated[
        bool,
        typer.Option(
            "--simulate",
            help="Closed loop on the nonlinear plant at the coldest and warmest fuel "
            "(setpoint step of 10 % span, then a 0.2 V load step).",
        ),
    ] = False,
    sweep: Annotated[
        int | None,
        typer.Option(
            help="Evaluate the gains on N plant variants (temperature and the model's covariance).",
            show_default=False,
        ),
    ] = None,
    plot: Annotated[
        Path | None,
        typer.Option(
            metavar="FIG.png",
            help="Write the figure (PNG, SVG, PDF): the closed-loop figure, or with --schedule "
            "the gain schedule over fuel temperature; an existing file only with --force.",
            show_default=False,
        ),
    ] = None,
    force: ForceFigureOption = False,
    list_rules: Annotated[
        bool, typer.Option("--list-rules", help="List the tuning rules and exit.")
    ] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """PI gains for K·e^(−θs)/((T·s+1)(T2·s+1)(T_f·s+1)) and the evidence they are safe.

    Gains come in engineering units (Kc in V per L/min, Ti in s), in percent of span and in the
    discrete form a PLC block runs. Margins and Ms are computed with the dead time exact and the
    sampled controller included; the gains are also checked over the fuel-temperature range.
    """
    if list_rules:
        _print_rules(as_json)
        return
    from fuelid import workflow
    from fuelid.plant import load_plant_config

    # options checked at the edge, before any work is done
    check_figure_path(plot, overwrite=force)
    _check_run_options(schedule, simulate, sweep)
    tau = closed_loop_time(rule, tau_c, lam)
    check_spans(flow_span, u_span)
    model, loaded = _model_from_options(
        model_file, K, T, T2, T_f, delay, need_cov=sweep is not None
    )
    loose = _check_model_file(loaded, model_file, accept_signals, accept_undetermined)
    if model is None and not schedule:
        raise FuelidError(
            "give a model: --model ident.json, or --K and --T (with --delay, --flowmeter-T), "
            "or --schedule for a schedule from the plant's physics"
        )
    facts = site_facts(site)
    period_sources = {
        "option": control_period,
        "site file": None if facts is None else facts.control_period,
        "model file": None if loaded is None else loaded.control_period,
    }
    period = workflow.control_period_from(*period_sources.values())
    fuel_temp, fuel_source, u, clip_u = _operating_point(fuel_temp, u, loaded)
    if config is None and facts is not None and facts.plant is not None:
        config = facts.plant  # the plant file the site file names
    T_fuel, T_range = temperature_options(
        DEFAULT_FUEL_TEMPERATURE_C if fuel_temp is None else fuel_temp, t_min, t_max
    )
    plant = workflow.PlantSource(load_plant_config(config), None if config is None else str(config))
    request = workflow.TuneRequest(
        model=model,
        rule=rule.value,
        closed_loop_time=tau,
        control_period=period.value,
        control_period_basis=period.basis,
        y_span=flow_span,
        u_span=u_span,
        site_spans=(None, None) if facts is None else facts.spans,
        T_fuel=T_fuel,
        u=u,
        clip_u=clip_u,
        T_range=T_range,
        band_width=band_width,
        ms_target=ms_target,
        flow_bands=flow_bands,
        simulate=simulate,
        sweep=sweep,
        **workflow.model_file_fields(loaded),
    )
    notices = _notices(plant, request, fuel_source, loaded, model_file, loose)
    notices += workflow.overridden(period_sources, "s", period)
    extra = {
        "plant": plant.to_json() | _calibration_json(plant, T_fuel),
        "notices": notices,
        "fuel_temperature_source": fuel_source or "assumed",
        "undetermined": loose,
    }
    options = {
        "model": str(model_file) if model_file else None,
        "K": K,
        "T": T,
        "T2": T2,
        "T_f": T_f,
        "delay": delay,
        "rule": rule.value,
        "tau_c": tau_c,
        "lambda": lam,
        "control_period": control_period,
        "site": str(site) if site else None,
        "config": str(config) if config else None,
        "flow_span": flow_span,
        "u_span": u_span,
        "fuel_temp": fuel_temp,
        "accept_signals": accept_signals,
        "accept_undetermined": accept_undetermined,
        "u": None,  # the command used, filled in by the run
        "t_min": t_min,
        "t_max": t_max,
        "band_width": band_width,
        "ms_target": ms_target,
        "flow_bands": flow_bands,
        "schedule": schedule,
        "simulate": simulate,
        "sweep": sweep,
    }
    output = _Output(plot, as_json, extra, options, model_file, facts)
    if schedule:
        _run_schedule(plant, request, output)
    else:
        _run_tune(plant, request, output, fuel_source or "assumed")


@dataclass(frozen=True)
class _Output:
    """Where and how a run's results go: the figure, JSON or text, and what goes with them."""

    plot: Path | None
    as_json: bool
    extra: dict[str, Any]
    """The JSON's plant, notices, fuel-temperature source and undetermined parameters."""
    options: dict[str, Any]
    model_file: Path | None
    facts: SiteFacts | None


def _run_schedule(plant: PlantSource, request: TuneRequest, output: _Output) -> None:
    """``tune --schedule``: the schedule, its figure, its JSON or its table."""
    from fuelid.workflow import schedule_gains

    with progress_display() as stage:
        table = schedule_gains(plant, request, progress=stage)
    for notice in output.extra["notices"]:  # after the work: a refusal stays one line
        warn(notice)
    if output.plot is not None:
        from fuelid.plots import save_figure, schedule_figure

        save_figure(schedule_figure(table.schedule), output.plot)
    if output.as_json:
        options = output.options | {"u": table.u}
        emit_json(table.to_json() | output.extra | provenance(options, output.model_file))
    else:
        _print_schedule(table, request.control_period_basis, output.facts)


def _run_tune(plant: PlantSource, request: TuneRequest, output: _Output, fuel_source: str) -> None:
    """``tune``: one set of gains and its checks, its figure, its JSON or its text."""
    from fuelid.workflow import tune_model

    with progress_display() as stage:
        outcome = tune_model(plant, request, progress=stage)
    for message in output.extra["notices"] + outcome.warnings:
        warn(message)
    if output.plot is not None:
        from fuelid.plots import save_figure, tune_figure

        save_figure(tune_figure(outcome), output.plot)
    if output.as_json:
        options = output.options | {"u": outcome.u}
        emit_json(outcome.to_json() | output.extra | provenance(options, output.model_file))
        return
    _print_tuning(outcome, fuel_source, output.facts)


def _check_run_options(schedule: bool, simulate: bool, sweep: int | None) -> None:
    """Refuse checks that --schedule does not run, and a sweep of a size out of range."""
    from fuelid.tuning import check_sweep_size

    unused = [n for n, given in (("--simulate", simulate), ("--sweep", sweep is not None)) if given]
    if schedule and unused:
        verb = "checks" if len(unused) == 1 else "check"
        raise FuelidError(
            f"--schedule prints the gain schedule only: {' and '.join(unused)} {verb} one set of "
            "gains, run without --schedule"
        )
    if sweep is not None:
        check_sweep_size(sweep)


def _operating_point(
    fuel_temp: float | None, u: float | None, loaded: FittedModel | None
) -> tuple[float | None, str | None, float | None, bool]:
    """(fuel temperature [°C], its source, command [V], clip it): the options, else the file's.

    The model file's mean command a little outside the drive's range is taken to its end (its
    signal check has said why); a command given with --u is refused there.
    """
    fuel_source = "option" if fuel_temp is not None else None
    if fuel_temp is None and loaded is not None and loaded.fuel_temperature is not None:
        fuel_temp, fuel_source = loaded.fuel_temperature, "model file"
    if u is None and loaded is not None and loaded.u is not None:
        return fuel_temp, fuel_source, loaded.u, True
    return fuel_temp, fuel_source, u, False


def _check_model_file(
    loaded: FittedModel | None,
    model_file: Path | None,
    accept_signals: bool,
    accept_undetermined: bool,
) -> list[str]:
    """Refuse a model file that is no model of the loop; return what it leaves undetermined.

    A flow that moves before its command always; signal findings unless ``accept_signals``;
    a K, T or delay the log does not determine unless ``accept_undetermined``.
    """
    from fuelid.workflow import LEADING_RESPONSE, undetermined, undetermined_refusal_line

    if loaded is None:
        return []
    if loaded.leads:
        raise FuelidError(f"{model_file}: {LEADING_RESPONSE}")
    if loaded.signal_check and not accept_signals:
        raise FuelidError(
            f"{model_file}: its identification's signal check found: "
            f"{'; '.join(loaded.signal_check)}; the gains would be wrong by the same factor "
            "(--accept-signals to tune anyway)"
        )
    loose = undetermined(loaded.model.to_json(), loaded.ci95, loaded.fixed)
    if loose and not accept_undetermined:
        raise FuelidError(undetermined_refusal_line(loose, f"the model of {model_file}"))
    return loose


def _notices(
    plant: PlantSource,
    request: TuneRequest,
    fuel_source: str | None,
    loaded: FittedModel | None,
    model_file: Path | None,
    loose: list[str],
) -> list[str]:
    """The assumptions said first: the library's, the spans' conflicts, an accepted model."""
    from fuelid.workflow import tune_notices, undetermined_refusal

    notices = tune_notices(
        plant,
        request,
        fuel_basis=fuel_source,
        conditional=loaded is not None and loaded.conditional,
        model_label=str(model_file),
    )
    notices += request.span_notes(plant)
    if loose:
        notices.append(
            "accepted (--accept-undetermined): "
            + undetermined_refusal(loose, f"the model of {model_file}")
        )
    return notices


def _calibration_json(plant: PlantSource, T_fuel: float) -> dict[str, Any]:
    """``{"calibration": ...}`` for a calibrated plant file (empty otherwise)."""
    if plant.is_reference or plant.config.calibration is None:
        return {}
    from fuelid.plant import calibration_summary

    return {"calibration": calibration_summary(plant.config, T_fuel)[0]}


def _model_from_options(
    model_file: Path | None,
    K: float | None,
    T: float | None,
    T2: float | None,
    T_f: float | None,
    delay: float | None,
    need_cov: bool = False,
) -> tuple[ProcessModel | None, FittedModel | None]:
    """The model of ``--model`` (with the file's covariance) or of ``--K --T ...``; None: none."""
    from fuelid.io.fitted_model import load_fitted_model
    from fuelid.model import ProcessModel

    flags = {"--K": K, "--T": T, "--T2": T2, "--flowmeter-T (--T-f)": T_f, "--delay": delay}
    given = [name for name, value in flags.items() if value is not None]
    if model_file is not None:
        if given:
            raise FuelidError(f"give either --model or {', '.join(given)}, not both")
        loaded = load_fitted_model(model_file)
        if need_cov and loaded.cov_problem is not None:
            raise FuelidError(
                f"--sweep draws from the covariance of {str(model_file)!r}, but "
                f"{loaded.cov_problem}"
            )
        return loaded.model, loaded
    if not given:
        return None, None
    if K is None or T is None:
        raise FuelidError("a model from flags needs at least --K and --T")
    for name, value in flags.items():
        if value is not None and not math.isfinite(value):
            raise FuelidError(f"{name} must be a finite number")
    if T <= 0.0:
        raise FuelidError(f"--T must be a positive time constant, got {T:g} s")
    for name, value in (("--T2", T2), ("--flowmeter-T (--T-f)", T_f)):
        if value is not None and value < 0.0:
            raise FuelidError(f"{name} must be zero or a positive time constant, got {value:g} s")
    if delay is not None and delay < 0.0:
        raise FuelidError(f"--delay must not be negative, got {delay:g} s")
    return ProcessModel(K=K, T=T, T2=T2 or 0.0, T_f=T_f or 0.0, delay=delay or 0.0), None


def _print_rules(as_json: bool) -> None:
    from fuelid.tuning import TUNING_RULES

    if as_json:
        emit_json(
            {
                "rules": [
                    {
                        "name": r.name,
                        "parameter": r.parameter,
                        "formula": r.summary,
                        "source": r.source,
                    }
                    for r in TUNING_RULES.values()
                ]
            }
        )
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title="PI tuning rules (--rule)")
    for column in ("rule", "tuning parameter", "formula", "source"):
        table.add_column(column)
    for r in TUNING_RULES.values():
        table.add_row(r.name, r.parameter or "none", r.summary, r.source)
    Console().print(table)


def _print_tuning(outcome: TuneOutcome, fuel_source: str, facts: SiteFacts | None) -> None:
    """The gains in every form and their evidence, from the JSON (engineering units).

    ``fuel_source`` says where the model's fuel temperature came from (option, model file,
    assumed); ``facts`` is the site file's controller, whose block form is printed too. Only
    figures about the user's loop are printed (:mod:`fuelid.workflow._trust`).
    """
    from rich.console import Console

    data = outcome.to_json()
    console = Console(emoji=False)
    console.print(_gains_table(outcome, data, facts))
    if data["plc"]["percent_of_span"] is None:
        console.print(f"no %/% gains: {data['spans']['reason']}", highlight=False, markup=False)
    _print_margins(console, data)
    _print_ranges(console, outcome, data, fuel_source)
    for result in outcome.runs:
        run = result.to_json(events=False)
        s = run["summary"]
        console.print(
            f"nonlinear plant at {run['fuel_temperature']:g} °C, setpoint "
            f"{run['start_flow']:.1f} → {result.setpoint[-1]:.1f} L/min: overshoot "
            f"{s['overshoot_percent']:.1f} %, settling {s['settling_time']:.1f} s, load peak "
            f"{s['disturbance_peak']:.2f} L/min, at the limits {s['time_at_limits']:g} s"
        )
    _print_spread(console, data)


def _gains_table(outcome: TuneOutcome, data: dict[str, Any], facts: SiteFacts | None) -> Table:
    """The gains in every form: ideal, percent of span, parallel, velocity, the site's block."""
    from rich.table import Table

    plc, h = data["plc"], data["control_period"]
    period = (
        f"h = {h:g} s ({data['control_period_basis']})"
        if h > 0
        else f"continuous ({data['control_period_basis']})"
    )
    gains = Table(title=f"{data['rule']} PI for {outcome.tuning.model.describe()}, {period}")
    for column in ("form", "gain", "integral", "unit"):
        gains.add_column(column)
    gains.add_row("ideal (ISA)", f"Kc = {data['Kc']:.5g}", f"Ti = {data['Ti']:.4g}", "V/(L/min), s")
    span = plc["percent_of_span"]
    if span is None:
        gains.add_row("percent of span", "spans not given", "", "see below")
    else:
        gains.add_row(
            "percent of span",
            f"Kc = {span['Kc']:.4g}",
            f"Ti = {span['Ti']:.4g} s = {span['Ti_min']:.4g} min",
            f"%/% ({span['u_span']:g} V, {span['y_span']:g} L/min; "
            + _span_basis(data["spans"])
            + ")",
        )
    gains.add_row(
        "parallel",
        f"Kp = {data['Kc']:.5g}",
        f"Ki = {data['Ki']:.5g}",
        "V/(L/min), V/((L/min)·s)",
    )
    if plc["discrete"] is not None:
        d = plc["discrete"]
        gains.add_row(
            "velocity, Δu = q0·e(k) + q1·e(k−1)",
            f"q0 = {d['q0']:.5g}",
            f"q1 = {d['q1']:.5g}",
            "V/(L/min)",
        )
    block = _block_row(outcome, facts)
    if block is not None:
        gains.add_row(*block)
    return gains


def _print_margins(console: Console, data: dict[str, Any]) -> None:
    """The margins, Ms and step response on the model (and its full order), and the misfit's."""
    rob = data["robustness"]
    step = data["closed_loop"]["setpoint_step"]
    settle = step["settling_time"]
    full = data["full_order"]
    if full is not None:
        full_step = full["setpoint_step"]
        console.print(
            f"on the full-order model (the model file's linear_model): gain margin "
            f"{full['gain_margin']:.2f}, phase margin {full['phase_margin_deg']:.1f}°, "
            f"Ms {full['Ms']:.2f}; setpoint step overshoot "
            f"{full_step['overshoot_percent']:.1f} %"
        )
    console.print(
        ("on its reduction" if full is not None else "on the model")
        + f": gain margin {rob['gain_margin']:.2f}, phase margin "
        f"{rob['phase_margin_deg']:.1f}°, Ms {rob['Ms']:.2f}; setpoint step overshoot "
        f"{step['overshoot_percent']:.1f} %, "
        + ("does not settle" if math.isnan(settle) else f"settling {settle:.1f} s")
    )
    misfit = data["misfit_Ms"]
    if misfit is not None:
        console.print(
            f"allowing for the misfit the log shows (up to {misfit['up_to']:.3g} rad/s, 95 %): "
            + ("Ms not bounded" if misfit["Ms"] is None else f"Ms ≤ {misfit['Ms']:.2f}")
            + (
                ""
                if misfit["overshoot_percent"] is None
                else f"; setpoint overshoot {misfit['overshoot_percent']:.1f} % with the misfit"
            ),
            highlight=False,
        )


def _print_ranges(
    console: Console, outcome: TuneOutcome, data: dict[str, Any], fuel_source: str
) -> None:
    """The gains over fuel temperature (the user's plant file) and over the log's commands."""
    check = data["temperature_check"]
    if check is not None:
        fuel = format_celsius(outcome.request.T_fuel)
        anchored = outcome.check is not None and outcome.check.cases[0].case.anchored
        console.print(
            f"model found at u = {outcome.u:.3g} V with the fuel at {fuel} °C "
            f"({fuel_source}): the temperature check is anchored there"
            if anchored
            else "the temperature check runs on your plant file's full linearisation at every "
            "case (the model is its own reduction)"
        )
        cases = check["cases"]
        console.print(
            f"over {cases[0]['fuel_temperature']:g}…{cases[-1]['fuel_temperature']:g}"
            f" °C and the drive range (your plant file): worst Ms {check['worst_Ms']:.2f}, "
            f"worst overshoot {check['worst_overshoot_percent']:.1f} %, smallest gain margin "
            f"{check['worst_gain_margin']:.2f}"
            + ("" if check["all_stable"] else " — UNSTABLE in some case")
        )
    bands = data["command_band_check"]
    if bands is not None:
        low, high = bands["u_range"]
        console.print(
            f"over the log's commands {low:.3g}…{high:.3g} V (K per band, 95 % interval): "
            f"worst Ms {bands['worst_Ms']:.2f}, worst overshoot "
            f"{bands['worst_overshoot_percent']:.1f} %, smallest gain margin "
            f"{bands['worst_gain_margin']:.2f}"
            + ("" if bands["all_stable"] else " — UNSTABLE in some band")
        )
    if check is None:
        console.print(
            "over fuel temperature: not checked, no plant file of yours (--config) says how "
            "the loop moves with it",
            highlight=False,
        )


def _print_spread(console: Console, data: dict[str, Any]) -> None:
    """What the model's uncertainty leaves open: disagreements, other structures, the sweep."""
    for disagreement in data["disagreements"]:
        console.print(f"[bold]DISAGREE:[/bold] {disagreement}", highlight=False)
    spread = data["structure_spread"]
    if spread is not None:
        worst = max(s["Ms_of_chosen_gains"] for s in spread["structures"])
        console.print(
            f"across the {len(spread['structures']) + 1} structures the log could not tell apart:"
            f" Kc {format_interval(spread['Kc'][0], spread['Kc'][1], minimum=4)} V/(L/min), Ti "
            f"{format_interval(spread['Ti'][0], spread['Ti'][1])} s; these gains' Ms on the others "
            f"at most {worst:.2f}",
            highlight=False,
        )
    sweep = data["sweep"]
    if sweep is not None:
        console.print(
            f"{sweep['n']:.0f} variants: worst Ms {sweep['worst_Ms']:.2f} (95 % below "
            f"{sweep['Ms_p95']:.2f}), worst overshoot {sweep['worst_overshoot_percent']:.1f} %, "
            f"unstable {100 * sweep['unstable_fraction']:.1f} %"
        )


def _span_basis(spans: dict[str, Any]) -> str:
    """Where the spans came from, for the %/% row: one basis, or each span's."""
    u, y = spans["u_span"]["basis"], spans["y_span"]["basis"]
    return u if u == y else f"{u}, {y}"


def _block_row(outcome: TuneOutcome, facts: SiteFacts | None) -> tuple[str, str, str, str] | None:
    """The gains as the site's PI block takes them ([controller]), or None without a site."""
    if facts is None or facts.controller is None:
        return None
    from fuelid.tuning import BlockForm, block_units

    block = BlockForm.of(facts.controller)
    kc, ti = outcome.pi.to_block(block)
    units = block_units(block)
    integral = "Ki" if block.form == "parallel" else "Ti"
    return (
        f"your block ({block.form}, site file)",
        f"Kc = {kc:.5g}",
        f"{integral} = {ti:.5g}",
        f"{units['Kc']}, {units['Ti']}",
    )


def _print_schedule(outcome: ScheduleOutcome, period_basis: str, facts: SiteFacts | None) -> None:
    """The schedule table, on the user's plant file (``period_basis``: where h came from).

    With a site file's ``[controller]`` the gains are printed as the block takes them (its form
    and units: Ki for a parallel block, minutes where it counts in minutes); otherwise in
    V per L/min, %/% where the spans are known, and Ti in s. The band holding the model's
    operating point is marked ``*``; each band's design point is said below the table.
    """
    from rich.console import Console

    from fuelid.tuning import BlockForm

    data: dict[str, Any] = outcome.to_json()
    block = None if facts is None or facts.controller is None else BlockForm.of(facts.controller)
    console = Console(emoji=False)
    console.print(_schedule_table(data, period_basis, block))
    for row in data["bands"]:
        if row["operating"]:
            console.print(
                f"* holds the model's operating point ({row['design_u']:.3g} V, "
                f"{row['design_fuel_temperature']:g} °C): designed on the identified model, as "
                "the headline gains are"
                + (
                    ""
                    if row["detune"] == 1.0
                    else f", detuned ×{row['detune']:.3g} to keep Ms ≤ {data['ms_target']:g} "
                    "over the band"
                ),
                highlight=False,
            )
    if block is not None:
        console.print(
            f"gains as your block takes them ({block.form}, site file); Kc V/(L/min) for reference",
            highlight=False,
        )
    console.print(_design_points(data["bands"]), highlight=False)
    if data["y_span"] is None or data["u_span"] is None:
        console.print("no %/% gains: spans not given (--u-span/--flow-span, --site)")
    else:
        console.print(
            f"%/%: Kc·{data['y_span']:g} L/min / {data['u_span']:g} V (the spans of a PLC block)"
        )
    single = data["single_set"]
    if single is not None:
        percent = single["Kc_percent_of_span"]
        console.print(
            f"one set of gains suffices: Kc = {single['Kc']:.4g} V/(L/min)"
            + ("" if percent is None else f" ({percent:.4g} %/%)")
            + f", Ti = {single['Ti']:.3g} s (Ms ≤ {single['Ms']:.2f} over every band)"
        )


def _schedule_table(data: dict[str, Any], period_basis: str, block: BlockForm | None) -> Table:
    """One row per band: its range, design gains (%/% or the block's), Ms and margins."""
    from rich import box
    from rich.table import Table

    from fuelid.tuning import PISettings, block_units

    anchored = data["anchored_to_model"] is not None
    out = Table(
        title=f"{data['rule']} gain schedule, h = {data['control_period']:g} s "
        f"({period_basis}), Ms ≤ "
        f"{data['ms_target']:g}" + (" (anchored to the model)" if anchored else " (plant physics)"),
        box=box.SIMPLE_HEAD,  # nine columns: light rules keep them within 80 characters
        collapse_padding=True,
    )
    if block is None:
        gain_columns: tuple[str, str] = ("Kc %/%", "Ti s")
    else:
        units = block_units(block)
        integral = "Ki" if block.form == "parallel" else "Ti"
        gain_columns = (f"Kc {units['Kc']}", f"{integral} {units['Ti']}")
    columns = ("fuel °C", "u V", "flow L/min", "Kc V/(L/min)", *gain_columns, "Ms", "GM", "PM °")
    for column in columns:
        out.add_column(column, justify="right")
    for row in data["bands"]:
        if block is None:
            percent = row["Kc_percent_of_span"]
            gains = ("—" if percent is None else f"{percent:.4g}", f"{row['Ti']:.3g}")
        else:
            pi = PISettings("schedule", row["Kc"], row["Ti"], data["control_period"])
            kc, ti = pi.to_block(block)
            gains = (f"{kc:.4g}", f"{ti:.4g}")
        out.add_row(
            ("* " if row["operating"] else "") + f"{row['t_low']:g}…{row['t_high']:g}",
            f"{row['u_low']:.2f}…{row['u_high']:.2f}",
            f"{row['flow_low']:.1f}…{row['flow_high']:.1f}",
            f"{row['Kc']:.4g}",
            *gains,
            f"{row['Ms']:.2f}",
            f"{row['gain_margin']:.2f}",
            f"{row['phase_margin_deg']:.1f}",
        )
    return out


def _design_points(bands: list[dict[str, Any]]) -> str:
    """Where each band (but the operating point's) was designed: its most demanding case."""
    others = [row for row in bands if not row["operating"]]
    corner = all(
        math.isclose(row["design_fuel_temperature"], row["t_low"], abs_tol=1e-9)
        and math.isclose(row["design_u"], row["u_low"], abs_tol=1e-9)
        for row in others
    )
    return (
        "each band is designed on its most demanding case (largest K/T)"
        + (
            ": its coldest fuel and lowest command"
            if corner
            else ": "
            + "; ".join(
                f"{row['t_low']:g}…{row['t_high']:g} °C at {row['design_fuel_temperature']:g} "
                f"°C, {row['design_u']:.2f} V"
                for row in others
            )
        )
        + " (JSON design_fuel_temperature, design_u)"
    )
