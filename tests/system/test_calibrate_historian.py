"""``fuelid calibrate`` on a historian export: identify's log options, signal check, misfit, gaps.

A new user calibrated a log whose command column was in % of output (0-100), not V: calibrate
had no --input-scale, ran no signal check, printed "every parameter determined" beside a fit of
0 % and wrote a wrong plant file; with a few bad cells it used only the log's first 25 s.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from fuelid.cli import main
from fuelid.plant import load_plant_config

LEAK = "pump.leakage_Lpm_per_MPa"
TRUE_LEAK = 9.8
HISTORIAN = ["--time-col", "Timestamp", "--input-col", "FIC201.OUT", "--output-col", "FT201.PV",
             "--bad-values", "No Data", "--free", LEAK, "--fuel-temp", "20"]  # fmt: skip
SCALED = ["--input-scale", "0:100:1:5", "--flow-unit", "L/min"]


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("historian")
    worn = folder / "worn.toml"
    assert main(["plant", "init", str(worn)]) == 0
    text = worn.read_text().replace(
        "leakage_Lpm_per_MPa = 7.0\n", f"leakage_Lpm_per_MPa = {TRUE_LEAK}\n"
    )
    worn.write_text(text)
    clean = folder / "clean.csv"
    code = main(["simulate", str(clean), "-c", str(worn), "-p", "steps", "--levels",
                 "2.5,3.5,2,4,3", "--dwell", "12", "--duration", "60", "--fuel-temp", "20",
                 "--seed", "3", "-q"])  # fmt: skip
    assert code == 0
    log = pd.read_csv(clean)
    start = pd.Timestamp("2026-11-20 08:15:00")
    stamps = [start + pd.Timedelta(milliseconds=round(s * 1000)) for s in log["t_s"]]
    hist = pd.DataFrame(
        {
            "Timestamp": [s.strftime("%d.%m.%Y %H:%M:%S.%f")[:-3] for s in stamps],
            "FIC201.OUT": ((log["u_V"] - 1.0) / 4.0 * 100.0).round(3),
            "FT201.PV": log["q_Lpm"],
        }
    ).astype(object)
    for row, text_ in ((400, "#N/A"), (401, "Bad Input"), (1300, "No Data"), (2100, "")):
        hist.loc[row, "FT201.PV"] = text_
    hist.loc[1700, "FIC201.OUT"] = "Comm Fail"
    path = folder / "hist.csv"
    hist.to_csv(path, index=False)
    # a log with one long gap (2 s of rows missing) after its first 40 s
    long_gap = folder / "long_gap.csv"
    log[(log["t_s"] < 40.0) | (log["t_s"] >= 42.0)].to_csv(long_gap, index=False)
    return {"folder": folder, "hist": path, "clean": clean, "long_gap": long_gap}


def test_a_percent_command_is_refused_with_the_fix(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    out = files["folder"] / "bogus.toml"
    code = main(["calibrate", str(files["hist"]), *HISTORIAN, "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 2
    assert captured.out == ""
    reason = captured.err.strip().splitlines()[-1]
    assert reason.startswith("error: ")
    assert "it looks like percent: scale it with --input-scale 0:100:1:5" in reason
    assert "--accept-signals" in reason
    assert not out.exists()


def test_accepted_percent_signals_do_not_fit_and_are_not_written_as_trusted(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    out = files["folder"] / "forced.toml"
    argv = ["calibrate", str(files["hist"]), *HISTORIAN, "--accept-signals"]
    # --out refused: the model does not fit the data
    assert main([*argv, "--out", str(out)]) == 2
    reason = capsys.readouterr().err.strip().splitlines()[-1]
    assert "does not fit the data" in reason
    assert "not to be trusted" in reason
    assert "--force-misfit" in reason
    assert not out.exists()
    # the text output does not call the result determined
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "every parameter determined" not in text
    assert "NOT to be trusted" in text
    # the JSON says so
    assert main([*argv, "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["trusted"] is False
    assert "does not fit the data" in result["misfit"]
    assert result["fit_quality"][0]["misfit"] is True
    assert result["fit_quality"][0]["ratio"] > 3.0
    assert result["signal_check"]
    # written only when forced, and the file's [calibration] notes say it
    assert main([*argv, "--out", str(out), "--force-misfit"]) == 0
    capsys.readouterr()
    record = load_plant_config(out).calibration
    assert record is not None
    assert any("not to be trusted" in warning for warning in record.warnings)


def test_the_scaled_export_calibrates_the_whole_log_through_its_bad_cells(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    out = files["folder"] / "good.toml"
    code = main(["calibrate", str(files["hist"]), *HISTORIAN, *SCALED, "--out", str(out),
                 "--json"])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0, captured.err
    result = json.loads(captured.out)
    assert result["trusted"] is True
    assert result["misfit"] is None
    assert abs(result["parameters"][LEAK] / TRUE_LEAK - 1.0) < 0.03
    # every sample but the 5 bad rows is used: the gaps are simulated through
    assert result["logs"][0]["samples"] == 3001 - 5
    assert any("simulated through with the command held" in w for w in result["warnings"])
    assert not any("only the first stretch" in w for w in result["warnings"])
    assert result["options"]["input_scale"] == "0:100:1:5"
    assert out.exists()


def test_a_clean_log_still_calibrates_and_is_trusted(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    out = files["folder"] / "clean.toml"
    code = main(["calibrate", str(files["clean"]), "--free", LEAK, "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "every parameter determined" in captured.out
    assert "does not fit" not in captured.err
    assert out.exists()


def test_a_long_gap_says_how_much_of_the_log_is_calibrated(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["calibrate", str(files["long_gap"]), "--free", LEAK, "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    result = json.loads(captured.out)
    [note] = [w for w in result["warnings"] if "only the first stretch" in w]
    assert "2000 of 2901 samples" in note
    assert "of 60 s" in note
    assert "69 % of the log" in note
    assert result["logs"][0]["samples"] == 2000
