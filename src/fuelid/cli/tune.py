"""``fuelid tune``: PI gains from a model, their margins, closed-loop checks and a schedule."""

from __future__ import annotations

import enum
import math
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from fuelid.cli._common import check_figure_path, emit_json, guarded, provenance, warn
from fuelid.errors import FuelidError
from fuelid.htmlreport import schedule_figure
from fuelid.io.modelfile import load_model_file
from fuelid.model import ProcessModel
from fuelid.plant import load_plant_config
from fuelid.plots import plot_closed_loop_runs, plot_linear_closed_loop, save_figure
from fuelid.tuning.closedloop import (
    ClosedLoopResult,
    flow_at,
    standard_runs,
)
from fuelid.tuning.result import (
    UNITS,
    TuningResult,
    check_control_period,
    check_tunable,
    evaluate_tuning,
)
from fuelid.tuning.rules import TUNING_RULES
from fuelid.tuning.schedule import (
    Anchor,
    FixedPIEvaluation,
    GainSchedule,
    band_edges,
    evaluate_fixed,
    gain_schedule,
    plant_cases,
    uncertainty_sweep,
)

MAX_SWEEP = 20_000
"""Most plant variants of --sweep (about 30 s on two cores)."""


class RuleChoice(enum.StrEnum):
    """Tuning rules of ``fuelid tune`` (the keys of ``fuelid.tuning.TUNING_RULES``)."""

    simc = "simc"
    isimc = "isimc"
    lambda_ = "lambda"
    amigo = "amigo"


# options fuelid report shares with fuelid tune
RuleOption = Annotated[
    RuleChoice,
    typer.Option(
        help="simc (Skogestad), isimc (improved SIMC), lambda (IMC-PI), amigo "
        "(Åström-Hägglund); see fuelid tune --list-rules."
    ),
]
TauCOption = Annotated[
    float | None,
    typer.Option(
        "--tau-c", help="SIMC closed-loop time constant [s] (default: θ).", show_default=False
    ),
]
LambdaOption = Annotated[
    float | None,
    typer.Option(
        "--lambda",
        help="Lambda-rule closed-loop time constant [s] (default: T1).",
        show_default=False,
    ),
]
ControlPeriodOption = Annotated[
    float, typer.Option(help="PLC control period h [s]; 0 for a continuous controller.")
]
TMinOption = Annotated[float, typer.Option(help="Coldest fuel [°C].")]
TMaxOption = Annotated[float, typer.Option(help="Warmest fuel [°C].")]
BandWidthOption = Annotated[float, typer.Option(help="Temperature band of the schedule [°C].")]
MsTargetOption = Annotated[
    float, typer.Option(help="Largest Ms the schedule accepts in any band [-].")
]
FlowBandsOption = Annotated[
    int, typer.Option(help="Flow bands where the gain depends on the flow (1: none).")
]


def _model_from_options(
    model_file: Path | None,
    K: float | None,
    T: float | None,
    T2: float | None,
    T_f: float | None,
    delay: float | None,
    need_cov: bool = False,
) -> tuple[ProcessModel | None, tuple[str, ...], Any]:
    flags = {"--K": K, "--T": T, "--T2": T2, "--T-f": T_f, "--delay": delay}
    given = [name for name, value in flags.items() if value is not None]
    if model_file is not None:
        if given:
            raise FuelidError(f"give either --model or {', '.join(given)}, not both")
        loaded = load_model_file(model_file)
        if need_cov and loaded.cov_problem is not None:
            raise FuelidError(
                f"--sweep draws from the covariance of {str(model_file)!r}, but "
                f"{loaded.cov_problem}"
            )
        return loaded.model, loaded.cov_names, loaded.cov
    if not given:
        return None, (), None
    if K is None or T is None:
        raise FuelidError("a model from flags needs at least --K and --T")
    for name, value in flags.items():
        if value is not None and not math.isfinite(value):
            raise FuelidError(f"{name} must be a finite number")
    if T <= 0.0:
        raise FuelidError(f"--T must be a positive time constant, got {T:g} s")
    for name, value in (("--T2", T2), ("--T-f", T_f)):
        if value is not None and value < 0.0:
            raise FuelidError(f"{name} must be zero or a positive time constant, got {value:g} s")
    if delay is not None and delay < 0.0:
        raise FuelidError(f"--delay must not be negative, got {delay:g} s")
    model = ProcessModel(K=K, T=T, T2=T2 or 0.0, T_f=T_f or 0.0, delay=delay or 0.0)
    return model, (), None


