"""Issue 37: a time column that runs backwards is refused; a few rows out of order are sorted.

The log is the built-in reference plant's step log as ``fuelid simulate`` writes it (a 0.5 V
step at 10 s, 60 s at 0.02 s: 3001 rows, t = 0 … 60 s).

Acceptance, stated before running:

* the clock reversed (t → t_max − t, rows kept in time order): refused with a DataError whose
  one line names data row 1 and its time (60 s), says the column runs backwards (a reversed clock
  column, or rows in reverse order) and what to do (reverse the rows / check the time column);
* five swapped pairs of rows: loaded, sorted, with today's note naming the first row out of
  order, and the same samples as the log in order (exactly);
* rows shuffled at random (about half the steps go back): still sorted, not refused (the
  threshold is three quarters of the steps);
* reversed apart from a few stray rows (over 99 % of the steps go back): refused.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from fuelid.errors import DataError
from fuelid.io._log_grid import BACKWARDS_FRACTION
from fuelid.io.logs import load_log
from fuelid.plant import load_plant_config
from fuelid.workflow import SimulationRequest, simulate_log


@pytest.fixture(scope="module")
def step_log() -> pd.DataFrame:
    """The reference plant's default step log, as ``fuelid simulate`` writes it."""
    log = simulate_log(load_plant_config(), SimulationRequest()).to_log()
    return log.to_pandas()[["t_s", "u_V", "q_Lpm"]]


def _write(frame: pd.DataFrame, path: Path) -> Path:
    frame.to_csv(path, index=False)
    return path


def test_a_clock_column_that_counts_down_is_refused_naming_row_1(
    step_log: pd.DataFrame, tmp_path: Path
) -> None:
    reversed_clock = step_log.assign(t_s=step_log["t_s"].max() - step_log["t_s"])
    path = _write(reversed_clock, tmp_path / "reversed.csv")
    with pytest.raises(DataError) as refused:
        load_log(path)
    message = str(refused.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: the time column 't_s' runs backwards")
    assert "t = 60 s at data row 1 " in message
    assert "t = 0 s at data row 3001" in message
    assert "3000 of 3000 steps go back in time" in message
    assert "a reversed clock column, or rows in reverse order" in message
    assert "reverse them (oldest first)" in message
    assert "check the time column" in message


def test_date_time_stamps_that_count_down_are_refused(
    step_log: pd.DataFrame, tmp_path: Path
) -> None:
    start = pd.Timestamp("2026-03-01 12:00:00")
    stamps = start + pd.to_timedelta(step_log["t_s"].max() - step_log["t_s"], unit="s")
    frame = step_log.assign(t_s=stamps.dt.strftime("%Y-%m-%d %H:%M:%S.%f").str[:-3])
    with pytest.raises(DataError, match="runs backwards: it falls from t = 0 s at data row 1"):
        load_log(_write(frame, tmp_path / "stamps.csv"))


def test_a_few_swapped_rows_are_still_sorted_with_a_note(
    step_log: pd.DataFrame, tmp_path: Path
) -> None:
    in_order = load_log(_write(step_log, tmp_path / "log.csv"))
    order = np.arange(len(step_log))
    for i in (100, 400, 501, 1700, 2900):  # five swapped pairs
        order[[i, i + 1]] = order[[i + 1, i]]
    data = load_log(_write(step_log.iloc[order], tmp_path / "swapped.csv"))
    # today's note: data rows count from 1, so the first row out of order is row 102
    assert "timestamps out of order (first at data row 102): sorted by time" in data.notes
    assert data.n_samples == in_order.n_samples == 3001
    np.testing.assert_array_equal(data.u, in_order.u)
    np.testing.assert_array_equal(data.y, in_order.y)


def test_rows_shuffled_at_random_are_sorted_not_refused(
    step_log: pd.DataFrame, tmp_path: Path
) -> None:
    # a table exported without an order has a clock that runs forward: about half of its steps
    # go back in time (50 % ± 1 % for 3001 rows), well below the three quarters refused
    order = np.random.default_rng(37).permutation(len(step_log))
    shuffled = step_log.iloc[order]
    backwards = float(np.mean(np.diff(shuffled["t_s"].to_numpy()) < 0.0))
    assert 0.45 < backwards < 0.55 < BACKWARDS_FRACTION
    data = load_log(_write(shuffled, tmp_path / "shuffled.csv"))
    assert any(note.startswith("timestamps out of order") for note in data.notes)
    in_order = load_log(_write(step_log, tmp_path / "log.csv"))
    np.testing.assert_array_equal(data.y, in_order.y)


def test_a_reversed_clock_with_a_few_stray_rows_is_still_refused(
    step_log: pd.DataFrame, tmp_path: Path
) -> None:
    order = np.arange(len(step_log))[::-1].copy()
    for i in (10, 1000, 2000):
        order[[i, i + 1]] = order[[i + 1, i]]  # turns one step forward (the pair's own)
    with pytest.raises(DataError, match=r"runs backwards: .* \(2997 of 3000 steps go back"):
        load_log(_write(step_log.iloc[order], tmp_path / "newest_first.csv"))
