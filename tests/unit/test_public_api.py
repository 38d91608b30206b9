"""The public API: every promised name imports from its promised path, without a warning.

What is promised is written in the packages' docstrings (``fuelid/__init__.py`` lists them) and
``__all__``; the table below repeats it on purpose, so that a split or a move that drops a name
fails here rather than in a user's script. The old paths of 0.2.0's moves and their deprecated
names were removed in 0.3.0 (CHANGELOG.md lists each with its replacement).
"""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
import warnings
from pathlib import Path
from types import ModuleType

import pytest

import fuelid

PROMISED: dict[str, tuple[str, ...]] = {
    "fuelid": (
        "ConfigError",
        "DataError",
        "FuelidError",
        "NotFittedError",
        "OutOfRangeError",
        "__version__",
    ),
    "fuelid.units": (
        "DEFAULT_FUEL_TEMPERATURE_C",
        "FUEL_TEMPERATURE_RANGE_C",
        "LPM_PER_M3S",
        "M3_PER_CM3",
        "M_PER_MM",
        "PA_PER_MPA",
        "PA_S_PER_MPA_S",
        "RAD_S_PER_RPM",
        "T0",
        "TWO_PI",
        "W_PER_KW",
        "celsius_to_kelvin",
        "format_celsius",
        "kelvin_to_celsius",
    ),
    "fuelid.errors": (
        "VALUE_ERROR_PREFIX",
        "ConfigError",
        "DataError",
        "FuelidError",
        "NotExcitingError",
        "NotFittedError",
        "OutOfRangeError",
        "plain_reason",
        "validation_reason",
    ),
    "fuelid.lti": (
        "MAX_CONTROL_PERIOD",
        "SETTLING_BAND",
        "check_control_period",
        "DiscreteLagModel",
        "discretise",
        "FloatArray",
        "lag_chain",
        "modified_z",
        "ModifiedZ",
        "settling_time",
        "step_measures",
        "step_response",
        "step_settling_time",
        "StepMeasures",
        "zoh_discretise",
    ),
    "fuelid.params": ("Params",),
    "fuelid.blas": ("single_threaded_blas",),
    "fuelid.numerics_mode": (
        "DEFAULT_NUMERICS",
        "REFERENCE_NUMERICS",
        "STATISTICAL_TOLERANCES",
        "TIGHT_TOLERANCES",
        "WINDOW_NUMERICS",
        "Numerics",
        "SearchTolerances",
    ),
    "fuelid.htmlreport": (
        "FIGURE_KEYS",
        "TEMPLATE",
        "check_report_path",
        "figure_paths",
        "figure_png",
        "render_report",
        "report_figures",
        "ReportFigure",
        "write_report",
    ),
    "fuelid.plant": (
        "PlantConfig",
        "load_plant_config",
        "plant_coefficients",
        "operating_point",
        "linearise",
        "plant_parameters",
        "with_parameters",
        "prediction_uncertainty",
    ),
    "fuelid.plant.simulate": ("simulate", "SimulationResult", "FuelTemperature", "integrate_held"),
    "fuelid.profiles": (
        "InputProfile",
        "step_profile",
        "step_sequence",
        "random_levels",
        "held_profile",
    ),
    "fuelid.profiles.runs": (
        "Profile",
        "load_profile",
        "run_profile",
        "steps_profile",
        "demo_run_profile",
        "demo_temperature",
    ),
    "fuelid.io.timeseries": ("TimeSeries", "IOData"),
    "fuelid.io.logs": ("load_log",),
    "fuelid.io.tables": ("read_table",),
    "fuelid.io.files": ("write_table",),
    "fuelid.io.fitted_model": ("FittedModel", "load_fitted_model"),
    "fuelid.io.jsonsafe": ("json_ready",),
    "fuelid.io.plantfile": ("update_plant_file",),
    "fuelid.model": (
        "DISTINCT_LAGS",
        "MODEL_KEYS",
        "Z95",
        "check_gain_identified",
        "FloatArray",
        "gain_not_identified",
        "model_covariance",
        "nrmse_fit",
        "nrmse_fit_columns",
        "ProcessModel",
        "simulate_model",
    ),
    "fuelid.identify": (
        "identify",
        "IdentificationResult",
        "IdentifyOptions",
        "METHODS",
        "StepResponseLS",
        "OutputError",
        "PredictionError",
        "residual_whiteness",
    ),
    "fuelid.identify.preprocess": ("select", "lowpass", "decimate", "join_segments"),
    "fuelid.greybox": ("GreyBoxEstimator", "OdeModel", "Record", "identifiability"),
    "fuelid.greybox.modelfile": ("load_model_file", "read_model_file", "ModelFile"),
    "fuelid.calibration.calibrate": (
        "calibrate",
        "CalibrationResult",
        "load_calibration_log",
        "CalibrationRefused",
    ),
    "fuelid.calibration.plant_model": ("PlantGreyBox",),
    "fuelid.tuning": ("tune", "PISettings", "TUNING_RULES", "robustness"),
    "fuelid.tuning.closedloop": ("simulate_closed_loop",),
    "fuelid.workflow": ("identify_log", "tune_model", "simulate_log", "analyse_log", "plant_info"),
    "fuelid.plots": (
        "save_figure",
        "plot_log",
        "plot_step_responses",
        "plot_identification",
        "plot_correlation_tests",
        "plot_bode",
        "plot_linear_closed_loop",
        "plot_closed_loop_runs",
        "plot_schedule",
        "schedule_figure",
        "runs_figure",
        "tune_figure",
        "plot_online_history",
        "plot_greybox_fit",
        "FitPanel",
        "DRIVE_LIMITS",
        "NO_UNIT",
        "PROPOSAL_COLOURS",
    ),
    "fuelid.online": ("loop_health", "LoopHealth", "KTracker", "prefit_gates", "postfit_gates"),
    "fuelid.store": ("SampleStore", "SQLiteStore", "OnlineHistory", "open_store"),
    "fuelid.central": ("Sender", "CentralError", "migrate", "file_central_request"),
    "fuelid.dashboard": (
        "LoopReader",
        "SQLiteLoop",
        "CentralLoop",
        "CentralLoops",
        "Loops",
        "create_app",
        "serve",
    ),
    "fuelid.plc.site": ("load_site", "SiteConfig"),
    "fuelid.plc.adapters": ("PlcSource", "open_source"),
}
"""Promised path → the names a user's script may import from it."""

