"""Gaps, jitter, sample time and fuel temperature in PLC logs (issue 12, items 3 and 7).

A log with gaps loads as segments (nothing interpolated across a gap unless asked, and then
only for short gaps); time stamps that scatter around a steady period are placed on its grid with
their values unchanged; a sample time and a time column must agree; the fuel temperature follows
u and y through every step and arrives in kelvin.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.cli._common import read_log
from fuelid.errors import DataError
from fuelid.io.logs import FILL_GAPS_MAX_PERIODS, MIN_SAMPLES, load_log

runner = CliRunner()
H = 0.02
N = 1000
LOST = (150, 400, 401, 402, 640, 800)
"""Samples (0-based) left out: four gaps, 0.04, 0.08, 0.04 and 0.04 s long."""


def signals(n: int = N, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """u: levels between 2.5 and 3.5 V every 50 samples; y: a noisy first-order response; T [°C]."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(2.5, 3.5, n // 50 + 1), 50)[:n]
    y = np.empty(n)
    y[0] = 40.0
    a = np.exp(-H / 1.2)
    for k in range(1, n):
        y[k] = a * y[k - 1] + (1 - a) * 13.0 * u[k - 1]
    y = np.round(y + rng.normal(0.0, 0.05, n), 6)
    T_degC = np.round(8.0 + 0.5 * np.sin(np.arange(n) / 200.0), 3)
    return u, y, T_degC


def frame(t: np.ndarray, keep: np.ndarray | None = None) -> pd.DataFrame:
    u, y, T_degC = signals(t.size)
    data = pd.DataFrame({"t_s": np.round(t, 6), "u_V": u, "q_Lpm": y, "T_fuel_degC": T_degC})
    return data if keep is None else data[keep]


def gappy(path: Path) -> Path:
    keep = np.ones(N, dtype=bool)
    keep[list(LOST)] = False
    frame(H * np.arange(N), keep).to_csv(path, index=False)
    return path


def refused(path: Path, **options: object) -> str:
    with pytest.raises(DataError) as info:
        load_log(path, **options)  # type: ignore[arg-type]
    message = str(info.value)
    assert "\n" not in message
    return message


# --- gaps ----------------------------------------------------------------------------------------


def test_every_gap_is_listed_and_the_log_loads_as_segments(tmp_path: Path) -> None:
    data = load_log(gappy(tmp_path / "gaps.csv"))
    u, y, _ = signals()
    keep = np.setdiff1d(np.arange(N), LOST)
    np.testing.assert_array_equal(data.u, u[keep])
    np.testing.assert_array_equal(data.y, y[keep])
    assert data.sample_time == H
    assert data.n_segments == 5
    assert data.segment_starts == (150, 399, 636, 795)
    assert data.segment_t0 == pytest.approx((3.02, 8.06, 12.82, 16.02))
    sizes = [stop - start for start, stop in data.segment_bounds()]
    assert sizes == [150, 249, 237, 159, 199]
    assert sum(sizes) == N - len(LOST)
    np.testing.assert_allclose(data.t, H * keep)
    (note,) = (note for note in data.notes if "gaps" in note)
    assert note.startswith("4 gaps split the log into 5 segments, identified jointly")
    assert "0.04 s at t = 2.98 s (data row 150), 0.08 s at t = 7.98 s (data row 399)" in note
    assert "0.04 s at t = 12.78 s (data row 636), and 1 more" in note


def test_a_missing_row_in_a_log_without_gaps_elsewhere_is_one_gap(tmp_path: Path) -> None:
    """The issue's case: one missing row used to block loading."""
    keep = np.ones(N, dtype=bool)
    keep[500] = False
    frame(H * np.arange(N), keep).to_csv(tmp_path / "one.csv", index=False)
    data = load_log(tmp_path / "one.csv")
    assert data.segment_starts == (500,)
    assert any(
        note.startswith("1 gap splits the log into 2 segments")
        and "0.04 s at t = 9.98 s (data row 500)" in note
        for note in data.notes
    )


