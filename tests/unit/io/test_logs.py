"""Loading real and messy PLC logs: what loads (with notes) and what is refused (and how)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from fuelid.errors import DataError
from fuelid.io.logs import load_log, parse_scale

H = 0.02
N = 200
REF_DATA = Path(__file__).resolve().parents[4] / "shared" / "ref-data"


def step_response(n: int = N, h: float = H) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step of u from 1 to 1.5 V at t = 1 s; y a first-order response from 14.6 L/min."""
    t = h * np.arange(n)
    u = np.where(t >= 1.0, 1.5, 1.0)
    y = 14.6 + 3.5 * (1.0 - np.exp(-np.clip(t - 1.0, 0.0, None) / 1.2))
    return t, u, np.round(y, 6)


def write_csv(
    path: Path,
    rows: Sequence[Sequence[object]],
    header: str = "t_s,u_V,q_Lpm",
    sep: str = ",",
    encoding: str = "utf-8",
) -> Path:
    lines = [header] + [sep.join(str(cell) for cell in row) for row in rows]
    path.write_bytes(("\n".join(lines) + "\n").encode(encoding))
    return path


def plain_rows() -> list[tuple[str, str, str]]:
    t, u, y = step_response()
    return [(f"{ti:.2f}", f"{ui:g}", f"{yi:.6f}") for ti, ui, yi in zip(t, u, y, strict=True)]


def refused(path: Path, **options: object) -> str:
    """The one-line message of the DataError that loading ``path`` raises."""
    with pytest.raises(DataError) as info:
        load_log(path, **options)  # type: ignore[arg-type]
    message = str(info.value)
    assert message
    assert "\n" not in message
    return message


# --- what loads ----------------------------------------------------------------------------------


def test_plain_csv_loads_as_written(tmp_path: Path) -> None:
    _, u, y = step_response()
    data = load_log(write_csv(tmp_path / "log.csv", plain_rows()))
    assert data.n_samples == N
    assert data.sample_time == H
    assert data.t0 == 0.0
    np.testing.assert_array_equal(data.u, u)
    np.testing.assert_array_equal(data.y, y)
    assert (data.u_unit, data.y_unit) == ("V", "L/min")
    assert data.source == str(tmp_path / "log.csv")
    assert data.notes == ()


def test_semicolons_and_decimal_commas(tmp_path: Path) -> None:
    rows = [
        (f"{i * H:.2f}".replace(".", ","), "1,25" if i < 50 else "1,5", "14,6") for i in range(N)
    ]
    rows[-1] = (rows[-1][0], "1,5", "15,1")
    data = load_log(write_csv(tmp_path / "plc.csv", rows, header="t_s;u_V;q_Lpm", sep=";"))
    assert data.u[0] == 1.25
    assert data.y[0] == 14.6
    assert data.y[-1] == 15.1
    assert data.sample_time == H
    assert any("';'" in note for note in data.notes)


@pytest.mark.parametrize("suffix", [".tsv", ".txt"])
def test_tab_separated_text(tmp_path: Path, suffix: str) -> None:
    path = write_csv(tmp_path / f"log{suffix}", plain_rows(), header="t_s\tu_V\tq_Lpm", sep="\t")
    data = load_log(path)
    assert data.n_samples == N
    assert data.u[-1] == 1.5


def test_utf8_bom_is_stripped_from_the_first_column_name(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "bom.csv", plain_rows(), encoding="utf-8-sig")
    assert path.read_bytes().startswith(b"\xef\xbb\xbf")
    data = load_log(path)
    assert data.n_samples == N
    assert data.t0 == 0.0


def test_gbk_chinese_headers(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "gbk.csv", plain_rows(), header="时间,电压,流量", encoding="gbk")
    data = load_log(path, time_col="时间", input_col="电压", output_col="流量")
    assert data.n_samples == N
    assert data.y[0] == 14.6
    assert (data.u_unit, data.y_unit) == ("", "")  # the column names say no unit
    assert "read as GBK text" in data.notes


