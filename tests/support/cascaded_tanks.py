"""The real-like cascaded-tanks record (examples/cascaded_tanks_data.py, seed 42) as records.

A plant richer than the user's models (power-law outflows with a leak, a steep overflow pipe, a
drifting pump gain, an offset and a 10 V clip), so every fit of it has a model error, as on the
benchmark's real record.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pandas as pd

from fuelid.greybox import Record

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
"""The examples folder: the record's generator and the user's model files."""
REFERENCE_VALIDATION_RMSE = 0.438
"""A least_squares + odeint script's validation RMSE on this record [V], from the start values
of examples/cascaded_tanks.py, its overflow an undeclared ``if``."""


def cascaded_tanks_records(folder: Path) -> list[Record]:
    """The estimation and validation records, written to ``folder`` by the example's generator."""
    subprocess.run(
        [sys.executable, str(EXAMPLES / "cascaded_tanks_data.py"), str(folder)], check=True
    )
    out = []
    for name in ("estimation", "validation"):
        frame = pd.read_csv(folder / f"cascaded_tanks_{name}.csv")
        out.append(
            Record(
                t=frame["t_s"].to_numpy(float),
                u=frame[["u_V"]].to_numpy(float),
                y=frame[["y_V"]].to_numpy(float),
                name=name,
            )
        )
    return out
