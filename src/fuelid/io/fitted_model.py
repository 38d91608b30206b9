"""Reading a process model (and its covariance) from a fuelid JSON result file.

``fuelid identify --json`` and ``fuelid plant info --json`` write the model family's parameters
under ``model``; ``tune --model`` and the sweep read them back here, with the covariance's model
block when the file has one, or refuse the file with the reason.

Before 0.2.0 this was ``fuelid.io.modelfile`` with ``ModelFile`` and ``load_model_file``, the
same names as :mod:`fuelid.greybox.modelfile`'s, which loads a user's Python gray-box model: the
names now say which is the fitted model of a JSON result.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import DataError, FuelidError
from fuelid.model import MODEL_KEYS, ProcessModel, check_gain_identified, model_covariance


def _covariance_entry(value: Any) -> float:
    """One covariance entry from JSON: a number, or null for "not known" (NaN)."""
    if value is None:
        return math.nan
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TypeError(value)
    return float(value)


@dataclass(frozen=True)
class FittedModel:
    """A process model read from a JSON result, with its covariance when there is one.

    ``cov`` is the model parameters' block (:func:`model_covariance`) of the file's covariance;
    nuisance parameters (offset, initial state) are dropped, unknown correlations taken as zero.
    """

    model: ProcessModel
    cov_names: tuple[str, ...]
    cov: list[list[float]] | None
    source: str
    cov_problem: str | None = None
    """Why the file's ``cov`` could not be used (wrong shape, not symmetric, …), else None."""
    u: float | None = None
    """Command the model was identified around [V] (the file's ``operating_point.u``), or None."""
    fuel_temperature: float | None = None
    """Fuel temperature during the identification [°C] (``operating_point``), or None."""
    signal_check: tuple[str, ...] = ()
    """The identification's findings that the signals were not in the units the gains are
    computed for (``signal_check``)."""
    alternatives: tuple[ProcessModel, ...] = ()
    """The structures the identification could not tell apart from its model
    (``structure.indistinct``): the gains are tuned on each too."""
    conditional: bool = False
    """Whether the file's intervals hold only within its structure (``structure.conditional``)."""


