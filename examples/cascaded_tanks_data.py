"""Simulate a pair of cascaded tanks like the public benchmark's, and write its two records.

    python examples/cascaded_tanks_data.py OUT_DIR [--seed 42] [--noise 0.03]

writes ``OUT_DIR/cascaded_tanks_estimation.csv`` and ``OUT_DIR/cascaded_tanks_validation.csv``
(1024 samples each, 4 s apart, like the cascaded-tanks benchmark of Schoukens & Noël, 2017) with
the columns ``t_s`` (time [s]), ``u_V`` (pump voltage [V]) and ``y_V`` (the lower tank's level
sensor [V]). Generated data are not committed: run this script to make them.

The input is, as the benchmark's, a random-phase multisine with its power below 0.0144 Hz (a
low-pass band), scaled to swing over the pump's 0…10 V; the two records are two realisations
(other phases). The plant that makes the data is richer than the model a user writes for it
(``cascaded_tanks.py``), so that fitting that model leaves a model error, as on the real record:

- each tank drains as a·x^0.55 plus a small laminar leak, not exactly Torricelli's a·√x;
- the upper tank's rim is at X_MAX = 10 (in the sensor's volts): above it a pipe drains the
  excess within seconds (a steep kink, not the user's switch), and OVERFLOW_SHARE of what spills
  falls into the lower tank, the rest is lost;
- the pump's flow per volt drifts slowly (a first-order random process, ±PUMP_DRIFT relative,
  time constant 300 s), which no model of the record can follow;
- the sensor reads the lower level plus an offset C, saturates at 10 V, and adds white noise.

Each record says in how many samples the upper tank overflows and the sensor is clipped.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

DT = 4.0  # sample interval [s]
N_SAMPLES = 1024
F_MAX = 0.0144  # highest multisine frequency [Hz], as the benchmark's
TRUE = {"k1": 0.055, "k2": 0.050, "k3": 0.048, "k4": 0.028, "leak": 0.002}
"""Outflow and pump coefficients of the plant (the sensor's volts as level unit)."""
EXPONENT = 0.55  # the outflows' power of the level (Torricelli: 0.5)
X_MAX = 10.0  # the upper tank's rim [V of level]
K_SPILL = 2.0  # the overflow pipe above the rim [1/s]: drains the excess within seconds
OVERFLOW_SHARE = 0.4  # the share of the spill that falls into the lower tank
C = 0.6  # the sensor's offset [V]
Y_MAX = 10.0  # the sensor saturates here [V]
PUMP_DRIFT = 0.05  # the pump gain's slow drift, relative standard deviation
DRIFT_TIME = 300.0  # its time constant [s]


def multisine(rng: np.random.Generator, n: int = N_SAMPLES) -> np.ndarray:
    """A random-phase multisine over one period of n samples, power below F_MAX, on 0…10 V."""
    freqs = np.arange(1, n // 2) / (n * DT)
    band = freqs <= F_MAX
    phases = rng.uniform(0.0, 2.0 * math.pi, int(band.sum()))
    t = np.arange(n) * DT
    # amplitudes falling as 1/f: a low-pass multisine, most of its power where the tanks follow
    amplitude = freqs[0] / freqs[band]
    waves = np.cos(2.0 * math.pi * np.outer(t, freqs[band]) + phases)
    signal = waves @ amplitude
    signal = signal / np.max(np.abs(signal))  # −1…1
    return np.clip(5.0 + 4.6 * signal, 0.0, 10.0)


def pump_gain(rng: np.random.Generator, n: int = N_SAMPLES) -> np.ndarray:
    """The pump's flow per volt at each sample: k4 times a slow first-order drift around 1."""
    a = math.exp(-DT / DRIFT_TIME)
    drift = np.empty(n)
    drift[0] = rng.normal(0.0, PUMP_DRIFT)
    for k in range(1, n):
        drift[k] = a * drift[k - 1] + math.sqrt(1.0 - a * a) * rng.normal(0.0, PUMP_DRIFT)
    return TRUE["k4"] * (1.0 + drift)


def rhs(t: float, x: np.ndarray, inflow: float) -> list[float]:
    """The plant: power-law outflows with a leak, a steep overflow pipe above the upper rim."""
    x1, x2 = max(x[0], 0.0), max(x[1], 0.0)
    out1 = TRUE["k1"] * x1**EXPONENT + TRUE["leak"] * x1
    into2 = TRUE["k2"] * x1**EXPONENT + TRUE["leak"] * x1
    spill = K_SPILL * max(x[0] - X_MAX, 0.0)
    dx1 = inflow - out1 - spill
    dx2 = into2 - TRUE["k3"] * x2**EXPONENT - TRUE["leak"] * x2 + OVERFLOW_SHARE * spill
    return [dx1, dx2]


def simulate(u: np.ndarray, gain: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """Both levels at every sample, the input held between samples (LSODA, tight tolerance)."""
    x = np.array(x0, dtype=float)
    out = np.empty((len(u), 2))
    for k in range(len(u)):
        out[k] = x
        step = solve_ivp(
            rhs, (0.0, DT), x, args=(gain[k] * u[k],), method="LSODA", rtol=1e-9, atol=1e-10
        )
        x = step.y[:, -1]
    return out


def write_record(path: Path, u: np.ndarray, y: np.ndarray) -> None:
    """A CSV record: t_s, u_V, y_V."""
    frame = pd.DataFrame({"t_s": np.arange(len(u)) * DT, "u_V": u, "y_V": y})
    frame.to_csv(path, index=False, float_format="%.6g")


def main() -> None:
    """Write the estimation and validation records."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path, help="folder to write the two CSV records into")
    parser.add_argument("--seed", type=int, default=42, help="random seed (default 42)")
    parser.add_argument("--noise", type=float, default=0.03, help="sensor noise [V] (0.03)")
    args = parser.parse_args()
    args.out_dir.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    for name in ("cascaded_tanks_estimation.csv", "cascaded_tanks_validation.csv"):
        u = multisine(rng)
        levels = simulate(u, pump_gain(rng), np.array([3.0, 4.0]))
        sensor = np.minimum(levels[:, 1] + C, Y_MAX)
        y = sensor + rng.normal(0.0, args.noise, len(u))
        write_record(args.out_dir / name, u, y)
        print(
            f"wrote {args.out_dir / name} ({len(u)} samples, {DT:g} s apart; upper tank over "
            f"its rim in {int(np.sum(levels[:, 0] > X_MAX))}, sensor clipped in "
            f"{int(np.sum(sensor >= Y_MAX))})"
        )


if __name__ == "__main__":
    main()
