"""``fuelid reidentify`` on a real Dask local cluster (two worker processes on 127.0.0.1).

The archive is written from the session's two fleet stores (line-a AUTO with warming fuel,
line-b MAN with missing values; 3 h each on 2026-01-01) by tests/support/archive_fixture.py.
One cluster serves the module; the whole module takes ~30 s on the 2-core machine.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest

pytest.importorskip("distributed")

from distributed import Client, LocalCluster

from fuelid.archive import list_loop_days
from fuelid.cli import main
from fuelid.fleet import RESULT_SCHEMA, TIMING_COLUMNS, reidentify
from fuelid.fleet import _run as fleet_run
from fuelid.fleet._task import day_windows
from fuelid.online import Online
from support.archive_fixture import archive_store
from support.fleet import T0
from support.rounding import gamma, inverse_gram_budget, least_squares_budget

ROOT = Path(__file__).resolve().parents[3]
DATE = "2026-01-01"


@pytest.fixture(scope="module")
def cluster() -> Iterator[Client]:
    """Two single-threaded worker processes, as ``fuelid reidentify --workers 2`` starts them."""
    with (
        LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address="127.0.0.1:0",  # a free port on loopback, never 8787
        ) as local,
        Client(local) as client,
    ):
        yield client


@pytest.fixture(scope="module")
def archive(fleet_loops: dict[str, Any], tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("archive")
    for loop in fleet_loops.values():
        assert archive_store(loop.path, root) == [DATE]
    return root


@pytest.fixture(scope="module")
def two_workers(archive: Path, cluster: Client, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("two")
    run = reidentify(archive, out, client=cluster)
    assert (run.workers, run.loop_days, run.computed, run.skipped) == (2, 2, 2, 0)
    return out


def results(out: Path) -> dict[str, pa.Table]:
    """Each loop-day's result without its timing columns, by ``loop=…/date=…``."""
    files = sorted((out / "windows").glob("loop=*/date=*/*"))
    return {
        f"{f.parent.parent.name}/{f.parent.name}/{f.name}": pq.read_table(f).drop_columns(
            list(TIMING_COLUMNS)
        )
        for f in files
    }


def test_one_and_two_workers_give_identical_results(
    archive: Path, two_workers: Path, tmp_path: Path
) -> None:
    with (
        LocalCluster(
            n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
            dashboard_address="127.0.0.1:0",  # a free port on loopback, never 8787
        ) as local,
        Client(local) as client,
    ):  # fmt: skip
        run = reidentify(archive, tmp_path, client=client)
    assert run.workers == 1
    one, two = results(tmp_path), results(two_workers)
    assert sorted(one) == [
        f"loop=line-a/date={DATE}/part.parquet",
        f"loop=line-b/date={DATE}/part.parquet",
    ]
    assert sorted(one) == sorted(two)
    for key in one:
        assert one[key].num_rows > 0
        assert one[key].equals(two[key]), key
    # the schedule: windows end on the day's 5-minute marks, the empty ones skipped (3 h of
    # data from midnight: the window ending 00:05 holds 5 min, the last ends 03:05)
    ends = pq.read_table(two_workers / "windows" / "loop=line-a" / f"date={DATE}").column("t_to")
    schedule = [t for _, t in day_windows(DATE, Online())]
    assert ends.to_pylist() == schedule[: len(ends)]
    assert len(ends) == 37


