"""``fuelid greybox`` end to end: the two-tank example, the JSON contract and every refusal."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from fuelid.cli import main
from fuelid.errors import ConfigError
from fuelid.greybox import ParameterSpec
from fuelid.greybox.modelfile import load_model_file, read_model_file

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
MODEL = EXAMPLES / "two_tanks.py"
TRUTH = {"k1": 0.05, "k2": 0.04, "k3": 0.05, "k4": 0.06}
JSON_KEYS = {
    "parameters",
    "stderr",
    "ci95",
    "fixed",
    "fit_percent",
    "validation_fit_percent",
    "validation_rmse",
    "validation_initial_state",
    "noise_std",
    "identifiability",
    "profile",
    "warnings",
    "units",
    "start",
    "provenance",
}


@pytest.fixture(scope="module")
def tank_logs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The example's estimation and validation logs, made by its own data script."""
    out = tmp_path_factory.mktemp("tanks")
    subprocess.run(
        [sys.executable, str(EXAMPLES / "two_tanks_data.py"), str(out)],
        check=True,
        capture_output=True,
        timeout=120,
    )
    return out / "two_tanks_estimation.csv", out / "two_tanks_validation.csv"


@pytest.fixture(scope="module")
def fitted(tank_logs: tuple[Path, Path]) -> tuple[int, dict, str]:
    """``--fix k4`` with validation, as JSON (one fit shared by several tests)."""
    estimation, validation = tank_logs
    capture = _Capture()
    with capture:
        code = main(
            [
                "greybox",
                str(MODEL),
                str(estimation),
                "--fix",
                "k4",
                "--validate-file",
                str(validation),
                "--json",
            ]
        )
    return code, json.loads(capture.out), capture.err


class _Capture:
    """stdout and stderr of a block (capsys is function-scoped; the fit is module-scoped)."""

    def __enter__(self) -> _Capture:
        import contextlib
        import io

        self._out, self._err = io.StringIO(), io.StringIO()
        self._stack = contextlib.ExitStack()
        self._stack.enter_context(contextlib.redirect_stdout(self._out))
        self._stack.enter_context(contextlib.redirect_stderr(self._err))
        return self

    def __exit__(self, *exc: object) -> None:
        self._stack.close()
        self.out, self.err = self._out.getvalue(), self._err.getvalue()


def _write(folder: Path, name: str, source: str) -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(source).lstrip(), encoding="utf-8")
    return path


