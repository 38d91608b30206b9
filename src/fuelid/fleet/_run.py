"""The re-identification run: loop-days to Dask, results as they complete, then the per-loop pass.

One Dask task per loop-day (:func:`~fuelid.fleet._task.reidentify_day`), on a
``LocalCluster`` (one single-threaded worker process per core by default) or on any running
scheduler by address. Loop-days whose result file exists are not submitted (resumable); a task
that raises is retried once, and a task whose worker dies is rescheduled by Dask itself (up to
``distributed.scheduler.allowed-failures`` times). When every loop-day is done, the K(T)
tracker and the summary of each loop (:mod:`fuelid.fleet._summary`) are computed from the
result files, so a resumed run summarises the whole period, not only what it computed.

Dask is the ``fleet`` extra: imported here, when a run starts.
"""

from __future__ import annotations

import datetime as _dt
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fuelid.archive import LoopDay, day_bounds, list_loop_days
from fuelid.errors import FuelidError
from fuelid.fleet._summary import loop_summary, read_results, track_loop, write_tracking
from fuelid.fleet._task import LoopSettings, loop_settings, reidentify_day, result_path
from fuelid.online import Online

__all__ = ["FleetError", "ReidentifyRun", "online_from_toml", "reidentify"]

CONNECT_TIMEOUT_S = 10.0
"""How long to wait for a scheduler given by address [s]."""
TASK_RETRIES = 1
"""Retries of a task that raised (a worker's death is retried by the scheduler, not counted)."""

Progress = Callable[[int, int, dict[str, Any] | None], None]
"""``progress(done, total, day_summary)``: called once with (0, total, None), then per loop-day."""


class FleetError(FuelidError):
    """A re-identification that cannot run: no archive, unknown loop, bad dates, no scheduler."""


@dataclass
class ReidentifyRun:
    """What a run did (``fuelid reidentify --json``)."""

    archive: str
    out: str
    scheduler: str
    workers: int
    loop_days: int
    computed: int
    skipped: int
    windows: int
    seconds: float
    fit_seconds: float
    loops: list[dict[str, Any]] = field(default_factory=list)
    settings: dict[str, str] = field(default_factory=dict)
    central: dict[str, Any] | None = None

    def to_json(self) -> dict[str, Any]:
        """JSON-ready record (keys in docs/reference/json.md)."""
        from fuelid.fleet._summary import SUMMARY_UNITS

        return {
            "archive": self.archive,
            "out": self.out,
            "scheduler": self.scheduler,
            "workers": self.workers,
            "loop_days": self.loop_days,
            "computed": self.computed,
            "skipped": self.skipped,
            "windows": self.windows,
            "seconds": self.seconds,
            "windows_per_s": self.windows / self.seconds if self.seconds > 0 else None,
            "settings": self.settings,
            "loops": self.loops,
            "central": self.central,
            "units": SUMMARY_UNITS,
        }


def online_from_toml(path: str | Path) -> Online:
    """The ``[online]`` table of a TOML file (``--settings``), validated as a site file's.

    Raises
    ------
    FleetError
        The file is missing, not TOML, has no ``[online]`` table, or an invalid one.
    """
    import tomllib

    from pydantic import ValidationError

    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as error:
        raise FleetError(f"--settings {path}: cannot read it ({error})") from None
    except tomllib.TOMLDecodeError as error:
        raise FleetError(f"--settings {path}: not TOML ({error})") from None
    table = data.get("online")
    if not isinstance(table, dict):
        raise FleetError(f"--settings {path}: no [online] table")
    try:
        return Online(**table)
    except ValidationError as error:
        problems = "; ".join(
            f"{'.'.join(str(p) for p in e['loc']) or 'online'}: {e['msg']}" for e in error.errors()
        )
        raise FleetError(f"--settings {path}: [online] {problems}") from None


def select_loop_days(
    archive_root: str | Path,
    loops: list[str] | None,
    date_from: str | None,
    date_to: str | None,
) -> list[LoopDay]:
    """The archive's loop-days in the selection; :class:`FleetError` with the reason if none."""
    from fuelid.store import StoreError

    for name, date in (("--from", date_from), ("--to", date_to)):
        if date is not None:
            try:
                day_bounds(date)
                _dt.date.fromisoformat(date)
            except (StoreError, ValueError):
                raise FleetError(f"{name} {date!r}: not a date (YYYY-MM-DD)") from None
    if date_from is not None and date_to is not None and date_from > date_to:
        raise FleetError(f"--from {date_from} is after --to {date_to}")
    try:
        every = list_loop_days(archive_root)
    except StoreError as error:
        raise FleetError(str(error)) from None
    known = sorted({d.loop_id for d in every})
    if loops is not None:
        unknown = [loop for loop in loops if loop not in known]
        if unknown:
            raise FleetError(
                f"unknown loop(s) {', '.join(unknown)}: the archive holds "
                f"{', '.join(known) or 'no loop'}"
            )
    days = list_loop_days(archive_root, loops, date_from, date_to)
    if not days:
        raise FleetError("no loop-day of the archive is in the selection (--loops, --from, --to)")
    return days


