"""Issue 38 items 4 and 6: a bad control period or tuning rule is refused the same way everywhere.

A control period that is negative, not finite or beyond 10 s (or, where a number is expected,
not a number) is refused by every command and file that gives one, with exit code 2 and one
line naming where it came from; 0 (a continuous controller, or in a simulation a command
applied at once) is allowed where it means something. An unknown tuning rule is named with the
known ones, without pydantic's "Value error," prefix.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fuelid.cli import main

SITE = Path(__file__).parents[2] / "docs" / "examples" / "site.toml"
BAD_PERIODS = ("-1", "nan", "inf", "20")
MODEL = {
    "model": {"K": 14.0, "T": 1.2, "T2": 0.0, "T_f": 0.0, "delay": 0.25},
    "units": {"K": "(L/min)/V", "T": "s", "T2": "s", "T_f": "s", "delay": "s"},
    "options": {"control_period": 1.0, "control_period_given": True},
}


def _one_line_refusal(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("error: "), err
    assert err.count("\n") == 1, err
    assert "Traceback" not in err
    assert "Value error" not in err
    return err


@pytest.fixture
def log(tmp_path: Path) -> Path:
    t = 0.1 * np.arange(600)
    u = np.where(t < 20.0, 1.0, 1.5)
    q = 14.0 + 14.0 * (u - 1.0) * (1.0 - np.exp(-np.clip(t - 20.25, 0.0, None) / 1.2))
    path = tmp_path / "log.csv"
    path.write_text(
        "t_s,u_V,q_Lpm\n"
        + "\n".join(f"{a:.1f},{b},{c:.4f}" for a, b, c in zip(t, u, q, strict=True))
    )
    return path


@pytest.fixture
def model_file(tmp_path: Path) -> Path:
    path = tmp_path / "model.json"
    path.write_text(json.dumps(MODEL))
    return path


@pytest.mark.parametrize("period", BAD_PERIODS)
@pytest.mark.parametrize(
    "command", ["identify-step-ls", "identify-oe", "tune", "report", "simulate"]
)
def test_a_bad_control_period_option_is_refused(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    log: Path,
    model_file: Path,
    command: str,
    period: str,
) -> None:
    argv = {
        "identify-step-ls": ["identify", str(log), "--method", "step-ls", "--json"],
        "identify-oe": ["identify", str(log), "--json"],
        "tune": ["tune", "--model", str(model_file), "--json"],
        "report": ["report", str(log), "-o", str(tmp_path / "r.html")],
        "simulate": ["simulate", str(tmp_path / "s.csv"), "--duration", "5"],
    }[command]
    err = _one_line_refusal(capsys, [*argv, "--control-period", period])
    assert (
        f"control period (--control-period) must be 0 (continuous) or up to 10 s, got {period} s"
        in err
    )


def test_simulate_takes_a_control_period_of_zero(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    out = tmp_path / "s.csv"
    assert (
        main(
            [
                "simulate",
                str(out),
                "--duration",
                "5",
                "--t-step",
                "1",
                "--control-period",
                "0",
                "-q",
            ]
        )
        == 0
    )
    assert out.exists()


@pytest.mark.parametrize("period", BAD_PERIODS)
@pytest.mark.parametrize("command", ["site-check", "tune", "report", "online"])
def test_a_bad_control_period_in_the_site_file_is_refused(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    log: Path,
    model_file: Path,
    command: str,
    period: str,
) -> None:
    site = tmp_path / "site.toml"
    text = SITE.read_text(encoding="utf-8")
    assert "control_period_s = 1.0" in text
    site.write_text(text.replace("control_period_s = 1.0", f"control_period_s = {period}"))
    argv = {
        "site-check": ["site", "check", "-c", str(site)],
        "tune": ["tune", "--model", str(model_file), "--site", str(site), "--json"],
        "report": ["report", str(log), "--site", str(site), "-o", str(tmp_path / "r.html")],
        "online": ["online", "-c", str(site), "--duration", "1"],
    }[command]
    err = _one_line_refusal(capsys, argv)
    assert "sampling.control_period_s" in err
    assert f"got {period} s" in err


@pytest.mark.parametrize("recorded", [-1.0, float("nan"), float("inf"), 20.0, "1 s"])
def test_a_bad_control_period_recorded_in_a_model_file_is_refused(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, recorded: object
) -> None:
    path = tmp_path / "model.json"
    path.write_text(
        json.dumps(MODEL | {"options": {**MODEL["options"], "control_period": recorded}})
    )
    err = _one_line_refusal(capsys, ["tune", "--model", str(path), "--json"])
    assert "model.json" in err
    assert "options.control_period must be" in err


def test_an_unknown_rule_option_lists_the_known_rules(
    capsys: pytest.CaptureFixture[str], model_file: Path
) -> None:
    err = _one_line_refusal(capsys, ["tune", "--model", str(model_file), "--rule", "foo"])
    assert "'foo'" in err
    for rule in ("simc", "isimc", "lambda", "amigo"):
        assert rule in err


@pytest.mark.parametrize("command", ["site-check", "tune", "online"])
def test_an_unknown_rule_in_the_site_file_lists_the_known_rules(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, model_file: Path, command: str
) -> None:
    site = tmp_path / "site.toml"
    site.write_text(SITE.read_text(encoding="utf-8") + '\n[online]\nrule = "foo"\n')
    argv = {
        "site-check": ["site", "check", "-c", str(site)],
        "tune": ["tune", "--model", str(model_file), "--site", str(site), "--json"],
        "online": ["online", "-c", str(site), "--duration", "1"],
    }[command]
    err = _one_line_refusal(capsys, argv)
    assert "online.rule: 'foo' is not one of the known choices: simc, isimc, lambda, amigo" in err
