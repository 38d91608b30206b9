"""Benchmark: the designed test signal against a PRBS at the same standard error of K.

Issue 40, item 5: for each loop, the signal the service designs
(:func:`fuelid.online.excitation._design.design_signal`: a generalized binary noise whose hold
and sequence are chosen on the loop's model in closed loop) and a maximum-length PRBS clocked at
the PLC's control period (the usual default), both over the same burst (``max_share`` 0.3 of a
10-minute window) and each at the smallest amplitude that brings the expected standard error of
K to the same 4 % (0.8 × the 5 % gate; T and the fit not asked for, so that only K decides).
The cost is the flow variance the signal adds over the window, on the model with the PI in
force (SIMC, τc = θ, at h = 1 s); the target is a ratio of at most 0.5. The expected standard
errors are the Cramér–Rao bound of the window's fit (K, T, the dead time and the offset free),
checked against output-error fits in tests/unit/online/test_excitation_design.py.

Loops: the reference plant at three commands and the fuel's extremes (its linearised model), and
three held-out first-order-plus-delay loops slower and faster than it; noise white (0.1 L/min)
and coloured (AR(1), pole 0.98 per 20 ms sample, the same standard deviation). Run on demand:

    .venv/bin/python benchmarks/bench_excitation.py
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from _docs_table import run_to_docs
from fuelid.identify import ResidualAR
from fuelid.model import ProcessModel
from fuelid.online.excitation._design import DesignGoal, LoopNoise, design_signal, prbs_design
from fuelid.tuning import simc

PERIOD_S = 0.02
WINDOW_S = 600.0
BURST_S = 180.0
SIGMA = 0.1
TARGET_RATIO = 0.5


def _reference_loops() -> list[tuple[str, ProcessModel]]:
    from fuelid.plant import linearise, load_plant_config
    from fuelid.units import celsius_to_kelvin

    config = load_plant_config()
    loops = []
    for u, T_C in ((2.0, 20.0), (3.0, 20.0), (4.0, 20.0), (3.0, 5.0), (3.0, 40.0)):
        model = linearise(config, u, celsius_to_kelvin(T_C)).equivalent_model().model
        loops.append((f"reference {u:g} V, {T_C:g} °C", model))
    return loops


HELD_OUT = (
    ("held-out slow", ProcessModel(K=5.0, T=8.0, T_f=0.3, delay=1.0)),
    ("held-out mid", ProcessModel(K=20.0, T=3.0, delay=0.5)),
    ("held-out fast", ProcessModel(K=8.0, T=0.6, T_f=0.2, delay=0.3)),
)


def _noises() -> list[tuple[str, LoopNoise]]:
    pole = 0.98
    innovation = SIGMA * math.sqrt(1.0 - pole**2)
    coloured = LoopNoise(ResidualAR(np.array([1.0, -pole]), innovation, {1: 0.0}), SIGMA, SIGMA)
    return [("white", LoopNoise.white(SIGMA)), ("AR(1) 0.98", coloured)]


def main() -> int:
    goal = DesignGoal(max_rel_stderr_T=math.inf, min_fit_percent=-math.inf)
    kwargs = {"period_s": PERIOD_S, "window_s": WINDOW_S, "burst_s": BURST_S}
    header = (
        f"{'loop':<26} {'noise':<11} {'K':>6} {'T s':>5} {'θ s':>5} | {'GBN V':>7} "
        f"{'hold s':>6} {'sd L/min':>8} | {'PRBS V':>7} {'sd L/min':>8} | {'var ratio':>9} "
        f"{'design s':>8}"
    )
    print(header)
    print("-" * len(header))
    ratios = []
    for name, model in _reference_loops() + list(HELD_OUT):
        pi = simc(model, control_period=1.0)
        for noise_name, noise in _noises():
            started = time.perf_counter()
            designed = design_signal(model, pi, noise, goal, amplitude_cap_V=10.0, **kwargs)
            seconds = time.perf_counter() - started
            prbs = prbs_design(model, pi, noise, goal, **kwargs)
            ratio = (designed.added_flow_sd_Lpm / prbs.added_flow_sd_Lpm) ** 2
            ratios.append(ratio)
            print(
                f"{name:<26} {noise_name:<11} {model.K:>6.3g} {model.T:>5.3g} "
                f"{model.delay:>5.3g} | {designed.amplitude_V:>7.3g} {designed.hold_s:>6g} "
                f"{designed.added_flow_sd_Lpm:>8.3g} | {prbs.amplitude_V:>7.3g} "
                f"{prbs.added_flow_sd_Lpm:>8.3g} | {ratio:>9.2f} {seconds:>8.2f}"
            )
    met = sum(r <= TARGET_RATIO for r in ratios)
    print()
    print(
        f"same expected se(K) (4 %): the designed signal's added flow variance over the PRBS's, "
        f"median {np.median(ratios):.2f}, worst {max(ratios):.2f}; at most {TARGET_RATIO:g} on "
        f"{met} of {len(ratios)} loops × noises"
    )
    return 0


if __name__ == "__main__":
    sys.exit(run_to_docs("excitation", main, __doc__))
