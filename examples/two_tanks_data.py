"""Simulate the two tanks of ``two_tanks.py`` and write an estimation and a validation log.

    python examples/two_tanks_data.py OUT_DIR [--seed 1] [--noise 0.01]

writes ``OUT_DIR/two_tanks_estimation.csv`` and ``OUT_DIR/two_tanks_validation.csv`` with the
columns ``t_s`` (time [s], 1 s samples), ``u_V`` (pump voltage [V], random steps held 40 to 120 s)
and ``h2_dm`` (the lower level [dm] with white measurement noise). The true parameters are
k1 = 0.05, k2 = 0.04, k3 = 0.05 [dm^0.5/s] and k4 = 0.06 [dm/(s·V)]; the tanks start part full,
not at rest. Generated data are not committed: run this script to make them.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

TRUE = {"k1": 0.05, "k2": 0.04, "k3": 0.05, "k4": 0.06}
"""The parameter values the logs are simulated with."""
H_MAX = 10.0  # rim of each tank [dm], as in two_tanks.py
K_OVERFLOW = 1.0  # overflow pipe above each rim [1/s], as in two_tanks.py


def rhs(t: float, x: np.ndarray, u: float, p: dict[str, float]) -> list[float]:
    """The model of two_tanks.py, for one state."""
    x1, x2 = max(x[0], 0.0), max(x[1], 0.0)
    dx1 = -p["k1"] * np.sqrt(x1) + p["k4"] * u
    dx2 = p["k2"] * np.sqrt(x1) - p["k3"] * np.sqrt(x2)
    dx1 -= K_OVERFLOW * max(x[0] - H_MAX, 0.0)  # the overflow pipes above the rims
    dx2 -= K_OVERFLOW * max(x[1] - H_MAX, 0.0)
    return [dx1, dx2]


def input_steps(rng: np.random.Generator, n_samples: int) -> np.ndarray:
    """Random pump voltages 0.4…2 V, each held 40 to 120 samples."""
    u = np.empty(n_samples)
    k = 0
    while k < n_samples:
        hold = int(rng.integers(40, 121))
        u[k : k + hold] = rng.uniform(0.4, 2.0)
        k += hold
    return u


def simulate(u: np.ndarray, x0: tuple[float, float], dt: float = 1.0) -> np.ndarray:
    """The lower level at every sample, the input held between samples."""
    x = np.array(x0, dtype=float)
    out = np.empty(len(u))
    for k, u_k in enumerate(u):
        out[k] = x[1]
        step = solve_ivp(rhs, (0.0, dt), x, args=(u_k, TRUE), rtol=1e-9, atol=1e-11)
        x = step.y[:, -1]
    return out


def write_log(path: Path, u: np.ndarray, level: np.ndarray, dt: float = 1.0) -> None:
    """A CSV log: t_s, u_V, h2_dm."""
    frame = pd.DataFrame({"t_s": np.arange(len(u)) * dt, "u_V": u, "h2_dm": level})
    frame.to_csv(path, index=False, float_format="%.6g")


def main() -> None:
    """Write the estimation (1500 s) and validation (1000 s) logs."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path, help="folder to write the two CSV logs into")
    parser.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    parser.add_argument(
        "--noise", type=float, default=0.01, help="level noise standard deviation [dm]"
    )
    args = parser.parse_args()
    args.out_dir.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    for name, n_samples, x0 in (
        ("two_tanks_estimation.csv", 1500, (1.0, 0.8)),
        ("two_tanks_validation.csv", 1000, (2.0, 0.5)),
    ):
        u = input_steps(rng, n_samples)
        level = simulate(u, x0) + rng.normal(0.0, args.noise, n_samples)
        write_log(args.out_dir / name, u, level)
        print(f"wrote {args.out_dir / name} ({n_samples} samples, 1 s apart)")


if __name__ == "__main__":
    main()
