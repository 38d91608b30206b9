"""fuelid demo on the built-in reference plant (what ``make demo`` runs).

1. The plant's operating point and equivalent model over the fuel-temperature range: the gain K
   drifts with viscosity, the settling time hardly moves (the article's observation).
2. PLC-like logs from the nonlinear plant: the article's 1 V → 1.5 V step and a step sequence.
3. Identification of the step-sequence log with the article's step-response least squares and
   the output-error fit, side by side.
4. PI gains (SIMC, 1 s PLC period) from the output-error model, in every PLC form, with their
   margins; the same gains checked over −20…50 °C fuel, on the nonlinear plant at the coldest and
   warmest fuel, and a gain schedule that keeps Ms ≤ 1.7 everywhere.
5. Figures (step responses at the coldest and warmest fuel, the simulated logs) and the HTML
   report of the step-sequence log with its figures.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from fuelid.htmlreport import write_report
from fuelid.io.logs import load_log
from fuelid.plant import linearise, load_plant_config
from fuelid.plant.simulate import simulate
from fuelid.plots import plot_log, plot_step_responses, save_figure
from fuelid.profiles import step_profile, step_sequence
from fuelid.units import LPM_PER_M3S, PA_PER_MPA, celsius_to_kelvin, kelvin_to_celsius
from fuelid.workflow import T_REF, AnalysisSettings, LogAnalysis, PlantSource, analyse_log

TEMPERATURES_DEGC = (-20.0, 0.0, 20.0, 35.0, 50.0)
U_ARTICLE = 1.25  # middle of the article's 1 V → 1.5 V step


def main() -> None:
    """Run the demo and write its files to --out."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("demo-output"))
    args = parser.parse_args()
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    console = Console()
    config = load_plant_config()

    table = Table(
        title=f"reference plant, RP-3 fuel, u = {U_ARTICLE} V (K in (L/min)/V, times in s)"
    )
    for column in ("fuel °C", "q L/min", "p MPa", "rpm", "K", "T", "T_f", "delay", "t98"):
        table.add_column(column, justify="right")
    models = {}
    for t_degC in TEMPERATURES_DEGC:
        linear = linearise(config, U_ARTICLE, celsius_to_kelvin(t_degC))
        eq = linear.equivalent_model()
        models[t_degC] = (linear, eq)
        op = linear.operating_point
        m = eq.model
        table.add_row(
            f"{t_degC:g}",
            f"{op.q * LPM_PER_M3S:.2f}",
            f"{op.p_pump / PA_PER_MPA:.4f}",
            f"{op.speed_rpm:.0f}",
            f"{m.K:.3f}",
            f"{m.T:.3f}",
            f"{m.T_f:.2f}",
            f"{m.delay:.2f}",
            f"{eq.settling_time:.2f}",
        )
    console.print(table)
    k_cold = models[TEMPERATURES_DEGC[0]][1].model.K
    k_warm = models[TEMPERATURES_DEGC[-1]][1].model.K
    console.print(
        f"K falls by {100 * (1 - k_warm / k_cold):.1f} % from {TEMPERATURES_DEGC[0]:g} °C to "
        f"{TEMPERATURES_DEGC[-1]:g} °C: warm fuel leaks more through the pump's clearances."
    )

    # the article's experiment: hold 1 V until steady, step to 1.5 V
    article = simulate(config, step_profile(1.0, 1.5, t_step=10.0, duration=60.0), seed=1)
    article_log = article.to_log(include_truth=True)
    article_log.write(out / "step_1V_to_1.5V.csv", overwrite=True)
    sequence = simulate(
        config, step_sequence([1.0, 1.5, 2.5, 2.0, 3.5, 3.0, 1.5], dwell=30.0), seed=2
    )
    sequence_log = sequence.to_log(include_truth=True)
    sequence_log.write(out / "step_sequence.csv", overwrite=True)

    # step responses: nonlinear 1 → 1.5 V step (per volt) against the linear models
    t = np.arange(0.0, 15.0, 0.02)
    curves = []
    settle = []
    for t_degC in (TEMPERATURES_DEGC[0], TEMPERATURES_DEGC[-1]):
        linear, eq = models[t_degC]
        run = simulate(
            config,
            step_profile(1.0, 1.5, t_step=5.0, duration=20.0),
            T_fuel=celsius_to_kelvin(t_degC),
            noise_std=0.0,
            resolution=0.0,
        )
        after = run.time >= 5.0
        dq = (run.q_meter[after] - run.q_meter[0]) * LPM_PER_M3S / 0.5
        curves.append((f"nonlinear plant, {t_degC:g} °C", np.interp(t, run.time[after] - 5.0, dq)))
        curves.append((f"linearised at {U_ARTICLE} V, {t_degC:g} °C", linear.step_response(t)))
        curves.append((f"equivalent model, {t_degC:g} °C", eq.model.step_response(t)))
        settle.append(eq.settling_time)
    figures = [
        save_figure(
            plot_step_responses(t, curves, settle, "1 V → 1.5 V step, coldest and warmest fuel"),
            out / "step_responses.png",
        ),
        save_figure(plot_log(article_log, "simulated PLC log: 1 V → 1.5 V"), out / "step_log.png"),
        save_figure(
            plot_log(sequence_log, "simulated PLC log: step sequence"), out / "sequence_log.png"
        ),
    ]
    # the whole chain on the step-sequence log: identify (the article's method beside the
    # output-error fit), tune, check over fuel temperature, schedule, report
    data = load_log(out / "step_sequence.csv")
    # the logs were simulated on the reference plant, so its plant file is this loop's: it gives
    # the flowmeter priors and the nonlinear runs (a real log needs its own plant's file)
    plant = PlantSource(config, "reference_plant.toml (packaged)")
    # the log's 20 °C; the article's PLC runs its PI every second
    analysis = analyse_log(data, plant, AnalysisSettings(T_fuel=T_REF, control_period=1.0))
    ident = Table(title="identified from step_sequence.csv (fit on 70 %, validated on 30 %)")
    for column in ("method", "K (L/min)/V", "± se", "T s", "± se", "fit %", "validation %"):
        ident.add_column(column, justify="right")
    for method, result in analysis.identifications.items():
        m = result.model
        ident.add_row(
            method,
            f"{m.K:.3f}",
            f"{result.stderr['K']:.3f}",
            f"{m.T:.3f}",
            f"{result.stderr['T']:.3f}",
            f"{result.fit_percent:.2f}",
            f"{result.validation_fit_percent:.2f}",
        )
    console.print(ident)
    console.print(
        "plant gain over the logged range (plant info): "
        + ", ".join(
            f"{u:g} V: {linearise(config, u, T_REF).static_gain:.2f}" for u in (1.5, 2.5, 3.5)
        )
        + " (L/min)/V; the identified K is an average over the levels visited."
    )
    console.print(_summary(analysis))
    report = out / "report.html"
    written = write_report(analysis, report, overwrite=True)
    console.print(f"logs:    {out / 'step_1V_to_1.5V.csv'}, {out / 'step_sequence.csv'}")
    console.print("figures: " + ", ".join(str(f) for f in [*figures, *written[1:]]))
    console.print(f"report:  {report}")


