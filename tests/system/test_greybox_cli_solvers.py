"""``fuelid greybox`` with kinked models: the solver options, held parameters and honest misfit."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from fuelid.cli import main
from support.kinked_models import TRUTH, kinked_record

VALVE = """
    states = ["level"]
    inputs = ["u"]
    outputs = ["y"]
    parameters = {"K": (2.5, 0.0), "T": (10.0, 0.0), "u_max": (0.9, 0.0)}
    {extra}

    def f(t, x, u, p):
        opening = min(max(u[0], 0.0), p["u_max"])  # the valve at its stops
        return [(p["K"] * opening - x[0]) / p["T"]]

    x0 = [0.0]
"""


def _model(folder: Path, extra: str = "") -> Path:
    path = folder / "valve.py"
    path.write_text(textwrap.dedent(VALVE).replace("{extra}", extra).lstrip(), encoding="utf-8")
    return path


def _log(folder: Path, seed: int, input_range: tuple[float, float] | None = None) -> Path:
    record, _ = kinked_record("valve", seed=seed, input_range=input_range)
    path = folder / f"valve_{seed}.csv"
    pd.DataFrame({"t_s": record.t, "u": record.u[:, 0], "y": record.y[:, 0]}).to_csv(
        path, index=False
    )
    return path


def _run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(["greybox", *args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.fixture(scope="module")
def reaching(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A log whose inputs drive the valve to its stop (u up to 1.2 against u_max 0.8)."""
    return _log(tmp_path_factory.mktemp("valve"), seed=81)


def test_the_json_says_which_solver_ran_and_that_nothing_was_held(
    tmp_path: Path, reaching: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = _run(capsys, str(_model(tmp_path)), str(reaching), "--json")
    assert code == 0
    result = json.loads(out)
    assert result["solver"] == {
        "method": "lsoda",
        "max_step": None,
        "substeps": None,
        "rtol": 1e-6,
        "requested": "auto",
        "reason": "",
    }
    assert result["not_determined"] == {}
    assert result["misfit"] is None
    assert set(result["linearity"]) == {"K", "T", "u_max"}
    for key, value in TRUTH["valve"].items():
        # band: 4 standard errors (a correct estimator misses it with probability 6e-5)
        assert abs(result["parameters"][key] - value) <= 4.0 * result["stderr"][key]


def test_the_model_file_s_solver_is_used_and_the_command_line_overrides_it(
    tmp_path: Path, reaching: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = _model(tmp_path, 'solver = "rk4"\nsubsteps = 4')
    code, out, _ = _run(capsys, str(model), str(reaching))
    assert code == 0
    assert "solver rk4 (4 steps per sample)" in " ".join(out.split())
    code, out, _ = _run(capsys, str(model), str(reaching), "--solver", "bdf", "--max-step", "0.5")
    assert code == 0
    assert "solver bdf (max step 0.5 s)" in " ".join(out.split())


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--substeps", "0", "--solver", "rk4"), "substeps must be an integer from 1 to 64"),
        (("--substeps", "65", "--solver", "rk4"), "substeps must be an integer from 1 to 64"),
        (("--solver", "lsoda", "--substeps", "4"), "substeps apply to the rk4 solver only"),
        (("--max-step", "-1"), "max_step must be a positive"),
        (("--max-step", "nan"), "max_step must be a positive"),
    ],
)
def test_bad_solver_options_are_refused_in_one_line(
    tmp_path: Path,
    reaching: Path,
    capsys: pytest.CaptureFixture[str],
    args: tuple[str, ...],
    message: str,
) -> None:
    code, out, err = _run(capsys, str(_model(tmp_path)), str(reaching), *args)
    assert (code, out) == (2, "")
    assert message in err
    assert err.count("\n") == 1


def test_an_unknown_solver_is_a_usage_error(
    tmp_path: Path, reaching: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = _run(capsys, str(_model(tmp_path)), str(reaching), "--solver", "euler")
    assert (code, out) == (2, "")
    assert "euler" in err


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ('solver = "euler"', "line 5: solver must be one of auto, lsoda, bdf, radau, rk45, rk4"),
        ("substeps = 2.5", "line 5: substeps must be an integer from 1 to 64"),
        ("max_step = 0", "line 5: max_step must be a positive number of seconds"),
    ],
)
def test_bad_solver_settings_in_the_model_file_name_their_line(
    tmp_path: Path, reaching: Path, capsys: pytest.CaptureFixture[str], extra: str, message: str
) -> None:
    code, out, err = _run(capsys, str(_model(tmp_path, extra)), str(reaching))
    assert (code, out) == (2, "")
    assert message in err