@pytest.mark.parametrize(
    ("sep", "stamp"),
    [
        (",", "2026-03-01 12:00:{sec:06.3f}"),
        (",", "2026-03-01T12:00:{sec:06.3f}"),
        (";", "2026/03/01 12:00:{sec:06.3f}"),
        (";", "01.03.2026 12:00:{sec:06.3f}"),
    ],
)
def test_datetime_stamps_become_seconds(tmp_path: Path, sep: str, stamp: str) -> None:
    t, u, y = step_response()
    decimal = "," if sep == ";" else "."
    rows: list[tuple[str, str, str]] = []
    for ti, ui, yi in zip(t, u, y, strict=True):
        whole, fraction = stamp.format(sec=20.0 + ti).rsplit(".", 1)
        rows.append(
            (
                f"{whole}{decimal}{fraction}",
                f"{ui:g}".replace(".", decimal),
                f"{yi}".replace(".", decimal),
            )
        )
    data = load_log(
        write_csv(
            tmp_path / "stamps.csv", rows, header=sep.join(["time", "u_V", "q_Lpm"]), sep=sep
        ),
        time_col="time",
    )
    assert data.sample_time == H
    assert data.t0 == 0.0
    np.testing.assert_array_equal(data.u, u)
    np.testing.assert_allclose(data.y, y, rtol=0, atol=1e-12)
    assert any("2026-03-01 12:00:20" in note for note in data.notes)
    assert not any("resampled" in note for note in data.notes)


def test_numeric_time_keeps_its_origin(tmp_path: Path) -> None:
    rows = [(f"{100 + float(row[0]):.2f}", row[1], row[2]) for row in plain_rows()]
    data = load_log(write_csv(tmp_path / "late.csv", rows))
    assert data.t0 == 100.0
    assert data.t[1] == pytest.approx(100.02)


def test_linear_scaling_of_raw_units(tmp_path: Path) -> None:
    t, u, y = step_response()
    ma = 4.0 + (u - 1.0) * 4.0  # 1 V ↔ 4 mA, 1.5 V ↔ 6 mA
    ma[5] = 12.0  # 3 V
    counts = np.round(y / 100.0 * 27648.0)
    rows = [(f"{ti:.2f}", f"{a:g}", f"{c:g}") for ti, a, c in zip(t, ma, counts, strict=True)]
    path = write_csv(tmp_path / "raw.csv", rows, header="t_s,u_mA,q_cnt")
    data = load_log(
        path,
        input_col="u_mA",
        output_col="q_cnt",
        input_scale=(4, 20, 1, 5),
        output_scale=parse_scale("0:27648:0:100"),
    )
    assert data.u[5] == 3.0
    assert data.u[0] == 1.0
    np.testing.assert_allclose(data.y, counts * 100.0 / 27648.0)
    # scaled to the engineering units of the gains (the contract of --input/--output-scale)
    assert (data.u_unit, data.y_unit) == ("V", "L/min")
    assert sum("scaled linearly" in note for note in data.notes) == 2


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("4:20:1:5", (4.0, 20.0, 1.0, 5.0)),
        ("4,20,1,5", (4.0, 20.0, 1.0, 5.0)),
        (" 0 : 27648 : 0 : 100 ", (0.0, 27648.0, 0.0, 100.0)),
        ("4:20:0:2,5", (4.0, 20.0, 0.0, 2.5)),
    ],
)
def test_parse_scale(text: str, expected: tuple[float, float, float, float]) -> None:
    assert parse_scale(text) == expected


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("4:20:1", "four numbers"),
        ("4:20:1:5:6", "four numbers"),
        ("4:twenty:1:5", "four numbers"),
        ("4:4:1:5", "raw range"),
        ("4:20:1:1", "engineering range"),
        ("4:20:1:inf", "finite"),
    ],
)
def test_parse_scale_refuses(text: str, reason: str) -> None:
    with pytest.raises(DataError, match=reason):
        parse_scale(text)


def test_sample_time_replaces_a_missing_time_column(tmp_path: Path) -> None:
    _, u, y = step_response()
    rows = [(f"{ui:g}", f"{yi}") for ui, yi in zip(u, y, strict=True)]
    path = write_csv(tmp_path / "untimed.csv", rows, header="u_V,q_Lpm")
    for time_col in ("t_s", None):
        data = load_log(path, time_col=time_col, sample_time=0.05)
        assert data.sample_time == 0.05
        np.testing.assert_array_equal(data.y, y)
    message = refused(path)
    assert "'t_s'" in message
    assert "u_V, q_Lpm" in message
    assert "sample time" in message