PACKAGES = (
    "fuelid",
    "fuelid.calibration",
    "fuelid.central",
    "fuelid.dashboard",
    "fuelid.data",
    "fuelid.greybox",
    "fuelid.identify",
    "fuelid.io",
    "fuelid.online",
    "fuelid.plant",
    "fuelid.plc",
    "fuelid.plots",
    "fuelid.profiles",
    "fuelid.store",
    "fuelid.tuning",
    "fuelid.workflow",
)
"""The packages whose docstring states their public API and whose ``__all__`` lists it."""


@pytest.mark.parametrize("path", sorted(PROMISED))
def test_every_promised_name_imports_from_its_promised_path(path: str) -> None:
    module = importlib.import_module(path)
    missing = [name for name in PROMISED[path] if not hasattr(module, name)]
    assert not missing, f"{path} no longer has {missing}"


@pytest.mark.parametrize("path", PACKAGES)
def test_a_package_states_its_public_api(path: str) -> None:
    package = importlib.import_module(path)
    assert "The public API" in (package.__doc__ or ""), f"{path}'s docstring promises nothing"
    assert isinstance(package.__all__, list)
    unresolved = [name for name in package.__all__ if not hasattr(package, name)]
    assert not unresolved, f"{path}.__all__ names what it does not have: {unresolved}"
    promised_here = set(PROMISED.get(path, ())) - {"__version__"}
    assert promised_here <= set(package.__all__), promised_here - set(package.__all__)


def _fresh_import(path: str, monkeypatch: pytest.MonkeyPatch) -> ModuleType:
    """Import ``path`` as if for the first time; the test's end puts the old state back."""
    parent, _, child = path.rpartition(".")
    parent_module = importlib.import_module(parent)
    monkeypatch.delitem(sys.modules, path, raising=False)
    monkeypatch.delattr(parent_module, child, raising=False)
    return importlib.import_module(path)


@pytest.mark.parametrize("path", sorted(path for path in PROMISED if "." in path))
def test_a_promised_path_imports_without_a_warning(
    path: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _fresh_import(path, monkeypatch)
    assert not caught, [str(w.message) for w in caught]


def _modules_loaded_by(code: str) -> set[str]:
    """Top-level module names loaded by running ``code`` in a fresh interpreter."""
    src = str(Path(fuelid.__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}
    script = f"{code}\nimport sys\nprint(' '.join({{name.split('.')[0] for name in sys.modules}}))"
    out = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True
    )
    return set(out.stdout.split())


def test_importing_fuelid_loads_no_numerical_library() -> None:
    loaded = _modules_loaded_by("import fuelid")
    assert not loaded & {"numpy", "scipy", "pandas", "matplotlib"}, loaded


def test_the_packages_load_neither_pandas_nor_matplotlib() -> None:
    imports = "; ".join(f"import {path}" for path in PACKAGES) + "; import fuelid.plant.simulate"
    loaded = _modules_loaded_by(imports)
    assert not loaded & {"pandas", "matplotlib"}, loaded & {"pandas", "matplotlib"}