def _run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(["greybox", *args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


# --- the two-tank example ------------------------------------------------------------------------


def test_all_four_gains_free_is_refused_naming_what_trades(
    tank_logs: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
):
    code, out, err = _run(capsys, str(MODEL), str(tank_logs[0]))
    assert code == 2
    assert out == ""
    assert err.startswith("error: ")
    assert err.count("\n") == 1
    for name in ("k1", "k2", "k4", "x0[x1]"):
        assert name in err
    assert "k3" not in err.split("Fix one")[0]  # k3 is determined
    assert "--fix" in err


def test_json_refusal_prints_nothing_on_stdout(
    tank_logs: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
):
    code, out, err = _run(capsys, str(MODEL), str(tank_logs[0]), "--json")
    assert code == 2
    assert out == ""
    assert "trade against each other" in err


def test_fixed_pump_gain_recovers_the_outflow_coefficients(fitted: tuple[int, dict, str]):
    code, result, err = fitted
    assert code == 0, err
    assert result["fixed"] == ["k4"]
    assert result["parameters"]["k4"] == TRUTH["k4"]
    assert result["stderr"]["k4"] is None
    assert result["ci95"]["k4"] is None
    for name in ("k1", "k2", "k3"):
        value, se = result["parameters"][name], result["stderr"][name]
        lo, hi = result["ci95"][name]
        assert abs(value - TRUTH[name]) <= 3.0 * se, name
        assert abs(value / TRUTH[name] - 1.0) < 0.05, name
        assert lo < value < hi
    assert result["identifiability"]["identifiable"] is True
    assert result["warnings"] == []
    assert err == ""


def test_json_carries_the_documented_keys_and_provenance(
    fitted: tuple[int, dict, str], tank_logs: tuple[Path, Path]
):
    _, result, _ = fitted
    assert set(result) >= JSON_KEYS
    fit = result["fit_percent"]["two_tanks_estimation.csv"]["h2_dm"]
    assert fit > 90.0
    assert result["validation_fit_percent"]["h2_dm"] > 90.0
    assert 0.005 < result["validation_rmse"]["h2_dm"] < 0.02  # the 0.01 dm noise
    assert 0.005 < result["noise_std"]["h2_dm"] < 0.02
    assert result["validation_initial_state"] == (
        "fitted to the first 10 % of the validation record (at least 20 samples), parameters held"
    )
    assert result["profile"] is None
    assert result["start"] == "single shooting"  # the residuals are the noise: no second start
    assert "fuelid converts nothing" in result["units"]["parameters"]
    hashes = result["provenance"]["files_sha256"]
    assert set(hashes) == {str(MODEL), *(str(path) for path in tank_logs)}
    assert result["provenance"]["options"]["fix"] == ["k4"]
    assert result["input_sha256"] == hashes[str(tank_logs[0])]


def test_text_output_has_the_table_the_report_and_the_figure(
    tank_logs: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    fig = tmp_path / "fit.png"
    estimation, validation = tank_logs
    code, out, err = _run(
        capsys,
        str(MODEL),
        str(estimation),
        "--fix",
        "k4",
        "--validate-file",
        str(validation),
        "--plot",
        str(fig),
    )
    assert code == 0, err
    for text in ("k1", "k3", "fixed", "95 % interval", "validation on", "RMSE", "rank 5 of 5"):
        assert text in out
    assert "x0[x1]" in out  # names with brackets are not eaten as markup
    assert "confounded pairs: none" in out
    assert fig.stat().st_size > 10_000


# --- refusals: one line on stderr, exit code 2, nothing on stdout --------------------------------


def test_unknown_parameter_in_fix_lists_the_valid_ones(
    tank_logs: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
):
    code, out, err = _run(capsys, str(MODEL), str(tank_logs[0]), "--fix", "k9")
    assert (code, out) == (2, "")
    assert "k9" in err
    assert "k1, k2, k3, k4" in err


def test_a_name_both_fixed_and_freed_is_refused(
    tank_logs: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
):
    code, out, err = _run(capsys, str(MODEL), str(tank_logs[0]), "--fix", "k4", "--free", "k4")
    assert (code, out) == (2, "")
    assert "k4" in err
    assert "both fixed and freed" in err


def test_missing_columns_are_named_with_those_present(
    tank_logs: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
):
    code, out, err = _run(capsys, str(MODEL), str(tank_logs[0]), "--output-col", "level")
    assert (code, out) == (2, "")
    assert "'level'" in err
    assert "t_s, u_V, h2_dm" in err


def test_a_syntax_error_names_the_file_and_line(
    tank_logs: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    model = _write(
        tmp_path,
        "broken.py",
        """
        states = ["x"]
        parameters = {"a": 1.0}
        def f(t, x, u, p)
            return -x
        """,
    )
    code, out, err = _run(capsys, str(model), str(tank_logs[0]))
    assert (code, out) == (2, "")
    assert "broken.py line 3" in err
    assert "SyntaxError" in err


def test_an_exception_in_f_during_the_fit_names_the_line(
    tank_logs: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    model = _write(
        tmp_path,
        "raising.py",
        """
        states = ["x1", "x2"]
        parameters = {"k1": (0.05, 0.0), "k2": 0.04}

        def f(t, x, u, p):
            if t > 30.0:
                return [1.0 / 0.0, 0.0]
            return [-p["k1"] * x[0] + u[0], p["k2"] * x[0] - x[1]]
        """,
    )
    args = [str(model), str(tank_logs[0]), "--input-col", "u_V", "--output-col", "h2_dm"]
    code, out, err = _run(capsys, *args)
    assert (code, out) == (2, "")
    assert "raising.py line 6: ZeroDivisionError" in err
    assert err.count("\n") == 1


def test_a_mistake_in_f_stops_the_fit_at_its_line(
    tank_logs: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    model = _write(
        tmp_path,
        "typo.py",
        """
        states = ["x1", "x2"]
        outputs = ["h2_dm"]
        parameters = {"k1": (0.05, 0.0)}
        def f(t, x, u, p):
            return [-p["k1"] * x[0], p["k2"] * x[0]]
        """,
    )
    code, out, err = _run(capsys, str(model), str(tank_logs[0]))
    assert (code, out) == (2, "")
    assert "typo.py line 5: KeyError: 'k2' (raised in f)" in err


def test_a_bad_parameter_entry_names_its_line(tmp_path: Path):
    model = _write(
        tmp_path,
        "bounds.py",
        """
        states = ["x"]
        parameters = {
            "a": 1.0,
            "b": (1.0, 2.0, 0.5),
        }
        def f(t, x, u, p):
            return -x
        """,
    )
    with pytest.raises(ConfigError, match=r"bounds\.py line 4: parameter b"):
        load_model_file(model)


def test_a_name_error_while_loading_names_its_line(tmp_path: Path):
    model = _write(tmp_path, "undefined.py", 'states = ["x"]\n\nparameters = {"a": nothing}\n')
    with pytest.raises(ConfigError, match=r"undefined\.py line 3: NameError"):
        load_model_file(model)


def test_a_fit_that_does_not_converge_gives_no_numbers(
    tank_logs: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
):
    args = [str(MODEL), str(tank_logs[0]), "--fix", "k4", "--max-iterations", "1", "--json"]
    code, out, err = _run(capsys, *args)
    assert (code, out) == (2, "")
    assert "did not converge" in err
    assert "--segments" not in err  # "auto" tried it already
    code, out, err = _run(capsys, *args, "--segments", "none")
    assert (code, out) == (2, "")
    assert "--segments auto or N tries a segmented start" in err
    assert err.count("\n") == 1


def test_a_model_whose_outputs_are_nan_is_refused(
    tank_logs: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    model = _write(
        tmp_path,
        "nan.py",
        """
        import numpy as np
        states = ["x1", "x2"]
        inputs = ["u_V"]
        outputs = ["h2_dm"]
        parameters = {"k1": (0.05, 0.0), "k2": (0.04, 0.0)}
        def f(t, x, u, p):
            return [np.nan * x[0], -p["k2"] * x[1]]
        def h(x, u, p):
            return x[0]
        """,
    )
    code, out, err = _run(capsys, str(model), str(tank_logs[0]))
    assert (code, out) == (2, "")
    assert "cannot be simulated" in err


def test_f_returning_the_wrong_number_of_derivatives_is_refused(
    tank_logs: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    model = _write(
        tmp_path,
        "short.py",
        """
        states = ["x1", "x2"]
        outputs = ["h2_dm"]
        parameters = {"k1": (0.05, 0.0)}
        def f(t, x, u, p):
            return [-p["k1"] * x[0]]
        """,
    )
    code, out, err = _run(capsys, str(model), str(tank_logs[0]))
    assert (code, out) == (2, "")
    assert "f returned 1 value(s) for 2 state(s)" in err


def test_profile_of_a_fixed_parameter_is_refused_before_fitting(
    tank_logs: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
):
    args = [str(MODEL), str(tank_logs[0]), "--fix", "k4", "--profile", "k4"]
    code, out, err = _run(capsys, *args)
    assert (code, out) == (2, "")
    assert "free: k1, k2, k3" in err


@pytest.mark.parametrize(
    ("option", "value", "message"),
    [
        ("--set", "k4", "NAME=VALUE"),
        ("--set", "k4=-1", "outside its bounds"),
        ("--fix", "k1,,k2", "comma-separated"),
        ("--initial-state", "model", "defines no x0"),
        ("--input-col", "u_V,t_s", "has 1 input"),
        ("--segments", "1", "integer ≥ 2"),
        ("--segments", "many", "auto, none or an integer"),
    ],
)
def test_bad_options_are_refused_in_one_line(
    tank_logs: tuple[Path, Path],
    capsys: pytest.CaptureFixture[str],
    option: str,
    value: str,
    message: str,
):
    code, out, err = _run(capsys, str(MODEL), str(tank_logs[0]), option, value)
    assert (code, out) == (2, "")
    assert message in err
    assert err.count("\n") == 1


# --- the model file's forms ----------------------------------------------------------------------


def test_every_parameter_form_is_read(tmp_path: Path):
    model = _write(
        tmp_path,
        "forms.py",
        """
        states = ["x"]
        outputs = ["y"]
        parameters = {
            "a": 2,
            "b": (1.0, 0.0),
            "c": (1.0, 0.0, 5.0),
            "d": {"value": 0.5, "lower": 0.0, "fixed": True, "unit": "1/s"},
        }
        def f(t, x, u, p):
            return -p["a"] * x
        """,
    )
    read = read_model_file(model)
    assert read.model.parameters == (
        ParameterSpec("a", 2.0),
        ParameterSpec("b", 1.0, 0.0),
        ParameterSpec("c", 1.0, 0.0, 5.0),
        ParameterSpec("d", 0.5, 0.0, None, True),
    )
    assert read.units == {"d": "1/s"}
    assert read.model.output_names == ("y",)
    assert read.input_names is None
    assert not read.has_x0


@pytest.mark.parametrize(
    ("source", "message"),
    [
        ('parameters = {"a": 1.0}\ndef f(t, x, u, p):\n    return x\n', "no states list"),
        ('states = []\nparameters = {"a": 1.0}\n', "states is empty"),
        ('states = ["x"]\nparameters = {"a": 1.0}\n', "no function f"),
        ('states = ["x"]\nparameters = {"a": 1.0}\nf = 3\n', "f must be a function"),
        ('states = ["x"]\nparameters = {"1a": 1.0}\nf = abs\n', "not an identifier"),
        ('states = ["x"]\nparameters = {"a": (1, 2, 3, 4)}\nf = abs\n', "4 values"),
        ('states = ["x"]\nparameters = {"a": {"val": 1}}\nf = abs\n', "unknown key"),
    ],
)
def test_malformed_model_files_are_refused(tmp_path: Path, source: str, message: str):
    with pytest.raises(ConfigError, match=message):
        load_model_file(_write(tmp_path, "model.py", source))


def test_an_exception_in_h_names_its_line(tmp_path: Path):
    model = load_model_file(
        _write(
            tmp_path,
            "h_fails.py",
            """
            states = ["x"]
            parameters = {"a": 1.0}
            def f(t, x, u, p):
                return -x
            def h(x, u, p):
                return x[0] / p["missing"]
            """,
        )
    )
    with pytest.raises(ConfigError, match=r"h_fails\.py line 6: KeyError: 'missing'"):
        model.h(np.ones(1), np.ones(1), {"a": 1.0})


def test_two_records_and_a_sample_time(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    """A first-order model fitted to two logs without a time column, jointly."""
    model = _write(
        tmp_path,
        "lag.py",
        """
        states = ["y"]
        inputs = ["u"]
        outputs = ["y"]
        parameters = {"K": (1.0, 0.0), "T": (5.0, 0.0)}
        def f(t, x, u, p):
            return [(p["K"] * u[0] - x[0]) / p["T"]]
        def x0(p, u0, y0):
            return [y0[0]]
        """,
    )
    rng = np.random.default_rng(3)
    files = []
    for i in range(2):
        u = np.repeat(rng.uniform(0.0, 2.0, 8), 25)
        y = np.zeros_like(u)
        for k in range(1, len(u)):  # exact ZOH of K/(Ts+1), K = 2, T = 4 s, h = 0.5 s
            a = np.exp(-0.5 / 4.0)
            y[k] = a * y[k - 1] + 2.0 * (1 - a) * u[k - 1]
        y += rng.normal(0.0, 0.01, len(u))
        y[5::17] = np.nan  # missing samples
        path = tmp_path / f"lag{i}.csv"
        pd.DataFrame({"u": u, "y": y}).to_csv(path, index=False, na_rep="")
        files.append(str(path))
    code, out, err = _run(capsys, str(model), *files, "--sample-time", "0.5", "--json")
    assert code == 0, err
    result = json.loads(out)
    assert result["parameters"]["K"] == pytest.approx(2.0, rel=0.03)
    assert result["parameters"]["T"] == pytest.approx(4.0, rel=0.05)
    assert set(result["fit_percent"]) == {"lag0.csv", "lag1.csv"}
    assert result["initial_state"] == "the model's x0"


def test_a_fit_with_an_undetermined_parameter_exits_0_with_a_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """A parameter that barely moves the output: the fit is given, it without error bars."""
    model = _write(
        tmp_path,
        "weak.py",
        """
        states = ["y"]
        inputs = ["u"]
        outputs = ["y"]
        parameters = {"K": (1.0, 0.0), "T": (5.0, 0.0), "c": 0.1}
        def f(t, x, u, p):
            return [(p["K"] * u[0] - x[0]) / p["T"]]
        def h(x, u, p):
            return x[0] + 1e-3 * p["c"]
        def x0(p, u0, y0):
            return [y0[0]]
        """,
    )
    rng = np.random.default_rng(3)
    u = np.repeat(rng.uniform(0.0, 2.0, 8), 25)
    y = np.zeros_like(u)
    a = np.exp(-0.5 / 4.0)
    for k in range(1, len(u)):
        y[k] = a * y[k - 1] + 2.0 * (1 - a) * u[k - 1]
    y += rng.normal(0.0, 0.01, len(u))
    data = tmp_path / "lag.csv"
    pd.DataFrame({"t_s": 0.5 * np.arange(len(u)), "u": u, "y": y}).to_csv(data, index=False)
    code, out, err = _run(capsys, str(model), str(data), "--json")
    assert code == 0, err
    result = json.loads(out)
    assert result["stderr"]["c"] is None
    assert result["stderr"]["K"] is not None
    assert result["warnings"]
    assert "c" in result["identifiability"]["undetermined_parameters"]
    assert err.startswith("warning: ")


def test_help_says_the_model_runs_as_python_and_loads_no_numerical_library():
    probe = (
        "import contextlib, io, json, sys\n"
        "from fuelid.cli import main\n"
        "out = io.StringIO()\n"
        "with contextlib.redirect_stdout(out):\n"
        "    code = main(['greybox', '--help'])\n"
        "heavy = ('numpy', 'scipy', 'pandas', 'matplotlib')\n"
        "print(json.dumps({'code': code, 'help': out.getvalue(),\n"
        "                  'loaded': [m for m in heavy if m in sys.modules]}))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=True
    )
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["code"] == 0
    assert result["loaded"] == []
    text = " ".join(result["help"].split())
    assert "runs as such: only run files you trust" in text


def test_both_levels_measured_determine_all_four_gains(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """Two outputs (one with missing samples) from Parquet, f written for scalars (math.sqrt)."""
    from scipy.integrate import solve_ivp

    model = _write(
        tmp_path,
        "both.py",
        """
        import math
        states = ["x1", "x2"]
        inputs = ["u_V"]
        outputs = ["h1_dm", "h2_dm"]
        parameters = {"k1": (0.065, 0.0), "k2": (0.052, 0.0), "k3": (0.065, 0.0),
                      "k4": (0.078, 0.0)}
        def f(t, x, u, p):
            x1, x2 = max(x[0], 0.0), max(x[1], 0.0)
            return [-p["k1"] * math.sqrt(x1) + p["k4"] * u[0],
                    p["k2"] * math.sqrt(x1) - p["k3"] * math.sqrt(x2)]
        def h(x, u, p):
            return [x[0], x[1]]
        """,
    )
    rng = np.random.default_rng(5)
    u = np.repeat(rng.uniform(0.4, 2.0, 8), 80)

    def rhs(t: float, x: np.ndarray, u_k: float) -> list[float]:
        r1, r2 = np.sqrt(max(x[0], 0.0)), np.sqrt(max(x[1], 0.0))
        return [-0.05 * r1 + 0.06 * u_k, 0.04 * r1 - 0.05 * r2]

    x, levels = np.array([1.0, 0.8]), []
    for u_k in u:
        levels.append(x)
        x = solve_ivp(rhs, (0.0, 1.0), x, args=(u_k,), rtol=1e-9, atol=1e-11).y[:, -1]
    y = np.array(levels) + rng.normal(0.0, 0.01, (len(u), 2))
    frame = pd.DataFrame({"t_s": np.arange(len(u)), "u_V": u, "h1_dm": y[:, 0], "h2_dm": y[:, 1]})
    frame.loc[::7, "h1_dm"] = np.nan
    data = tmp_path / "both.parquet"
    frame.to_parquet(data)
    code, out, err = _run(capsys, str(model), str(data), "--json")
    assert code == 0, err
    result = json.loads(out)
    assert result["fixed"] == []
    for name, truth in TRUTH.items():
        assert result["parameters"][name] == pytest.approx(truth, rel=0.02), name
        assert abs(result["parameters"][name] - truth) < 4.0 * result["stderr"][name], name
    assert set(result["noise_std"]) == {"h1_dm", "h2_dm"}
    assert min(result["fit_percent"]["both.parquet"].values()) > 90.0


def test_a_constant_initial_state_may_be_a_list(tmp_path: Path):
    read = read_model_file(
        _write(
            tmp_path,
            "const.py",
            """
            states = ["x1", "x2"]
            parameters = {"a": 1.0}
            x0 = [1.0, 0.5]
            def f(t, x, u, p):
                return [-x[0], -x[1]]
            """,
        )
    )
    assert read.has_x0
    assert read.model.x0 is not None
    assert read.model.x0({"a": 1.0}, [0.0], [0.0]) == [1.0, 0.5]
    with pytest.raises(ConfigError, match="x0 must be a function"):
        load_model_file(
            _write(
                tmp_path,
                "bad_x0.py",
                'states = ["x"]\nparameters = {"a": 1.0}\nx0 = [1.0, 2.0]\nf = abs\n',
            )
        )


def test_a_wrong_fixed_value_is_warned_about_by_the_size_of_the_residuals(
    tank_logs: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
):
    """k3 held at 4× its truth: no parameter set fits, and the residuals say so.

    The fit still exits 0 (it is the best fit of this model), but the residuals are several times
    the 0.01 dm sample-to-sample noise, the standard errors that assume white residuals are
    called too small, and the segmented start that "auto" tries (within the plain fit's
    allowance of evaluations) replaces nothing.
    """
    args = [str(MODEL), str(tank_logs[0]), "--fix", "k3,k4", "--set", "k3=0.2", "--json"]
    code, out, err = _run(capsys, *args)
    assert code == 0
    result = json.loads(out)
    assert result["noise_std"]["h2_dm"] > 3 * 0.01
    assert any("sample-to-sample noise" in w and "too small" in w for w in result["warnings"])
    # the segmented start auto tries, within the evaluations the plain fit spent, gives no
    # better fit of this wrong model (it may end where the model cannot be simulated): the
    # single-shooting fit is kept and the start says so
    assert result["start"].startswith("single shooting (a segmented start ")
    assert "sample-to-sample noise" in err


def test_an_undeclared_switch_is_named_before_the_fit_and_in_the_json(
    tank_logs: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # the example with an `if` on the lower level that these logs never reach: the fit runs as
    # before, and the if is named (file and line) on stderr and in the JSON's warnings
    source = MODEL.read_text(encoding="utf-8").replace(
        "    return [dx1, dx2]",
        "    if x[1] > 100.0:  # never reached by these logs\n        dx2 = dx2 - 1.0\n"
        "    return [dx1, dx2]",
    )
    model = tmp_path / "two_tanks_if.py"
    model.write_text(source, encoding="utf-8")
    line = source.splitlines().index("    if x[1] > 100.0:  # never reached by these logs") + 1
    code, out, err = _run(capsys, str(model), str(tank_logs[0]), "--fix", "k4", "--json")
    assert code == 0
    named = f"{model} line {line}: f switches on the state (x[1] > 100.0)"
    assert named in err
    assert any(message.startswith(named) for message in json.loads(out)["warnings"])
