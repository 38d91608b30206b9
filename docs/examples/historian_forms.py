"""Rewrite a fuelid log (t_s, u_V, q_Lpm) as a historian would export it, to try the reader.

    python historian_forms.py IN.csv OUT.csv --start "2026-10-25 02:59:30" --zone Europe/Berlin

writes the log's samples with date-time stamps in column ``Timestamp``, the command as
``FIC101.OUT`` and the flow as ``FI101.PV``: local time of ``--zone`` from ``--start`` (local),
with UTC offsets (``--offsets``), in a strftime ``--form``, with ``--jitter-ms`` of uniform
jitter, and ``--preamble`` lines of export settings above the header.
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log")
    parser.add_argument("out")
    parser.add_argument("--start", required=True, help="local time of the first sample")
    parser.add_argument("--zone", default="UTC", help="IANA time zone of the stamps")
    parser.add_argument("--offsets", action="store_true", help="write UTC offsets (+01:00)")
    parser.add_argument("--form", default="%Y-%m-%d %H:%M:%S.%f", help="strftime codes")
    parser.add_argument("--jitter-ms", type=float, default=0.0, help="uniform jitter ± [ms]")
    parser.add_argument("--preamble", type=int, default=0, help="lines above the header")
    args = parser.parse_args()

    log = pd.read_csv(args.log)
    rng = np.random.default_rng(0)
    seconds = log["t_s"].to_numpy() + rng.uniform(-1.0, 1.0, len(log)) * args.jitter_ms / 1e3
    start = pd.Timestamp(args.start).tz_localize(args.zone, ambiguous=True)
    instants = (start + pd.to_timedelta(seconds, unit="s")).tz_convert(args.zone)
    stamps = [f"{s:{args.form}}" for s in instants]
    if args.offsets:
        stamps = [f"{text}{s:%z}"[:-2] + ":" + f"{s:%z}"[-2:] for text, s in zip(stamps, instants)]
    table = pd.DataFrame(
        {"Timestamp": stamps, "FIC101.OUT": log["u_V"], "FI101.PV": log["q_Lpm"].round(3)}
    )
    with open(args.out, "w", encoding="utf-8") as out:
        for line in range(args.preamble):
            out.write(f"Export setting {line + 1},,\n")
        table.to_csv(out, index=False)


if __name__ == "__main__":
    main()
