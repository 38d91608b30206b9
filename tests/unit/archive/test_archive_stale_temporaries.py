"""Temporary files that writers killed mid-write leave are removed by the next write.

Found by the fleet's kill-and-resume test: a worker killed between writing and renaming left
``.part.parquet.<pid>.tmp`` beside the file the resumed run wrote. A live writer's is kept.
"""

from __future__ import annotations

import os
from pathlib import Path

import pyarrow as pa

from fuelid.archive import write_table


def test_a_dead_writers_temporary_file_is_removed_and_a_live_ones_kept(tmp_path: Path) -> None:
    path = tmp_path / "date=2026-01-02" / "part.parquet"
    path.parent.mkdir()
    dead = path.with_name(f".{path.name}.{2**22 + 12345}.tmp")  # above Linux's pid_max
    live = path.with_name(f".{path.name}.{os.getppid()}.tmp")  # our parent runs
    dead.write_bytes(b"half a file")
    live.write_bytes(b"being written")
    write_table(pa.table({"x": [1.0, 2.0]}), path)
    assert path.exists()
    assert not dead.exists()
    assert live.exists()
