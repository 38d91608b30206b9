"""``fuelid identify`` through the CLI: the JSON contract, priors, validation and refusals."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.model import ProcessModel, simulate_model

runner = CliRunner()
H = 0.02
TRUTH = ProcessModel(K=13.12, T=1.268, T_f=0.3, delay=0.2)
JSON_KEYS = {
    "method",
    "model",
    "fixed",
    "stderr",
    "ci95",
    "ci95_method",
    "cov",
    "fit_percent",
    "validation_fit_percent",
    "n_samples",
    "sample_time",
    "units",
    "warnings",
    "fuelid_version",
    "input_sha256",
    "options",
}


def _log(path: Path, sigma: float = 0.05, seed: int = 0) -> Path:
    rng = np.random.default_rng(seed)
    u = np.repeat(np.r_[3.0, rng.uniform(2.5, 3.5, 9)], 500)
    y = 40.0 + simulate_model(TRUTH, u, H) + rng.normal(0.0, sigma, u.size)
    pd.DataFrame({"t_s": np.arange(u.size) * H, "u_V": u, "q_Lpm": y}).to_csv(path, index=False)
    return path


def _json(*args: str) -> dict:
    result = runner.invoke(app, ["identify", *args, "--json"])
    assert result.exit_code == 0, result.stderr
    return json.loads(result.stdout)


def test_json_schema_and_priors_held_fixed(tmp_path: Path):
    data = _json(
        str(_log(tmp_path / "log.csv")), "--flowmeter-T", "0.3", "--flowmeter-delay", "0.2"
    )
    assert set(data) >= JSON_KEYS
    assert data["method"] == "oe"
    assert set(data["model"]) == {"K", "T", "T2", "delay", "T_f"}
    assert data["fixed"] == ["T2", "delay", "T_f"]
    assert data["model"]["T_f"] == 0.3
    assert data["model"]["delay"] == 0.2
    for key in ("T2", "delay", "T_f"):
        assert data["stderr"][key] is None
        assert data["ci95"][key] is None
        assert data["ci95_method"][key] is None
    # the estimate is within a few standard errors of the truth; K's interval is ±1.96 se, the
    # positive T's the log-transformed exp(ln T ± 1.96 se/T)
    for key in ("K", "T"):
        est, se = data["model"][key], data["stderr"][key]
        assert abs(est - getattr(TRUTH, key)) < 4 * se
    assert data["ci95_method"]["K"] == "normal"
    K, se_K = data["model"]["K"], data["stderr"]["K"]
    assert data["ci95"]["K"] == [
        pytest.approx(K - 1.959964 * se_K, rel=1e-9),
        pytest.approx(K + 1.959964 * se_K, rel=1e-9),
    ]
    assert data["ci95_method"]["T"] == "log"
    T, se_T = data["model"]["T"], data["stderr"]["T"]
    assert data["ci95"]["T"] == [
        pytest.approx(T * np.exp(-1.959964 * se_T / T), rel=1e-9),
        pytest.approx(T * np.exp(1.959964 * se_T / T), rel=1e-9),
    ]
    assert data["cov"]["names"][:2] == ["K", "T"]
    assert len(data["cov"]["matrix"]) == len(data["cov"]["names"])
    assert data["n_samples"] == 5000
    assert data["sample_time"] == pytest.approx(H)
    assert data["validation_fit_percent"] is None
    # noise-limited fit: 100·(1 − ‖e‖/‖y − ȳ‖) with ‖e‖ ≈ σ√n, σ = 0.05
    y = pd.read_csv(tmp_path / "log.csv")["q_Lpm"].to_numpy()
    expected = 100 * (1 - 0.05 * np.sqrt(y.size) / np.linalg.norm(y - y.mean()))
    assert data["fit_percent"] == pytest.approx(expected, abs=0.1)
    assert len(data["input_sha256"]) == 64


def test_delay_auto_estimates_the_dead_time(tmp_path: Path):
    data = _json(str(_log(tmp_path / "log.csv")), "--flowmeter-T", "0.3", "--delay", "auto")
    assert "delay" not in data["fixed"]
    assert data["model"]["delay"] == pytest.approx(0.2, abs=4 * data["stderr"]["delay"])


def test_validation_split_scores_the_held_out_part(tmp_path: Path):
    data = _json(
        str(_log(tmp_path / "log.csv")),
        "--flowmeter-T",
        "0.3",
        "--flowmeter-delay",
        "0.2",
        "--validate-split",
        "0.3",
    )
    assert data["n_samples"] == 3500
    y = pd.read_csv(tmp_path / "log.csv")["q_Lpm"].to_numpy()[3500:]
    expected = 100 * (1 - 0.05 * np.sqrt(y.size) / np.linalg.norm(y - y.mean()))
    assert data["validation_fit_percent"] == pytest.approx(expected, abs=0.3)


def test_raw_units_are_scaled(tmp_path: Path):
    # the same log exported as 4-20 mA and as counts (0…27648 = 0…100 L/min), ';' and ','
    source = pd.read_csv(_log(tmp_path / "log.csv", sigma=0.0))
    raw = pd.DataFrame(
        {
            "t_s": source["t_s"],
            "u_mA": 4.0 + (source["u_V"] - 1.0) * 4.0,
            "q_counts": source["q_Lpm"] * 276.48,
        }
    )
    path = tmp_path / "raw.csv"
    raw.to_csv(path, sep=";", decimal=",", index=False)
    data = _json(
        str(path),
        "--input-col",
        "u_mA",
        "--output-col",
        "q_counts",
        "--input-scale",
        "4:20:1:5",
        "--output-scale",
        "0:27648:0:100",
        "--flowmeter-T",
        "0.3",
        "--flowmeter-delay",
        "0.2",
    )
    assert data["model"]["K"] == pytest.approx(TRUTH.K, rel=1e-5)


@pytest.mark.parametrize(
    ("content", "args", "expected"),
    [
        (
            "t_s,u_V,q_Lpm\n" + "".join(f"{k * 0.02},3.0,{40 + k % 3}\n" for k in range(100)),
            (),
            "constant",
        ),
        ("t_s,u_V,flow\n0,1,2\n0.02,1.5,2.1\n", (), "columns present"),
        ("", (), "empty"),
        ("t_s,u_V,q_Lpm\n0,1,inf\n0.02,2,1\n", (), "infinite"),
        (None, ("--validate-split", "1.5"), "validate-split"),
        (None, ("--order", "3"), "--order"),
        (None, ("--delay", "soon"), "--delay"),
        (None, ("--input-scale", "4:20"), "scale"),
        (None, ("--plot", "/no/such/dir/fig.png"), "does not exist"),
        (None, ("--plot", "/tmp"), "is a folder"),
        (None, ("--plot", "fig.xyz"), "name it .png"),
        # priors the record contradicts: longer than the record, input far off its range
        (None, ("--delay", "1e6"), "not shorter than the record"),
        (None, ("--flowmeter-T", "1e6"), "not shorter than the record"),
        (None, ("--method", "oe", "--u-before", "1e6"), "far outside the recorded input"),
    ],
)
def test_bad_input_exits_2_with_one_line(tmp_path: Path, content, args, expected):
    path = tmp_path / "bad.csv"
    if content is None:
        _log(path)
    else:
        path.write_text(content)
    result = runner.invoke(app, ["identify", str(path), *args])
    assert result.exit_code == 2
    assert expected in result.stderr
    assert result.stderr.count("\n") == 1


def test_missing_file_exits_2(tmp_path: Path):
    result = runner.invoke(app, ["identify", str(tmp_path / "none.csv")])
    assert result.exit_code == 2


def test_plot_is_written(tmp_path: Path):
    fig = tmp_path / "fit.png"
    result = runner.invoke(
        app,
        ["identify", str(_log(tmp_path / "log.csv")), "--flowmeter-T", "0.3", "--plot", str(fig)],
    )
    assert result.exit_code == 0, result.stderr
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_step_ls_decimates_and_reports_the_step_response(tmp_path: Path):
    data = _json(
        str(_log(tmp_path / "log.csv", sigma=0.02)),
        "--method",
        "step-ls",
        "--N",
        "8",
        "--flowmeter-T",
        "0.3",
        "--flowmeter-delay",
        "0.2",
    )
    assert data["method"] == "step-ls"
    assert data["sample_time"] == 1.0
    assert data["N"] == 8
    assert len(data["step_coefficients"]) == 8
    # N = 8 periods cover the 5.8 s settling time: the truncation bias is well below 1 %
    assert data["model"]["K"] == pytest.approx(TRUTH.K, rel=0.01)
    assert data["model"]["T"] == pytest.approx(TRUTH.T, rel=0.03)
    # the last coefficient is the static gain's estimate
    assert data["step_coefficients"][-1] == pytest.approx(TRUTH.K, rel=0.01)
    assert data["fixed"] == ["T2", "delay", "T_f"]


def test_step_ls_refuses_data_that_do_not_excite(tmp_path: Path):
    # one step, one second before the end of the record: no row sees N = 8 periods after it
    u = np.r_[np.full(1000, 3.0), np.full(50, 3.5)]
    y = 40.0 + simulate_model(TRUTH, u, H)
    path = tmp_path / "late.csv"
    pd.DataFrame({"t_s": np.arange(u.size) * H, "u_V": u, "q_Lpm": y}).to_csv(path, index=False)
    result = runner.invoke(
        app, ["identify", str(path), "--method", "step-ls", "--N", "8", "--flowmeter-delay", "0.2"]
    )
    assert result.exit_code == 2
    assert "N=8" in result.stderr
    assert result.stderr.count("\n") == 1


def test_time_range_selects_samples(tmp_path: Path):
    data = _json(
        str(_log(tmp_path / "log.csv")),
        "--flowmeter-T",
        "0.3",
        "--flowmeter-delay",
        "0.2",
        "--t-start",
        "20",
        "--t-stop",
        "80",
    )
    assert data["n_samples"] == 3000
    empty = runner.invoke(app, ["identify", str(tmp_path / "log.csv"), "--t-start", "500"])
    assert empty.exit_code == 2
    assert "spans" in empty.stderr


def _frame(seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    u = np.repeat(np.r_[3.0, rng.uniform(2.5, 3.5, 5)], 500)
    y = 40.0 + simulate_model(TRUTH, u, H) + rng.normal(0.0, 0.05, u.size)
    return pd.DataFrame({"t_s": np.round(np.arange(u.size) * H, 6), "u_V": u, "q_Lpm": y})


def test_real_plc_export_gbk_datetime_decimal_comma(tmp_path: Path):
    frame = _frame()
    stamps = pd.Timestamp("2026-03-01 12:00:00") + pd.to_timedelta(frame["t_s"], unit="s")
    export = pd.DataFrame(
        {
            "时间": stamps.dt.strftime("%Y-%m-%d %H:%M:%S.%f").str[:-3],
            "给定电压": frame["u_V"],
            "流量": frame["q_Lpm"],
        }
    )
    path = tmp_path / "plc.csv"
    path.write_bytes(export.to_csv(sep=";", decimal=",", index=False).encode("gbk"))
    data = _json(
        str(path),
        "--time-col",
        "时间",
        "--input-col",
        "给定电压",
        "--output-col",
        "流量",
        "--flowmeter-T",
        "0.3",
        "--flowmeter-delay",
        "0.2",
    )
    assert data["sample_time"] == pytest.approx(H)
    assert abs(data["model"]["K"] - TRUTH.K) < 4 * data["stderr"]["K"]


def test_unsorted_log_loads_with_a_warning(tmp_path: Path):
    frame = _frame()
    shuffled = frame.sample(frac=1.0, random_state=3)
    path = tmp_path / "unsorted.csv"
    shuffled.to_csv(path, index=False)
    result = runner.invoke(app, ["identify", str(path), "--flowmeter-T", "0.3", "--json"])
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert any("sort" in w for w in data["warnings"])
    assert "sort" in result.stderr


@pytest.mark.parametrize(
    ("damage", "expected"),
    [
        ("conflicting duplicate", "t ="),
        ("text", "q_Lpm"),
    ],
)
def test_messy_logs_are_refused_with_the_place(tmp_path: Path, damage: str, expected: str):
    frame = _frame().astype({"q_Lpm": object})
    if damage == "conflicting duplicate":
        extra = frame.iloc[[700]].copy()
        extra["q_Lpm"] = 99.0
        frame = pd.concat([frame, extra])
    else:  # an empty or NaN cell is a missing sample (tests/unit/cli/test_newcomer_bad_values.py)
        frame.loc[1234, "q_Lpm"] = "E#07"
    path = tmp_path / "messy.csv"
    frame.to_csv(path, index=False)
    result = runner.invoke(app, ["identify", str(path)])
    assert result.exit_code == 2
    assert expected in result.stderr
    assert result.stderr.count("\n") == 1


def test_a_gap_is_listed_and_no_longer_refused(tmp_path: Path):
    """Issue 12 item 3: a log with a gap loads as two segments (identified jointly)."""
    path = tmp_path / "gap.csv"
    _frame().drop(index=range(1000, 1300)).to_csv(path, index=False)
    result = runner.invoke(app, ["identify", str(path), "--json"])
    assert "1 gap splits the log into 2 segments" in result.stderr
    assert "6.02 s at t = 19.98 s (data row 1000)" in result.stderr


def test_second_file_validates(tmp_path: Path):
    fit_log = _log(tmp_path / "fit.csv", seed=1)
    other = _log(tmp_path / "other.csv", seed=2)
    data = _json(
        str(fit_log),
        "--flowmeter-T",
        "0.3",
        "--flowmeter-delay",
        "0.2",
        "--validate-file",
        str(other),
    )
    y = pd.read_csv(other)["q_Lpm"].to_numpy()
    expected = 100 * (1 - 0.05 * np.sqrt(y.size) / np.linalg.norm(y - y.mean()))
    assert data["validation_fit_percent"] == pytest.approx(expected, abs=0.3)
    both = runner.invoke(
        app, ["identify", str(fit_log), "--validate-file", str(other), "--validate-split", "0.3"]
    )
    assert both.exit_code == 2


def test_order_2_reports_the_t2_delay_correlation(tmp_path: Path):
    data = _json(str(_log(tmp_path / "log.csv")), "--order", "2", "--delay", "auto")
    assert -1.0 <= data["correlation_T2_delay"] <= 1.0
    assert data["model"]["T2"] > 0.0
