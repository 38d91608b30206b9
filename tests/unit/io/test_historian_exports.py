"""Historian exports as they come: time zones, clock changes, stamp forms, preambles, clocks.

Every log here is a first-order response sampled on a known grid, then written the way a
historian writes it. What is read back is checked against that grid: the samples' count, the
period and the segments are fixed by how the log was made, not by what the reader printed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.errors import DataError
from fuelid.io._log_grid import PeriodFit, fit_period, round_period
from fuelid.io.logs import load_log

runner = CliRunner()
H = 0.1
N = 3000


def signals(n: int = N, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A command stepping every 30 s and the flow following it, with meter noise."""
    rng = np.random.default_rng(seed)
    u = np.where((np.arange(n) // 300) % 2 == 1, 1.5, 1.0)
    y = 20.0 + 13.8 * (u - 1.0) + rng.normal(0.0, 0.05, n)
    return u, y


def utc_grid(start: str, n: int = N, h: float = H) -> pd.DatetimeIndex:
    """``n`` instants ``h`` apart from ``start`` (UTC)."""
    return pd.date_range(start, periods=n, freq=pd.Timedelta(seconds=h), tz="UTC")


def write(path: Path, stamps: list[str] | np.ndarray, n: int = N, sep: str = ",") -> Path:
    u, y = signals(n)
    pd.DataFrame({"t": stamps, "u_V": u, "q_Lpm": y}).to_csv(path, index=False, sep=sep)
    return path


def refused(path: Path, *args: str) -> str:
    result = runner.invoke(app, ["identify", str(path), "--time-col", "t", *args])
    assert result.exit_code == 2, result.output
    assert result.stderr.count("\n") == 1, result.stderr
    return result.stderr


# --- time zones and clock changes ----------------------------------------------------------------


def test_offsets_that_change_at_the_spring_clock_change_are_read_as_utc(tmp_path: Path) -> None:
    # 2.5 minutes either side of 01:00 UTC on 2026-03-29, when Berlin goes from +01:00 to +02:00
    instants = utc_grid("2026-03-29 00:57:30")
    local = instants.tz_convert("Europe/Berlin")
    stamps = [f"{s:%Y-%m-%dT%H:%M:%S.%f}"[:-3] + f"{s:%z}"[:3] + ":00" for s in local]
    assert stamps[0].endswith("+01:00")
    assert stamps[-1].endswith("+02:00")
    data = load_log(write(tmp_path / "offsets.csv", stamps), time_col="t")
    assert data.sample_time == H
    assert data.n_samples == N
    assert data.n_segments == 1
    assert any("UTC offsets converted to UTC" in note for note in data.notes)


def test_local_stamps_through_the_autumn_change_need_the_zone(tmp_path: Path) -> None:
    # 02:57:30 to 03:00 summer time, then 02:00 to 02:02:30 again in winter time
    instants = utc_grid("2026-10-25 00:57:30")
    local = instants.tz_convert("Europe/Berlin").tz_localize(None)
    path = write(tmp_path / "autumn.csv", [f"{s:%Y-%m-%d %H:%M:%S.%f}"[:-3] for s in local])
    message = refused(path)
    assert "steps back by an hour" in message
    assert "--timezone" in message
    data = load_log(path, time_col="t", timezone="Europe/Berlin")
    assert data.n_samples == N
    assert data.n_segments == 1
    assert data.sample_time == H


def test_local_stamps_through_the_spring_change_have_no_hour_long_gap(tmp_path: Path) -> None:
    instants = utc_grid("2026-03-29 00:57:30")
    local = instants.tz_convert("Europe/Berlin").tz_localize(None)
    path = write(tmp_path / "spring.csv", [f"{s:%d.%m.%Y %H:%M:%S,%f}"[:-3] for s in local])
    data = load_log(path, time_col="t", timezone="Europe/Berlin")
    assert data.n_samples == N
    assert data.n_segments == 1


def test_the_repeated_hour_alone_cannot_be_placed_and_is_refused_naming_its_rows(
    tmp_path: Path,
) -> None:
    # 02:10 to 02:15 local on the autumn day: summer or winter time, nothing in the rows says
    local = pd.date_range("2026-10-25 02:10:00", periods=N, freq=pd.Timedelta(seconds=H))
    path = write(tmp_path / "repeated.csv", [f"{s:%Y-%m-%d %H:%M:%S.%f}" for s in local])
    message = refused(path, "--timezone", "Europe/Berlin")
    assert "hour repeated at the autumn clock change" in message
    assert "data rows 1 to 3000" in message


def test_a_stamp_in_the_skipped_spring_hour_is_refused(tmp_path: Path) -> None:
    local = pd.date_range("2026-03-29 02:10:00", periods=N, freq=pd.Timedelta(seconds=H))
    path = write(tmp_path / "skipped.csv", [f"{s:%Y-%m-%d %H:%M:%S.%f}" for s in local])
    message = refused(path, "--timezone", "Europe/Berlin")
    assert "data row 1" in message
    assert "does not exist in Europe/Berlin" in message


def test_an_unknown_time_zone_is_refused(tmp_path: Path) -> None:
    path = write(tmp_path / "log.csv", list(H * np.arange(N)))
    assert "not an IANA name" in refused(path, "--timezone", "Mars/Olympus")


# --- the stamps' form ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("form", "given"),
    [
        ("%d-%b-%y %H:%M:%S.%f", None),  # 28-Mar-26 01:58:30.100, guessed
        ("%m/%d/%Y %I:%M:%S.%f %p", None),  # 03/28/2026 01:58:30.100 PM, guessed
        ("%Y%m%d %H%M%S.%f", "%Y%m%d %H%M%S.%f"),  # a form no one guesses: given
    ],
)
def test_stamp_forms_are_read_guessed_or_given(
    tmp_path: Path, form: str, given: str | None
) -> None:
    instants = utc_grid("2026-03-28 13:58:30").tz_localize(None)
    path = write(tmp_path / "forms.csv", [f"{s:{form}}" for s in instants])
    data = load_log(path, time_col="t", time_format=given)
    assert data.n_samples == N
    assert data.sample_time == H
    assert data.n_segments == 1


def test_a_time_format_that_does_not_match_is_refused_naming_the_row(tmp_path: Path) -> None:
    instants = utc_grid("2026-03-28 13:58:30").tz_localize(None)
    path = write(tmp_path / "log.csv", [f"{s:%Y-%m-%d %H:%M:%S.%f}" for s in instants])
    message = refused(path, "--time-format", "%d.%m.%Y %H:%M:%S")
    assert "data row 1" in message
    assert "does not match the time format" in message


def test_day_and_month_that_the_stamps_cannot_tell_apart_are_named(tmp_path: Path) -> None:
    instants = utc_grid("2026-03-04 10:00:00").tz_localize(None)  # 04/03 or 03/04?
    path = write(tmp_path / "slashed.csv", [f"{s:%d/%m/%Y %H:%M:%S.%f}" for s in instants])
    data = load_log(path, time_col="t")
    assert any("read as day/month" in note and "--time-format" in note for note in data.notes)
    assert data.n_samples == N
    assert data.sample_time == H


# --- preambles ------------------------------------------------------------------------------------


PREAMBLE = "Export of FIC-101;;\nTag;Description;\nFrom;28.03.2026 00:00;To 28.03.2026 01:00\n\n"


def test_a_preamble_above_the_header_is_found_by_the_columns_asked_for(tmp_path: Path) -> None:
    body = write(tmp_path / "body.csv", list(H * np.arange(N)), sep=";").read_text()
    path = tmp_path / "preamble.csv"
    path.write_text(PREAMBLE + body)
    data = load_log(path, time_col="t")
    assert data.n_samples == N
    assert any("skipped 4 line(s) above the header" in note for note in data.notes)
    assert load_log(path, time_col="t", skip_rows=4).n_samples == N


def test_a_preamble_with_other_column_names_is_refused_naming_the_header_row(
    tmp_path: Path,
) -> None:
    body = write(tmp_path / "body.csv", list(H * np.arange(N)), sep=";").read_text()
    path = tmp_path / "preamble.csv"
    path.write_text(PREAMBLE + body)
    message = refused(path, "--output-col", "FIC101.PV")
    assert "line 5 ('t;u_V;q_Lpm') looks like the header" in message
    assert "--skip-rows 4" in message


# --- the sample time ------------------------------------------------------------------------------


def jittered(seed: int, n: int = N) -> tuple[np.ndarray, np.ndarray]:
    """Stamps on a 0.1 s grid with ±15 ms of uniform jitter, one 20-sample gap, in ms."""
    rng = np.random.default_rng(seed)
    t = H * np.arange(n) + rng.uniform(-0.015, 0.015, n)
    keep = np.ones(n, dtype=bool)
    start = int(rng.integers(100, n - 100))
    keep[start : start + 20] = False
    return np.round(t, 3), keep


def test_the_period_under_jitter_is_rounded_to_what_the_stamps_support(tmp_path: Path) -> None:
    # seed 1 gave 0.100001 s before: a fit over 3000 samples with sd 8.7 ms has a standard
    # error of 8.7 ms·√12 / 3000^1.5 ≈ 1.8e-7 s, so 0.1 is within 3 standard errors
    t, keep = jittered(1)
    u, y = signals()
    path = tmp_path / "jitter.csv"
    pd.DataFrame({"t": t[keep], "u_V": u[keep], "q_Lpm": y[keep]}).to_csv(path, index=False)
    data = load_log(path, time_col="t")
    assert data.sample_time == H
    assert data.n_segments == 2
    given = load_log(path, time_col="t", sample_time=H)
    assert given.sample_time == H
    assert any("lie on the 0.1 s grid given" in note for note in given.notes)


def test_fitted_period_and_its_standard_error_match_the_jitter() -> None:
    # stamps with white jitter of sd σ: the least-squares slope has se σ/√Σ(k−k̄)²
    rng = np.random.default_rng(7)
    n, sigma = 20_000, 0.003
    t = 0.02 * np.arange(n) + rng.normal(0.0, sigma, n)
    fit = fit_period(t, np.zeros(n - 1, dtype=bool), 0.02)
    expected_se = sigma / np.sqrt(n * (n * n - 1) / 12.0)
    assert fit.se == pytest.approx(expected_se, rel=0.05)  # σ̂ from 20,000 residuals: ±1 %
    assert abs(fit.h - 0.02) < 4.0 * expected_se
    assert round_period(PeriodFit(fit.h, fit.se), n) == 0.02


def test_a_slow_plc_clock_with_a_late_poll_is_read(tmp_path: Path) -> None:
    # the PLC's 20 ms period is 20.4 ms of the recorder's clock; one poll answered 17.2 ms late
    rng = np.random.default_rng(3)
    n, h = 6000, 0.0204
    t = h * np.arange(n) + rng.normal(0.0, 0.0007, n)
    t[1000] += 0.0172
    t[1001] -= 0.0014
    u, y = signals(n)
    path = tmp_path / "slow.csv"
    pd.DataFrame({"t_s": np.round(t - t[0], 4), "u_V": u, "q_Lpm": y}).to_csv(path, index=False)
    data = load_log(path)
    assert data.sample_time == h
    assert data.n_samples == n
    assert data.n_segments == 1
    assert any("1 late or early poll(s) put on their own slots" in note for note in data.notes)
    with pytest.raises(DataError, match=r"says 0\.0204 s between samples"):
        load_log(path, sample_time=0.02)


# --- files that are not what they say -----------------------------------------------------------


def test_a_text_file_named_parquet_is_named_as_such(tmp_path: Path) -> None:
    path = write(tmp_path / "log.csv", list(H * np.arange(N)))
    renamed = path.rename(tmp_path / "log.parquet")
    message = refused(renamed)
    assert "is not a Parquet file" in message
    assert "name it .csv" in message


def test_a_flow_column_without_a_number_says_which_and_why(tmp_path: Path) -> None:
    u, _ = signals()
    path = tmp_path / "nan.csv"
    pd.DataFrame({"t": H * np.arange(N), "u_V": u, "q_Lpm": ["NaN"] * N}).to_csv(path, index=False)
    message = refused(path)
    assert "column 'q_Lpm' holds no samples: 3000 of its 3000 cells" in message
    assert "'NaN' ×3000" in message


def test_bytes_and_decoded_text_read_alike(tmp_path: Path) -> None:
    # plain ASCII is parsed from its bytes, a byte-order mark makes it decoded text first
    path = write(tmp_path / "ascii.csv", list(np.round(H * np.arange(N), 3)))
    with_bom = tmp_path / "bom.csv"
    with_bom.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    fast, slow = load_log(path, time_col="t"), load_log(with_bom, time_col="t")
    np.testing.assert_array_equal(fast.u, slow.u)
    np.testing.assert_array_equal(fast.y, slow.y)
    assert fast.sample_time == slow.sample_time == H


# --- held-out exports (a new user's trial) -------------------------------------------------------


def test_a_time_format_reads_stamps_of_digits_only(tmp_path: Path) -> None:
    # 20260328135830 at 1 s: pandas reads the column as integers; the format still applies
    instants = utc_grid("2026-03-28 13:58:30", h=1.0).tz_localize(None)
    path = write(tmp_path / "packed.csv", [f"{s:%Y%m%d%H%M%S}" for s in instants])
    data = load_log(path, time_col="t", time_format="%Y%m%d%H%M%S")
    assert data.sample_time == 1.0
    assert data.n_segments == 1  # no invented gap at each minute and hour boundary


def test_a_zone_that_does_not_change_there_is_refused_not_sorted(tmp_path: Path) -> None:
    # New York's autumn change (2026-11-01 06:00 UTC) read in Berlin's zone: still an hour back
    instants = utc_grid("2026-11-01 05:57:30")
    local = instants.tz_convert("America/New_York").tz_localize(None)
    path = write(tmp_path / "ny.csv", [f"{s:%Y-%m-%d %H:%M:%S.%f}" for s in local])
    message = refused(path, "--timezone", "Europe/Berlin")
    assert "steps back by an hour at data row 1501" in message
    assert "even in Europe/Berlin" in message
    assert load_log(path, time_col="t", timezone="America/New_York").n_segments == 1


def test_the_spring_jump_without_a_zone_is_named(tmp_path: Path) -> None:
    instants = utc_grid("2026-03-08 06:57:30")
    local = instants.tz_convert("America/New_York").tz_localize(None)
    path = write(tmp_path / "ny.csv", [f"{s:%Y-%m-%d %H:%M:%S.%f}" for s in local])
    data = load_log(path, time_col="t")
    assert any("jump forward by an hour between data rows 1500 and 1501" in n for n in data.notes)
    in_berlin = load_log(path, time_col="t", timezone="Europe/Berlin")  # the wrong zone
    assert any("even in Europe/Berlin" in note for note in in_berlin.notes)


def test_stamps_coarser_than_the_samples_say_what_to_do(tmp_path: Path) -> None:
    instants = utc_grid("2026-03-28 13:58:30").tz_localize(None)
    path = write(tmp_path / "seconds.csv", [f"{s:%Y-%m-%d %H:%M:%S}" for s in instants])
    message = refused(path)
    assert "2700 of 3000 rows repeat the stamp before them" in message
    assert "--sample-time 0.1 --time-col ''" in message
    data = load_log(path, time_col="", sample_time=H)
    assert data.n_samples == N


def test_a_row_of_units_under_the_header_with_an_empty_time_cell(tmp_path: Path) -> None:
    instants = utc_grid("2026-03-28 13:58:30").tz_localize(None)
    body = write(tmp_path / "b.csv", [f"{s:%d/%m/%Y %H:%M:%S.%f}" for s in instants]).read_text()
    header, rows = body.split("\n", 1)
    path = tmp_path / "units.csv"
    path.write_text(f"{header}\n,V,L/min\n{rows}")
    data = load_log(path, time_col="t")
    assert data.n_samples == N
    assert data.y_unit == "L/min"


def test_a_field_more_than_the_header_is_refused(tmp_path: Path) -> None:
    lines = ["t,u_V,q_Lpm"] + [
        f"2026-03-28 13:58:{30 + k // 10:02d},{k % 10}00,1.0,20.0" for k in range(30)
    ]
    path = tmp_path / "comma_ms.csv"
    path.write_text("\n".join(lines) + "\n")
    assert "one field more than the header (4 against 3)" in refused(path)


def test_a_gap_between_jittered_stamps_is_measured_in_periods(tmp_path: Path) -> None:
    # two samples missing: 3 periods between the stamps either side, 0.312 s with their jitter
    t = H * np.arange(N)
    t[1000] -= 0.006
    t[1003] += 0.006
    keep = np.ones(N, dtype=bool)
    keep[1001:1003] = False
    u, y = signals()
    path = tmp_path / "gap.csv"
    pd.DataFrame({"t": t[keep], "u_V": u[keep], "q_Lpm": y[keep]}).to_csv(path, index=False)
    data = load_log(path, time_col="t", fill_gaps=0.3)
    assert data.n_segments == 1
    assert data.n_samples == N


def test_utf16_without_a_byte_order_mark_is_read(tmp_path: Path) -> None:
    text = write(tmp_path / "log.csv", list(H * np.arange(N)), sep="\t").read_text()
    path = tmp_path / "utf16.csv"
    path.write_bytes(text.encode("utf-16-le"))
    assert load_log(path, time_col="t").n_samples == N


def test_skip_rows_that_land_off_the_header_point_at_it(tmp_path: Path) -> None:
    body = write(tmp_path / "body.csv", list(H * np.arange(N)), sep=";").read_text()
    path = tmp_path / "preamble.csv"
    path.write_text(PREAMBLE + body)
    message = refused(path, "--skip-rows", "3")
    assert "line 4, below --skip-rows 3, is no header" in message
    assert "--skip-rows 4" in message


def test_a_preamble_line_naming_the_columns_is_not_the_header(tmp_path: Path) -> None:
    body = write(tmp_path / "body.csv", list(H * np.arange(N))).read_text()
    path = tmp_path / "tags.csv"
    path.write_text("Historian export,,\nTags:,t,u_V,q_Lpm\n\n" + body)
    data = load_log(path, time_col="t")
    assert data.n_samples == N
    assert any("skipped 3 line(s) above the header" in note for note in data.notes)


def test_a_trailing_separator_on_the_data_rows_is_named(tmp_path: Path) -> None:
    lines = ["t,u_V,q_Lpm"] + [f"{k * H:.1f},{1 + k // 100},{20 + k % 7}," for k in range(300)]
    path = tmp_path / "trailing.csv"
    path.write_text("\n".join(lines) + "\n")
    assert "an empty last one: each row ends with a ','" in refused(path)


def test_stamps_to_the_minute_are_guessed_and_called_coarse(tmp_path: Path) -> None:
    # Excel's default 28/03/2026 13:58 for samples every second
    instants = utc_grid("2026-03-28 13:58:00", n=300, h=1.0).tz_localize(None)
    path = write(tmp_path / "excel.csv", [f"{s:%d/%m/%Y %H:%M}" for s in instants], n=300)
    message = refused(path)
    assert "(whole minutes?)" in message
    assert "--sample-time 1 --time-col ''" in message


def test_skip_rows_beside_the_header_point_at_it(tmp_path: Path) -> None:
    body = write(tmp_path / "body.csv", list(H * np.arange(N)), sep=";").read_text()
    path = tmp_path / "preamble.csv"
    path.write_text(PREAMBLE + body)
    message = refused(path, "--skip-rows", "5")
    assert "line 6, below --skip-rows 5, does not name the columns asked for" in message
    assert "--skip-rows 4" in message