def rule_speed(rule: RuleChoice, tau_c: float | None, lam: float | None) -> float | None:
    """The rule's tuning parameter from ``--tau-c`` or ``--lambda``, refusing a mismatch."""
    if tau_c is not None and lam is not None:
        raise FuelidError("give --tau-c (SIMC) or --lambda (lambda rule), not both")
    if tau_c is not None and rule not in (RuleChoice.simc, RuleChoice.isimc):
        raise FuelidError(f"--tau-c belongs to the simc and isimc rules, not {rule.value}")
    if lam is not None and rule is not RuleChoice.lambda_:
        raise FuelidError(f"--lambda belongs to the lambda rule, not {rule.value}")
    return tau_c if tau_c is not None else lam


def _run_json(run: ClosedLoopResult) -> dict[str, Any]:
    return {
        "fuel_temperature": run.fuel_temperature,
        "start_flow": float(run.setpoint[0]),
        "summary": run.summary(),
        "events": [e.as_dict() for e in run.events],
    }


@guarded
def tune_command(
    model_file: Annotated[
        Path | None,
        typer.Option(
            "--model",
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
        typer.Option("--T-f", help="Flowmeter lag [s] (default 0).", show_default=False),
    ] = None,
    delay: Annotated[
        float | None,
        typer.Option("--delay", help="Total dead time [s] (default 0).", show_default=False),
    ] = None,
    rule: RuleOption = RuleChoice.simc,
    tau_c: TauCOption = None,
    lam: LambdaOption = None,
    control_period: ControlPeriodOption = 1.0,
    config: Annotated[
        Path | None,
        typer.Option(
            "--config",
            "-c",
            help="Plant TOML: spans, temperature physics and the nonlinear plant (default: the "
            "reference plant).",
            show_default=False,
        ),
    ] = None,
    flow_span: Annotated[
        float | None,
        typer.Option(
            help="Flowmeter span for the %/% gain [L/min] (default: the plant's meter span).",
            show_default=False,
        ),
    ] = None,
    fuel_temp: Annotated[
        float, typer.Option(help="Fuel temperature the model was identified at [°C].")
    ] = 20.0,
    u: Annotated[
        float | None,
        typer.Option(
            "--u",
            help="Command the model was identified around [V] (default: mid-range).",
            show_default=False,
        ),
    ] = None,
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
        typer.Option(help="Write the closed-loop figure (PNG, SVG, PDF).", show_default=False),
    ] = None,
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
    check_figure_path(plot)
    if sweep is not None and not 1 <= sweep <= MAX_SWEEP:
        raise FuelidError(f"--sweep takes 1 to {MAX_SWEEP:,} variants, got {sweep}")
    check_control_period(control_period)
    for name, value in (("--fuel-temp", fuel_temp), ("--t-min", t_min), ("--t-max", t_max)):
        if not math.isfinite(value):
            raise FuelidError(f"{name} must be a finite temperature")
    if not t_min < t_max:
        raise FuelidError(f"--t-min must be below --t-max, got {t_min:g} and {t_max:g} °C")
    speed = rule_speed(rule, tau_c, lam)
    model, cov_names, cov = _model_from_options(
        model_file, K, T, T2, T_f, delay, need_cov=sweep is not None
    )
    if model is not None:
        check_tunable(model, control_period)
    plant = load_plant_config(config)
    u_span = plant.vfd.u_max_V - plant.vfd.u_min_V
    y_span = plant.flowmeter.span_Lpm if flow_span is None else flow_span
    if not (math.isfinite(y_span) and y_span > 0.0):
        raise FuelidError(f"--flow-span must be positive, got {y_span:g} L/min")
    u_op = 0.5 * (plant.vfd.u_min_V + plant.vfd.u_max_V) if u is None else u
    if not plant.vfd.u_min_V <= u_op <= plant.vfd.u_max_V:
        raise FuelidError(f"--u {u_op:g} V lies outside the drive's signal range")
    anchor = Anchor(model, fuel_temp, u_op) if model is not None else None
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
        "config": str(config) if config else None,
        "flow_span": y_span,
        "fuel_temp": fuel_temp,
        "u": u_op,
        "t_min": t_min,
        "t_max": t_max,
        "band_width": band_width,
        "ms_target": ms_target,
        "flow_bands": flow_bands,
        "schedule": schedule,
        "simulate": simulate,
        "sweep": sweep,
    }
    if schedule:
        table = gain_schedule(
            plant,
            rule.value,
            control_period,
            speed,
            t_range=(t_min, t_max),
            band_width=band_width,
            ms_target=ms_target,
            flow_bands=flow_bands,
            anchor=anchor,
        )
        if plot is not None:
            save_figure(schedule_figure(table), plot)
        if as_json:
            payload = table.as_dict() | {
                "anchored_to_model": model.as_dict() if model is not None else None,
                "units": UNITS,
            }
            emit_json(payload | provenance(options, model_file))
        else:
            _print_schedule(table, model is not None)
        return
    if model is None:
        raise FuelidError(
            "give a model: --model ident.json, or --K and --T (with --delay, --T-f), "
            "or --schedule for a schedule from the plant's physics"
        )
    result = evaluate_tuning(model, rule.value, control_period, speed, u_span, y_span)
    temps = tuple(float(t) for t in band_edges(t_min, t_max, band_width))
    commands = (plant.vfd.u_min_V, u_op, plant.vfd.u_max_V)
    check = evaluate_fixed(result.pi, plant_cases(plant, temps, commands, anchor))
    runs = []
    if simulate:
        start = flow_at(plant, u_op, fuel_temp)
        runs = standard_runs(plant, result.pi, (t_min, t_max), start, 0.1 * y_span)
    for message in result.warnings:
        warn(message)
    sweep_summary = None
    if sweep is not None:
        assert anchor is not None
        cov_array = np.asarray(cov if cov is not None else np.zeros((0, 0)), dtype=float)
        sweep_summary = uncertainty_sweep(
            result.pi, anchor, cov_names, cov_array, plant, n=sweep, t_range=(t_min, t_max)
        ).summary()
    if plot is not None:
        if runs:
            fig = plot_closed_loop_runs(
                [
                    (f"{r.fuel_temperature:g} °C", r.time, r.setpoint, r.flow, r.command)
                    for r in runs
                ],
                f"{rule.value} PI on the nonlinear plant",
            )
        else:
            cl = result.closed_loop
            fig = plot_linear_closed_loop(
                cl.time,
                cl.setpoint_response,
                cl.setpoint_command,
                cl.disturbance_response,
                f"{rule.value}: Kc = {result.pi.Kc:.4g} V/(L/min), Ti = {result.pi.Ti:.3g} s, "
                f"Ms = {result.robustness.Ms:.2f}",
            )
        save_figure(fig, plot)
    if as_json:
        payload = result.to_json() | {
            "temperature_check": {
                "worst_Ms": check.worst_Ms,
                "worst_overshoot_percent": check.worst_overshoot,
                "worst_gain_margin": check.worst_gain_margin,
                "worst_phase_margin_deg": check.worst_phase_margin,
                "all_stable": check.all_stable,
                "cases": check.rows(),
            },
            "closed_loop_plant": [_run_json(r) for r in runs] if runs else None,
            "sweep": sweep_summary,
            "units": UNITS,
        }
        emit_json(payload | provenance(options, model_file))
        return
    _print_tuning(result, check, runs, sweep_summary)


