"""What ``load_fitted_model`` reads besides the model (issue 37).

The operating point in either form (``operating_point.u`` or plant info's top-level ``u``), the
full linearisation ``linear_model``, the control period identify was given, the standard errors,
95 % intervals and ``fixed`` list that tune needs to refuse undetermined models.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from fuelid.errors import DataError
from fuelid.identify import interval95
from fuelid.io.fitted_model import FittedModel, LinearModelSpec, load_fitted_model
from fuelid.io.jsonsafe import json_ready
from fuelid.model import MODEL_KEYS

MODEL = {"K": 13.5, "T": 1.26, "T2": 0.0, "T_f": 0.3, "delay": 0.2}


def _load(tmp_path: Path, extra: dict[str, Any], *, text: str | None = None) -> FittedModel:
    path = tmp_path / "model.json"
    path.write_text(text or json.dumps({"model": MODEL} | extra), encoding="utf-8")
    return load_fitted_model(path)


def _refusal(tmp_path: Path, extra: dict[str, Any]) -> str:
    with pytest.raises(DataError) as caught:
        _load(tmp_path, extra)
    message = str(caught.value)
    assert "\n" not in message  # one line, as the CLI prints it
    assert str(tmp_path / "model.json") in message  # names the file
    return message


# --- a file without any of the new keys ----------------------------------------------------------


def test_a_bare_model_file_reads_as_before(tmp_path: Path) -> None:
    fitted = _load(tmp_path, {})
    assert fitted.control_period is None
    assert fitted.linear_model is None
    assert fitted.stderr == dict.fromkeys(MODEL_KEYS)
    assert fitted.ci95 == {}  # no intervals to judge: a model given by its numbers
    assert fitted.fixed == ()
    assert (fitted.u, fitted.fuel_temperature) == (None, None)


# --- control period ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ({"control_period": 0.1, "control_period_given": True}, 0.1),
        ({"control_period": 0, "control_period_given": True}, 0.0),  # continuous PI, given
        ({"control_period": 0.1, "control_period_given": False}, None),
        ({"control_period": 0.1}, None),  # before the flag: 1.0 was written whether given or not
        ({"control_period": 1.0}, None),
        ({"control_period": None, "control_period_given": False}, None),
        ({"control_period": None, "control_period_given": True}, None),
        ({"control_period": 0.1, "control_period_given": "true"}, None),  # only true is true
        ({"control_period": 0.1, "control_period_given": 1}, None),
    ],
)
def test_control_period_only_when_given(
    tmp_path: Path, options: dict[str, Any], expected: float | None
) -> None:
    assert _load(tmp_path, {"options": options}).control_period == expected


@pytest.mark.parametrize("recorded", ["-0.1", '"0.1"', "true", "Infinity", "NaN", "20"])
def test_a_recorded_control_period_that_is_no_period_is_refused(
    tmp_path: Path, recorded: str
) -> None:
    # issue 38: read as absent before, so a damaged file tuned for a period nobody gave
    text = f'{{"model": {{"K": 1, "T": 2}}, "options": {{"control_period": {recorded}, ' + (
        '"control_period_given": true}}'
    )
    with pytest.raises(DataError, match=r"options\.control_period must be"):
        _load(tmp_path, {}, text=text)


def test_options_that_are_not_an_object_give_none(tmp_path: Path) -> None:
    assert _load(tmp_path, {"options": ["control_period", 0.1]}).control_period is None


# --- linear model --------------------------------------------------------------------------------


def test_linear_model_reads_as_a_transfer_function(tmp_path: Path) -> None:
    block = {"num": [2, 1.0], "den": [0.5, 1.5, 1.0], "delay": 0.2, "poles": [[-1.0, 0.0]]}
    spec = _load(tmp_path, {"linear_model": block}).linear_model
    assert spec == LinearModelSpec(num=(2.0, 1.0), den=(0.5, 1.5, 1.0), delay=0.2)
    assert spec is not None
    assert all(isinstance(v, float) for v in (*spec.num, *spec.den, spec.delay))
    tf = spec.to_control()
    assert float(tf.dcgain()) == pytest.approx(1.0, rel=1e-15)  # 1/1: num[-1]/den[-1]
    assert list(tf.num[0][0]) == [2.0, 1.0]
    assert list(tf.den[0][0]) == [0.5, 1.5, 1.0]


def test_a_null_linear_model_is_none(tmp_path: Path) -> None:
    assert _load(tmp_path, {"linear_model": None}).linear_model is None


@pytest.mark.parametrize(
    ("block", "key"),
    [
        ({"num": [1.0], "den": [0, 1], "delay": 0.2}, "linear_model.den"),
        ({"num": [1.0, 2.0, 3.0], "den": [1.0, 1.0], "delay": 0.2}, "linear_model.num"),
        ("1/(s+1)", "linear_model"),
        (["num", "den"], "linear_model"),
        ({"num": "1", "den": [1.0, 1.0], "delay": 0.2}, "linear_model.num"),
        ({"num": [1.0], "den": "s+1", "delay": 0.2}, "linear_model.den"),
        ({"num": [1.0], "den": [], "delay": 0.2}, "linear_model.den"),
        ({"num": [], "den": [1.0, 1.0], "delay": 0.2}, "linear_model.num"),
        ({"num": [None], "den": [1.0, 1.0], "delay": 0.2}, "linear_model.num"),
        ({"num": [1.0], "den": [1.0, True], "delay": 0.2}, "linear_model.den"),
        ({"num": [1.0], "den": [1.0, 1.0], "delay": -0.1}, "linear_model.delay"),
        ({"num": [1.0], "den": [1.0, 1.0], "delay": None}, "linear_model.delay"),
        ({"num": [1.0], "den": [1.0, 1.0]}, "linear_model.delay"),
        ({"num": [1.0], "den": [1.0, 1.0], "delay": "0.2"}, "linear_model.delay"),
    ],
)
def test_a_malformed_linear_model_is_refused_naming_the_key(
    tmp_path: Path, block: Any, key: str
) -> None:
    message = _refusal(tmp_path, {"linear_model": block})
    assert key in message
    assert len(message) < 250


def test_a_non_finite_coefficient_is_refused(tmp_path: Path) -> None:
    for bad in ("NaN", "Infinity"):
        text = (
            '{"model": {"K": 1, "T": 2}, '
            f'"linear_model": {{"num": [1.0], "den": [1.0, {bad}], "delay": 0.1}}}}'
        )
        with pytest.raises(DataError, match=r"linear_model\.den is not a list of finite"):
            _load(tmp_path, {}, text=text)


def test_linear_model_spec_checks_itself() -> None:
    with pytest.raises(DataError, match=r"linear_model\.num has 3 coefficients, den 2"):
        LinearModelSpec(num=(1.0, 2.0, 3.0), den=(1.0, 1.0), delay=0.0)
    with pytest.raises(DataError, match=r"linear_model\.delay"):
        LinearModelSpec(num=(1.0,), den=(1.0, 1.0), delay=math.inf)


# --- standard errors, intervals, fixed -----------------------------------------------------------


def _identify_json(values: dict[str, float], stderr: dict[str, float | None]) -> str:
    """The ``model``/``stderr``/``ci95`` of a file as identify writes them (json_ready, no NaN)."""
    ci95 = {}
    for key in MODEL_KEYS:
        ci = interval95(values[key], stderr.get(key), positive=key != "K")
        ci95[key] = None if ci is None else ci[0]
    payload = {"model": values, "stderr": stderr, "ci95": ci95, "fixed": ["T_f"]}
    return json.dumps(json_ready(payload), allow_nan=False)


def test_stderr_ci95_and_fixed_as_identify_writes_them(tmp_path: Path) -> None:
    stderr = {"K": 0.1, "T": 0.05, "T2": None, "T_f": None, "delay": 0.01}
    fitted = _load(tmp_path, {}, text=_identify_json(MODEL, stderr))
    assert fitted.stderr == stderr
    assert fitted.fixed == ("T_f",)
    ci_K = fitted.ci95["K"]
    assert ci_K == pytest.approx((13.5 - 1.959963984540054 * 0.1, 13.5 + 1.959963984540054 * 0.1))
    assert fitted.ci95["T2"] is None
    assert fitted.ci95["T_f"] is None
    assert all(isinstance(ci, tuple) for ci in (fitted.ci95["K"], fitted.ci95["delay"]))


def test_an_unbounded_interval_reads_back_unbounded(tmp_path: Path) -> None:
    # identify's intervals for a standard error so large the bound overflows: json_ready writes
    # the ±inf bound as null, which must read back as ±inf, not as "no interval" (K keeps a
    # small standard error: a K within 1.96 of them of zero is refused, as before)
    stderr = {"K": 0.1, "T": 1e308, "T2": None, "T_f": None, "delay": 1e300}
    text = _identify_json(MODEL, stderr)
    assert '"T": [0.0, null]' in text  # clipped at 0 below, overflowed above
    ci95 = _load(tmp_path, {}, text=text).ci95
    assert ci95["T"] == (0.0, math.inf)
    low, high = ci95["delay"] or (math.nan, math.nan)  # finite but huge: kept as it is
    assert low == 0.0
    assert high == pytest.approx(0.2 + 1.959963984540054e300, rel=1e-15)
    assert math.isfinite(high)


def test_an_interval_unbounded_on_both_sides(tmp_path: Path) -> None:
    # K ± 1.96·se overflowing both ways is written [null, null] (no stderr.K here: with one, a
    # gain that does not differ from zero is refused before its interval matters)
    fitted = _load(tmp_path, {"ci95": {"K": [None, None]}})
    assert fitted.ci95["K"] == (-math.inf, math.inf)


def test_huge_and_infinite_bounds_survive(tmp_path: Path) -> None:
    # as a hand-written file or a json.dumps without allow_nan=False has them
    text = (
        '{"model": {"K": 1, "T": 2}, "stderr": {"T": 1e300, "delay": Infinity}, '
        '"ci95": {"K": [-1e300, 1e300], "T": [0, Infinity], "delay": [-Infinity, 3]}}'
    )
    fitted = _load(tmp_path, {}, text=text)
    assert fitted.ci95["K"] == (-1e300, 1e300)
    assert fitted.ci95["T"] == (0.0, math.inf)
    assert fitted.ci95["delay"] == (-math.inf, 3.0)
    assert fitted.stderr["T"] == 1e300
    assert fitted.stderr["delay"] == math.inf


@pytest.mark.parametrize(
    "entry",
    ["wide", [1.0], [1.0, 2.0, 3.0], [2.0, 1.0], [1.0, "2"], [True, 2.0], {"low": 1.0}, 3.0],
)
def test_a_malformed_interval_is_none_not_a_crash(tmp_path: Path, entry: Any) -> None:
    fitted = _load(tmp_path, {"ci95": {"K": entry, "T": [1.0, 1.5]}})
    assert fitted.ci95["K"] is None
    assert fitted.ci95["T"] == (1.0, 1.5)


def test_a_nan_bound_is_malformed(tmp_path: Path) -> None:
    text = '{"model": {"K": 1, "T": 2}, "ci95": {"T": [NaN, 3]}}'
    assert _load(tmp_path, {}, text=text).ci95["T"] is None


@pytest.mark.parametrize("entry", ["0.1", -0.1, True, [0.1], {"se": 0.1}, None])
def test_a_malformed_stderr_is_none(tmp_path: Path, entry: Any) -> None:
    fitted = _load(tmp_path, {"stderr": {"T": entry, "delay": 0.01}})
    assert fitted.stderr["T"] is None
    assert fitted.stderr["delay"] == 0.01


def test_stderr_and_ci95_that_are_not_objects_give_none(tmp_path: Path) -> None:
    fitted = _load(tmp_path, {"stderr": [0.1, 0.2], "ci95": "none", "fixed": "T_f"})
    assert fitted.stderr == dict.fromkeys(MODEL_KEYS)
    assert fitted.ci95 == dict.fromkeys(MODEL_KEYS)
    assert fitted.fixed == ()


def test_fixed_keeps_the_names(tmp_path: Path) -> None:
    assert _load(tmp_path, {"fixed": ["T_f", "delay", 3]}).fixed == ("T_f", "delay")


# --- operating point in either form --------------------------------------------------------------


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        ({"operating_point": {"u": 2.5, "fuel_temperature": 40.0}}, (2.5, 40.0)),
        ({"u": 2, "fuel_temperature": 35}, (2.0, 35.0)),  # plant info's top-level keys
        ({"u": 1.0, "operating_point": {"u": 2.5, "flow": 30.0}}, (2.5, None)),
        ({"fuel_temperature": 35.0, "operating_point": {"u": 2.5}}, (2.5, 35.0)),
        ({"fuel_temperature": 35.0, "operating_point": {"fuel_temperature": None}}, (None, 35.0)),
        ({"operating_point": None, "u": 3.0}, (3.0, None)),
    ],
)
def test_operating_point_in_either_form(
    tmp_path: Path, extra: dict[str, Any], expected: tuple[float | None, float | None]
) -> None:
    fitted = _load(tmp_path, extra)
    assert (fitted.u, fitted.fuel_temperature) == expected


@pytest.mark.parametrize(
    ("extra", "key"),
    [
        ({"u": "2 V"}, "u"),
        ({"fuel_temperature": True}, "fuel_temperature"),
        ({"operating_point": {"u": "2"}}, "operating_point u"),
        ({"operating_point": "2 V"}, "operating_point"),
    ],
)
def test_a_bad_operating_point_is_refused(tmp_path: Path, extra: dict[str, Any], key: str) -> None:
    assert key in _refusal(tmp_path, extra)
