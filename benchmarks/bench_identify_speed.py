"""Benchmark: speed and memory of the output-error fit on one hour of 50 Hz data.

Targets (issue 3): the `oe` fit of 180,000 samples (reading the file reported separately) in at
most 0.5 s with peak memory under 200 MB; a 10-minute window (30,000 samples) refitted from the
previous estimate in under 50 ms. In the same run, SysIdentPy's linear ARX (FROLS, degree 1) on
the same data as a peer reference (install with `pip install -e '.[bench]'`; skipped if absent).

    .venv/bin/python benchmarks/bench_identify_speed.py
"""

from __future__ import annotations

import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from _docs_table import run_to_docs
from _timing import best_of
from fuelid.identify import OutputError
from fuelid.io.logs import load_log
from fuelid.model import nrmse_fit
from fuelid.plant import load_plant_config
from fuelid.plant.simulate import simulate
from fuelid.profiles import step_sequence


def peak_mb(fn: Callable[[], Any]) -> float:
    tracemalloc.start()
    fn()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak / 1e6


def main() -> None:
    config = load_plant_config()
    rng = np.random.default_rng(0)
    profile = step_sequence(rng.uniform(2.5, 3.5, 120).round(2).tolist(), 30.0)
    log = simulate(config, profile, seed=1).to_log()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "hour.parquet"
        log.write(path)
        csv = Path(tmp) / "hour.csv"
        log.write(csv)
        t_parquet, data = best_of(3, lambda: load_log(path))
        t_csv, _ = best_of(3, lambda: load_log(csv))
    rows.append(("read 1 h log (Parquet)", t_parquet, None, None, ""))
    rows.append(("read 1 h log (CSV)", t_csv, None, None, ""))
    meter = config.flowmeter

    def oe_fixed() -> OutputError:
        return OutputError(T_f=meter.time_constant_s, delay=meter.delay_s).fit(data)

    def oe_free() -> OutputError:
        return OutputError(T_f=meter.time_constant_s).fit(data)

    t, est = best_of(3, oe_fixed)
    rows.append(
        ("oe, delay = meter prior", t, peak_mb(oe_fixed), est.fit_percent_, "target 0.5 s, 200 MB")
    )
    t, est = best_of(1, oe_free)
    rows.append(("oe, delay estimated", t, peak_mb(oe_free), est.fit_percent_, ""))

    # moving window: 10 min at 50 Hz, slid by 1 min, warm-started from the previous estimate
    window, slide = 30_000, 3_000
    previous = OutputError(T_f=meter.time_constant_s, delay=meter.delay_s).fit(
        data.segment(0, window)
    )
    times = []
    for start in range(slide, data.n_samples - window, slide):
        segment = data.segment(start, start + window)
        t0 = time.perf_counter()
        previous = OutputError(T_f=meter.time_constant_s, delay=meter.delay_s).fit(
            segment, init=previous.model_
        )
        times.append(time.perf_counter() - t0)
    rows.append(
        (
            f"oe, 30k window warm start (median of {len(times)})",
            float(np.median(times)),
            None,
            previous.fit_percent_,
            "target 50 ms",
        )
    )

    try:
        from sysidentpy.basis_function import Polynomial
        from sysidentpy.model_structure_selection import FROLS
        from sysidentpy.parameter_estimation import LeastSquares
    except ImportError:
        rows.append(
            (
                "SysIdentPy ARX (not installed: pip install -e '.[bench]')",
                float("nan"),
                None,
                None,
                "",
            )
        )
    else:
        x = data.u.reshape(-1, 1)
        y = data.y.reshape(-1, 1)

        def arx() -> Any:
            model = FROLS(
                order_selection=False,
                n_terms=6,
                ylag=3,
                xlag=3,
                estimator=LeastSquares(),
                basis_function=Polynomial(degree=1),
            )
            model.fit(X=x, y=y)
            return model

        t, model = best_of(1, arx)
        y_hat = model.predict(X=x, y=y[:3]).ravel()
        rows.append(
            (
                "SysIdentPy ARX(3,3), FROLS degree 1",
                t,
                peak_mb(arx),
                nrmse_fit(data.y, y_hat),
                "peer reference",
            )
        )

    print(f"one hour of 50 Hz data: {data.n_samples} samples")
    print(f"{'task':52s} {'seconds':>9s} {'peak MB':>8s} {'fit %':>7s}  note")
    for name, seconds, mem, fit, note in rows:
        mem_s = f"{mem:8.1f}" if mem is not None else f"{'':8s}"
        fit_s = f"{fit:7.2f}" if fit is not None else f"{'':7s}"
        print(f"{name:52s} {seconds:9.3f} {mem_s} {fit_s}  {note}")


if __name__ == "__main__":
    run_to_docs("identify_speed", main, __doc__)  # the printed tables, also in docs/benchmarks
