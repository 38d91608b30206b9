"""The dashboard's live reader reads every column of the samples (store schema 5).

The live stream reads the samples committed since its cursor (``SQLiteLoop.samples_after``);
with a column list of its own it read the rows of schema 4 only, the arrays' reader failed on
them, and the stream stopped sending after its first status event (a trial at 5x saw the page
"disconnected" within seconds while the service ran). Every reader now takes the one list
(:data:`fuelid.store._records.SAMPLE_COLUMNS_SQL`).
"""

from __future__ import annotations

from pathlib import Path

from fuelid.dashboard import SQLiteLoop
from fuelid.store import Sample, SQLiteStore

T0 = 1.7e9


def test_the_live_reader_reads_the_applied_signal_and_the_run_flag(tmp_path: Path) -> None:
    path = tmp_path / "loop.db"
    signal = [0.1 * (k % 2) for k in range(10)]
    samples = [
        Sample(T0 + 0.02 * k, k, 2.0, 40.0, 40.0, 20.0, 1, 0, signal[k], 1) for k in range(10)
    ]
    with SQLiteStore(path, site_name="loop", tag_map_hash="ab", period_s=0.02) as store:
        store.append(samples, [])
    loop = SQLiteLoop(path)
    try:
        cursor, batch = loop.samples_after(0, 100)
        again, empty = loop.samples_after(cursor, 100)
    finally:
        loop.close()
    assert len(batch) == 10
    assert batch.excitation.tolist() == signal
    assert batch.run.tolist() == [1.0] * 10
    assert (again, len(empty)) == (cursor, 0)
