"""Uncertainty of the plant's predictions from the covariance of its calibrated parameters.

A plant calibrated from logs carries the covariance Σ of its calibrated parameters θ (the
``[calibration]`` table, :class:`~fuelid.plant._config.CalibrationRecord`, in the keys' units).
The delta method propagates it to any smooth prediction g(θ):

    var g ≈ ∇g(θ)ᵀ · Σ · ∇g(θ),

with the gradient by central finite differences of g over the calibrated parameters. The
predictions here are those of ``fuelid plant info`` at one command and fuel temperature: the
static gain K [(L/min)/V] and the lag T [s] of the equivalent model and the 98 % settling time of
the linearised plant [s] (:func:`fuelid.plant._linear.linearise`). The 95 % interval is
g ± 1.96·σ_g (first order: valid while g is close to linear over the parameters' spread).

Outside the fuel-temperature range of the calibration logs the physics carries the parameters
there; :attr:`PredictionUncertainty.extrapolated` says so.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fuelid.errors import ConfigError
from fuelid.plant._config import PlantConfig, calibrated_temperature_range
from fuelid.plant._linear import linearise
from fuelid.plant._parameters import get_parameter, plant_parameters, with_parameters
from fuelid.units import kelvin_to_celsius

FloatArray = NDArray[np.float64]

Z95 = 1.959963984540054
"""Two-sided 95 % quantile of the standard normal distribution [-]."""

RELATIVE_STEP = 1e-3
"""Finite-difference step, relative to max(|θ|, σ_θ) of each parameter [-]."""

QUANTITIES = ("K", "T", "settling_time")
"""The predictions whose uncertainty is propagated."""

QUANTITY_UNITS = {"K": "(L/min)/V", "T": "s", "settling_time": "s"}
"""Units of :data:`QUANTITIES`."""

Prediction = Callable[[PlantConfig], dict[str, float]]
"""A function of a plant config returning named predictions."""


METER_LAG = "flowmeter.time_constant_s"
"""The plant parameter that is the equivalent model's T_f."""


@dataclass(frozen=True)
class QuantityUncertainty:
    """A prediction with its standard error and 95 % interval."""

    value: float
    """The prediction at the calibrated parameters [its unit]."""
    stderr: float
    """Standard error by the delta method [its unit]."""
    gradient: dict[str, float]
    """∂(prediction)/∂θ for each calibrated parameter [its unit per the parameter's unit]."""

    @property
    def ci95(self) -> tuple[float, float]:
        """The 95 % interval, value ∓ 1.96·stderr [its unit]."""
        return (self.value - Z95 * self.stderr, self.value + Z95 * self.stderr)

    def to_json(self) -> dict[str, Any]:
        """``{"value", "stderr", "ci95": [lo, hi]}``."""
        return {"value": self.value, "stderr": self.stderr, "ci95": list(self.ci95)}


@dataclass(frozen=True)
class PredictionUncertainty:
    """K, T and the settling time at one operating point, with their uncertainty."""

    u: float
    """Command [V]."""
    T_fuel: float
    """Fuel temperature [K]."""
    parameters: tuple[str, ...]
    """The calibrated parameters whose covariance was propagated."""
    quantities: dict[str, QuantityUncertainty]
    """``K`` [(L/min)/V], ``T`` [s], ``settling_time`` [s]; ``T_f`` [s] when the meter's lag was
    calibrated."""
    temperature_range: tuple[float, float] | None
    """Fuel-temperature range of the calibration logs [°C]; None when they are not recorded."""
    warnings: tuple[str, ...] = field(default=())
    """What the numbers rest on that the user should know (extrapolation, stale record)."""
    calibration_warnings: tuple[str, ...] = field(default=())
    """What the calibration itself warned about (its ``[calibration] warnings``)."""

    @property
    def extrapolated(self) -> bool:
        """True when the fuel temperature lies outside the calibration logs' range."""
        return _outside(self.T_fuel, self.temperature_range)

    def to_json(self) -> dict[str, Any]:
        """``{"uncertainty": {...}, "calibration": {...}}`` for ``fuelid plant info --json``."""
        lo_hi = None if self.temperature_range is None else list(self.temperature_range)
        return {
            "uncertainty": {name: q.to_json() for name, q in self.quantities.items()},
            "calibration": {
                "parameters": list(self.parameters),
                "fuel_temperature_range_C": lo_hi,
                "extrapolated": self.extrapolated,
                "warnings": list(self.calibration_warnings),
            },
        }