def test_a_limit_never_reached_is_refused_with_both_ways_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = _log(tmp_path, seed=82, input_range=(0.0, 0.6))
    code, out, err = _run(capsys, str(_model(tmp_path)), str(log))
    assert (code, out) == (2, "")
    assert "do not depend on u_max" in err
    assert "--fix u_max --set u_max=VALUE" in err
    assert "--hold-undetermined" in err


def test_a_model_that_raises_is_refused_without_blaming_stiffness(
    tmp_path: Path, reaching: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A division by zero in f fails every solver; the refusal names the line, not stiffness."""
    model = _model(tmp_path).read_text(encoding="utf-8")
    model = model.replace('/ p["T"]]', '/ p["T"] + t / t]')
    path = tmp_path / "raising.py"
    path.write_text(model, encoding="utf-8")
    code, out, err = _run(capsys, str(path), str(reaching))
    assert (code, out) == (2, "")
    assert "raising.py line 9: ZeroDivisionError" in err
    assert "which no solver mends" in err
    assert "stiff" not in err


def test_hold_undetermined_reports_the_held_parameter_apart_from_the_fixed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = _log(tmp_path, seed=82, input_range=(0.0, 0.6))
    model = _model(tmp_path)
    code, out, _ = _run(capsys, str(model), str(log), "--hold-undetermined", "--json")
    assert code == 0
    result = json.loads(out)
    assert list(result["not_determined"]) == ["u_max"]
    assert result["fixed"] == []
    assert result["free"] == ["K", "T"]
    assert result["parameters"]["u_max"] == 0.9
    assert result["stderr"]["u_max"] is None
    assert result["provenance"]["options"]["hold_undetermined"] is True
    for key in ("K", "T"):
        # band: 4 standard errors, as above
        assert abs(result["parameters"][key] - TRUTH["valve"][key]) <= 4.0 * result["stderr"][key]
    code, out, _ = _run(capsys, str(model), str(log), "--hold-undetermined")
    assert code == 0
    text = " ".join(out.split())
    assert "│ not determined │" in out
    assert "u_max not determined: the outputs do not depend on it" in text


def test_a_wrong_model_says_its_intervals_are_conditional_and_what_to_quote(
    tmp_path: Path, reaching: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # the valve's stop removed from the model: the record (which reaches it) shows a misfit
    model = tmp_path / "no_stop.py"
    model.write_text(
        textwrap.dedent(
            """
            states = ["level"]
            inputs = ["u"]
            outputs = ["y"]
            parameters = {"K": (2.5, 0.0), "T": (10.0, 0.0)}
            def f(t, x, u, p):
                return [(p["K"] * u[0] - x[0]) / p["T"]]
            x0 = [0.0]
            """
        ).lstrip(),
        encoding="utf-8",
    )
    validation = _log(tmp_path, seed=83)
    code, out, _ = _run(
        capsys, str(model), str(reaching), "--validate-file", str(validation), "--json"
    )
    assert code == 0
    result = json.loads(out)
    misfit = result["misfit"]
    assert misfit is not None
    assert misfit["residual_to_noise"]["y"] > 3.0
    assert "hold only if the model were right" in misfit["note"]
    assert "validation RMSE" in misfit["note"]
    assert f"{result['validation_rmse']['y']:.4g}" in misfit["note"]
    code, out, _ = _run(capsys, str(model), str(reaching), "--validate-file", str(validation))
    text = " ".join(out.split())
    # on the first screen: the note is the table's caption, before any other figure
    assert text.index("hold only if the model were right") < text.index("fit (NRMSE")
    assert np.isfinite(result["validation_rmse"]["y"])


def test_every_top_level_json_key_and_the_solver_s_are_in_the_reference(
    tmp_path: Path, reaching: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from unit.test_docs_reference import REFERENCE, documented_names

    code, out, _ = _run(capsys, str(_model(tmp_path)), str(reaching), "--json")
    assert code == 0
    result = json.loads(out)
    keys = set(result) | set(result["solver"]) | {"residual_to_noise", "note"}
    missing = sorted(keys - documented_names(REFERENCE / "json.md"))
    assert not missing, f"fuelid greybox --json keys not in json.md: {missing}"
