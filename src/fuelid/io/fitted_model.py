"""Reading a process model (and its covariance) from a fuelid JSON result file.

``fuelid identify --json`` and ``fuelid plant info --json`` write the model family's parameters
under ``model``; ``tune --model`` and the sweep read them back here, with the covariance's model
block when the file has one, or refuse the file with the reason. Also read: the operating point
(``operating_point.u``/``.fuel_temperature``, or the top-level ``u``/``fuel_temperature`` that
plant-info files have always had), the full linearisation ``linear_model`` of a plant-info
file, the control period identify was given (``options.control_period`` with
``options.control_period_given``), the standard errors, 95 % intervals and the ``fixed`` list.
docs/reference/model-file.md lists them.

This module only reads: it does not tune, identify or decide what an undetermined model means.

Before 0.2.0 this was ``fuelid.io.modelfile`` with ``ModelFile`` and ``load_model_file``, the
same names as :mod:`fuelid.greybox.modelfile`'s, which loads a user's Python gray-box model: the
names now say which is the fitted model of a JSON result.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import DataError, FuelidError
from fuelid.io._model_units import in_default_units
from fuelid.lti import check_control_period
from fuelid.model import MODEL_KEYS, ProcessModel, check_gain_identified, model_covariance

if TYPE_CHECKING:
    import control


@dataclass(frozen=True)
class LinearModelSpec:
    """A plant's full linear model as a model file gives it (``linear_model`` of plant info).

    The transfer function num(s)/den(s)·e^(−delay·s) from the command u [V] to the meter reading
    [L/min], so that its static gain num[-1]/den[-1] is in (L/min)/V; coefficients in descending
    powers of s. The dead time is kept apart, never Padé-approximated.

    Raises
    ------
    DataError
        If a coefficient or the delay is not a finite number, ``den`` is empty or starts with 0,
        ``num`` is empty or longer than ``den`` (improper), or the delay is negative.

    Examples
    --------
    >>> spec = LinearModelSpec(num=(2.0,), den=(0.5, 1.0), delay=0.2)
    >>> float(spec.to_control().dcgain()), spec.delay
    (2.0, 0.2)
    >>> LinearModelSpec(num=(1.0,), den=(0.0, 1.0), delay=0.0)
    Traceback (most recent call last):
    ...
    fuelid.errors.DataError: linear_model.den starts with 0: the leading coefficient must not be 0
    """

    num: tuple[float, ...]
    """Numerator coefficients, descending powers of s [(L/min)/V · s^k]."""
    den: tuple[float, ...]
    """Denominator coefficients, descending powers of s; ``den[0]`` ≠ 0 [s^k]."""
    delay: float
    """Dead time of the meter reading [s], ≥ 0, explicit (not in num/den)."""

    def __post_init__(self) -> None:
        problem = _linear_model_problem(self.num, self.den, self.delay)
        if problem is not None:
            raise DataError(problem)
        # lists (as JSON gives them) and ints become the tuples of floats the fields say
        object.__setattr__(self, "num", tuple(float(v) for v in self.num))
        object.__setattr__(self, "den", tuple(float(v) for v in self.den))
        object.__setattr__(self, "delay", float(self.delay))

    def to_control(self) -> control.TransferFunction:
        """The delay-free part num(s)/den(s) as a :class:`control.TransferFunction`.

        The dead time is :attr:`delay`: apply it explicitly (``control.pade(spec.delay, n)`` or
        e^(−jω·delay) on a frequency grid) where a caller needs it.
        """
        import control  # slow to import: only when the transfer function is wanted

        return control.tf(list(self.num), list(self.den))


def _linear_model_problem(num: Any, den: Any, delay: Any) -> str | None:
    """Why ``num``, ``den``, ``delay`` are not a proper delayed transfer function, or None."""
    for key, coefficients in (("num", num), ("den", den)):
        if not isinstance(coefficients, tuple | list) or not all(
            _is_finite_number(v) for v in coefficients
        ):
            return f"linear_model.{key} is not a list of finite numbers ({_shown(coefficients)})"
        if not coefficients:
            return f"linear_model.{key} is empty"
    if den[0] == 0.0:
        return "linear_model.den starts with 0: the leading coefficient must not be 0"
    if len(num) > len(den):
        return (
            f"linear_model.num has {len(num)} coefficients, den {len(den)}: the transfer "
            "function is improper (more zeros than poles)"
        )
    if not _is_finite_number(delay) or delay < 0.0:
        return f"linear_model.delay is not a finite number of seconds >= 0 ({_shown(delay)})"
    return None


def _shown(value: Any) -> str:
    """A JSON value in a one-line message: a number or a short list as it is, else its type."""
    text = json.dumps(value) if isinstance(value, int | float | list | type(None)) else ""
    return f"got {text}" if text and len(text) <= 60 else f"got a {type(value).__name__}"


def _is_finite_number(value: Any) -> bool:
    """Whether a JSON value is a finite number (a bool is not)."""
    return not isinstance(value, bool) and isinstance(value, int | float) and math.isfinite(value)


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
    """Command the model was identified around [V] (the file's ``operating_point.u``, else its
    top-level ``u`` as plant info writes it), or None."""
    fuel_temperature: float | None = None
    """Fuel temperature the model is for [°C] (``operating_point.fuel_temperature``, else the
    top-level ``fuel_temperature``), or None."""
    signal_check: tuple[str, ...] = ()
    """The identification's findings that the signals were not in the units the gains are
    computed for (``signal_check``)."""
    alternatives: tuple[ProcessModel, ...] = ()
    """The structures the identification could not tell apart from its model
    (``structure.indistinct``): the gains are tuned on each too."""
    conditional: bool = False
    """Whether the file's intervals hold only within its structure (``structure.conditional``)."""
    control_period: float | None = None
    """The control period identify was given with ``--control-period`` [s] (0: continuous PI):
    the file's ``options.control_period`` only when ``options.control_period_given`` is true
    (a recorded value that is not 0 … 10 s is refused); else None (files written before the flag
    recorded 1.0 whether it was given or not)."""
    linear_model: LinearModelSpec | None = None
    """The full linearisation u [V] → meter reading [L/min] with its dead time [s]
    (``linear_model`` of ``plant info --json``), or None when the file has none."""
    stderr: dict[str, float | None] = field(default_factory=lambda: dict.fromkeys(MODEL_KEYS))
    """Standard error of each of K [(L/min)/V], T, T2, T_f, delay [s] (``stderr``); None when
    the file gives none (a fixed or undetermined parameter) or a malformed one."""
    ci95: dict[str, tuple[float, float] | None] = field(
        default_factory=lambda: dict.fromkeys(MODEL_KEYS)
    )
    """95 % interval (low, high) of each of K [(L/min)/V], T, T2, T_f, delay [s] (``ci95``);
    None when the file gives none or a malformed one. A bound written as null (the JSON of an
    interval that overflowed to ±inf) reads back as -inf (low) or +inf (high), and a huge bound
    such as 1e300 stays as it is: an unbounded interval is visible as such."""
    fixed: tuple[str, ...] = ()
    """The parameters the identification held fixed (``fixed``): priors, not estimates."""
    misfit: dict[str, Any] | None = None
    """The identification's ``diagnostics.misfit`` as written (the model error its log shows:
    ``omega``, ``delta_re``, ``delta_im``, ``radius``, ``averages``), when it is well formed."""
    leads: bool = False
    """Whether the identification found the flow moving before its command
    (``diagnostics.lead.leads``): a reversed clock or swapped columns."""
    gain_bands: tuple[tuple[float, float, float, float | None], ...] = ()
    """K per command band of the identification's log (``diagnostics.nonlinearity.bands``):
    (u_low [V], u_high [V], K [(L/min)/V], its standard error or None)."""