def test_a_sample_time_and_a_time_column_must_agree(tmp_path: Path) -> None:
    """Issue 12 item 3: a sample time no longer silently replaces an existing time column."""
    path = write_csv(tmp_path / "log.csv", plain_rows())
    message = refused(path, sample_time=0.1)
    assert "time column 't_s' says 0.02 s" in message
    assert "says 0.1 s" in message
    assert "--sample-time" in message
    data = load_log(path, sample_time=0.02)
    assert data.sample_time == 0.02
    assert any("time column t_s used" in note for note in data.notes)
    assert load_log(path, time_col=None, sample_time=0.1).sample_time == 0.1


def test_unsorted_timestamps_are_sorted_with_a_note(tmp_path: Path) -> None:
    rows = plain_rows()
    rows[60], rows[61] = rows[61], rows[60]
    rows[10:20] = rows[10:20][::-1]
    data = load_log(write_csv(tmp_path / "unsorted.csv", rows))
    _, u, y = step_response()
    np.testing.assert_array_equal(data.u, u)
    np.testing.assert_array_equal(data.y, y)
    assert any("sorted" in note and "data row 12" in note for note in data.notes)


def test_identical_duplicates_are_dropped(tmp_path: Path) -> None:
    rows = plain_rows()
    rows = [*rows[:30], rows[29], rows[29], *rows[30:]]
    data = load_log(write_csv(tmp_path / "dup.csv", rows))
    assert data.n_samples == N
    assert any("dropped 2 duplicated" in note for note in data.notes)


def test_conflicting_duplicates_are_refused(tmp_path: Path) -> None:
    rows = plain_rows()
    rows.insert(31, (rows[30][0], rows[30][1], "99.0"))
    message = refused(write_csv(tmp_path / "conflict.csv", rows))
    assert "conflicting" in message
    assert "t = 0.6 s" in message
    assert "data rows 31 and 32" in message
    assert "q_Lpm" in message


def test_jittered_timestamps_are_placed_on_the_grid_unchanged(tmp_path: Path) -> None:
    """Issue 12 item 3: jitter within a fraction of a period is placed, not interpolated."""
    rng = np.random.default_rng(1)
    t = H * np.arange(N) + rng.uniform(-0.004, 0.004, N) * H
    t[0] = 0.0
    u = np.where(t >= 1.0, 1.5, 1.0)
    y = 10.0 + 2.0 * t
    rows = [(f"{ti:.7f}", f"{ui:g}", f"{yi:.9f}") for ti, ui, yi in zip(t, u, y, strict=True)]
    rows[100] = (f"{100 * H + 0.0015:.7f}", rows[100][1], f"{10 + 2 * (100 * H + 0.0015):.9f}")
    data = load_log(write_csv(tmp_path / "jitter.csv", rows))
    assert data.sample_time == H
    assert data.n_segments == 1
    np.testing.assert_array_equal(data.u, u)
    np.testing.assert_array_equal(data.y, [float(row[2]) for row in rows])
    assert not any("resampled" in note for note in data.notes)
    assert any("1.5 ms" in note and "values unchanged" in note for note in data.notes)


def drifting_times() -> np.ndarray:
    """Intervals 5 % long, then 5 % short: up to 1.6 periods off any steady grid."""
    dt = H * (1.0 + 0.05 * np.sin(2 * np.pi * np.arange(N - 1) / (N - 1)))
    return np.concatenate(([0.0], np.cumsum(dt)))