def test_resume_recomputes_only_the_missing_loop_day(
    archive: Path, two_workers: Path, cluster: Client, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    shutil.copytree(two_workers, out)
    kept = out / "windows" / "loop=line-a" / f"date={DATE}" / "part.parquet"
    removed = out / "windows" / "loop=line-b" / f"date={DATE}" / "part.parquet"
    before = kept.stat()
    removed.unlink()
    seen: list[dict[str, Any] | None] = []
    run = reidentify(archive, out, client=cluster, progress=lambda d, n, s: seen.append(s))
    assert (run.loop_days, run.computed, run.skipped) == (2, 1, 1)
    assert [s["loop_id"] for s in seen if s is not None] == ["line-b"]
    after = kept.stat()
    assert (after.st_ino, after.st_mtime_ns) == (before.st_ino, before.st_mtime_ns)
    assert results(out) == results(two_workers)
    # no temporary file left behind, one file per loop-day
    assert sorted(p.name for p in (out / "windows").rglob("*") if p.is_file()) == [
        "part.parquet",
        "part.parquet",
    ]


def test_settings_replace_the_archived_gates(
    archive: Path, cluster: Client, tmp_path: Path
) -> None:
    # line-a's first 40 min only (a refused window has no warm start: each one is a cold fit)
    short = tmp_path / "short"
    shutil.copytree(archive / "loops", short / "loops")
    for f in (archive / "samples" / "loop=line-a").rglob("*.parquet"):
        table = pq.read_table(f)
        target = short / f.relative_to(archive)
        target.parent.mkdir(parents=True)
        pq.write_table(table.filter(pc.less(table.column("time"), T0 + 2400.0)), target)
    # a free-run fit of exactly 100 % is impossible on noisy data: no window can pass; the
    # schedule is replaced too (10-min windows every 10 min)
    online = Online(min_fit_percent=100.0, identify_every_s=600.0, window_s=600.0)
    run = reidentify(
        short,
        tmp_path / "out",
        online=online,
        settings_source="--settings test",
        client=cluster,
    )
    result = pq.read_table(tmp_path / "out" / "windows" / "loop=line-a")
    assert result.column("t_to").to_pylist() == [T0 + 600.0 * k for k in range(1, 5)]
    assert not any(result.column("accepted").to_pylist())
    reasons = result.column("reason").to_pylist()
    assert all("fit" in r for r in reasons), reasons
    assert run.loops[0]["accepted_share"] == 0.0
    assert run.settings == {"line-a": "--settings test"}


def _weighted_line(T: np.ndarray, y: np.ndarray, se: np.ndarray) -> tuple[float, float, float]:
    """Slope, its Birge-inflated standard error and T_ref of a weighted line (written out)."""
    w = 1.0 / se**2
    T_ref = float(np.sum(w * T) / np.sum(w))
    X = np.column_stack([np.ones_like(T), T - T_ref])
    cov = np.linalg.inv(X.T @ (w[:, None] * X))
    beta = cov @ (X.T @ (w * y))
    chi2 = float(np.sum(w * (y - X @ beta) ** 2))
    cov *= max(1.0, chi2 / (T.size - 2))
    return float(beta[1]), math.sqrt(cov[1, 1]), T_ref


def _wls(X: np.ndarray, y: np.ndarray, se: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Coefficients, covariance (unscaled) and Birge ratio of a weighted fit (normal equations)."""
    w = 1.0 / se**2
    cov = np.linalg.inv(X.T @ (w[:, None] * X))
    beta = cov @ (X.T @ (w * y))
    chi2 = float(np.sum(w * (y - X @ beta) ** 2))
    return beta, cov, max(1.0, chi2 / (y.size - X.shape[1]))


def test_summary_numbers_recomputed_from_the_parquet(two_workers: Path, archive: Path) -> None:
    from scipy import stats

    tracking = json.loads((two_workers / "tracking" / "line-a.json").read_text())
    summary = tracking["summary"]
    frame = pq.read_table(two_workers / "windows" / "loop=line-a").to_pandas()
    assert summary["windows"] == len(frame) == 37
    assert summary["accepted"] == int(frame["accepted"].sum())
    assert summary["accepted_share"] == pytest.approx(frame["accepted"].mean(), abs=1e-12)
    assert summary["loop_days"] == 1
    ok = frame[frame["accepted"]].sort_values("t_to")
    # K drift: windows that share no sample (600 s every 300 s: every other one), no plant file:
    # K referred to T_ref by K = a + b(T - T_ref) + c t; first vs last tenth, the errors
    # inflated by the Birge ratio of a line q(t) over the period, b's error carried through
    apart = ok.iloc[::2]
    assert (apart["t_from"].to_numpy()[1:] >= apart["t_to"].to_numpy()[:-1]).all()
    T, K, se, t = (apart[c].to_numpy(float) for c in ("T_fuel", "K", "se_K", "t_to"))
    t = (t - t.mean()) / 86400.0
    w = 1.0 / se**2
    T_ref = float(np.sum(w * T) / np.sum(w))
    X = np.column_stack([np.ones_like(T), T - T_ref, t])
    beta, cov, birge_fit = _wls(X, K, se)
    b, se_b = beta[1], math.sqrt(birge_fit * cov[1, 1])
    q = K - b * (T - T_ref)
    birge = _wls(np.column_stack([np.ones_like(t), t]), q, se)[2]
    n = math.ceil(len(q) / 10)
    first = float(np.sum(w[:n] * q[:n]) / np.sum(w[:n]))
    last = float(np.sum(w[-n:] * q[-n:]) / np.sum(w[-n:]))
    se_first = math.sqrt(birge / np.sum(w[:n]))
    se_last = math.sqrt(birge / np.sum(w[-n:]))
    # the summary solves these weighted fits by lstsq, this test by the normal equations: with
    # T and t moving together (the fuel warms over the day) they round b apart by up to its
    # least-squares budget, which moves each mean by Δb·max|T − T_ref|
    dq = least_squares_budget(X / se[:, None], K / se)[1] * float(np.max(np.abs(T - T_ref)))
    ratio = abs(last / first)
    drift_budget = dq * (1.0 + ratio) / abs(first) + gamma(4 * len(q)) * ratio
    assert summary["k_drift"] == pytest.approx(last / first - 1.0, rel=0.0, abs=drift_budget)
    dT = float(np.mean(T[-n:]) - np.mean(T[:n]))
    se_drift = math.sqrt(
        (se_last / first) ** 2 + (last * se_first / first**2) ** 2 + (dT * se_b / first) ** 2
    )
    # b's variance by an inverse here, a pseudo-inverse there; the means as above; the Birge
    # ratios are sums of squared residuals r about the fit, to which b's rounding adds nothing
    # to first order: each residual rounds by γ·|K|, so χ² by 2γ·max|K/se|·Σ|r|/Σr² relative
    # and its root by half that
    dse_b = 0.5 * se_b * inverse_gram_budget(X / se[:, None])[1, 1] / cov[1, 1]
    r = (K - X @ beta) / se
    birge_rounding = (
        gamma(len(K)) * float(np.max(np.abs(K) / se)) * np.sum(np.abs(r)) / np.sum(r**2)
    )
    se_budget = (dT / first) ** 2 * se_b * dse_b / se_drift + se_drift * (
        3.0 * dq / abs(first) + birge_rounding
    )
    assert summary["k_drift_se"] == pytest.approx(se_drift, rel=0.0, abs=se_budget)
    # K(T) slope: the command band with the most windows (1 V bands; all accepted windows, as
    # the service's tracker), 95 % = Student's t with the line's degrees of freedom
    T, K, se = (ok[c].to_numpy(float) for c in ("T_fuel", "K", "se_K"))
    band = np.floor(ok["u_mean"].to_numpy(float))
    values, counts = np.unique(band, return_counts=True)
    m = band == values[np.argmax(counts)]
    slope, se_slope, _ = _weighted_line(T[m], K[m], se[m])
    assert summary["k_slope"] == pytest.approx(slope, rel=1e-9)
    lo, hi = summary["k_slope_ci95"]
    quantile = stats.t.ppf(0.975, int(m.sum()) - 2)
    assert (hi - lo) / 2 == pytest.approx(quantile * se_slope, rel=1e-9)
    assert tracking["tracking"]["mode"] == "band"
    # the fuel warmed 15 → 25 °C: K (viscosity, the pump) moves with it, the slope is resolved
    assert hi < 0.0 or lo > 0.0


# --- the command --------------------------------------------------------------------------------


def cli(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["reidentify", *argv])
    return code, out.getvalue(), err.getvalue()


def documented_names(page: Path) -> set[str]:
    """Every identifier inside a code span of the page (as tests/unit/test_docs_reference)."""
    text = re.sub(r"^\s*(```|~~~).*?^\s*\1", "", page.read_text(encoding="utf-8"),
                  flags=re.DOTALL | re.MULTILINE)  # fmt: skip
    names: set[str] = set()
    for span in re.findall(r"`([^`]+)`", text):
        names.update(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", span))
    return names


def key_names(data: Any, skip: frozenset[str]) -> Iterator[str]:
    if isinstance(data, dict):
        for key, value in data.items():
            yield key
            if key not in skip:
                yield from key_names(value, skip)
    elif isinstance(data, list):
        for item in data:
            yield from key_names(item, skip)


def test_cli_on_a_scheduler_address_resumes_and_documents_its_json(
    archive: Path, two_workers: Path, cluster: Client, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    shutil.copytree(two_workers, out)
    address = cluster.scheduler.address
    code, stdout, err = cli(str(archive), "--out", str(out), "--scheduler", address, "--json")
    assert code == 0, err
    data = json.loads(stdout)
    assert (data["loop_days"], data["computed"], data["skipped"]) == (2, 0, 2)
    assert [loop["loop_id"] for loop in data["loops"]] == ["line-a", "line-b"]
    keys = set(key_names(data, frozenset({"options", "units", "settings"})))
    missing = sorted(keys - documented_names(ROOT / "docs" / "reference" / "json.md"))
    assert not missing, f"`fuelid reidentify --json` keys not in json.md: {missing}"
    code, stdout, err = cli(str(archive), "--out", str(out), "--scheduler", address, "--quiet")
    assert code == 0, err
    assert stdout.splitlines()[1].startswith("loop")
    assert stdout.splitlines()[2].startswith("line-a")


def test_resuming_with_other_settings_is_refused(
    archive: Path, two_workers: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    shutil.copytree(two_workers, out)
    (tmp_path / "online.toml").write_text("[online]\nmin_fit_percent = 90\n", encoding="utf-8")
    code, _, err = cli(str(archive), "--out", str(out), "--settings", str(tmp_path / "online.toml"))
    assert code == 2
    assert "made with other settings ([online] min_fit_percent differ)" in err
    assert results(out) == results(two_workers)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["{missing}"], "not a fuelid archive"),
        (["{archive}", "--loops", "line-z"], "unknown loop(s) line-z"),
        (["{archive}", "--from", "2026-13-01"], "--from '2026-13-01': not a date"),
        (["{archive}", "--from", "2026-01-02", "--to", "2026-01-01"], "is after --to"),
        (["{archive}", "--from", "2027-01-01"], "no loop-day of the archive"),
        (["{archive}", "--settings", "{no_online}"], "no [online] table"),
        (["{archive}", "--settings", "{bad_online}"], "min_fit_percent"),
        (["{archive}", "--scheduler", "tcp://127.0.0.1:9", "--workers", "2"], "not both"),
        (["{archive}", "--scheduler", "tcp://127.0.0.1:9"], "unreachable"),
    ],
)
def test_cli_refuses_bad_input_with_one_line_and_exit_2(
    archive: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    argv: list[str],
    message: str,
) -> None:
    monkeypatch.setattr(fleet_run, "CONNECT_TIMEOUT_S", 0.5)  # a refused port: fail fast
    (tmp_path / "none.toml").write_text("[site]\nname = 'x'\n", encoding="utf-8")
    (tmp_path / "bad.toml").write_text("[online]\nmin_fit_percent = 200\n", encoding="utf-8")
    values = {
        "missing": str(tmp_path / "missing"),
        "archive": str(archive),
        "no_online": str(tmp_path / "none.toml"),
        "bad_online": str(tmp_path / "bad.toml"),
    }
    args = [a.format(**values) for a in argv]
    code, stdout, err = cli(*args, "--out", str(tmp_path / "out"))
    assert code == 2
    assert stdout == ""
    assert len(err.strip().splitlines()) == 1
    assert message in err
    assert not (tmp_path / "out" / "windows").exists()


def test_result_schema_has_every_window_column() -> None:
    names = set(RESULT_SCHEMA.names)
    for key in ("K", "T", "delay", "se_K", "fit_percent", "T_fuel", "u_mean", "plant_K",
                "gates", "reason", "mode", "method", "seconds"):  # fmt: skip
        assert key in names


def test_a_worker_that_does_not_see_the_archive_marks_nothing_done(
    archive: Path, tmp_path: Path
) -> None:
    from fuelid.archive import LoopDay
    from fuelid.errors import DataError
    from fuelid.fleet import loop_settings, reidentify_day
    from fuelid.fleet._task import result_path

    settings, plant = loop_settings(archive, "line-a")
    elsewhere = tmp_path / "not-mounted"
    shutil.copytree(archive / "loops", elsewhere / "loops")  # the settings, not the samples
    day = LoopDay("line-a", DATE)
    with pytest.raises(DataError, match="readable at the same path on every worker"):
        reidentify_day(elsewhere, day, settings, plant, tmp_path / "out")
    assert not result_path(tmp_path / "out", day).exists()


# --- results to the central store -------------------------------------------------------------


def test_results_sent_to_the_central_store_whole_per_loop_day_and_again_unchanged(
    archive: Path, two_workers: Path, central_url: str, tmp_path: Path
) -> None:
    from fuelid.central import connect
    from fuelid.fleet._to_central import send_results

    def central_rows() -> dict[tuple[str, float], tuple[Any, ...]]:
        with connect(central_url) as con:
            rows = con.execute(
                "SELECT loop_id, t_to, accepted, k, se_k, reason, gates FROM reidentified"
            ).fetchall()
        return {(r[0], r[1]): r[2:] for r in rows}

    days = list_loop_days(archive)
    sent = send_results(central_url, two_workers, days)
    frames = {
        loop: pq.read_table(two_workers / "windows" / f"loop={loop}").to_pandas()
        for loop in ("line-a", "line-b")
    }
    assert sent["loop_days"] == 2
    assert sent["windows"] == sum(len(f) for f in frames.values())
    rows = central_rows()
    assert len(rows) == sent["windows"]
    for loop, frame in frames.items():  # value for value (NaN as NULL)
        for r in frame.itertuples():
            accepted, k, se_k, reason, gates = rows[(loop, r.t_to)]
            assert accepted == r.accepted
            assert reason == r.reason
            assert gates == json.loads(r.gates)
            assert (k, se_k) == (
                None if math.isnan(r.K) else r.K,
                None if math.isnan(r.se_K) else r.se_K,
            )
    with connect(central_url) as con:
        runs = con.execute("SELECT loop_id, run_id, summary FROM reidentify_runs").fetchall()
    assert sorted(r[0] for r in runs) == ["line-a", "line-b"]
    assert {r[0]: r[1] for r in runs} == sent["run_ids"]
    assert all(r[2]["windows"] == len(frames[r[0]]) for r in runs)
    # sent again: the same rows, none doubled
    send_results(central_url, two_workers, days)
    assert central_rows() == rows
    # a loop-day recomputed with fewer windows replaces its rows whole
    copy = tmp_path / "copy"
    shutil.copytree(two_workers, copy)
    part = copy / "windows" / "loop=line-b" / f"date={DATE}" / "part.parquet"
    pq.write_table(pq.read_table(part).slice(0, 5), part)
    send_results(central_url, copy, days)
    after = central_rows()
    assert sum(1 for key in after if key[0] == "line-b") == 5
    assert {k: v for k, v in after.items() if k[0] == "line-a"} == {
        k: v for k, v in rows.items() if k[0] == "line-a"
    }
