"""Deprecated: this module moved to :mod:`fuelid.io.fitted_model` in fuelid 0.2.0.

The old path still works and re-exports the module's names; importing it warns once
(DeprecationWarning). Import :mod:`fuelid.io.fitted_model` instead, where ``ModelFile`` is
:class:`~fuelid.io.fitted_model.FittedModel` and ``load_model_file`` is
:func:`~fuelid.io.fitted_model.load_fitted_model` (the old names were those of
:mod:`fuelid.greybox.modelfile`, which reads a user's Python model file).
"""

from __future__ import annotations

from typing import Any

import fuelid.io.fitted_model as _moved
from fuelid._deprecated import warn_moved
from fuelid.io.fitted_model import FittedModel as ModelFile
from fuelid.io.fitted_model import load_fitted_model as load_model_file

warn_moved("fuelid.io.modelfile", "fuelid.io.fitted_model")


def __getattr__(name: str) -> Any:
    # anything else the old module had (a private helper a script reached for) comes from the new
    return getattr(_moved, name)


__all__ = [
    "ModelFile",
    "load_model_file",
]
