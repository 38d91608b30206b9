"""``fuelid plant serve --run START:END``: the run windows parsed, in seconds of plant time."""

from __future__ import annotations

from fuelid.cli._serve import parse_run_windows


def test_run_windows_parse_as_start_end_pairs() -> None:
    assert parse_run_windows(["0:3", "10.5:20"]) == [(0.0, 3.0), (10.5, 20.0)]
