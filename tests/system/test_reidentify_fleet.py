"""Re-identification of a six-loop fleet over two UTC days, and kills mid-run (slow).

Time budget: 200 s for the module on the 2-core machine (simulation ~30 s in two processes,
then three full runs of 12 loop-days on 2-worker local clusters and one partial run).

Six loops, each with its own plant file (archived beside its samples, so the analyser's priors
and plant K are that plant's): the reference plant with the fuel warming 5 → 35 °C over the two
days; a worn pump (leakage doubled, 7 → 14 L/min/MPa: K −9 %) at 20 °C; a worn pump
(displacement 50 → 45 cm³/rev) cooling 30 → 10 °C; a slow flowmeter (time constant 0.3 → 1.0 s,
dead time 0.2 → 0.5 s) at 15 °C; a slow drive (VFD lag 1.2 → 2.5 s) in MAN at 25 °C; the
reference plant in MAN with the fuel cooling 40 → 20 °C. A wind tunnel runs in short runs:
each loop records 12-minute runs at 02:00 and 10:00 of the first day, one across midnight
(23:54–00:06, so that the second day's first windows reach into the first day's file), and at
09:00 and 16:00 of the second day; samples only during runs (10 Hz).

The band, stated before running: for each accepted window z = (K − K_plant(u, T)) / se_K with
K_plant the plant model's linearised gain at the window's mean command and temperature
(:func:`fuelid.online._tracking.plant_gain_function` of the loop's own plant). If the standard
errors were exact and the linearisation exact, |z| ≤ 3 would hold with probability 0.9973;
the windows' standard errors may be optimistic by up to 1.5× (the nonlinear plant around its
linearisation, coloured noise estimated by the HAC covariance), under which |z| ≤ 3 still holds
with probability ≥ 0.95. So: the number of accepted windows with |z| ≤ 3 must be at least the
99.9 % lower binomial bound of Binomial(n, 0.95). And the re-identification must tell each worn
plant from the reference plant: the median |K − K_reference(u, T)| / se_K of its accepted
windows above 10.
"""

from __future__ import annotations

import copy
import os
import shutil
import signal
import subprocess
import sys
import tomllib
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest
from scipy import stats

pytest.importorskip("distributed")

import psutil
import tomlkit
from distributed import Client, LocalCluster

from fuelid.archive import list_loop_days
from fuelid.fleet import TIMING_COLUMNS, reidentify
from fuelid.online import plant_gain_function
from fuelid.plant import plant_config_from_dict, reference_plant_text
from support.archive_fixture import archive_store
from support.fleet import T0, simulate_loop
from support.waiting import wait_until

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
RUN_S = 720.0
"""Length of a run [s]."""
RUNS = (2 * 3600.0, 10 * 3600.0, 86400.0 - 360.0, 86400.0 + 9 * 3600.0, 86400.0 + 16 * 3600.0)
"""Start of each run from 2026-01-01 00:00 UTC [s]."""
SPAN = 2 * 86400.0

# (loop id, plant changes {section: {key: value}}, mode, fuel temperature at start and end [°C])
LOOPS: tuple[tuple[str, dict[str, dict[str, float]], str, tuple[float, float]], ...] = (
    ("ref-warming", {}, "AUTO", (5.0, 35.0)),
    ("worn-leakage", {"pump": {"leakage_Lpm_per_MPa": 14.0}}, "AUTO", (20.0, 20.0)),
    ("worn-displacement", {"pump": {"displacement_cm3_per_rev": 45.0}}, "AUTO", (30.0, 10.0)),
    ("slow-meter", {"flowmeter": {"time_constant_s": 1.0, "delay_s": 0.5}}, "AUTO", (15.0, 15.0)),
    ("slow-drive", {"vfd": {"lag_s": 2.5}}, "MAN", (25.0, 25.0)),
    ("ref-cooling", {}, "MAN", (40.0, 20.0)),
)
WORN = ("worn-leakage", "worn-displacement")


