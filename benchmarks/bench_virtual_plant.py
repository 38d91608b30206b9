"""Benchmark: how many times real time the virtual PLC runs while keeping the 0.02 s sample period.

Target (issue 14): ≥ 50× real time. Two measurements:

1. the engine alone (no sockets): plant seconds simulated per wall second, in AUTO on the
   wind-tunnel run (the PI at work, one LSODA call per 1 s control period);
2. the engine on its Modbus TCP front end with a plain pymodbus client reading every ring record
   in blocks of 12 (as a recorder does), for each speed X: whether plant time kept pace with
   X × wall time (the largest lateness of a tick behind its absolute deadline, in wall and in
   plant time), the share of wall time the PLC's thread was busy, and whether the client got
   every sample (no gap, no duplicate in the sequence numbers).

A speed "keeps the period" when the client lost no sample, no tick was later than
``--max-lag`` [s of wall time] and the PLC's thread was busy less than 80 % of the time.
Run on demand:

    .venv/bin/python benchmarks/bench_virtual_plant.py [--speeds 10 50 100 200 400] [--seconds 5]
"""

from __future__ import annotations

import argparse
import asyncio
import time

from _docs_table import run_to_docs
from fuelid.plc.virtual import VirtualPLC, VirtualPlcThread
from fuelid.plc.virtual._points import (
    RING_FIRST_REGISTER,
    RING_HEAD_REGISTER,
    RING_RECORD_REGISTERS,
)

TARGET = 50.0
SEQ_MODULUS = 2**32
BUSY_LIMIT = 0.8


def engine_speed(plant_s: float) -> float:
    """Plant time per wall time of the engine alone, on the wind-tunnel run [×]."""
    plc = VirtualPLC(setpoint_profile="run", seed=0)
    n = round(plant_s / plc.period_s)
    start = time.perf_counter()
    done = 0
    while done < n:  # in slices as the runner advances it (50 samples a tick at 50×)
        plc.advance(50)
        done += 50
    return done * plc.period_s / (time.perf_counter() - start)


async def read_ring(port: int, seconds: float, ring_size: int, speed: float) -> tuple[int, int]:
    """Read every ring record for ``seconds``: (records received, gaps or duplicates)."""
    from pymodbus.client import AsyncModbusTcpClient

    client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=2, retries=1)
    assert await client.connect()

    async def head() -> int:
        rr = await client.read_input_registers(RING_HEAD_REGISTER, count=2, device_id=1)
        return (rr.registers[0] << 16) | rr.registers[1]

    # poll well within the ring's span of wall time: it holds ring_size samples
    poll = min(0.1, 0.25 * ring_size * 0.02 / speed)
    last = await head()
    received = bad = 0
    stop = time.monotonic() + seconds
    while time.monotonic() < stop:
        await asyncio.sleep(poll)
        now = await head()
        count = (now - last) % SEQ_MODULUS
        if count >= ring_size:
            bad += count - ring_size + 1  # overrun: the oldest were overwritten unread
            last = (now - ring_size + 1) % SEQ_MODULUS
            count = ring_size - 1
        seq = (last + 1) % SEQ_MODULUS
        while count > 0:
            slot = seq % ring_size
            n = min(12, count, ring_size - slot)
            rr = await client.read_input_registers(
                RING_FIRST_REGISTER + RING_RECORD_REGISTERS * slot,
                count=RING_RECORD_REGISTERS * n,
                device_id=1,
            )
            for i in range(n):
                first = RING_RECORD_REGISTERS * i
                got = (rr.registers[first] << 16) | rr.registers[first + 1]
                bad += got != seq
                seq = (seq + 1) % SEQ_MODULUS
            received += n
            count -= n
        last = now
    client.close()
    return received, bad


def served(speed: float, seconds: float, max_lag: float) -> dict[str, float | bool]:
    """The engine on Modbus at ``speed`` with a client reading the whole ring."""
    with VirtualPlcThread(speed=speed, seed=0, setpoint_profile="run") as virtual:
        virtual.stats.keep_lags = True
        time.sleep(0.3)  # let the clock settle after start-up
        busy0, wall0 = virtual.stats.busy_s, virtual.stats.wall_s
        virtual.stats.max_lag_s = 0.0
        received, bad = asyncio.run(read_ring(virtual.port, seconds, virtual.plc.ring_size, speed))
        stats = virtual.stats
        busy = (stats.busy_s - busy0) / max(stats.wall_s - wall0, 1e-9)
        result: dict[str, float | bool] = {
            "speed": speed,
            "plant_s": received * virtual.plc.period_s,
            "expected_plant_s": speed * seconds,
            "max_lag_s": stats.max_lag_s,
            "max_lag_plant_s": stats.max_lag_s * speed,
            "busy": busy,
            "max_batch": stats.max_batch,
            "bad": bad,
        }
    result["keeps"] = bad == 0 and stats.max_lag_s < max_lag and busy < BUSY_LIMIT
    return result


def main() -> None:
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--speeds", type=float, nargs="+", default=[10.0, 50.0, 100.0, 200.0, 400.0]
    )
    parser.add_argument("--seconds", type=float, default=5.0, help="wall time per speed [s]")
    parser.add_argument(
        "--max-lag", type=float, default=0.1, help="largest tick lateness allowed [s]"
    )
    args = parser.parse_args()

    alone = engine_speed(600.0)
    print(f"engine alone (wind-tunnel run, AUTO): {alone:,.0f}x real time")
    print()
    header = (
        f"{'speed':>7} {'plant s read':>13} {'expected':>9} {'max lag [ms]':>13} "
        f"{'= plant s':>10} {'busy':>6} {'batch':>6} {'lost/dup':>9} {'keeps 20 ms':>12}"
    )
    print(header)
    print("-" * len(header))
    best = 0.0
    for speed in args.speeds:
        r = served(speed, args.seconds, args.max_lag)
        print(
            f"{r['speed']:>6.0f}x {r['plant_s']:>13.1f} {r['expected_plant_s']:>9.1f} "
            f"{1e3 * r['max_lag_s']:>13.1f} {r['max_lag_plant_s']:>10.2f} {r['busy']:>6.0%} "
            f"{r['max_batch']:>6.0f} {r['bad']:>9.0f} {'yes' if r['keeps'] else 'NO':>12}"
        )
        if r["keeps"]:
            best = max(best, speed)
    print()
    verdict = "meets" if best >= TARGET else "misses"
    print(f"highest speed that keeps the 0.02 s period: {best:g}x ({verdict} {TARGET:g}x)")


if __name__ == "__main__":
    run_to_docs("virtual_plant", main, __doc__)  # the printed tables, also in docs/benchmarks
