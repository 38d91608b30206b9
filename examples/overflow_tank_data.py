"""Simulate the tank of ``overflow_tank.py`` and write an estimation and a validation log.

    python examples/overflow_tank_data.py OUT_DIR [--seed 1] [--noise 0.01] [--max-voltage 0.95]

writes ``OUT_DIR/overflow_tank_estimation.csv`` (600 s) and ``OUT_DIR/overflow_tank_validation.csv``
(400 s) with the columns ``t_s`` (time [s], 1 s samples), ``u_V`` (pump voltage [V], random steps
0.4…MAX_VOLTAGE held 30 to 90 s) and ``level_m`` (the level [m] with white measurement noise). The
true parameters are a = 0.2 m/(s·V), b = 0.1 m^0.5/s and c = 0.3 1/s; the steady level (a·u/b)²
below the rim is 0.64 m at 0.4 V and would be 3.6 m at 0.95 V, so with the default voltages the
level crosses the rim (2 m) and the overflow pipe runs; with ``--max-voltage 0.65`` it never
reaches the rim. Each log says in how many samples the level is above the rim. Generated data are
not committed: run this script to make them.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

TRUE = {"a": 0.2, "b": 0.1, "c": 0.3}
"""The parameter values the logs are simulated with."""
RIM = 2.0  # the overflow pipe's rim [m], as in overflow_tank.py


def rhs(t: float, x: np.ndarray, u: float, p: dict[str, float]) -> list[float]:
    """The model of overflow_tank.py."""
    level = max(x[0], 0.0)
    return [p["a"] * u - p["b"] * math.sqrt(level) - p["c"] * max(x[0] - RIM, 0.0)]


def input_steps(rng: np.random.Generator, n_samples: int, high: float) -> np.ndarray:
    """Random pump voltages 0.4…high V, each held 30 to 90 samples."""
    u = np.empty(n_samples)
    k = 0
    while k < n_samples:
        hold = int(rng.integers(30, 91))
        u[k : k + hold] = rng.uniform(0.4, high)
        k += hold
    return u


def simulate(u: np.ndarray, x0: float, dt: float = 1.0) -> np.ndarray:
    """The level at every sample, the input held between samples.

    DOP853 at a tight tolerance: its error control finds the kink at the rim by rejecting the
    steps that straddle it.
    """
    x = np.array([x0])
    out = np.empty(len(u))
    for k, u_k in enumerate(u):
        out[k] = x[0]
        step = solve_ivp(
            rhs, (0.0, dt), x, args=(u_k, TRUE), method="DOP853", rtol=1e-10, atol=1e-12
        )
        x = step.y[:, -1]
    return out


def write_log(path: Path, u: np.ndarray, level: np.ndarray, dt: float = 1.0) -> None:
    """A CSV log: t_s, u_V, level_m."""
    frame = pd.DataFrame({"t_s": np.arange(len(u)) * dt, "u_V": u, "level_m": level})
    frame.to_csv(path, index=False, float_format="%.6g")


def main() -> None:
    """Write the estimation (600 s) and validation (400 s) logs."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path, help="folder to write the two CSV logs into")
    parser.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    parser.add_argument(
        "--noise", type=float, default=0.01, help="level noise standard deviation [m]"
    )
    parser.add_argument(
        "--max-voltage",
        type=float,
        default=0.95,
        help="highest pump voltage [V] (default 0.95; 0.65 keeps the level below the rim)",
    )
    args = parser.parse_args()
    args.out_dir.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    for name, n_samples, x0 in (
        ("overflow_tank_estimation.csv", 600, 1.0),
        ("overflow_tank_validation.csv", 400, 1.5),
    ):
        u = input_steps(rng, n_samples, args.max_voltage)
        clean = simulate(u, x0)
        level = clean + rng.normal(0.0, args.noise, n_samples)
        write_log(args.out_dir / name, u, level)
        above = int(np.sum(clean > RIM))
        print(
            f"wrote {args.out_dir / name} ({n_samples} samples, 1 s apart; "
            f"level above the rim in {above})"
        )


if __name__ == "__main__":
    main()