def load_fitted_model(path: str | Path) -> FittedModel:
    """Read the model of a ``fuelid identify --json`` (or ``plant info --json``) result.

    Raises
    ------
    DataError
        If the file is missing, not JSON, not such a result, or its model is incomplete or
        physically impossible (non-positive T, negative delay).
    """
    file = Path(path)
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DataError(f"model file {str(file)!r} does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"cannot read model file {str(file)!r}: {exc}") from None
    except json.JSONDecodeError as exc:
        msg = f"model file {str(file)!r} is not JSON ({exc.msg}, line {exc.lineno})"
        raise DataError(msg) from None
    if not isinstance(data, dict) or not isinstance(data.get("model"), dict):
        raise DataError(
            f"model file {str(file)!r} is not a fuelid identification result: it has no "
            "'model' object (write one with fuelid identify --json > ident.json)"
        )
    raw = data["model"]
    missing = [key for key in ("K", "T") if raw.get(key) is None]
    if missing:
        raise DataError(f"model file {str(file)!r}: the model lacks {', '.join(missing)}")
    values: dict[str, float] = {}
    for key in MODEL_KEYS:
        value = raw.get(key, 0.0)
        if value is None:
            value = 0.0
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise DataError(f"model file {str(file)!r}: model {key} is not a number: {value!r}")
        if not math.isfinite(value):
            raise DataError(f"model file {str(file)!r}: model {key} is not finite")
        values[key] = float(value)
    try:
        model = ProcessModel(**values)
    except FuelidError as exc:
        raise DataError(f"model file {str(file)!r}: {exc}") from None
    errors = data.get("stderr")
    se_K = errors.get("K") if isinstance(errors, dict) else None
    if isinstance(se_K, int | float) and not isinstance(se_K, bool):
        check_gain_identified(model.K, float(se_K), f"model file {str(file)!r}")
    cov_names: tuple[str, ...] = ()
    cov = None
    # a covariance that cannot be used is noted, not fatal: the model alone still tunes, and
    # only an uncertainty sweep needs it
    cov_problem: str | None = None
    block = data.get("cov")
    if block is not None and not (isinstance(block, dict) and isinstance(block.get("names"), list)):
        cov_problem = "its 'cov' is not an object with 'names' and 'matrix'"
    elif block is not None:
        names = [str(n) for n in block["names"]]
        matrix = block.get("matrix")
        full = None
        if not (
            names
            and isinstance(matrix, list)
            and len(matrix) == len(names)
            and all(isinstance(r, list) and len(r) == len(names) for r in matrix)
        ):
            cov_problem = f"its covariance matrix is not {len(names)}×{len(names)} like its names"
        else:
            try:
                full = [[_covariance_entry(v) for v in row] for row in matrix]
            except TypeError:
                cov_problem = "its covariance matrix holds entries that are not numbers"
        if full is not None:
            kept, model_block = model_covariance(names, full)
            cov_problem = _covariance_problem(kept, model_block)
            if cov_problem is None:
                cov_names, cov = tuple(kept), model_block.tolist()
    u, fuel_temperature = _operating_point(data.get("operating_point"), file)
    findings = data.get("signal_check")
    alternatives, conditional = _structure(data.get("structure"), file)
    return FittedModel(
        alternatives=alternatives,
        conditional=conditional,
        model=model,
        cov_names=cov_names,
        cov=cov,
        source=str(file),
        cov_problem=cov_problem,
        u=u,
        fuel_temperature=fuel_temperature,
        signal_check=tuple(str(f) for f in findings) if isinstance(findings, list) else (),
    )


def _operating_point(block: Any, file: Path) -> tuple[float | None, float | None]:
    """The command [V] and fuel temperature [°C] of an ``operating_point`` object (None: absent)."""
    if block is None:
        return None, None
    if not isinstance(block, dict):
        raise DataError(f"model file {str(file)!r}: 'operating_point' is not an object")
    found: list[float | None] = []
    for key in ("u", "fuel_temperature"):
        value = block.get(key)
        if value is None:
            found.append(None)
            continue
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise DataError(
                f"model file {str(file)!r}: operating_point {key} is not a finite number"
            )
        found.append(float(value))
    return found[0], found[1]


def _covariance_problem(names: list[str], block: NDArray[np.float64]) -> str | None:
    """Why the model parameters' covariance block cannot be sampled, or None."""
    if not names:
        return "its covariance has no variance for any of K, T, T2, T_f, delay"
    if not np.allclose(block, block.T, rtol=1e-6, atol=0.0):
        return "its covariance matrix is not symmetric"
    eigenvalues = np.linalg.eigvalsh(block)
    if eigenvalues[0] < -1e-9 * max(eigenvalues[-1], 0.0):
        return "its covariance matrix is not positive semi-definite"
    return None


def _structure(block: object, file: Path) -> tuple[tuple[ProcessModel, ...], bool]:
    """The indistinct structures and the conditional flag of an identification's ``structure``.

    Files written before the order rule have no ``structure``: no alternatives, not conditional.
    """
    if block is None:
        return (), False
    if not isinstance(block, dict):
        raise DataError(f"model file {str(file)!r}: its 'structure' is not an object")
    models = []
    for item in block.get("indistinct") or []:
        raw = item.get("model") if isinstance(item, dict) else None
        if not isinstance(raw, dict):
            raise DataError(
                f"model file {str(file)!r}: a 'structure.indistinct' entry has no model"
            )
        try:
            models.append(ProcessModel(**{key: float(raw.get(key) or 0.0) for key in MODEL_KEYS}))
        except (TypeError, ValueError, FuelidError) as exc:
            raise DataError(
                f"model file {str(file)!r}: a 'structure.indistinct' model is invalid: {exc}"
            ) from None
    return tuple(models), bool(block.get("conditional", False))
