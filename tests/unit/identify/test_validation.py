"""Validation that does not mislead: no score without excitation, a validation record's start.

A held-out stretch whose command never moves cannot tell a good model from a bad one (its fit %
measures only the offset); a validation record that does not start at rest must not be
simulated as if it did. The truths here come from the model family itself.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from fuelid.cli import app
from fuelid.errors import FuelidError
from fuelid.identify import IdentifyOptions, identify
from fuelid.io.timeseries import IOData
from fuelid.model import ProcessModel, simulate_model

H = 0.05
TRUTH = ProcessModel(K=2.0, T=1.5, delay=0.2)
OPTIONS: dict[str, object] = {"order": 1, "delay": 0.2}


def _record(levels: list[float], dwell: float, noise: float = 0.01, seed: int = 0) -> IOData:
    u = np.repeat(levels, round(dwell / H))
    y = 40.0 + simulate_model(TRUTH, u, H)
    y = y + np.random.default_rng(seed).normal(0.0, noise, u.size)
    return IOData(u, y, H)


def test_a_held_out_plateau_gets_no_score_and_a_reason() -> None:
    # the last 30 % of this record is one long plateau: the command never moves there
    data = _record([1.0, 1.5, 1.2, 1.8, 1.8, 1.8, 1.8], 15.0)
    result = identify(data, IdentifyOptions(validate_split=0.3, **OPTIONS))
    assert result.validation_fit_percent is None
    assert result.validation_initial == "continued"
    assert any("held-out part of the record has no excitation" in w for w in result.warnings)
    assert result.to_json()["validation_fit_percent"] is None


def test_a_held_out_part_with_steps_is_scored() -> None:
    data = _record([1.0, 1.5, 1.2, 1.8, 1.3, 1.6, 1.1], 15.0)
    result = identify(data, IdentifyOptions(validate_split=0.3, **OPTIONS))
    assert result.validation_fit_percent is not None
    assert result.validation_fit_percent > 95.0
    assert not any("no excitation" in w for w in result.warnings)


def _not_at_rest() -> IOData:
    # a record cut out of a longer run 1 s after a step: the output is still moving at its start
    full = _record([1.0, 1.6, 1.2, 1.7, 1.3], 12.0, seed=1)
    start = round(13.0 / H)
    return full.segment(start)


def test_a_validation_record_is_scored_from_its_estimated_initial_state() -> None:
    data = _record([1.0, 1.5, 1.2, 1.8, 1.3, 1.6, 1.1], 15.0)
    validation = _not_at_rest()
    estimated = identify(data, IdentifyOptions(**OPTIONS), validation)
    at_rest = identify(
        data,
        IdentifyOptions(validation_initial="rest", **OPTIONS),
        validation,
    )
    assert estimated.validation_initial == "estimate"
    assert at_rest.validation_initial == "rest"
    assert estimated.to_json()["validation_initial"] == "estimate"
    # the same model: the estimated start scores what the model can do, rest penalises the start
    assert estimated.validation_fit_percent is not None
    assert at_rest.validation_fit_percent is not None
    assert estimated.validation_fit_percent > 95.0
    assert at_rest.validation_fit_percent < estimated.validation_fit_percent - 5.0


def test_a_flat_validation_record_gets_no_score() -> None:
    data = _record([1.0, 1.5, 1.2, 1.8, 1.3], 15.0)
    flat = _record([1.4, 1.4], 10.0, seed=2)
    result = identify(data, IdentifyOptions(**OPTIONS), flat)
    assert result.validation_fit_percent is None
    assert any("validation record has no excitation" in w for w in result.warnings)


def test_an_unknown_validation_start_is_refused() -> None:
    with pytest.raises(FuelidError, match="estimate or rest"):
        IdentifyOptions(validation_initial="zero")


def _write(path: Path, record: IOData) -> str:
    t = np.arange(record.n_samples) * H
    rows = zip(t, record.u, record.y, strict=True)
    path.write_text("t_s,u_V,q_Lpm\n" + "\n".join(f"{a:.2f},{b:.6f},{c:.6f}" for a, b, c in rows))
    return str(path)


def test_the_cli_names_the_validation_start(tmp_path: Path) -> None:
    fit = _write(tmp_path / "fit.csv", _record([1.0, 1.5, 1.2, 1.8, 1.3], 15.0))
    val = _write(tmp_path / "val.csv", _not_at_rest())
    runner = CliRunner()
    for start in ("estimate", "rest"):
        args = ["identify", fit, "--delay", "0.2", "--validate-file", val]
        result = runner.invoke(app, [*args, "--validate-initial", start, "--json"])
        assert result.exit_code == 0, result.output
        data = json.loads(result.stdout)
        assert data["validation_initial"] == start
        assert data["options"]["validate_initial"] == start