def test_segments_too_short_to_use_are_dropped_with_a_note(tmp_path: Path) -> None:
    keep = np.ones(N, dtype=bool)
    keep[[300, 307]] = False  # samples 301..306 (6) between two gaps
    frame(H * np.arange(N), keep).to_csv(tmp_path / "short.csv", index=False)
    data = load_log(tmp_path / "short.csv")
    assert data.n_samples == N - 2 - 6
    assert data.segment_starts == (300,)
    assert data.segment_t0 == pytest.approx((308 * H,))
    assert any(
        f"dropped 1 segment(s) shorter than {MIN_SAMPLES} samples (6 samples, the first at "
        "t = 6.02 s, data row 301): 2 segment(s) left" in note
        for note in data.notes
    )


def test_a_log_of_only_short_segments_is_refused(tmp_path: Path) -> None:
    keep = (np.arange(60) % 6) != 5  # 5 samples, one missing, 5 samples, ...
    frame(H * np.arange(60), keep).to_csv(tmp_path / "broken.csv", index=False)
    message = refused(tmp_path / "broken.csv")
    assert f"no stretch of {MIN_SAMPLES} samples or more between the 9 gap(s)" in message
    assert "--fill-gaps" in message
    data = load_log(tmp_path / "broken.csv", fill_gaps=0.04)
    assert data.n_samples == 59
    assert data.n_segments == 1


def test_fill_gaps_bridges_short_gaps_only(tmp_path: Path) -> None:
    path = gappy(tmp_path / "gaps.csv")
    data = load_log(path, fill_gaps=0.05)
    u, y, _ = signals()
    assert data.n_segments == 2  # the 0.08 s gap stays a break
    assert data.n_samples == N - 3
    assert data.segment_starts == (400,)
    # a bridged sample: y on the straight line between its neighbours, u held
    assert data.y[150] == pytest.approx((y[149] + y[151]) / 2)
    assert data.u[150] == u[149]
    np.testing.assert_array_equal(data.y[:150], y[:150])
    np.testing.assert_array_equal(data.u[400:637], u[403:640])
    assert any(
        "bridged 3 gap(s) up to 0.04 s (fill_gaps, --fill-gaps 0.05 s): 3 sample(s) inserted, "
        "y interpolated linearly, u held" in note
        for note in data.notes
    )
    assert any("1 gap splits the log into 2 segments" in note for note in data.notes)
    assert load_log(path, fill_gaps=0.08).n_segments == 1


def test_fill_gaps_is_bounded(tmp_path: Path) -> None:
    path = gappy(tmp_path / "gaps.csv")
    bound = FILL_GAPS_MAX_PERIODS * H
    assert load_log(path, fill_gaps=bound).n_segments == 1
    message = refused(path, fill_gaps=0.2)
    assert "fill_gaps (--fill-gaps) 0.2 s is longer than 5 sample periods (0.1 s)" in message
    assert "must be a positive" in refused(path, fill_gaps=0.0)


def test_a_long_interval_is_a_gap_even_off_the_grid(tmp_path: Path) -> None:
    """A recorder restarted 1.5 periods later: off the old grid; --max-gap splits it there."""
    t = np.concatenate((H * np.arange(100), H * (100.5 + np.arange(900))))
    frame(t).to_csv(tmp_path / "restart.csv", index=False)
    message = refused(tmp_path / "restart.csv")
    assert "irregular sampling: interval of 0.03 s at t = 1.98 s (data row 100)" in message
    assert "max_gap (--max-gap) below 0.03 s makes it a gap" in message
    assert "resample=" not in message
    data = load_log(tmp_path / "restart.csv", max_gap=0.025)
    assert data.segment_starts == (100,)
    assert data.segment_t0 == pytest.approx((2.01,))
    assert any("0.03 s at t = 1.98 s (data row 100)" in note for note in data.notes)
    assert "must be longer than the median interval" in refused(
        tmp_path / "restart.csv", max_gap=0.02
    )