@contextmanager
def dask_client(scheduler: str | None, workers: int | None) -> Iterator[Any]:
    """A Dask client: of a scheduler at ``scheduler``, else of a local cluster of ``workers``."""
    try:
        import distributed
    except ImportError:  # pragma: no cover - the fleet extra is missing
        raise FleetError(
            "fuelid reidentify needs Dask distributed: pip install 'fuelid[fleet]'"
        ) from None
    # distributed is only partly typed: its classes are used as untyped (Any) here
    Client: Any = distributed.Client
    LocalCluster: Any = distributed.LocalCluster
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError, ValueError) as error:
            raise FleetError(f"Dask scheduler {scheduler} is unreachable: {error}") from None
        try:
            yield client
        finally:
            client.close()
        return
    import os

    n = workers if workers is not None else (os.cpu_count() or 1)
    if n < 1:
        raise FleetError(f"--workers must be at least 1, got {n}")
    with (
        LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address="127.0.0.1:0",  # a free port on loopback, never 8787
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


def _prepared(
    archive_root: str | Path, days: list[LoopDay], online: Online | None, source: str
) -> dict[str, tuple[LoopSettings, str | None]]:
    return {
        loop: loop_settings(archive_root, loop, online, source)
        for loop in sorted({d.loop_id for d in days})
    }


def reidentify(
    archive_root: str | Path,
    out_root: str | Path,
    *,
    loops: list[str] | None = None,
    date_from: str | None = None,
    date_to: str | None = None,
    online: Online | None = None,
    settings_source: str = "",
    scheduler: str | None = None,
    workers: int | None = None,
    client: Any = None,
    progress: Progress | None = None,
    central: str | None = None,
) -> ReidentifyRun:
    """Re-identify the selected loop-days of an archive into ``out_root`` (module docstring).

    Parameters
    ----------
    archive_root, out_root : path
        The archive, and the result folder (created).
    loops : list of str, optional
        Loop ids (default every loop of the archive).
    date_from, date_to : str, optional
        UTC dates YYYY-MM-DD, inclusive.
    online : Online, optional
        An ``[online]`` table replacing every loop's archived one; ``settings_source`` names it.
    scheduler : str, optional
        A running Dask scheduler's address (``tcp://host:8786``).
    workers : int, optional
        Worker processes of the local cluster (default the machine's cores).
    client : distributed.Client, optional
        A client to use as is (tests; ``scheduler`` and ``workers`` are then ignored).
    progress : callable, optional
        Told of each finished loop-day.
    central : str, optional
        A central store's URL: every finished loop-day of the selection and each loop's
        summary are sent there afterwards (:mod:`fuelid.fleet._to_central`).

    Raises
    ------
    FleetError
        Not an archive, an unknown loop, bad dates, an unreachable scheduler.
    ConfigError
        A loop's archived settings or plant file are unusable.
    """
    started = time.perf_counter()
    # absolute before anything derives a path from it: the plant files' paths go to workers
    # that may run in another folder (a remote scheduler's)
    archive_root = Path(archive_root).resolve()
    days = select_loop_days(archive_root, loops, date_from, date_to)
    specs = _prepared(archive_root, days, online, settings_source)
    out = Path(out_root)
    out.mkdir(parents=True, exist_ok=True)
    check_settings(out, specs)
    pending = [d for d in days if not result_path(out, d).exists()]
    summaries: list[dict[str, Any]] = []
    if progress is not None:
        progress(len(days) - len(pending), len(days), None)
    if pending:
        if client is not None:
            summaries, label, n_workers = _run(
                client, archive_root, out, pending, specs, progress, len(days) - len(pending)
            )
        else:
            with dask_client(scheduler, workers) as own:
                summaries, label, n_workers = _run(
                    own, archive_root, out, pending, specs, progress, len(days) - len(pending)
                )
    else:
        label, n_workers = scheduler or "local", 0
    loops_out = []
    for loop_id, (settings, plant_path) in specs.items():
        table = read_results(out, loop_id, date_from, date_to)
        k_plant = _k_plant(plant_path, settings)
        tracker, note = track_loop(table, k_plant)
        summary = loop_summary(loop_id, table, tracker, note)
        write_tracking(out, loop_id, tracker, summary)
        loops_out.append(summary)
    sent = None
    if central is not None:
        from fuelid.fleet._to_central import send_results

        sent = send_results(central, out, days)
    return ReidentifyRun(
        archive=str(archive_root),
        out=str(out),
        scheduler=label,
        workers=n_workers,
        loop_days=len(days),
        computed=sum(not s["skipped"] for s in summaries),
        skipped=len(days) - sum(not s["skipped"] for s in summaries),
        windows=sum(int(s["windows"]) for s in summaries),
        seconds=time.perf_counter() - started,
        fit_seconds=sum(float(s["fit_seconds"]) for s in summaries),
        loops=loops_out,
        settings={loop: spec[0].source for loop, spec in specs.items()},
        central=sent,
    )


def _fingerprint(settings: LoopSettings, plant_path: str | None) -> dict[str, Any]:
    """What makes a loop's results: the analyser's settings and the plant file's SHA-256."""
    import hashlib

    return {
        "online": settings.online.model_dump(mode="json"),
        "sample_time": settings.sample_time,
        "control_period": settings.control_period,
        "ti_s": settings.ti_s,
        "step_ls": settings.step_ls,
        "plant_sha256": None
        if plant_path is None
        else hashlib.sha256(Path(plant_path).read_bytes()).hexdigest(),
    }


def check_settings(out: Path, specs: dict[str, tuple[LoopSettings, str | None]]) -> None:
    """Refuse to resume into results made with other settings; record them for a new loop.

    ``RESULT/settings/<loop_id>.json`` holds what a loop's results were made with; a run whose
    settings differ would mix two analyses in one loop's results (the finished loop-days are
    skipped, not recomputed).
    """
    import json
    import os

    folder = out / "settings"
    folder.mkdir(parents=True, exist_ok=True)
    for loop_id, (settings, plant_path) in specs.items():
        now = _fingerprint(settings, plant_path)
        path = folder / f"{loop_id}.json"
        if path.exists():
            before = json.loads(path.read_text(encoding="utf-8"))
            if before != now:
                keys = sorted(k for k in set(before) | set(now) if before.get(k) != now.get(k))
                if "online" in keys:
                    online = before.get("online") or {}
                    keys.remove("online")
                    keys += sorted(
                        f"[online] {k}" for k in now["online"] if online.get(k) != now["online"][k]
                    )
                raise FleetError(
                    f"{out} holds loop {loop_id}'s results made with other settings "
                    f"({', '.join(keys)} differ): use another --out, or delete "
                    f"{out / 'windows' / f'loop={loop_id}'} and {path}"
                )
            continue
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(now, indent=2, sort_keys=True), encoding="utf-8")
        os.replace(tmp, path)