def test_a_drifting_clock_is_resampled_onto_the_median_grid(tmp_path: Path) -> None:
    """Intervals within ±10 % of the period that fit no steady grid: interpolated (y linear)."""
    t = drifting_times()
    u = np.where(t >= 1.0, 1.5, 1.0)
    y = 10.0 + 2.0 * t  # linear: interpolation is exact
    rows = [(f"{ti:.7f}", f"{ui:g}", f"{yi:.9f}") for ti, ui, yi in zip(t, u, y, strict=True)]
    data = load_log(write_csv(tmp_path / "drift.csv", rows))
    h = data.sample_time
    assert h == pytest.approx(H, rel=0.02)
    np.testing.assert_allclose(data.y, 10.0 + 2.0 * data.t, atol=1e-6)
    expected_u = u[np.searchsorted(t, data.t + 1e-6 * h, side="right") - 1]
    np.testing.assert_array_equal(data.u, expected_u)
    assert any("resampled" in note for note in data.notes)


def test_a_gap_splits_the_log_into_segments_with_where_it_is(tmp_path: Path) -> None:
    """Issue 12 item 3: a gap is no longer refused; the log loads as two segments."""
    rows = plain_rows()
    del rows[100:110]  # 0.22 s between t = 1.98 s and t = 2.20 s
    path = write_csv(tmp_path / "gap.csv", rows)
    _, u, y = step_response()
    for options in ({}, {"max_gap": 0.5}, {"max_gap": 0.5, "resample": "always"}):
        data = load_log(path, **options)
        assert data.segment_starts == (100,)
        assert data.segment_t0 == pytest.approx((2.2,))
        np.testing.assert_array_equal(data.u, np.delete(u, range(100, 110)))
        np.testing.assert_array_equal(data.y, np.delete(y, range(100, 110)))
        assert any("0.22 s at t = 1.98 s (data row 100)" in note for note in data.notes)
    assert "more than 5 sample periods" not in str(data.notes)
    assert "5 sample periods" in refused(path, fill_gaps=0.22)


def test_resample_never_refuses_what_needs_interpolation(tmp_path: Path) -> None:
    rows = plain_rows()
    rows[50] = ("1.001", rows[50][1], rows[50][2])
    path = write_csv(tmp_path / "jitter.csv", rows)
    data = load_log(path, resample="never")  # 5 % jitter: placed, no interpolation
    assert any("placed" in note for note in data.notes)
    rows = [
        (f"{ti:.7f}", row[1], row[2])
        for ti, row in zip(drifting_times(), plain_rows(), strict=True)
    ]
    path = write_csv(tmp_path / "drift.csv", rows)
    assert any("resampled" in note for note in load_log(path).notes)
    message = refused(path, resample="never")
    assert "irregular sampling" in message
    assert "data row" in message
    assert "resampling is off" in message


def test_non_numeric_cell_is_refused_with_column_and_row(tmp_path: Path) -> None:
    # empty cells and "NaN" are historian bad-value markers (missing samples, issue 24): other
    # text is refused
    rows = plain_rows()
    rows[41] = (rows[41][0], rows[41][1], "ERR")
    rows[90] = (rows[90][0], rows[90][1], "?")
    rows[120] = (rows[120][0], "n/a", rows[120][2])
    path = write_csv(tmp_path / "nan.csv", rows)
    message = refused(path)
    assert "'u_V'" in message
    assert "1 non-numeric cell" in message
    assert "data row 121" in message
    rows[120] = plain_rows()[120]
    message = refused(write_csv(path, rows))
    assert "'q_Lpm' has 2 non-numeric cell(s), first at data row 42 ('ERR')" in message


def test_isolated_bad_rows_can_be_dropped(tmp_path: Path) -> None:
    rows = plain_rows()
    rows[41] = (rows[41][0], rows[41][1], "")
    rows[120] = (rows[120][0], "?", rows[120][2])
    data = load_log(write_csv(tmp_path / "nan.csv", rows), drop_bad_rows=True)
    _, u, y = step_response()
    assert data.n_samples == N
    assert data.y[41] == pytest.approx((y[40] + y[42]) / 2)
    assert data.u[120] == u[119]
    # the empty cell is a bad-value marker, counted apart; the "?" row is dropped on request
    assert any("1 sample marked bad in column q_Lpm" in note for note in data.notes)
    assert any("dropped 1 row(s)" in note and "121" in note for note in data.notes)
    rows[41] = (rows[41][0], rows[41][1], "?")
    rows[42] = (rows[42][0], rows[42][1], "?")
    message = refused(write_csv(tmp_path / "nan2.csv", rows), drop_bad_rows=True)
    assert "data rows 42 and 43" in message


