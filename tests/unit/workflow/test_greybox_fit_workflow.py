"""The library side of ``fuelid greybox``: the model's free parameters, the columns, the records."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fuelid.errors import ConfigError
from fuelid.greybox.modelfile import read_model_file
from fuelid.workflow import data_columns, greybox_model, read_record

MODEL = Path(__file__).resolve().parents[3] / "examples" / "two_tanks.py"


def test_the_fixed_and_freed_parameters_reach_the_model() -> None:
    model = greybox_model(read_model_file(MODEL), fixed=["k4"], values={"k1": 0.07})
    by_name = {spec.name: spec for spec in model.parameters}
    assert by_name["k4"].fixed
    assert not by_name["k1"].fixed
    assert by_name["k1"].value == 0.07


def test_a_model_with_nothing_to_estimate_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"every parameter of .* is fixed"):
        greybox_model(read_model_file(MODEL), fixed=["k1", "k2", "k3", "k4"])


def test_columns_default_to_the_model_files_names() -> None:
    assert data_columns(read_model_file(MODEL), (), ()) == (("u_V",), ("h2_dm",))
    with pytest.raises(ConfigError, match="output"):
        data_columns(read_model_file(MODEL), (), ("a", "b"))


def test_an_empty_output_cell_is_a_missing_sample(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    path.write_text("t_s,u_V,h2_dm\n0,1.0,0.5\n1,1.0,\n2,1.5,0.7\n", encoding="utf-8")
    record = read_record(path, "t_s", ("u_V",), ("h2_dm",), None)
    assert record.name == "log.csv"
    assert np.isnan(record.y[1, 0])
    assert record.y[2, 0] == 0.7
