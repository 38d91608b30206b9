"""Send a re-identification's results to the central store (``fuelid reidentify --central``).

After the loop-days are done, every loop-day of the selection with a result file is sent whole
(:func:`fuelid.central._reidentified.send_loop_day`: deleted and copied in one transaction), then
each loop's fingerprint, summary and K(T) tracking
(:func:`~fuelid.central._reidentified.register_run`). Sending again is harmless: the same rows
replace themselves. So a run that was killed, or whose central store was away, is completed by
running the same command again: the loop-days already computed are skipped, and all are sent.
The run id is the SHA-256 of the loop's fingerprint (``RESULT/settings/<loop_id>.json``).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import pyarrow.parquet as pq

from fuelid.archive import LoopDay
from fuelid.fleet._task import result_path

__all__ = ["run_id_of", "send_results"]


def run_id_of(fingerprint: dict[str, Any]) -> str:
    """The result set's id: SHA-256 hex of the fingerprint's canonical JSON."""
    text = json.dumps(fingerprint, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def send_results(url: str, out_root: str | Path, days: Iterable[LoopDay]) -> dict[str, Any]:
    """Send the finished loop-days of ``days`` and their loops' summaries; what was sent.

    Returns ``{"url", "loop_days", "windows", "run_ids": {loop_id: run_id}}`` (the URL without
    a password).

    Raises
    ------
    CentralError
        The store is unreachable, has another schema version, or refused a loop-day (the
        loop-days sent before it stay sent; run the command again).
    """
    from fuelid.central import check_schema, connect, redact, register_run, send_loop_day

    out = Path(out_root)
    by_loop: dict[str, list[LoopDay]] = {}
    for day in days:
        by_loop.setdefault(day.loop_id, []).append(day)
    sent_days = sent_rows = 0
    run_ids: dict[str, str] = {}
    with connect(url, application_name="fuelid reidentify") as con:
        check_schema(con)
        con.commit()
        for loop_id, loop_days in sorted(by_loop.items()):
            fingerprint = json.loads((out / "settings" / f"{loop_id}.json").read_text("utf-8"))
            run_id = run_ids[loop_id] = run_id_of(fingerprint)
            for day in sorted(loop_days):
                path = result_path(out, day)
                if not path.exists():  # failed or not selected: nothing to send
                    continue
                rows = pq.read_table(path).to_pylist()
                sent_rows += send_loop_day(con, run_id, loop_id, day.date, rows)
                sent_days += 1
            tracking_file = out / "tracking" / f"{loop_id}.json"
            tracked = json.loads(tracking_file.read_text("utf-8")) if tracking_file.exists() else {}
            register_run(
                con,
                run_id,
                loop_id,
                fingerprint,
                tracked.get("summary"),
                tracked.get("tracking"),
            )
    return {"url": redact(url), "loop_days": sent_days, "windows": sent_rows, "run_ids": run_ids}