def test_bad_time_cell_is_refused(tmp_path: Path) -> None:
    rows = plain_rows()
    rows[7] = ("", rows[7][1], rows[7][2])
    message = refused(write_csv(tmp_path / "t.csv", rows))
    assert "'t_s' has 1 empty or unreadable time cell(s), first at data row 8" in message


def test_missing_column_names_the_columns_present(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "names.csv", plain_rows(), header="time,cmd_V,flow_Lpm")
    message = refused(path, time_col="time")
    assert "'u_V'" in message
    assert "time, cmd_V, flow_Lpm" in message
    data = load_log(path, time_col="TIME", input_col="cmd_v", output_col="flow_Lpm")
    assert (data.u_unit, data.y_unit) == ("V", "L/min")


def test_constant_signals_are_refused(tmp_path: Path) -> None:
    rows = [(row[0], "1.0", row[2]) for row in plain_rows()]
    message = refused(write_csv(tmp_path / "const_u.csv", rows))
    assert message.endswith("input u_V is constant (1.0 V): nothing to identify")
    rows = [(row[0], row[1], "14.6") for row in plain_rows()]
    message = refused(write_csv(tmp_path / "const_y.csv", rows))
    assert "output q_Lpm is constant (14.6 L/min)" in message


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        (b"", "is empty"),
        (b"\n \r\n\t\n", "is empty"),
        (b"t_s,u_V,q_Lpm\n", "no data rows"),
        (bytes(range(256)) * 4, "not a text table"),
        (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "not a text table"),
        (b"\x81\x30\xff\xfe\x83" * 20, "not a text table"),
        (b"flow\n1\n2\n3\n4\n5\n6\n7\n8\n9\n10\n11\n", "single column"),
        (b"t_s,u_V,q_Lpm\n0,1,2\n1,2,3,4\n", "cannot read"),
    ],
)
def test_unreadable_files_are_refused(tmp_path: Path, content: bytes, reason: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_bytes(content)
    assert reason in refused(path)


def test_infinite_and_huge_values_are_refused(tmp_path: Path) -> None:
    rows = plain_rows()
    rows[3] = (rows[3][0], "inf", rows[3][2])
    message = refused(write_csv(tmp_path / "inf.csv", rows))
    assert "'u_V' has 1 infinite or huge" in message
    assert "data row 4" in message
    rows = plain_rows()
    rows[8] = (rows[8][0], rows[8][1], "3e13")
    assert "'q_Lpm' has 1 infinite or huge" in refused(write_csv(tmp_path / "huge.csv", rows))


def test_too_few_samples_are_refused(tmp_path: Path) -> None:
    message = refused(write_csv(tmp_path / "short.csv", plain_rows()[45:54]))
    assert "only 9 sample(s)" in message


def test_file_and_option_errors(tmp_path: Path) -> None:
    assert "does not exist" in refused(tmp_path / "missing.csv")
    (tmp_path / "log.xlsx").write_bytes(b"PK")
    assert "unknown log format '.xlsx'" in refused(tmp_path / "log.xlsx")
    path = write_csv(tmp_path / "log.csv", plain_rows())
    assert "resample" in refused(path, resample="sometimes")
    assert "max_gap" in refused(path, max_gap=-1.0)
    assert "sample time" in refused(path, sample_time=0.0)
    assert "raw range" in refused(path, input_scale=(4, 4, 1, 5))
    assert "time column or a sample time" in refused(path, time_col=None)


def test_parquet_with_datetime_time_column(tmp_path: Path) -> None:
    t, u, y = step_response()
    start = pd.Timestamp("2026-03-01 12:00:00")
    frame = pd.DataFrame(
        {"stamp": start + pd.to_timedelta(t, unit="s"), "u_V": u, "q_Lpm": y},
    )
    frame.to_parquet(tmp_path / "log.parquet", index=False)
    data = load_log(tmp_path / "log.parquet", time_col="stamp")
    assert data.sample_time == H
    np.testing.assert_array_equal(data.u, u)
    np.testing.assert_array_equal(data.y, y)
    frame.assign(stamp=t + 5.0).to_parquet(tmp_path / "log.pq", index=False)
    data = load_log(tmp_path / "log.pq", time_col="stamp")
    assert data.t0 == 5.0
    (tmp_path / "broken.parquet").write_bytes(b"PAR1 not really")
    assert "cannot read" in refused(tmp_path / "broken.parquet")


@pytest.mark.refdata
def test_reference_heating_system_log() -> None:
    path = REF_DATA / "daisy_heating_system.csv"
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    data = load_log(path, input_col="u_lamp_drive_V", output_col="y_plate_temp_degC")
    assert data.n_samples == 801
    assert data.sample_time == 2.0
    assert (data.u_unit, data.y_unit) == ("V", "degC")


def test_a_row_of_units_under_the_header_is_skipped(tmp_path: Path) -> None:
    rows = [("s", "V", "[L/min]"), *plain_rows()]
    data = load_log(
        write_csv(tmp_path / "units.csv", rows, header="t_s,cmd,flow"),
        input_col="cmd",
        output_col="flow",
    )
    assert data.n_samples == N
    assert data.y[0] == 14.6
    assert (data.u_unit, data.y_unit) == ("V", "L/min")
    assert any("row of units" in note for note in data.notes)


def test_a_dropped_blank_line_needs_no_resampling(tmp_path: Path) -> None:
    rows: list[tuple[str, ...]] = list(plain_rows())
    rows.insert(70, ("",))
    path = write_csv(tmp_path / "blank.csv", rows)
    _, u, y = step_response()
    # a blank line's empty cells are missing samples (issue 24): no slot is missing around it
    for data in (load_log(path), load_log(path, drop_bad_rows=True)):
        np.testing.assert_array_equal(data.u, u)
        np.testing.assert_array_equal(data.y, y)
        assert not any("resampled" in note for note in data.notes)
        assert data.segment_starts == ()


def test_unreadable_time_stamps_say_what_is_expected(tmp_path: Path) -> None:
    rows = [(f"12:00:{i * H:06.3f}", row[1], row[2]) for i, row in enumerate(plain_rows())]
    message = refused(
        write_csv(tmp_path / "clock.csv", rows, header="time,u_V,q_Lpm"), time_col="time"
    )
    assert f"'time' has {N} empty or unreadable time cell(s), first at data row 1" in message
    assert "expected seconds or stamps" in message


def test_utf16_text_with_bom(tmp_path: Path) -> None:
    path = write_csv(
        tmp_path / "u16.txt", plain_rows(), header="t_s\tu_V\tq_Lpm", sep="\t", encoding="utf-16"
    )
    data = load_log(path)
    assert data.n_samples == N
    assert "read as UTF-16 text" in data.notes


def test_sample_intervals_beyond_an_hour_are_refused(tmp_path: Path) -> None:
    """Time stamps 1e298 s apart (or a sample time of 1e6 s) are a unit mix-up, not a flow log."""
    _, u, y = step_response()
    rows = [
        (f"{k * 2e298:.6g}", f"{ui:g}", f"{yi:.6f}")
        for k, (ui, yi) in enumerate(zip(u, y, strict=True))
    ]
    assert "(is the time column in seconds?)" in refused(write_csv(tmp_path / "t.csv", rows))
    plain = write_csv(tmp_path / "log.csv", plain_rows())
    assert "up to 3600" in refused(plain, sample_time=1e6)
    assert load_log(plain, time_col=None, sample_time=3600.0).sample_time == 3600.0


def test_input_and_output_from_one_column_is_refused(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "log.csv", plain_rows())
    assert "the same column 'u_V'" in refused(path, output_col="u_V")


@pytest.mark.parametrize(
    ("before", "after"),
    [("", "  \n\t\n"), (" \n\n", ""), ("\r\n \r\n", " \r\n")],
)
def test_whitespace_only_lines_around_the_table_are_ignored(
    tmp_path: Path, before: str, after: str
) -> None:
    path = write_csv(tmp_path / "padded.csv", plain_rows())
    path.write_bytes(before.encode() + path.read_bytes() + after.encode())
    data = load_log(path)
    _, u, y = step_response()
    np.testing.assert_array_equal(data.u, u)
    np.testing.assert_array_equal(data.y, y)