def test_a_dropped_bad_row_keeps_its_slot_without_a_time_column(tmp_path: Path) -> None:
    """Without a time column a dropped row used to shift every later sample by one period."""
    u, y, _ = signals(200)
    rows = [f"{ui:g},{yi}" for ui, yi in zip(u, y, strict=True)]
    rows[50] = f"{u[50]:g},"
    (tmp_path / "untimed.csv").write_text("u_V,q_Lpm\n" + "\n".join(rows) + "\n")
    data = load_log(tmp_path / "untimed.csv", sample_time=H, drop_bad_rows=True)
    assert data.n_samples == 200
    assert data.y[50] == pytest.approx((y[49] + y[51]) / 2)
    np.testing.assert_array_equal(data.y[51:], y[51:])


# --- jitter --------------------------------------------------------------------------------------


def receipt_times(n: int, seed: int = 7) -> np.ndarray:
    """20 ms poll stamped on receipt: N(0, 0.7 ms) per sample, single intervals within 7–33 ms.

    As measured on a Modbus poll: standard deviation 0.7 ms, intervals from 7 ms to 33 ms (a few
    deviations of ±6.5 ms put in to reach both ends).
    """
    rng = np.random.default_rng(seed)
    deviation = np.clip(rng.normal(0.0, 0.0007, n), -0.0065, 0.0065)
    deviation[[200, 201, 600, 601]] = [0.0065, -0.0065, -0.0065, 0.0065]
    return np.round(H * np.arange(n) + deviation, 6)


def test_receipt_time_jitter_is_placed_on_the_grid_with_the_values_unchanged(
    tmp_path: Path,
) -> None:
    t = receipt_times(N)
    dt = np.diff(t)
    assert dt.min() == pytest.approx(0.007, abs=2e-6)
    assert dt.max() == pytest.approx(0.033, abs=2e-6)
    written = frame(t)
    written.to_csv(tmp_path / "receipt.csv", index=False)
    data = load_log(tmp_path / "receipt.csv")
    assert data.sample_time == H
    assert data.n_segments == 1
    np.testing.assert_array_equal(data.u, written["u_V"].to_numpy())
    np.testing.assert_array_equal(data.y, written["q_Lpm"].to_numpy())
    assert np.max(np.abs(data.t - t)) < 0.0068  # each sample within its slot's jitter
    (note,) = (note for note in data.notes if "jitter" in note or "scatter" in note)
    assert "steady 0.02 s period (sd 0.7" in note
    assert "at most 6.5 ms" in note
    assert "values unchanged" in note
    assert not any("resampled" in note for note in data.notes)


def test_jitter_and_a_missing_row_give_a_gap_not_a_slip(tmp_path: Path) -> None:
    t = receipt_times(N)
    keep = np.ones(N, dtype=bool)
    keep[700] = False
    frame(t, keep).to_csv(tmp_path / "receipt_gap.csv", index=False)
    data = load_log(tmp_path / "receipt_gap.csv")
    assert data.segment_starts == (700,)
    assert data.segment_t0[0] == pytest.approx(701 * H, abs=0.002)
    assert data.t[-1] == pytest.approx((N - 1) * H, abs=0.002)
    assert any("1 gap splits the log" in note for note in data.notes)


def test_a_late_sample_within_half_a_period_is_a_late_poll_on_its_slot(tmp_path: Path) -> None:
    # issue 38: a poll answered 0.45 of a period late is still nearest its own slot, alone there
    t = H * np.arange(N)
    t[300] += 0.45 * H
    t[301] += 0.1 * H
    frame(t).to_csv(tmp_path / "late.csv", index=False)
    data = load_log(tmp_path / "late.csv")
    assert data.n_samples == N
    assert data.n_segments == 1
    assert any("1 late or early poll(s) put on their own slots" in note for note in data.notes)