def plant_dict(changes: dict[str, dict[str, float]]) -> dict[str, Any]:
    data = copy.deepcopy(tomllib.loads(reference_plant_text()))
    for section, values in changes.items():
        data[section].update(values)
    return data


def simulate(args: tuple[Path, int]) -> Path:
    """One loop's store and plant file (run in a worker process)."""
    folder, index = args
    loop_id, changes, mode, (T_start, T_end) = LOOPS[index]
    data = plant_dict(changes)
    data["name"] = loop_id
    plant_file = folder / f"{loop_id}.toml"
    plant_file.write_text(tomlkit.dumps(data), encoding="utf-8")
    plant = plant_config_from_dict(data)
    store = folder / f"{loop_id}.db"
    for k, offset in enumerate(RUNS):
        temps = [T_start + (T_end - T_start) * (offset + s) / SPAN for s in (0.0, RUN_S)]
        simulate_loop(
            store, loop_id, hours=RUN_S / 3600.0, seed=100 * index + k,
            start=T0 + offset, mode=mode, plant=plant,
            fuel_temp_profile=([0.0, RUN_S], temps),
        )  # fmt: skip
    return plant_file


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Path]]:
    folder = tmp_path_factory.mktemp("fleet6")
    jobs = [(folder, index) for index in range(len(LOOPS))]
    with ProcessPoolExecutor(max_workers=2) as pool:
        plant_files = list(pool.map(simulate, jobs))
    root = folder / "archive"
    for (loop_id, *_), plant_file in zip(LOOPS, plant_files, strict=True):
        dates = archive_store(folder / f"{loop_id}.db", root, plant_file=plant_file)
        assert dates == ["2026-01-01", "2026-01-02"]
    assert len(list_loop_days(root)) == 12
    return root, dict(zip([x[0] for x in LOOPS], plant_files, strict=True))


def local_client() -> Any:
    cluster = LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
    )  # fmt: skip
    return cluster, Client(cluster)


@pytest.fixture(scope="module")
def clean(fleet: tuple[Path, dict[str, Path]], tmp_path_factory: pytest.TempPathFactory) -> Path:
    root, _ = fleet
    out = tmp_path_factory.mktemp("clean")
    cluster, client = local_client()
    with cluster, client:
        run = reidentify(root, out, client=client)
    assert (run.loop_days, run.computed) == (12, 12)
    return out


def results(out: Path) -> dict[str, Any]:
    files = sorted((out / "windows").rglob("*"))
    assert all(f.is_dir() or f.name == "part.parquet" for f in files), files
    return {
        str(f.relative_to(out)): pq.read_table(f).drop_columns(list(TIMING_COLUMNS))
        for f in files
        if f.is_file()
    }


def test_accepted_windows_match_each_plant_within_the_binomial_band(
    fleet: tuple[Path, dict[str, Path]], clean: Path
) -> None:
    _, plant_files = fleet
    reference = plant_gain_function(plant_config_from_dict(plant_dict({})))
    z_all: list[float] = []
    for loop_id, plant_file in plant_files.items():
        k_plant = plant_gain_function(plant_config_from_dict(tomllib.loads(plant_file.read_text())))
        frame = pq.read_table(clean / "windows" / f"loop={loop_id}").to_pandas()
        ok = frame[frame["accepted"]]
        assert len(ok) >= 5, (loop_id, frame["reason"].tolist())
        z = [(r.K - k_plant(r.u_mean, r.T_fuel)) / r.se_K for r in ok.itertuples()]
        z_all += z
        if loop_id in WORN:
            z_ref = [abs(r.K - reference(r.u_mean, r.T_fuel)) / r.se_K for r in ok.itertuples()]
            assert float(np.median(z_ref)) > 10.0, (loop_id, np.median(z_ref))
    n = len(z_all)
    inside = int(np.sum(np.abs(z_all) <= 3.0))
    need = int(stats.binom.ppf(0.001, n, 0.95))
    assert inside >= need, (inside, n, need, np.round(sorted(z_all, key=abs)[-10:], 2))
    # both days of every loop have results, and the midnight run's windows of day 2 read day 1
    for loop_id in plant_files:
        days = sorted(p.name for p in (clean / "windows" / f"loop={loop_id}").iterdir())
        assert days == ["date=2026-01-01", "date=2026-01-02"]
        day2 = pq.read_table(clean / "windows" / f"loop={loop_id}" / "date=2026-01-02")
        first = day2.slice(0, 1).to_pylist()[0]
        assert first["t_to"] == T0 + 86400.0 + 300.0  # 23:55–00:05: half in the first day's file
        assert first["samples"] == 6000  # 10 min at 10 Hz: both days' samples


