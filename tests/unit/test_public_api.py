"""The public API: every promised name imports from its promised path, and every old path works.

What is promised is written in the packages' docstrings (``fuelid/__init__.py`` lists them) and
``__all__``; the table below repeats it on purpose, so that a split or a move that drops a name
fails here rather than in a user's script. The modules that moved in 0.2.0 keep a shim at their
old path that imports with exactly one DeprecationWarning (CHANGELOG.md).
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
    "fuelid.model": ("ProcessModel",),
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

MOVED = {
    "fuelid.simulate": "fuelid.plant.simulate",
    "fuelid.preprocess": "fuelid.identify.preprocess",
    "fuelid.plots_greybox": "fuelid.plots.greybox",
    "fuelid.plc.virtual.profiles": "fuelid.profiles.runs",
    "fuelid.io.modelfile": "fuelid.io.fitted_model",
}
"""Old path → new path of every module moved in 0.2.0."""

RENAMED = {
    "fuelid.io.modelfile": {
        "ModelFile": "fuelid.io.fitted_model.FittedModel",
        "load_model_file": "fuelid.io.fitted_model.load_fitted_model",
    },
    "fuelid.plots_greybox": {"save_greybox_figure": "fuelid.plots.save_figure"},
}
"""Names a shim keeps under their old name: old module → {old name: where the object lives}."""


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


@pytest.mark.parametrize(("old", "new"), sorted(MOVED.items()))
def test_an_old_path_imports_with_exactly_one_deprecation_warning(
    old: str, new: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    with pytest.warns(DeprecationWarning, match=f"{old} moved to {new}") as caught:
        shim = _fresh_import(old, monkeypatch)
    deprecations = [w for w in caught if issubclass(w.category, DeprecationWarning)]
    assert len(deprecations) == 1, [str(w.message) for w in deprecations]
    # attributed to the importing line (here, importlib's caller in this file), not to the import
    # machinery: Python's default filter then shows it to a script run as __main__
    assert Path(deprecations[0].filename) == Path(__file__), deprecations[0].filename

    for name in shim.__all__:
        home, _, new_name = RENAMED.get(old, {}).get(name, f"{new}.{name}").rpartition(".")
        assert getattr(shim, name) is getattr(importlib.import_module(home), new_name), name


@pytest.mark.parametrize("old", sorted(MOVED))
def test_an_old_path_still_reaches_names_it_does_not_list(
    old: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    with pytest.warns(DeprecationWarning, match=f"{old} moved to"):
        shim = _fresh_import(old, monkeypatch)
    moved = importlib.import_module(MOVED[old])
    private = sorted(name for name in vars(moved) if name.startswith("_") and "__" not in name)
    for name in private:
        assert getattr(shim, name) is getattr(moved, name), name


@pytest.mark.parametrize("path", ["fuelid.plots", "fuelid.profiles", "fuelid.plant.simulate"])
def test_a_new_home_imports_without_a_warning(path: str, monkeypatch: pytest.MonkeyPatch) -> None:
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