def _summary(analysis: LogAnalysis) -> Table:
    """The story in one table: model, gains, margins, the check over temperature, the plant."""
    pi, rob, check = analysis.tuning.pi, analysis.tuning.robustness, analysis.check
    assert check is not None  # the reference plant's own file: its temperature check
    model = analysis.model_result.model
    plc = analysis.tuning.to_json()["plc"]
    table = Table(title="from the log to the PLC (SIMC, PLC period 1 s)", show_header=False)
    table.add_column("what", justify="left")
    table.add_column("result", justify="left")
    table.add_row(
        "model (oe)",
        f"K = {model.K:.3f} (L/min)/V, T = {model.T:.3f} s, T_f = {model.T_f:g} s, "
        f"delay = {model.delay:g} s",
    )
    table.add_row(
        "PI gains",
        f"Kc = {pi.Kc:.4f} V/(L/min) ({plc['percent_of_span']['Kc']:.3f} %/%), Ti = {pi.Ti:.2f} s",
    )
    table.add_row(
        "on the model",
        f"GM {rob.gain_margin:.2f}, PM {rob.phase_margin_deg:.1f}°, Ms {rob.Ms:.2f}",
    )
    low, high = (kelvin_to_celsius(T) for T in analysis.settings.T_range)
    table.add_row(
        f"fixed gains, {low:g}…{high:g} °C",
        f"worst Ms {check.worst_Ms:.2f}, worst overshoot {check.worst_overshoot:.1f} %, "
        + ("stable everywhere" if check.all_stable else "UNSTABLE somewhere"),
    )
    for run in analysis.runs:
        s = run.summary()
        table.add_row(
            f"nonlinear plant, {kelvin_to_celsius(run.T_fuel):g} °C",
            f"overshoot {s['overshoot_percent']:.1f} %, settling {s['settling_time']:.1f} s, "
            f"load peak {s['disturbance_peak']:.2f} L/min",
        )
    schedule = analysis.schedule
    table.add_row(
        "gain schedule",
        f"{len(schedule.bands)} bands, Kc {min(b.pi.Kc for b in schedule.bands):.4f}…"
        f"{max(b.pi.Kc for b in schedule.bands):.4f} V/(L/min), worst Ms {schedule.worst_Ms:.2f} "
        f"(target {schedule.ms_target:g})",
    )
    return table


if __name__ == "__main__":
    main()