def _workers(pid: int) -> list[psutil.Process]:
    """The Dask worker processes a ``fuelid reidentify`` process started (spawned children)."""
    children = psutil.Process(pid).children(recursive=True)
    return [c for c in children if "spawn_main" in " ".join(c.cmdline())]


def _command(root: Path, out: Path) -> subprocess.Popen[bytes]:
    env = {
        **os.environ,
        "PYTHONPATH": f"{ROOT / 'src'}{os.pathsep}{os.environ.get('PYTHONPATH', '')}",
    }
    return subprocess.Popen(
        [sys.executable, "-m", "fuelid", "reidentify", str(root), "--out", str(out),
         "--workers", "2", "--quiet"],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip


def _wait_for_results(out: Path, count: int, process: subprocess.Popen[bytes]) -> None:
    def written() -> bool:
        assert process.poll() is None, process.communicate()
        return len(list((out / "windows").rglob("part.parquet"))) >= count

    wait_until(written, 120.0, f"{count} windows' results written", every=0.05)


def test_kill_a_worker_mid_run_the_task_is_retried_whole(
    fleet: tuple[Path, dict[str, Path]], clean: Path, tmp_path: Path
) -> None:
    root, _ = fleet
    out = tmp_path / "out"
    process = _command(root, out)
    try:
        _wait_for_results(out, 1, process)
        workers = _workers(process.pid)
        assert len(workers) == 2
        os.kill(workers[0].pid, signal.SIGKILL)  # busy with a loop-day: Dask reschedules it
        stdout, stderr = process.communicate(timeout=180)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 0, stderr.decode()
    # the killed worker's loop-day is rerun elsewhere; if the kill came after its result was
    # renamed into place, the rerun finds it whole and skips it ("1 already done")
    assert stdout.decode().startswith("12 loop-day(s): ")
    assert results(out) == results(clean)


def test_kill_the_command_mid_run_then_resume(
    fleet: tuple[Path, dict[str, Path]], clean: Path, tmp_path: Path
) -> None:
    root, _ = fleet
    out = tmp_path / "out"
    process = _command(root, out)
    try:
        _wait_for_results(out, 3, process)
        workers = _workers(process.pid)
        process.send_signal(signal.SIGKILL)
        process.communicate(timeout=10)  # reaps it and closes its pipes
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    # the orphaned workers lose their scheduler; end any still there (they are ours)
    _, alive = psutil.wait_procs(workers, timeout=15)
    for worker in alive:
        worker.kill()
    done = len(list((out / "windows").rglob("part.parquet")))
    assert 3 <= done < 12
    rerun = _command(root, out)
    stdout, stderr = rerun.communicate(timeout=180)
    assert rerun.returncode == 0, stderr.decode()
    line = stdout.decode().splitlines()[0]
    assert line.startswith("12 loop-day(s): ")
    computed = int(line.split(": ")[1].split(" computed")[0])
    assert computed == 12 - done  # the finished loop-days were skipped
    assert results(out) == results(clean)
    shutil.rmtree(out)
