"""Modules split along their seams still answer to their old import paths with the same objects."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

import fuelid.fuel as fuel
import fuelid.fuel.correlations as correlations
import fuelid.fuel.registry as registry
import fuelid.greybox.estimator as estimator
import fuelid.greybox.fitting as fitting
import fuelid.greybox.multiple_shooting as multiple_shooting
import fuelid.greybox.profile as profile
import fuelid.identify.oe as oe
import fuelid.identify.pem as pem
import fuelid.identify.prediction_errors as prediction_errors
import fuelid.identify.procedure as procedure
import fuelid.identify.result as result
import fuelid.identify.step_ls as step_ls
import fuelid.identify.step_shape_fit as step_shape_fit
import fuelid.identify.variable_projection as variable_projection

# the package fuelid.greybox binds the name identifiability to the function: import the module
identifiability = importlib.import_module("fuelid.greybox.identifiability")

MOVED = [
    (estimator, fitting, ["ConvergenceError", "first_outputs", "noise_level", "XTOL"]),
    (estimator, identifiability, ["NotIdentifiableError", "correlation_warning"]),
    (estimator, multiple_shooting, ["SUSPECT_NOISE_RATIO", "SEGMENT_MIN_SAMPLES"]),
    (estimator, profile, ["PROFILE_DOUBLINGS", "CHI2_95"]),
    (oe, variable_projection, ["cramer_rao_bound", "continue_fitted", "GRID_SAMPLES"]),
    (procedure, result, ["IdentifyOptions", "IdentificationResult", "interval95", "METHODS"]),
    (step_ls, step_shape_fit, ["step_shape"]),
    (fuel, correlations, ["rho_TS1", "nu_TS1", "nu_JetA_CRC", "rho_JetA", "mu_JP8_table"]),
    (fuel, registry, ["Fuel", "FUELS", "DEFAULT_FUEL", "get_fuel", "fuel_properties"]),
]


@pytest.mark.parametrize(("old", "new", "names"), MOVED)
def test_old_path_gives_the_same_object(old: object, new: object, names: list[str]) -> None:
    for name in names:
        assert getattr(old, name) is getattr(new, name), name


def test_oe_keeps_its_private_names_for_scripts_and_benchmarks() -> None:
    assert oe._jacobian is variable_projection.jacobian
    assert oe._Structure is variable_projection.Structure
    assert oe._solve is variable_projection.solve_linear


def test_pem_and_oe_share_one_warm_start() -> None:
    model = importlib.import_module("fuelid.model").ProcessModel(K=1.0, T=4.0, T2=1.0, delay=0.5)
    st = variable_projection.Structure(2, 0.0, None, "estimate", None)
    z = variable_projection.start_from_model(model, st)
    assert z.tolist() == pytest.approx([np.log(4.0), np.log(1.0), 0.5])
    assert "start_from_model" in vars(pem)
    assert "_z_from" not in vars(pem.PredictionError)
    assert prediction_errors.JointFit.__module__ == "fuelid.identify.prediction_errors"


def test_cli_greybox_moved_constants_load_on_demand() -> None:
    cli = importlib.import_module("fuelid.cli.greybox")
    greybox_fit = importlib.import_module("fuelid.workflow.greybox_fit")
    assert cli.VALIDATION_CONVENTIONS is greybox_fit.VALIDATION_CONVENTIONS
    assert cli.RELATIVE_STDERR_LIMIT == greybox_fit.RELATIVE_STDERR_LIMIT
    with pytest.raises(AttributeError):
        _ = cli.NO_SUCH_NAME


def test_identifiability_text_names_what_the_data_do_not_determine() -> None:
    J = np.array([[1.0, 2.0], [2.0, 4.0], [3.0, 6.0]])
    lines = identifiability.describe_identifiability(
        identifiability.identifiability(J, ["a", "b"]).to_json()
    )
    assert lines[0].startswith("identifiability: rank 1 of 2 (a, b)")
    assert lines[1].startswith("undetermined combinations: a^")
    assert lines[2].startswith("confounded pairs: a–b")