def test_two_samples_for_one_slot_are_refused_with_where(tmp_path: Path) -> None:
    # an extra stamp 0.1 of a period after slot 300: two samples for one slot, no empty one
    t = H * np.arange(N)
    t = np.insert(t, 301, t[300] + 0.1 * H)
    pd.DataFrame(frame(t)).to_csv(tmp_path / "extra.csv", index=False)
    message = refused(tmp_path / "extra.csv")
    assert "irregular sampling: interval of 0.002 s at t = 6 s (data row 301)" in message
    data = load_log(tmp_path / "extra.csv", resample="always")
    assert data.n_samples == N
    assert any("resampled" in note for note in data.notes)


def test_a_clock_that_slips_a_period_is_not_a_lost_sample(tmp_path: Path) -> None:
    # a clock whose phase wanders by ±0.6 of a period: its stamps creep past the half-period
    # line, leaving a slot empty between one beyond +0.4 and one beyond −0.4 (and, going back,
    # two in one slot); a steady period cannot absorb a wander that is not linear
    k = np.arange(N)
    t = H * k + 0.6 * H * np.sin(2.0 * np.pi * k / N)
    frame(t).to_csv(tmp_path / "slip.csv", index=False)
    assert "irregular sampling" in refused(tmp_path / "slip.csv", resample="never")


# --- a sample time and a time column -------------------------------------------------------------


def test_a_sample_time_that_agrees_with_the_time_column_uses_it_and_its_gaps(
    tmp_path: Path,
) -> None:
    path = gappy(tmp_path / "gaps.csv")
    data = read_log(path, "t_s", "u_V", "q_Lpm", 0.02, None, None)
    assert data.n_segments == 5
    assert any("time column t_s used" in note for note in data.notes)
    assert load_log(path, sample_time=0.0201).n_segments == 5  # within 1 %


def test_a_time_column_without_a_readable_time_gives_way_to_the_sample_time(
    tmp_path: Path,
) -> None:
    written = frame(H * np.arange(200))
    clock = [f"12:00:{k * H:06.3f}" for k in range(200)]  # time of day only: not read
    written.assign(t_s=clock).to_csv(tmp_path / "clock.csv", index=False)
    assert "unreadable time" in refused(tmp_path / "clock.csv")
    data = load_log(tmp_path / "clock.csv", sample_time=H)
    assert data.n_samples == 200
    assert any("the sample time 0.02 s replaces it" in note for note in data.notes)


def test_cli_refuses_a_sample_time_that_contradicts_the_time_column(tmp_path: Path) -> None:
    frame(H * np.arange(N)).to_csv(tmp_path / "log.csv", index=False)
    result = runner.invoke(app, ["identify", str(tmp_path / "log.csv"), "--sample-time", "0.05"])
    assert result.exit_code == 2
    assert "time column 't_s' says 0.02 s" in result.stderr
    assert "--sample-time) says 0.05 s" in result.stderr
    assert result.stderr.count("\n") == 1


def test_cli_refuses_fill_gaps_beyond_its_bound(tmp_path: Path) -> None:
    path = gappy(tmp_path / "gaps.csv")
    result = runner.invoke(app, ["identify", str(path), "--fill-gaps", "1.0"])
    assert result.exit_code == 2
    assert "--fill-gaps" in result.stderr
    assert "5 sample periods" in result.stderr
    assert result.stderr.count("\n") == 1


def test_cli_names_max_gap_when_it_would_help(tmp_path: Path) -> None:
    t = np.concatenate((H * np.arange(100), H * (100.5 + np.arange(900))))
    frame(t).to_csv(tmp_path / "restart.csv", index=False)
    result = runner.invoke(app, ["identify", str(tmp_path / "restart.csv")])
    assert result.exit_code == 2
    assert "--max-gap" in result.stderr
    assert "resample=" not in result.stderr
    bad = runner.invoke(app, ["identify", str(tmp_path / "restart.csv"), "--max-gap", "0.01"])
    assert bad.exit_code == 2
    assert "--max-gap" in bad.stderr


