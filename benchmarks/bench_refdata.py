"""Benchmark: the two real DaISy records in ../shared/ref-data (skipped when absent).

Protocol (docs/explanation/identification.md): fit on the first half, free-run simulation scored
(NRMSE fit %) on the second half; and on the whole heating record, at rest versus estimated initial
state versus the known pre-record input of 6 V. Peers measured on the same files (SysIdentPy and a
plain FOPDT fit): ARX(3,3) about 85 % (dryer) and 64 % (plate); FOPDT output-error about 83 % /
68–69 %; whole plate 76 % at rest and 86 % from the 6 V pre-record input.

    .venv/bin/python benchmarks/bench_refdata.py
"""

from __future__ import annotations

from pathlib import Path

from _docs_table import run_to_docs
from fuelid.identify import OutputError
from fuelid.io.logs import load_log
from fuelid.model import nrmse_fit

REF = Path(__file__).resolve().parents[2] / "shared" / "ref-data"
RECORDS = {
    "heating plate": ("daisy_heating_system.csv", "u_lamp_drive_V", "y_plate_temp_degC"),
    "hair dryer": ("daisy_hair_dryer.csv", "u_heater_V", "y_outlet_temp_thermocouple_V"),
}


def main() -> None:
    if not REF.is_dir():
        print(f"skipped: {REF} is absent")
        return
    print(f"{'record':14s} {'model':38s} {'est. fit %':>10s} {'val. fit %':>10s}")
    for name, (file, u_col, y_col) in RECORDS.items():
        data = load_log(REF / file, input_col=u_col, output_col=y_col)
        half = data.n_samples // 2
        for label, kwargs in (
            ("order 1, delay estimated", {"order": 1}),
            ("order 2, delay estimated", {"order": 2}),
            ("order auto (AIC)", {"order": "auto"}),
        ):
            est = OutputError(**kwargs).fit(data.segment(0, half))
            y_hat = est.simulate(data)
            print(
                f"{name:14s} {label:38s} {est.fit_percent_:10.1f} "
                f"{nrmse_fit(data.y[half:], y_hat[half:]):10.1f}"
            )
    data = load_log(
        REF / RECORDS["heating plate"][0],
        input_col=RECORDS["heating plate"][1],
        output_col=RECORDS["heating plate"][2],
    )
    for label, kwargs in (
        ("whole record, assumed at rest", {"initial": "rest"}),
        ("whole record, initial state estimated", {}),
        ("whole record, u_before = 6 V", {"u_before": 6.0}),
    ):
        est = OutputError(order=1, **kwargs).fit(data)  # type: ignore[arg-type]
        print(f"{'heating plate':14s} {label:38s} {est.fit_percent_:10.1f} {'':>10s}")


if __name__ == "__main__":
    run_to_docs("refdata", main, __doc__)  # the printed tables, also in docs/benchmarks