def _print_rules(as_json: bool) -> None:
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
    table = Table(title="PI tuning rules (--rule)")
    for column in ("rule", "tuning parameter", "formula", "source"):
        table.add_column(column)
    for r in TUNING_RULES.values():
        table.add_row(r.name, r.parameter or "none", r.summary, r.source)
    Console().print(table)


def _print_tuning(
    result: TuningResult,
    check: FixedPIEvaluation,
    runs: list[ClosedLoopResult],
    sweep: dict[str, float] | None,
) -> None:
    data = result.to_json()
    plc = data["plc"]
    h = data["control_period"]
    console = Console()
    gains = Table(
        title=f"{data['rule']} PI for K = {result.model.K:.4g} (L/min)/V, T = "
        f"{result.model.T:.3g} s, delay = {result.model.delay:.3g} s, "
        + (f"h = {h:g} s" if h > 0 else "continuous")
    )
    for column in ("form", "gain", "integral", "unit"):
        gains.add_column(column)
    gains.add_row("ideal (ISA)", f"Kc = {data['Kc']:.5g}", f"Ti = {data['Ti']:.4g}", "V/(L/min), s")
    span = plc["percent_of_span"]
    gains.add_row(
        "percent of span",
        f"Kc = {span['Kc']:.4g}",
        f"Ti = {span['Ti']:.4g}",
        f"%/% ({span['u_span']:g} V, {span['y_span']:g} L/min), s",
    )
    gains.add_row("parallel", f"Kp = {data['Kc']:.5g}", f"Ki = {data['Ki']:.5g}", "V/(L/min), 1/s")
    if plc["discrete"] is not None:
        d = plc["discrete"]
        gains.add_row(
            "velocity, Δu = q0·e(k) + q1·e(k−1)",
            f"q0 = {d['q0']:.5g}",
            f"q1 = {d['q1']:.5g}",
            "V/(L/min)",
        )
    console.print(gains)
    rob = data["robustness"]
    settle = data["closed_loop"]["setpoint_step"]["settling_time"]
    console.print(
        f"on the model: gain margin {rob['gain_margin']:.2f}, phase margin "
        f"{rob['phase_margin_deg']:.1f}°, Ms {rob['Ms']:.2f}; setpoint step overshoot "
        f"{data['closed_loop']['setpoint_step']['overshoot_percent']:.1f} %, "
        + ("does not settle" if math.isnan(settle) else f"settling {settle:.1f} s")
    )
    console.print(
        f"over {check.cases[0].case.fuel_temperature:g}…{check.cases[-1].case.fuel_temperature:g}"
        f" °C and the drive range: worst Ms {check.worst_Ms:.2f}, worst overshoot "
        f"{check.worst_overshoot:.1f} %, smallest gain margin {check.worst_gain_margin:.2f}"
        + ("" if check.all_stable else " — UNSTABLE in some case")
    )
    for run in runs:
        s = run.summary()
        console.print(
            f"nonlinear plant at {run.fuel_temperature:g} °C, setpoint "
            f"{run.setpoint[0]:.1f} → {run.setpoint[-1]:.1f} L/min: overshoot "
            f"{s['overshoot_percent']:.1f} %, settling {s['settling_time']:.1f} s, load peak "
            f"{s['disturbance_peak']:.2f} L/min, at the limits {s['time_at_limits']:g} s"
        )
    if sweep is not None:
        console.print(
            f"{sweep['n']:.0f} variants: worst Ms {sweep['worst_Ms']:.2f} (95 % below "
            f"{sweep['Ms_p95']:.2f}), worst overshoot {sweep['worst_overshoot_percent']:.1f} %, "
            f"unstable {100 * sweep['unstable_fraction']:.1f} %"
        )


def _print_schedule(table: GainSchedule, anchored: bool) -> None:
    out = Table(
        title=f"{table.rule} gain schedule, h = {table.control_period:g} s, Ms ≤ "
        f"{table.ms_target:g}" + (" (anchored to the model)" if anchored else " (plant physics)")
    )
    for column in ("fuel °C", "u V", "flow L/min", "Kc V/(L/min)", "Ti s", "Ms", "GM", "PM °"):
        out.add_column(column, justify="right")
    for band in table.bands:
        row = band.as_dict()
        out.add_row(
            f"{row['t_low']:g}…{row['t_high']:g}",
            f"{row['u_low']:.2f}…{row['u_high']:.2f}",
            f"{row['flow_low']:.1f}…{row['flow_high']:.1f}",
            f"{row['Kc']:.4g}",
            f"{row['Ti']:.3g}",
            f"{row['Ms']:.2f}",
            f"{row['gain_margin']:.2f}",
            f"{row['phase_margin_deg']:.1f}",
        )
    Console().print(out)