def equivalent_predictions(u: float, T_fuel: float) -> Prediction:
    """K, T and the 98 % settling time of a plant at command ``u`` [V] and ``T_fuel`` [K]."""

    def predict(config: PlantConfig) -> dict[str, float]:
        reduced = linearise(config, u, T_fuel).equivalent_model()
        return {
            "K": reduced.model.K,
            "T": reduced.model.T,
            "settling_time": reduced.settling_time,
        }

    return predict


def delta_method(
    config: PlantConfig,
    names: tuple[str, ...],
    covariance: FloatArray,
    predict: Prediction,
    relative_step: float = RELATIVE_STEP,
) -> dict[str, QuantityUncertainty]:
    """Propagate a parameter covariance to predictions by the delta method.

    The gradient of each prediction over each parameter θᵢ is the central difference
    (g(θᵢ + hᵢ) − g(θᵢ − hᵢ)) / 2hᵢ with hᵢ = ``relative_step``·max(|θᵢ|, σᵢ) (σᵢ² the
    covariance's diagonal); a one-sided difference where a step would leave the parameter's
    valid range (θᵢ = 0 for a parameter that may not be negative, …).

    Parameters
    ----------
    config : PlantConfig
        The plant at the calibrated parameters.
    names : tuple of str
        Dotted names of the parameters, in the order of ``covariance``.
    covariance : ndarray, shape (n, n)
        Their covariance, in the products of their natural units.
    predict : callable
        Plant config to a dict of named predictions.
    relative_step : float
        See above [-].

    Returns
    -------
    dict of str to QuantityUncertainty
        One entry per prediction.

    Raises
    ------
    ConfigError
        If ``covariance`` is not n×n, or a parameter cannot be moved either way.
    """
    n = len(names)
    cov = np.asarray(covariance, dtype=float)
    if cov.shape != (n, n):
        raise ConfigError(f"the covariance is {cov.shape}, expected {n}×{n} for {n} parameters")
    centre = predict(config)
    gradients = {key: np.zeros(n) for key in centre}
    for i, name in enumerate(names):
        theta = get_parameter(config, name)
        sigma = math.sqrt(max(float(cov[i, i]), 0.0))
        h = relative_step * max(abs(theta), sigma)
        if h == 0.0:
            continue  # fixed: no spread, no contribution
        slope = _slope(config, name, theta, h, centre, predict)
        for key in centre:
            gradients[key][i] = slope[key]
    out: dict[str, QuantityUncertainty] = {}
    for key, value in centre.items():
        g = gradients[key]
        variance = max(float(g @ cov @ g), 0.0)
        out[key] = QuantityUncertainty(
            value=value,
            stderr=math.sqrt(variance),
            gradient={name: float(g[i]) for i, name in enumerate(names)},
        )
    return out


def _slope(
    config: PlantConfig,
    name: str,
    theta: float,
    h: float,
    centre: dict[str, float],
    predict: Prediction,
) -> dict[str, float]:
    """Central difference of every prediction over one parameter, one-sided at a bound."""
    up = _moved(config, name, theta + h, predict)
    down = _moved(config, name, theta - h, predict)
    if up is not None and down is not None:
        return {key: (up[key] - down[key]) / (2.0 * h) for key in centre}
    if up is not None:
        return {key: (up[key] - centre[key]) / h for key in centre}
    if down is not None:
        return {key: (centre[key] - down[key]) / h for key in centre}
    raise ConfigError(f"cannot vary {name} by ±{h:g} about {theta:g}: both steps are invalid")


def _moved(
    config: PlantConfig, name: str, value: float, predict: Prediction
) -> dict[str, float] | None:
    """Predictions with one parameter moved; None when the config refuses the value."""
    try:
        moved = with_parameters(config, {name: value})
    except ConfigError:
        return None
    return predict(moved)