# --- fuel temperature ----------------------------------------------------------------------------


def test_fuel_temperature_is_read_in_kelvin_and_follows_the_samples(tmp_path: Path) -> None:
    written = frame(H * np.arange(N))
    # shuffled (about half the steps go back: sorted, not a reversed clock), one duplicate, and
    # samples 899 (bridged: held like u), 499 and 498 (a gap) left out
    order = np.random.default_rng(4).permutation(N)
    shuffled = pd.concat([written.iloc[order], written.iloc[[10]]])
    keep = ~np.isin(np.r_[order, 10], [899, 499, 498])
    shuffled[keep].to_csv(tmp_path / "log.csv", index=False)
    data = load_log(tmp_path / "log.csv", fill_gaps=0.04)
    assert data.T_fuel is not None
    T_K = written["T_fuel_degC"].to_numpy() + 273.15
    assert data.n_samples == N - 2
    assert data.segment_starts == (498,)
    expected = T_K[np.r_[0:498, 500:899, 898, 900:N]]
    np.testing.assert_allclose(data.T_fuel, expected, rtol=0, atol=1e-12)
    second = data.segments()[1]
    assert second.T_fuel is not None
    assert second.T_fuel[0] == pytest.approx(T_K[500])


def test_fuel_temperature_column_absent_named_or_implausible(tmp_path: Path) -> None:
    written = frame(H * np.arange(200))
    written.drop(columns="T_fuel_degC").to_csv(tmp_path / "no_T.csv", index=False)
    assert load_log(tmp_path / "no_T.csv").T_fuel is None
    message = refused(tmp_path / "no_T.csv", fuel_temperature_col="Tf_degC")
    assert "missing column: 'Tf_degC' (fuel temperature)" in message
    assert "t_s, u_V, q_Lpm" in message
    written.rename(columns={"T_fuel_degC": "Tf"}).to_csv(tmp_path / "Tf.csv", index=False)
    data = read_log(
        tmp_path / "Tf.csv", "t_s", "u_V", "q_Lpm", None, None, None, fuel_temperature_col="Tf"
    )
    assert data.T_fuel is not None
    assert data.T_fuel[0] == pytest.approx(8.0 + 273.15)
    assert load_log(tmp_path / "Tf.csv", fuel_temperature_col=None).T_fuel is None
    kelvin = written.assign(T_fuel_degC=written["T_fuel_degC"] + 273.15)
    kelvin.to_csv(tmp_path / "kelvin.csv", index=False)
    message = refused(tmp_path / "kelvin.csv")
    assert "'T_fuel_degC' has 200 fuel temperature(s) outside -60 to 150 °C" in message
    assert "data row 1 (281.15): is it in °C?" in message
    # an empty cell is a missing sample (issue 24); other text is refused
    written = written.astype({"T_fuel_degC": object})
    written.loc[7, "T_fuel_degC"] = "err"
    written.to_csv(tmp_path / "nan.csv", index=False)
    assert "'T_fuel_degC' has 1 non-numeric cell(s), first at data row 8" in refused(
        tmp_path / "nan.csv"
    )


def test_fuel_temperature_is_held_when_resampled(tmp_path: Path) -> None:
    dt = H * (1.0 + 0.05 * np.sin(2 * np.pi * np.arange(N - 1) / (N - 1)))
    t = np.concatenate(([0.0], np.cumsum(dt)))
    written = frame(t)
    written.to_csv(tmp_path / "drift.csv", index=False)
    data = load_log(tmp_path / "drift.csv")
    assert any("resampled" in note for note in data.notes)
    assert data.T_fuel is not None
    held = np.searchsorted(written["t_s"].to_numpy(), data.t + 1e-6 * H, side="right") - 1
    np.testing.assert_allclose(data.T_fuel, written["T_fuel_degC"].to_numpy()[held] + 273.15)
