"""The PLC link end to end on the virtual PLC (what ``make plc-demo`` runs).

1. ``fuelid plant serve`` starts the virtual PLC on 127.0.0.1 (Modbus TCP): the nonlinear
   reference plant with its PLC emulated, accelerated, in MAN with command steps.
2. ``fuelid plant serve --print-site`` writes the site file that points at it.
3. ``fuelid record`` records a few minutes of plant time into an SQLite store.
4. ``fuelid store info`` and ``fuelid export`` show the store and write a log.
5. ``fuelid identify`` identifies the loop from that log, and the gain is compared with the
   physics (``fuelid plant info`` at the log's mean command and fuel temperature).

Every step is a command a user types; each is printed before it runs.
"""

from __future__ import annotations

import argparse
import json
import shlex
import socket
import subprocess
import sys
import time
from pathlib import Path

FUELID = [sys.executable, "-m", "fuelid"]
FUEL_TEMP_DEGC = 20.0


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
    return port


def _show(args: list[str]) -> None:
    shown = ["fuelid", *args[len(FUELID) :]] if args[: len(FUELID)] == FUELID else args
    print("$ " + shlex.join(shown), flush=True)


def _run(args: list[str], capture: bool = False) -> str:
    """Run one command as a user would, stop the demo if it fails."""
    _show(args)
    done = subprocess.run(args, capture_output=capture, text=True, check=False)
    if done.returncode != 0:
        if capture:
            sys.stderr.write(done.stderr)
        raise SystemExit(f"the demo stopped: {shlex.join(args[len(FUELID) :])} failed")
    return done.stdout if capture else ""


def main() -> None:
    """Serve, record, export and identify; print the identified and the physical gain."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("demo-output/plc"))
    parser.add_argument("--speed", type=float, default=20.0, help="times real time")
    parser.add_argument("--seconds", type=float, default=15.0, help="wall time to record [s]")
    options = parser.parse_args()
    out: Path = options.out
    out.mkdir(parents=True, exist_ok=True)
    store, log, site = out / "plc.db", out / "plc_log.csv", out / "site.toml"
    store.unlink(missing_ok=True)

    port = str(_free_port())
    serve = [
        *FUELID,
        *("plant", "serve", "--port", port, "--speed", f"{options.speed:g}"),
        *("--command-profile", "steps", "--fuel-temp", f"{FUEL_TEMP_DEGC:g}", "--seed", "1"),
    ]
    site.write_text(_run([*serve, "--print-site"], capture=True), encoding="utf-8")
    print(f"  (site file written to {site})")
    _show(serve)
    server = subprocess.Popen(serve, stdout=subprocess.DEVNULL)
    try:
        time.sleep(2.0)  # the server binds within a second; record would retry anyway
        _run(
            [
                *FUELID,
                *("record", "--config", str(site), "--store", str(store)),
                *("--duration", f"{options.seconds:g}", "--give-up-after", "20"),
            ]
        )
    finally:
        server.terminate()
        server.wait(timeout=10)
    _run([*FUELID, "store", "info", "--store", str(store)])
    _run([*FUELID, "export", "--store", str(store), "--out", str(log), "--force"])
    model = json.loads(_run([*FUELID, "identify", str(log), "--json"], capture=True))
    u_mean = model["operating_point"]["u"]
    physics = json.loads(
        _run(
            [
                *FUELID,
                *("plant", "info", "--u", f"{u_mean:.3f}", "--fuel-temp", f"{FUEL_TEMP_DEGC:g}"),
                "--json",
            ],
            capture=True,
        )
    )
    k_identified = model["model"]["K"]
    k_physics = physics["model"]["K"]
    print(
        f"\nidentified from the recorded PLC data: K = {k_identified:.3f} L/min per V; "
        f"physics at u = {u_mean:.2f} V, {FUEL_TEMP_DEGC:g} °C: K = {k_physics:.3f} "
        f"({100 * (k_identified / k_physics - 1):+.1f} %)"
    )


if __name__ == "__main__":
    main()