def prediction_uncertainty(
    config: PlantConfig, u: float, T_fuel: float, relative_step: float = RELATIVE_STEP
) -> PredictionUncertainty:
    """K, T and the 98 % settling time at (u, T_fuel), with the calibration's uncertainty.

    Parameters
    ----------
    config : PlantConfig
        A plant with a ``[calibration]`` table that has a ``covariance``.
    u : float
        Command [V].
    T_fuel : float
        Fuel temperature [K].
    relative_step : float
        Finite-difference step (see :func:`delta_method`) [-].

    Returns
    -------
    PredictionUncertainty

    Raises
    ------
    ConfigError
        If the config has no ``[calibration]`` table or the table has no covariance.
    OutOfRangeError
        If ``u`` or ``T_fuel`` is outside the plant's or the fuel correlation's range.
    """
    record = config.calibration
    if record is None:
        raise ConfigError("the plant config has no [calibration] table: nothing to propagate")
    if record.covariance is None:
        raise ConfigError("the plant config's [calibration] table has no covariance")
    names = record.parameters
    warnings: list[str] = []
    current = plant_parameters(config)
    stale = [
        name
        for name, recorded in zip(names, record.values, strict=True)
        if not math.isclose(current[name].value, recorded, rel_tol=1e-9, abs_tol=1e-12)
    ]
    if stale:
        warnings.append(
            "the plant's values of "
            + ", ".join(stale)
            + " differ from the [calibration] record's: the covariance is applied at the "
            "plant's values"
        )
    quantities = delta_method(
        config,
        names,
        np.array(record.covariance, dtype=float),
        equivalent_predictions(u, T_fuel),
        relative_step,
    )
    if METER_LAG in names:
        # the equivalent model's T_f is the meter's lag itself: its error is the parameter's
        i = names.index(METER_LAG)
        variance = float(np.asarray(record.covariance, dtype=float)[i, i])
        quantities = {
            **quantities,
            "T_f": QuantityUncertainty(
                current[METER_LAG].value,
                math.sqrt(max(variance, 0.0)),
                {name: float(name == METER_LAG) for name in names},
            ),
        }
    notes = calibration_summary(config, T_fuel)[1]
    return PredictionUncertainty(
        u=u,
        T_fuel=T_fuel,
        parameters=names,
        quantities=quantities,
        temperature_range=calibrated_temperature_range(config),
        warnings=(*warnings, *notes),
        calibration_warnings=record.warnings,
    )


def calibration_summary(config: PlantConfig, T_fuel: float) -> tuple[dict[str, Any], list[str]]:
    """What a prediction at ``T_fuel`` [K] rests on: the calibration's parameters and range.

    Parameters
    ----------
    config : PlantConfig
        A plant with a ``[calibration]`` table.
    T_fuel : float
        Fuel temperature of the prediction [K].

    Returns
    -------
    (dict, list of str)
        ``{"parameters", "fuel_temperature_range_C", "extrapolated", "warnings"}`` and the notes
        for the user (one when ``T_fuel`` lies outside the calibration logs' range, one per
        warning the calibration gave).

    Raises
    ------
    ConfigError
        If the config has no ``[calibration]`` table.
    """
    record = config.calibration
    if record is None:
        raise ConfigError("the plant config has no [calibration] table")
    span = calibrated_temperature_range(config)
    extrapolated = _outside(T_fuel, span)
    notes = []
    if extrapolated and span is not None:
        notes.append(
            f"{kelvin_to_celsius(T_fuel):g} °C is outside the calibration logs' "
            f"{span[0]:g}…{span[1]:g} °C: K, T come from the physics, not from data at this "
            "temperature"
        )
    notes.extend(f"the calibration warned: {warning}" for warning in record.warnings)
    summary = {
        "parameters": list(record.parameters),
        "fuel_temperature_range_C": None if span is None else list(span),
        "extrapolated": extrapolated,
        "warnings": list(record.warnings),
    }
    return summary, notes


def _outside(T_fuel: float, span: tuple[float, float] | None) -> bool:
    """True when ``T_fuel`` [K] lies outside ``span`` [°C] (to 1 nK); False without a span."""
    if span is None:
        return False
    t = round(kelvin_to_celsius(T_fuel), 9)
    return not span[0] <= t <= span[1]