def _k_plant(plant_path: str | None, settings: LoopSettings) -> Any:
    if plant_path is None:
        return None
    from fuelid.online import window_priors

    return window_priors(plant_path, control_period=settings.control_period)[1]


def _run(
    client: Any,
    archive_root: str | Path,
    out: Path,
    pending: list[LoopDay],
    specs: dict[str, tuple[LoopSettings, str | None]],
    progress: Progress | None,
    offset: int,
) -> tuple[list[dict[str, Any]], str, int]:
    import distributed

    as_completed: Any = distributed.as_completed

    info = client.scheduler_info()
    label = str(info.get("address", "?"))
    n_workers = len(info.get("workers", {}))
    root = str(Path(archive_root).resolve())
    target = str(out.resolve())
    futures = client.map(
        reidentify_day,
        [root] * len(pending),
        pending,
        [specs[d.loop_id][0] for d in pending],
        [specs[d.loop_id][1] for d in pending],
        [target] * len(pending),
        pure=False,
        retries=TASK_RETRIES,
    )
    killed: Any = distributed.KilledWorker
    summaries = []
    for future in as_completed(futures):
        try:
            summary = future.result()
        except killed as error:  # the same loop-day took down workers again and again
            raise FleetError(
                f"a loop-day's task killed its worker repeatedly ({error}): out of memory? "
                "give workers more memory (dask worker --memory-limit); finished loop-days "
                "are kept, run again to resume"
            ) from None
        summaries.append(summary)
        if progress is not None:
            progress(offset + len(summaries), offset + len(pending), summary)
    return sorted(summaries, key=lambda s: (s["loop_id"], s["date"])), label, n_workers