def load_fitted_model(path: str | Path) -> FittedModel:
    """Read the model of a ``fuelid identify --json`` (or ``plant info --json``) result.

    Raises
    ------
    DataError
        If the file is missing, not JSON, not such a result, or its model is incomplete or
        physically impossible (non-positive T, negative delay); if its operating point is not
        finite numbers, or its ``linear_model`` is not a proper transfer function of finite
        coefficients with a finite delay ≥ 0 (the message names the key); if its ``units`` map
        gives a unit fuelid neither writes nor converts (:mod:`fuelid.io._model_units`) for a
        number it reads. A malformed
        ``stderr`` or ``ci95`` entry is read as None, not refused; a recorded control period
        (``options.control_period`` with ``control_period_given``) that is not 0 … 10 s is.
    """
    file = Path(path)
    data = in_default_units(_read_result(file), file)  # an edited units map: converted or refused
    model = _process_model(data["model"], file)
    errors = data.get("stderr")
    se_K = errors.get("K") if isinstance(errors, dict) else None
    if isinstance(se_K, int | float) and not isinstance(se_K, bool):
        check_gain_identified(model.K, float(se_K), f"model file {str(file)!r}")
    cov_names, cov, cov_problem = _covariance(data.get("cov"))
    u, fuel_temperature = _operating_point(data, file)
    findings = data.get("signal_check")
    alternatives, conditional = _structure(data.get("structure"), file)
    fixed = data.get("fixed")
    return FittedModel(
        control_period=_control_period(data.get("options"), file),
        gain_bands=_gain_bands(data.get("diagnostics")),
        leads=_leads(data.get("diagnostics")),
        misfit=_misfit(data.get("diagnostics")),
        linear_model=_linear_model(data.get("linear_model"), file),
        stderr=_stderr(errors),
        ci95=_intervals(data.get("ci95")),
        fixed=tuple(k for k in fixed if isinstance(k, str)) if isinstance(fixed, list) else (),
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


def _read_result(file: Path) -> dict[str, Any]:
    """The JSON object of a result file that has a ``model`` object, or a DataError saying why."""
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
    return data


def _process_model(raw: dict[str, Any], file: Path) -> ProcessModel:
    """The ``model`` object as a ProcessModel: K and T given, every parameter a finite number."""
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
        return ProcessModel(**values)
    except FuelidError as exc:
        raise DataError(f"model file {str(file)!r}: {exc}") from None


def _covariance(block: Any) -> tuple[tuple[str, ...], list[list[float]] | None, str | None]:
    """The model block of the file's ``cov``: (names, matrix, None), or ((), None, the problem).

    A covariance that cannot be used is noted, not fatal: the model alone still tunes, and only
    an uncertainty sweep needs it. No ``cov`` at all is ((), None, None).
    """
    if block is None:
        return (), None, None
    if not (isinstance(block, dict) and isinstance(block.get("names"), list)):
        return (), None, "its 'cov' is not an object with 'names' and 'matrix'"
    names = [str(n) for n in block["names"]]
    matrix = block.get("matrix")
    if not (
        names
        and isinstance(matrix, list)
        and len(matrix) == len(names)
        and all(isinstance(r, list) and len(r) == len(names) for r in matrix)
    ):
        return (), None, f"its covariance matrix is not {len(names)}×{len(names)} like its names"
    try:
        full = [[_covariance_entry(v) for v in row] for row in matrix]
    except TypeError:
        return (), None, "its covariance matrix holds entries that are not numbers"
    kept, model_block = model_covariance(names, full)
    problem = _covariance_problem(kept, model_block)
    if problem is not None:
        return (), None, problem
    return tuple(kept), model_block.tolist(), None


def _gain_bands(diagnostics: Any) -> tuple[tuple[float, float, float, float | None], ...]:
    """``diagnostics.nonlinearity.bands`` as (u_low [V], u_high [V], K, its standard error).

    A row that is not four finite numbers (the error may be null) is left out: the bands are
    evidence for a range check, and a damaged row must not pass for one.
    """
    nonlinearity = diagnostics.get("nonlinearity") if isinstance(diagnostics, dict) else None
    rows = nonlinearity.get("bands") if isinstance(nonlinearity, dict) else None
    bands = []
    for row in rows if isinstance(rows, list) else []:
        if not isinstance(row, dict):
            continue
        values: list[Any] = [row.get(key) for key in ("u_low", "u_high", "K")]
        se = row.get("stderr")
        if not all(_finite_number(v) for v in values) or not (se is None or _finite_number(se)):
            continue
        low, high, K = (float(v) for v in values)
        if low < high and K > 0.0:
            bands.append((low, high, K, None if se is None else float(se)))
    return tuple(bands)


def _misfit(diagnostics: Any) -> dict[str, Any] | None:
    """``diagnostics.misfit`` when its arrays are equally long lists of finite numbers."""
    block = diagnostics.get("misfit") if isinstance(diagnostics, dict) else None
    if not isinstance(block, dict):
        return None
    keys = ("omega", "delta_re", "delta_im", "radius")
    arrays: list[list[Any]] = []
    for key in keys:
        values = block.get(key)
        if not (isinstance(values, list) and values and all(_finite_number(v) for v in values)):
            return None
        arrays.append(values)
    if len({len(a) for a in arrays}) != 1 or not _finite_number(block.get("averages")):
        return None
    return {key: block[key] for key in (*keys, "averages")}


def _leads(diagnostics: Any) -> bool:
    """``diagnostics.lead.leads`` is true (anything else: false)."""
    lead = diagnostics.get("lead") if isinstance(diagnostics, dict) else None
    return isinstance(lead, dict) and lead.get("leads") is True


def _finite_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _operating_point(data: dict[str, Any], file: Path) -> tuple[float | None, float | None]:
    """The command [V] and fuel temperature [°C] the model is for (None: not in the file).

    Each from ``operating_point`` when it is there (identify writes it there, plant info too),
    else from the top level (where ``plant info --json`` has always written them).
    """
    block = data.get("operating_point")
    if block is not None and not isinstance(block, dict):
        raise DataError(f"model file {str(file)!r}: 'operating_point' is not an object")
    found: list[float | None] = []
    for key in ("u", "fuel_temperature"):
        name, value = f"operating_point {key}", (block or {}).get(key)
        if value is None:
            name, value = key, data.get(key)
        if value is None:
            found.append(None)
        elif _is_finite_number(value):
            found.append(float(value))
        else:
            raise DataError(f"model file {str(file)!r}: {name} is not a finite number")
    return found[0], found[1]


def _control_period(options: Any, file: Path) -> float | None:
    """``options.control_period`` [s] when ``options.control_period_given`` is true, else None.

    A recorded period is the PLC's: one that is not a number, negative, not finite or beyond
    10 s is refused (:func:`~fuelid.lti.check_control_period`), never read as absent.
    """
    if not isinstance(options, dict) or options.get("control_period_given") is not True:
        return None
    value = options.get("control_period")
    if value is None:  # given, but not recorded: none, as in a file written without it
        return None
    try:
        check_control_period(value, "options.control_period")
    except FuelidError as exc:
        raise DataError(f"model file {str(file)!r}: {exc}") from None
    return float(value)  # a number: checked above


def _linear_model(block: Any, file: Path) -> LinearModelSpec | None:
    """The file's ``linear_model`` (None when absent), refused with the key when malformed."""
    if block is None:
        return None
    if not isinstance(block, dict):
        raise DataError(
            f"model file {str(file)!r}: 'linear_model' is not an object with num, den and delay "
            f"(it is a {type(block).__name__})"
        )
    num: Any = block.get("num")  # checked by LinearModelSpec, which names what is wrong
    den: Any = block.get("den")
    delay: Any = block.get("delay")
    try:
        return LinearModelSpec(num=num, den=den, delay=delay)
    except DataError as exc:
        raise DataError(f"model file {str(file)!r}: {exc}") from None


def _stderr(block: Any) -> dict[str, float | None]:
    """Each model parameter's standard error: a number ≥ 0 (inf kept), else None."""
    out: dict[str, float | None] = {}
    for key in MODEL_KEYS:
        value = block.get(key) if isinstance(block, dict) else None
        if isinstance(value, bool) or not isinstance(value, int | float):
            out[key] = None
        else:
            out[key] = float(value) if value >= 0.0 else None  # NaN fails value >= 0 too
    return out


def _intervals(block: Any) -> dict[str, tuple[float, float] | None]:
    """Each model parameter's 95 % interval (:func:`_interval`); empty without a ``ci95``.

    A file without ``ci95`` (``plant info --json``: a model from physics, not from data) has no
    intervals to judge; a file with one gives every key, None where it has no interval, and a
    ``ci95`` that is not an object gives None for every key.
    """
    if block is None:
        return {}
    if not isinstance(block, dict):  # there, but damaged: every interval unknown, judged so
        return dict.fromkeys(MODEL_KEYS)
    return {key: _interval(block.get(key)) for key in MODEL_KEYS}


def _interval(value: Any) -> tuple[float, float] | None:
    """(low, high) from a JSON [low, high]; None when absent or malformed.

    fuelid writes ±inf as null (:func:`fuelid.io.jsonsafe.json_ready`), and an interval's bound
    is never NaN when its standard error is finite (:func:`fuelid.identify._result.interval95`):
    a null low is -inf, a null high +inf. Large finite bounds are kept as they are.
    """
    if not isinstance(value, list) or len(value) != 2:
        return None
    bounds: list[float] = []
    for bound, unbounded in zip(value, (-math.inf, math.inf), strict=True):
        if bound is None:
            bounds.append(unbounded)
        elif (
            not isinstance(bound, bool) and isinstance(bound, int | float) and not math.isnan(bound)
        ):
            bounds.append(float(bound))
        else:
            return None
    return (bounds[0], bounds[1]) if bounds[0] <= bounds[1] else None


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
