"""The yardstick of ``fuelid identify`` on a long log: read it with pandas, solve one problem.

What a user's own script does with a day of 50 Hz samples before any identification tool is
involved: ``pandas.read_csv`` of the file, then one linear least-squares problem on every
sample, an ARX(2, 2) model with a constant,

    y[k] = a₁·y[k−1] + a₂·y[k−2] + b₁·u[k−d−1] + b₂·u[k−d−2] + c,

solved by ``numpy.linalg.lstsq``, and its one-step fit printed. ``benchmarks/bench_day_log.py``
times it beside ``fuelid identify`` and ``fuelid report`` on the same file, in the same run: the
issue's yardstick ("within 5× a read-and-solve script").

    .venv/bin/python benchmarks/read_and_solve.py LOG.csv [--input-col u_V] [--output-col q_Lpm]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

#: the ARX model's input delay [samples]: 0.26 s at 50 Hz, about the fuel loop's dead time
INPUT_DELAY = 13


def arx_regressors(u: np.ndarray, y: np.ndarray, delay: int) -> tuple[np.ndarray, np.ndarray]:
    """(Φ, target) of the ARX(2, 2) model with a constant: a row per sample whose lags exist."""
    start = delay + 2
    Phi = np.column_stack(
        [
            y[start - 1 : -1],
            y[start - 2 : -2],
            u[start - delay - 1 : u.size - delay - 1],
            u[start - delay - 2 : u.size - delay - 2],
            np.ones(y.size - start),
        ]
    )
    return Phi, y[start:]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("log", type=Path, help="CSV log with a header row")
    parser.add_argument("--input-col", default="u_V")
    parser.add_argument("--output-col", default="q_Lpm")
    args = parser.parse_args()
    started = time.perf_counter()
    frame = pd.read_csv(args.log)
    read = time.perf_counter()
    u = frame[args.input_col].to_numpy(dtype=float)
    y = frame[args.output_col].to_numpy(dtype=float)
    Phi, target = arx_regressors(u, y, INPUT_DELAY)
    theta, *_ = np.linalg.lstsq(Phi, target, rcond=None)
    error = target - Phi @ theta
    fit = 100.0 * (1.0 - np.linalg.norm(error) / np.linalg.norm(target - target.mean()))
    done = time.perf_counter()
    print(
        f"{y.size} rows; read {read - started:.2f} s, solved {done - read:.2f} s; "
        f"ARX(2,2) θ = {np.array2string(theta, precision=4)}, one-step fit {fit:.2f} %"
    )


if __name__ == "__main__":
    main()
